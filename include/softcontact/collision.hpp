#pragma once
// Collision detection and consistent penetration depth: steps 3 and 4 of the paper's
// Algorithm 1 (method.md, "Collision detection" and "Penetration vectors").
//
// Input: the World after the unconstrained motion (World::x holds x~).
// Output: one Collision record per (colliding vertex, penetrated body), in an order
// fixed by global ids whatever the thread count. The contact response consumes them.
//
// docs/collision.md describes the algorithms: which vertices are queried (surface
// vertices), the tie rule for points exactly on faces ("strictly inside": a point on a
// face shared by two tets belongs to exactly one; a point on the body's surface to
// none), the deep-intersection fallback, the thickness used by the tunnelling
// diagnostic, and the cost.
#include <array>
#include <cstdint>
#include <memory>
#include <unordered_map>
#include <vector>

#include "softcontact/mesh.hpp"
#include "softcontact/world.hpp"

namespace softcontact {

/// The collision (i, T_i) of method.md: vertex i (of object A) is inside object B;
/// T_i = (j, k, l) is the surface triangle of B that the ray x~_i + s r_i crosses,
/// omega the barycentric weights of x~_i + d_i projected onto T_i (clamped into the
/// triangle, renormalised to sum 1); d_i = D_i r_i the penetration vector, pointing from
/// x~_i out of B (so x~_i + d_i lies on B's surface).
struct Collision {
  index_t point = -1;                   ///< local index of vertex i in the World
  /// Edge-edge contacts (docs/collision.md, "Edge contacts"): the point side is the edge
  /// (point, point2) with weights point_weight and 1 - point_weight, the "triangle" side
  /// the other body's edge (triangle[0], triangle[1]; triangle[2] repeats triangle[0] with
  /// weight 0). Vertex collisions: point2 = -1, point_weight = 1.
  index_t point2 = -1;
  double point_weight = 1;
  std::array<index_t, 3> triangle{};    ///< local indices of j, k, l (outward order of B's surface)
  std::array<double, 3> weight{};       ///< omega_ij, omega_ik, omega_il; sum 1, each in [0, 1]
  std::array<double, 3> depth{};        ///< penetration vector d_i [m]
  gid_t point_gid = -1;                 ///< global id of i (sort key 1)
  gid_t triangle_gid = -1;              ///< global id of T_i (sort key 2)
  std::int32_t object = -1;             ///< object of i
  std::int32_t other_object = -1;       ///< object B (== object for a self-collision)
  bool fallback = false;                ///< depth not from the consistent depth: entry rule or nearest surface triangle
};

/// The order of a step's records, the same on any number of ranks: by the point's global
/// id, then the triangle's.
inline bool record_order(const Collision& a, const Collision& b) {
  return a.point_gid != b.point_gid ? a.point_gid < b.point_gid : a.triangle_gid < b.triangle_gid;
}

/// Per-step counts for the diagnostics.
struct CollisionStats {
  std::int64_t colliding_points = 0;    ///< distinct vertices inside another body
  std::int64_t collisions = 0;          ///< records (a vertex inside two bodies counts twice)
  std::int64_t border_points = 0;       ///< records whose point has at least one border edge into B
  std::int64_t deep_fallbacks = 0;      ///< regions with no border point: entry rule or nearest-triangle fallback
  std::int64_t entry_records = 0;       ///< records resolved towards where the point entered B (penetration_depth.hpp, item 5)
  std::int64_t redirected_depths = 0;   ///< consistent depths replaced by the way back, the rested-on triangle or the nearest surface point (docs/collision.md, item 5)
  std::int64_t nearest_records = 0;     ///< of those, replaced by the nearest surface point (no way back, or a long one)
  std::int64_t resting_records = 0;     ///< of those, replaced by the closest point of the triangle x^t rested on
  std::int64_t self_collisions = 0;     ///< vertices inside a tet of their own object away from their star (records: self-contact)
  std::int64_t self_objects = 0;        ///< objects tested for self-contact (the others cannot fold this step: self_culling.hpp)
  std::int64_t edge_crossings = 0;      ///< surface edge / surface triangle crossings between bodies at x~
  std::int64_t edge_contacts = 0;       ///< edge-edge records among `collisions`
  std::int64_t edge_unpaired = 0;       ///< crossing pairs left without a record
  std::int64_t edge_pairs = 0;          ///< candidate (edge, triangle) pairs of the edge search held
  std::int64_t edge_pair_searches = 0;  ///< 1 when those pairs were found again in this call (the skin was used up)
  std::int64_t point_searches = 0;      ///< 1 when the narrow phase's kept candidates were found again in this call
  std::int64_t mutual_settled = 0;      ///< records of contradicting mutual pairs given a common axis (settle_mutual)
  std::int64_t degenerate_skipped = 0;  ///< degenerate triangles/tets/edges and non-finite positions met and handled
  /// Largest |x~ - x^t| / thinnest object thickness (tunnelling risk; 0 without x^t).
  /// Thickness: smallest extent of an object's vertices along its principal and
  /// coordinate axes, at construction.
  double max_step_over_thickness = 0;
  std::int64_t surface_searches = 0;    ///< tet walks that gave up, replaced by a search of B's surface hierarchy
  std::int64_t large_tets = 0;          ///< tets whose box spans more grid cells than there are query points: tested against every point (counted when the candidates are searched)
  double detection_seconds = 0;         ///< wall time of broad and narrow phase [s]
  double depth_seconds = 0;             ///< wall time of penetration vectors, T_i and weights [s]
};

struct CollisionSettings {
  bool self_collisions = false;  ///< self-contact: a body's surface vertices against its own tets away from their star, with records
  bool edge_contacts = false;    ///< edge-edge contacts between bodies (docs/collision.md, "Edge contacts")
  double cell_size = 0;          ///< grid cell size [m]; 0: the average edge length of all tets
  /// With self_collisions: skip the self query of objects that cannot have folded (an
  /// exact test, self_culling.hpp). Off only to check that it changes nothing.
  bool self_culling = true;
  /// With edge_contacts: the Verlet skin of the edge search's candidate pairs, in grid
  /// cells (docs/collision.md, "Edge contacts", item 2). The crossings found do not
  /// depend on it; 0 (found again every step) only to check that.
  double edge_skin = 0.25;
  /// The skin of the narrow phase's candidates, in grid cells: each tet keeps the query
  /// points within it of its box, and they are found again only when some vertex has
  /// moved half of it (docs/collision.md, "Candidates kept across steps"). The records do
  /// not depend on it; 0 (found again every step) only to check that.
  double point_skin = 0.3;
};

/// What a vertex record tells its partner in a mutual contact (docs/collision.md,
/// "Penetration vectors", item 7): point j inside the body `other_object`, whose triangle
/// weighs most on vertex `heavy_gid`. Trivially copyable (sent to neighbouring ranks).
struct RecordKey {
  gid_t point_gid = -1;
  gid_t heavy_gid = -1;
  std::int32_t other_object = -1;
  std::int32_t pad = 0;
  double depth[3] = {0, 0, 0};
};

/// Per-object self-contact gaps (self_culling.hpp), kept across detectors by global
/// object index. A gap depends only on the object's rest mesh, so a detector rebuilt for a
/// new ghost set or after a migration takes the known ones (bitwise what it would compute:
/// a minimum over the same distances) and computes only the others.
struct SelfGapCache {
  std::unordered_map<std::int32_t, double> gap;
  /// Per scene object: an id shared by the copies of one scene entry, whose rest meshes
  /// are rigid images of one mesh with the same numbering (-1: an object of its own). A
  /// copy's true gap is its entry's, so only one copy per entry is computed; the others
  /// take its gap less 1e-9 of it and 64 eps of the two copies' largest |coordinate| (the
  /// rounding of the distances), a lower bound, which keeps the culling exact.
  std::vector<std::int32_t> entry;
  struct EntryGap {
    double gap = 0;    ///< the computed gap of the entry's first copy met [m]
    double scale = 0;  ///< that copy's largest |coordinate| at rest [m]
  };
  std::unordered_map<std::int32_t, EntryGap> entry_gap;
};

/// Spatial hashing (Teschner et al. 2003) and consistent penetration depth (Heidelberger
/// et al. 2004). Construction precomputes what does not change: edges, vertex adjacency,
/// surface vertices, object thickness. detect() reuses its buffers between steps.
class CollisionDetector {
public:
  /// `rest_x` (n_local,3): the positions the surface hierarchies are built from (the
  /// scene's initial positions, so that a detector rebuilt during a run, after a ghost
  /// change or a migration, searches exactly like the first); null: world.x.
  /// `gaps`: self-contact gaps known from earlier detectors built from the same rest
  /// positions; the new ones are added to it (null: computed here, not kept).
  /// `previous`: the detector of this scene's World before its ghost set changed or
  /// objects migrated, built from the same rest positions. The pieces of every object it
  /// held numbered alike (its tet faces, mesh edges and surface hierarchy) are moved from
  /// it to their new local indices instead of being built again; it is left fit only to
  /// be destroyed. The new detector is the same to the bit as one built without it.
  CollisionDetector(const World& world, const CollisionSettings& settings, const double* rest_x = nullptr,
                    SelfGapCache* gaps = nullptr, CollisionDetector* previous = nullptr);
  ~CollisionDetector();
  CollisionDetector(CollisionDetector&&) noexcept;
  CollisionDetector& operator=(CollisionDetector&&) noexcept;

  /// Finds every owned vertex strictly inside a tet of another object at the positions
  /// `world.x` (x~), computes the penetration vectors, and writes the records to `out`
  /// sorted by (point_gid, triangle_gid). `x_start` (n_local,3) are the positions
  /// x^t at the start of the step, for the tunnelling diagnostic and the depth's entry
  /// rule (null at the initial positions: neither applies).
  void detect(const World& world, const double* x_start, std::vector<Collision>& out, CollisionStats& stats);

  /// Delegates the points of `objects` (global indices; objects split over ranks,
  /// docs/architecture.md, "Contact of a split object"): their surface points, owned here
  /// or ghosts, are tested against the tets of this rank's own objects only, so that each
  /// record of such a point inside a body B is made by B's owner (and sent to the point's
  /// owner by the caller). Their records come out of detect() like any other, the ghost
  /// points' with ghost indices; the distinct points among them are not counted in
  /// CollisionStats::colliding_points but listed in delegated_points(). A ghost object's
  /// self-contact is never tested (its owner's), delegated or not. Not for edge contacts
  /// (they read every vertex record of the point's body). Empty: none (the default).
  void delegate(std::vector<std::int32_t> objects);
  /// After detect(): the distinct points (local indices, ascending) of delegated objects
  /// that are inside a body this call.
  const std::vector<index_t>& delegated_points() const;

  /// Item 7 of "Penetration vectors" (docs/collision.md), after detect(): the keys of the
  /// records that can be one half of a mutual pair (vertex records between two bodies
  /// whose triangle weighs at least kMutualWeight on one vertex), appended to `keys`.
  static void record_keys(const World& world, const std::vector<Collision>& records, std::vector<RecordKey>& keys);
  /// A vertex record (i inside B, T_i weighing >= kMutualWeight on vertex j) whose partner
  /// (j inside i's body, its triangle weighing >= kMutualWeight on i) has a depth pointing
  /// the same way contradicts it; both take the axis m = normalize(n_B(j) - n_A(i))
  /// (smoothed outward vertex normals at x~) and the length o = (x~_j - x~_i) . m clamped
  /// to [max(|d_i|, |d_j|), |d_i| + |d_j|]: d_i = o m (and, on the partner's side, d_j =
  /// -o m). `keys`: the keys of every record that can be a partner (this rank's and, with
  /// several ranks, its neighbours'), in any order (sorted here). Returns the number of
  /// records changed.
  std::int64_t settle_mutual(const World& world, std::vector<Collision>& records, std::vector<RecordKey>& keys);
  /// Smallest triangle weight on the partner vertex for item 7.
  static constexpr double kMutualWeight = 0.5;

private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace softcontact
