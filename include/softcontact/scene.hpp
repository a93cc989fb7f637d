#pragma once
// A validated scene: simulation settings, materials, friction table and the objects with
// their meshes already placed in world coordinates (SI units throughout). Produced by
// load_scene() from a YAML file whose format docs/scene-format.md documents key by key.
#include <array>
#include <cstdint>
#include <functional>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "softcontact/box.hpp"
#include "softcontact/material_laws.hpp"
#include "softcontact/mesh.hpp"
#include "softcontact/surface.hpp"

namespace softcontact {

using Vec3 = std::array<double, 3>;

/// A material's deformation model: its position in the registry list of material laws
/// (material_laws.hpp), one enumerator per law, named as in scene files.
enum class ModelKind {
#define SOFTCONTACT_MODEL_KIND(name) name,
  SOFTCONTACT_MATERIAL_LAWS(SOFTCONTACT_MODEL_KIND)
#undef SOFTCONTACT_MODEL_KIND
};
/// Number of material laws.
#define SOFTCONTACT_COUNT_LAW(name) +1
inline constexpr int kModelKinds = 0 SOFTCONTACT_MATERIAL_LAWS(SOFTCONTACT_COUNT_LAW);
#undef SOFTCONTACT_COUNT_LAW
enum class IntegratorKind { verlet, symplectic_euler, implicit_euler };
/// What bounds an object's highest frequency for the stable step: the largest of its tets'
/// own (Irons' element bound, cheap) or its assembled mesh's, certified (docs/models.md).
enum class DtBound { element, mesh };

const char* to_string(ModelKind m);
const char* to_string(IntegratorKind i);
const char* to_string(DtBound b);

struct Material {
  std::string name;
  ModelKind model = ModelKind::corotational;
  double young = 0;            ///< Young's modulus E [Pa]
  double poisson = 0;          ///< Poisson ratio nu, in (-1, 0.5)
  double density = 0;          ///< rho [kg/m^3]
  double damping_mass = 0;     ///< Rayleigh alpha [1/s]: damping force -alpha m v
  double damping_stiffness = 0;///< Rayleigh beta [s]: damping force -beta K v

  double lame_lambda() const { return young * poisson / ((1 + poisson) * (1 - 2 * poisson)); }
  double lame_mu() const { return young / (2 * (1 + poisson)); }
  /// Dilatational wave speed sqrt((lambda + 2 mu) / rho) [m/s].
  double wave_speed() const;
};

/// Coulomb coefficients of a pair of materials (symmetric).
struct Friction {
  double mu_static = 0;
  double mu_kinetic = 0;
};

/// Prescribed motion of an object's fixed vertices (all of them when the object is
/// kinematic, else those in its `fixed` boxes): constant velocity from `start` until
/// `stop`, standing still before and after.
struct Motion {
  Vec3 velocity{};                                        ///< [m/s]
  double start = 0;                                       ///< [s]
  double stop = std::numeric_limits<double>::infinity();  ///< [s], > start
  bool moves() const { return velocity[0] != 0 || velocity[1] != 0 || velocity[2] != 0; }
  /// Length of [t0, t1] that lies inside [start, stop] [s]; the displacement over the
  /// interval is velocity times this.
  double active_time(double t0, double t1) const;
};

/// What every rank knows of an object, whether or not it holds the object's mesh
/// (Scene::shape): enough to number its vertices, tets and triangles, to weigh it for the
/// partition and to find its neighbours.
struct ObjectShape {
  std::size_t vertices = 0;
  std::size_t tets = 0;
  std::size_t triangles = 0;   ///< of its boundary (extract_surface)
  Box box = Box::none();       ///< at its initial positions; a NaN coordinate replaces the bound (add_point in box.hpp)
};

/// Which mesh it is, to the bit: FNV-1a over the counts, points and tets, a 64-bit word
/// at a time.
std::uint64_t mesh_digest(const TetMesh& mesh);

/// An entry's mesh as its transform placed it (scaled, rotated, moved), shared by the
/// objects made from it. It is held, or let go and made again from its source (the mesh
/// file read again, the primitive generated again) on a rank that needs it later, bitwise
/// the same: a digest of the first mesh is compared with every mesh made again, so that a
/// mesh file changed or removed during the run is a RuntimeFailure, never another body
/// (docs/architecture.md, "Who holds which mesh"). Copies of a Scene share their entry
/// meshes, and what one drops the others make again: like Scene::mesh, not thread-safe.
class EntryMesh {
public:
  /// An entry mesh that holds `placed`; `remake` makes it again (none: never let go).
  static std::shared_ptr<const EntryMesh> held(std::string source, TetMesh placed, std::function<TetMesh()> remake);
  /// One that keeps only `placed`'s digest and `remake` until a rank needs the mesh.
  static std::shared_ptr<const EntryMesh> recipe(std::string source, const TetMesh& placed, std::function<TetMesh()> remake);
  /// One whose mesh another rank made and digested (`digest`): made here from `remake`
  /// only when this rank needs it, and checked against that digest.
  static std::shared_ptr<const EntryMesh> made_elsewhere(std::string source, std::uint64_t digest,
                                                         std::function<TetMesh()> remake);
  /// The mesh: the held one, or made again and then held until drop().
  const TetMesh& get() const;
  /// The mesh by value without holding it: a copy of the held one, or one made again.
  TetMesh make() const;
  bool held() const { return held_ != nullptr; }
  bool can_drop() const { return static_cast<bool>(remake_); }
  /// Lets go of the mesh when it can be made again. Returns the bytes let go.
  std::size_t drop() const;
  const std::string& source() const { return source_; }
  /// mesh_digest of the placed mesh.
  std::uint64_t digest() const { return digest_; }

private:
  EntryMesh(std::string source, std::uint64_t digest, std::function<TetMesh()> remake);
  TetMesh remade() const;
  std::string source_;
  std::function<TetMesh()> remake_;
  std::uint64_t digest_ = 0;
  mutable std::unique_ptr<TetMesh> held_;
};

/// How an object's mesh is made from its entry's mesh, so that a rank can drop the mesh
/// and make it again, bitwise the same, when it needs it (Scene::mesh, Scene::drop_meshes;
/// docs/architecture.md, "Who holds which mesh"). The scene parser places every copy
/// through place() itself.
struct Placement {
  enum class Kind {
    kept,          ///< no recipe (a checkpoint's mesh, a hand-made object): never dropped
    entry,         ///< x = base (a single-copy entry: the object is its entry's mesh)
    offset,        ///< x = base + offset (a grid copy)
    about_centre,  ///< x = rotation (base - centre) + offset (a random copy: rotated about its centre, moved there)
  };
  Kind kind = Kind::kept;
  std::shared_ptr<const EntryMesh> base;                ///< the entry's mesh, shared by its copies
  std::array<double, 3> offset{};                       ///< [m]
  std::array<double, 9> rotation{1, 0, 0, 0, 1, 0, 0, 0, 1};  ///< row-major
  std::array<double, 3> centre{};                       ///< [m]

  bool can_remake() const {
    return kind != Kind::kept && base != nullptr && (kind != Kind::entry || base->can_drop());
  }
  /// Whether the object is one of several copies placed from `base` (grid or random).
  bool is_copy() const { return (kind == Kind::offset || kind == Kind::about_centre) && base != nullptr; }
  /// The placed mesh (kind kept: an empty mesh).
  TetMesh place() const;
};

/// What the objects of one scene entry have in common besides their material and mesh:
/// every copy of an entry holds the same one (shared), so that a scene of many copies
/// keeps it once per entry, not once per object (docs/architecture.md, "Who holds which
/// mesh").
struct ObjectTraits {
  std::string source;          ///< "file.msh" or "primitive sphere" (for summaries)
  Vec3 velocity{};             ///< initial velocity of every vertex [m/s]
  bool kinematic = false;      ///< the whole object is fixed (infinite mass)
  std::vector<Box> fixed;      ///< vertices inside any of these (world coordinates) are fixed
  Motion motion;               ///< prescribed motion of the fixed vertices (none by default)
};

/// The traits of an object made by hand: no source, at rest, movable, nothing fixed, no
/// motion (one instance, shared).
const std::shared_ptr<const ObjectTraits>& default_object_traits();

/// One object (one instance of a scene entry), mesh in world coordinates.
struct SceneObject {
  std::string name;            ///< entry name, with "[k]" appended for instance k of a multi-instance entry
  int material = 0;            ///< index into Scene::materials
  /// The placed mesh. Empty on a rank that dropped it (Scene::drop_meshes): read it
  /// through Scene::mesh(k), which makes it again from `placement` when needed. Mutable
  /// because it is a cache of a pure function of the scene.
  mutable TetMesh mesh;
  Placement placement;
  mutable std::shared_ptr<const Surface> surface;       ///< cache of Scene::surface(k)
  mutable std::optional<ObjectShape> shape;             ///< cache of Scene::shape(k)
  /// Its entry's source, initial velocity, fixed vertices and motion (never null).
  std::shared_ptr<const ObjectTraits> traits = default_object_traits();
  /// The scene entry it is a copy of (-1: none known). All copies of an entry are rigid
  /// motions of one scaled mesh with one material, so they share their frequencies.
  int entry = -1;
  /// The rank that made its mesh while the scene was read, the only one that held it then
  /// (a single-copy entry made by one rank: docs/architecture.md, "Who reads which mesh
  /// file"); -1: every rank made it, or it was read on one rank alone.
  int maker = -1;

  const std::string& source() const { return traits->source; }
  const Vec3& velocity() const { return traits->velocity; }
  bool kinematic() const { return traits->kinematic; }
  const std::vector<Box>& fixed() const { return traits->fixed; }
  const Motion& motion() const { return traits->motion; }
  /// Gives this object traits of its own (objects made by hand, tests).
  void set_traits(ObjectTraits t) { traits = std::make_shared<const ObjectTraits>(std::move(t)); }
};

enum class ContactClosure { local, coupled };

/// How a split object's tets are cut into parts (split_tet_parts in partition.hpp):
/// METIS up to kSplitMetisMaxTets and a coordinate bisection above (automatic), or
/// always the one named.
enum class SplitParts { automatic, metis, bisection };

/// Node weights of a repartition: the measured cost (seconds and contacts), or tets.
enum class RebalanceWeights { measured, tets };

struct Simulation {
  bool dt_auto = true;
  double dt = 0;                    ///< [s]; when dt_auto, filled in from the stability limit
  double dt_safety = 0.5;           ///< fraction of the stable explicit step used by `dt: auto`
  DtBound dt_bound = DtBound::element;  ///< how the stable step bounds the highest frequencies
  std::optional<double> end_time;   ///< [s]; exactly one of end_time and steps is set
  std::optional<std::int64_t> steps;
  Vec3 gravity{0, 0, -9.81};        ///< [m/s^2]
  IntegratorKind integrator = IntegratorKind::verlet;
  std::int64_t output_every = 0;    ///< steps between frames (0: use output_interval)
  double output_interval = 0;       ///< simulated seconds between frames
  std::string output_dir;           ///< relative to the working directory
  bool self_collisions = false;
  /// Mutual vertex records that contradict each other take a common axis (docs/collision.md,
  /// "Penetration vectors", item 7); off by default: docs/validation.md, "Contradicting
  /// mutual records" (chess500 then ends with inverted tets).
  bool mutual_pairs = false;
  /// Objects with more tets than an even share of the scene's have their internal forces
  /// evaluated in parts over ranks (split_part_count; docs/architecture.md, "Objects split
  /// for their forces"); the results do not change, only who does the work.
  bool split_objects = true;
  /// On more than one rank, a split object's points inside a body are found by the body's
  /// owner (CollisionDetector::delegate; docs/architecture.md, "Contact of a split
  /// object"); the results do not change, only who does the work. Not with edge contacts.
  bool split_detection = true;
  /// How a split object's tets are cut into parts; the results do not change, only the
  /// set-up's time and memory and the parts' messages (docs/architecture.md).
  SplitParts split_parts = SplitParts::automatic;
  /// How the normal magnitudes of the collisions are chosen (docs/contact.md): each
  /// collision in closed form with shares of its vertices (local, the paper's structure),
  /// or all together so that every gap closes (coupled).
  ContactClosure contact_closure = ContactClosure::local;
  bool edge_contacts = false;       ///< edge-edge contacts between bodies (docs/collision.md, "Edge contacts"); off by default: a step of tori200 takes 2.4 times as long with them, chess500's 3.6 times
  // Overlaps that the step's own motion cannot explain (bodies that start overlapping,
  // a gap an earlier step left) are removed by a position-only shift of at most this
  // speed times dt per step [m/s] (docs/contact.md, "Fresh contact and old overlap").
  double separation_speed = 5.0;
  // Checkpoints (docs/reliability.md): every N steps and/or every T wall minutes; the
  // last `checkpoint_keep` are kept. 0 disables a trigger.
  std::int64_t checkpoint_every = 0;
  double checkpoint_minutes = 0;
  std::int64_t checkpoint_keep = 2;
  // Numerical-failure guard: the run stops when a vertex moves faster than max_speed
  // [m/s] (0: 10 times the fastest dilatational wave speed of the scene's materials) or
  // when more than max_inverted_fraction of the movable tets are inverted.
  double max_speed = 0;
  double max_inverted_fraction = 0.01;
  // Repartitioning as the run goes (docs/architecture.md, "Migration"; rebalance.hpp): a
  // check every N steps (0: never) repartitions when the ranks' measured work is more
  // than max_imbalance apart or more than max_cross_fraction of the collisions cross ranks.
  std::int64_t rebalance_every = 200;
  double rebalance_max_imbalance = 1.25;
  double rebalance_max_cross_fraction = 0.5;
  RebalanceWeights rebalance_weights = RebalanceWeights::measured;
};

struct Scene {
  std::string path;                  ///< the YAML file
  std::string text;                  ///< its text as read (checkpoints carry it)
  Simulation sim;
  std::vector<Material> materials;
  Friction default_friction{0.5, 0.4};
  std::vector<std::vector<Friction>> friction;  ///< [materials][materials], symmetric
  std::vector<SceneObject> objects;
  std::vector<std::string> warnings; ///< non-fatal findings (reoriented tets, dt above limit, ...)

  std::size_t num_vertices() const;
  std::size_t num_tets() const;

  /// Object k's placed mesh: its own when held, else made again from its placement (and
  /// then held until the next drop_meshes). Not thread-safe; a reference stays valid until
  /// drop_meshes.
  const TetMesh& mesh(std::size_t k) const;
  /// Object k's mesh for one use, without holding it afterwards: the held mesh, or one made
  /// for the view alone (whole-scene passes on a rank that dropped meshes: checks,
  /// verification, fingerprints).
  class MeshView {
  public:
    explicit MeshView(const TetMesh* held) : p_(held) {}
    explicit MeshView(TetMesh&& made) : own_(std::move(made)), p_(&own_) {}
    MeshView(const MeshView&) = delete;
    MeshView& operator=(const MeshView&) = delete;
    const TetMesh& get() const { return *p_; }

  private:
    TetMesh own_;
    const TetMesh* p_;
  };
  MeshView view_mesh(std::size_t k) const;
  /// Object k's boundary (extract_surface of its mesh), extracted on first use.
  const Surface& surface(std::size_t k) const;
  /// Object k's counts and initial box, computed on first use (from its mesh) and kept.
  const ObjectShape& shape(std::size_t k) const;
  /// Computes every object's shape (from the meshes held now), so that drop_meshes loses
  /// nothing a rank must know of all objects.
  void describe_objects() const;
  /// The same, shared over `parts` ranks: the boundary triangles of the objects without a
  /// shape yet (extract_surface, the costly part) are counted by one part each (the k-th
  /// such object by part k % parts) and `sum` adds the parts' counts (an MPI_Allreduce, as
  /// SceneLimits::sum), so that no rank extracts every boundary. Collective.
  void describe_objects(int part, int parts, const std::function<void(std::vector<double>&)>& sum) const;
  /// Drops the mesh and surface of every object with keep[k] == 0 whose placement can make
  /// it again (shapes are computed first), and the entry meshes (Placement::base) that no
  /// kept copy is placed from. Returns the bytes of mesh and surface dropped.
  std::size_t drop_meshes(const std::vector<char>& keep) const;
  /// Every object's mesh_digest, object k computed by part k % parts (a dropped
  /// single-copy mesh's from its entry's digest, without making it; a copy placed for it) and `sum`
  /// adds the parts' (null or one part: all here). The same on any number of parts.
  /// Collective over the parts.
  std::vector<std::uint64_t> object_digests(int part = 0, int parts = 1,
                                            const std::function<void(std::vector<double>&)>& sum = {}) const;
};

/// Bounds on the size of a scene, checked before a primitive is generated or an entry is
/// copied, so that a mistyped resolution or instance count is an InputError instead of an
/// exhausted memory. The defaults are what one rank can number with index_t (every rank
/// holds the whole scene); tests and fuzzing pass smaller ones.
struct SceneLimits {
  std::int64_t max_vertices = std::numeric_limits<index_t>::max();  ///< all objects together
  std::int64_t max_tets = std::numeric_limits<index_t>::max() / 4;  ///< all objects together
  std::int64_t max_objects = std::numeric_limits<int>::max();       ///< copies of all entries
  /// Whether the copies of multi-copy entries keep their placed meshes. Without, each copy
  /// keeps only its shape and placement, and Scene::mesh makes its mesh when a rank needs
  /// it (`run` and `bench` load so: docs/architecture.md, "Who holds which mesh").
  bool hold_copy_meshes = true;
  /// How ranks share the parser's costliest per-object work, the highest tet frequency of
  /// every distinct mesh of a movable object for the stable step (a 12 x 12 eigenproblem
  /// per tet; the copies of an entry share their entry's): this rank computes the k-th
  /// distinct mesh for k % parts == part, zeros elsewhere, and `sum` adds the ranks'
  /// vectors (one value per object) element by element (an MPI_Allreduce), so that every
  /// rank has every object's value, computed exactly as on one rank. parts = 1: all on
  /// this rank.
  int part = 0;
  int parts = 1;
  std::function<void(std::vector<double>&)> sum;
  /// How ranks share random placement (the copies of `instances: random` entries): each
  /// part places the independent groups of entries given to it, and `gather` returns
  /// every part's vector, concatenated in part order (an MPI_Allgatherv), so that every
  /// rank has every copy's placement, made exactly as on one rank. Unset: all placed here.
  std::function<std::vector<double>(const std::vector<double>&)> gather;
  /// How ranks share reading the mesh files that multi-copy entries name (every rank
  /// needs those meshes): the k-th such file in scene order is read by part k % parts,
  /// and `broadcast(bytes, root)` gives part root's bytes to every rank (MPI_Bcast), the
  /// mesh with its warnings, or that the read failed (then every rank reads the file
  /// itself at its entry, to report the error as one rank would). Unset: every rank reads
  /// them.
  std::function<void(std::vector<char>&, int)> broadcast;
  /// How ranks share the element frequencies of a large single-copy mesh, which only the
  /// rank that made it holds (a soft floor of half the scene's tets): its tets' corners go
  /// out in rounds of at most `spread_round_tets` tets, each round cut into `parts`
  /// consecutive pieces, and `scatter(all, counts, root)` returns this part's `counts[part]`
  /// values of part root's `all` (an MPI_Scatterv). Each part takes the highest frequency
  /// of its pieces and `sum` brings every part's to every rank: a maximum, so the value is
  /// bitwise the one rank's. For movable single-copy meshes of at least `spread_tets` tets,
  /// with the element bound (the mesh bound's eigenproblem needs the whole mesh and stays
  /// with its maker). Unset: the maker computes them alone.
  std::function<std::vector<double>(const std::vector<double>&, const std::vector<int>&, int)> scatter;
  std::int64_t spread_tets = std::int64_t{1} << 15;
  std::int64_t spread_round_tets = std::int64_t{1} << 18;
};

/// Reads, validates and instantiates a scene. Mesh paths are relative to the scene file.
/// Throws InputError (file:line: what was expected) for anything invalid.
Scene load_scene(const std::string& path, const SceneLimits& limits = {});

/// Same, from YAML text; `path` names it in messages and anchors relative mesh paths.
Scene load_scene_from_string(const std::string& yaml, const std::string& path, const SceneLimits& limits = {});

/// The explicit stability limit of a scene and the object that sets it.
struct StableStep {
  double dt = std::numeric_limits<double>::infinity();  ///< [s]; +inf when nothing can move
  int object = -1;            ///< scene object whose limit it is (-1: none)
  double omega = 0;           ///< the bound on that object's highest frequency [rad/s]
  double alpha = 0, beta = 0; ///< its material's Rayleigh damping: mass [1/s], stiffness [s]
  DtBound bound = DtBound::element;  ///< which bound omega is
  double omega_element = 0;   ///< that object's highest tet frequency (= omega for the element bound) [rad/s]
  double omega_estimate = 0;  ///< mesh bound: Lanczos's lower bound on its omega_max [rad/s] (0: none)

  bool damped() const { return alpha > 0 || beta > 0; }
  /// Damping ratio of the mode omega: alpha / (2 omega) + beta omega / 2.
  double damping_ratio() const { return alpha / (2 * omega) + beta * omega / 2; }
  /// What it is, for messages: "2 / the highest element frequency" and, with damping, the
  /// object, frequency, damping and damping ratio; for the mesh bound the object, its
  /// bound, the Lanczos estimate and the element bound (docs/models.md).
  std::string explain(const Scene& scene) const;
};

/// Largest time step for which the explicit integrators are guaranteed stable on the
/// movable objects, linearised about their rest state. Per object: omega = max over its
/// tets of omega_T, the highest frequency of the tet alone with a quarter of its mass on
/// each corner (tet_max_frequency in forces.hpp; Irons' element eigenvalue theorem), for
/// its model (mass-spring has its own stiffness), and the damped bound of that mode with
/// its material's Rayleigh damping, 4 / (c + sqrt(c^2 + 4 omega^2)), c = alpha + beta
/// omega^2 (damped_stable_step; 2 / omega without damping). The smallest over the
/// objects. Not multiplied by the safety factor; dt = +inf when nothing can move.
/// With the mesh bound, omega is instead a certified upper bound on the object's assembled
/// highest frequency (mesh_max_frequency in forces.hpp), computed once per scene entry.
/// Either omega is computed once per distinct mesh: the copies of an entry take their
/// entry's (docs/models.md, "Stability limit").
/// The first form takes the scene's simulation.dt_bound.
StableStep stable_step(const Scene& scene);
StableStep stable_step(const Scene& scene, DtBound bound);

/// stable_step(scene).dt.
double stable_time_step(const Scene& scene);

/// Number of steps the run takes (from steps or ceil(end_time / dt)).
std::int64_t total_steps(const Simulation& sim);

/// Steps between output frames (from output_every or round(output_interval / dt), >= 1).
std::int64_t steps_between_frames(const Simulation& sim);

}  // namespace softcontact
