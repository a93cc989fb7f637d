#pragma once
// One simulation in memory, on the ranks of a communicator: the parallel layer around the
// serial core (SerialStepper, stepper.hpp, which takes the paper's Algorithm 1 on this
// rank's World),
//
//   p  <- internal forces(x^t) + gravity + damping        ElasticForces
//   x~ <- unconstrained motion                             Verlet / symplectic / implicit Euler
//   C  <- detect collisions(x~)                            CollisionDetector (spatial hashing)
//   d  <- penetration vectors(C, x~)                       CollisionDetector (consistent depth)
//   F  <- contact forces(C, x~, d); x = x~ + dt^2 F / m    ContactResponse
//
// with the ghost objects refreshed between the phases (GhostSet, ghosts.hpp), the
// objects repartitioned and migrated when the work drifts apart (rebalance.hpp), the
// phases timed, and the measurements that gather over ranks. No file output, so that
// tests and benchmarks drive it directly; run_scene() adds frames, diagnostics and the
// progress line around it.
#include <mpi.h>

#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <utility>
#include <vector>

#include "softcontact/collision.hpp"
#include "softcontact/contact.hpp"
#include "softcontact/phase_times.hpp"
#include "softcontact/partition.hpp"
#include "softcontact/rebalance.hpp"
#include "softcontact/scene.hpp"
#include "softcontact/split_forces.hpp"
#include "softcontact/step_state.hpp"
#include "softcontact/surface.hpp"
#include "softcontact/verify.hpp"
#include "softcontact/world.hpp"

namespace softcontact {

class ElasticForces;
class ImplicitEuler;
class SerialStepper;
struct StepDiagnostics;
class GhostSet;
struct LocalCheck;

/// The scene's tet edges' median and mean [m], edges counted once per tet.
struct EdgeStatistics {
  double median = 0;
  double mean = 0;
};

/// The scene's edge statistics before the objects are given out: each object's edges are
/// measured by the rank that made its mesh while the scene was read (SceneObject::maker,
/// when it is a rank of `comm`), or else by rank k % ranks (a mesh not held there made
/// for the moment, not kept). The same values, to the bit, on any rank count. Collective.
EdgeStatistics scene_edge_statistics(MPI_Comm comm, const Scene& scene);

class Simulator {
public:
  /// Builds this rank's World (objects partitioned over the ranks of `comm` with METIS,
  /// or as `partition` gives them) and every phase's precomputed data. Collective.
  /// `hosts`: with a given partition, the ranks of the split objects' parts that came
  /// with it (partition_at's); empty: split_hosts' choice from the partition alone.
  /// Hosts that do not fit the partition (another count of split objects or parts, a
  /// part 0 off its owner, a rank out of range) throw RuntimeFailure. `edges`: this
  /// scene's scene_edge_statistics on `comm` where the caller has them (not computed
  /// again); none: computed here.
  Simulator(MPI_Comm comm, const Scene& scene, std::vector<int> partition = {}, SplitHosts hosts = {},
            std::optional<EdgeStatistics> edges = std::nullopt);
  ~Simulator();
  Simulator(const Simulator&) = delete;
  Simulator& operator=(const Simulator&) = delete;

  /// One time step. Collective.
  void step();

  std::int64_t step_count() const { return step_; }
  double time() const { return static_cast<double>(step_) * scene_.sim.dt; }
  World& world() { return world_; }
  const World& world() const { return world_; }
  const Scene& scene() const { return scene_; }

  /// Collisions of the last step (after detection, before the response), sorted.
  const std::vector<Collision>& collisions() const;
  const CollisionStats& collision_stats() const;
  const ContactStats& contact_stats() const;
  /// Contact force per local vertex of the last step, (n_local,3) [N].
  const std::vector<double>& contact_force();
  /// Sum of penetration vectors per colliding vertex of the last step, (n_local,3) [m].
  const std::vector<double>& penetration();

  /// Energies, momentum, contact counts, force balance and the residual penetration (the
  /// deepest surface vertex inside another body at the corrected positions, by the
  /// independent check of verify.hpp, over the median edge length: `check` when it is the
  /// verify() of this step already, else residual_surface_depth()). Collective; call it
  /// per frame.
  void measure(StepDiagnostics& d, const VerifyFrame* check = nullptr);

  /// The deepest surface vertex inside another body, over the median edge: verify()'s
  /// surface_depth() to the bit, at the cost of that part of the check alone (one
  /// MPI_Allreduce of the maximum). Collective.
  double residual_surface_depth();

  /// The check of `softcontact verify` (verify.hpp) on the current positions and
  /// velocities, equal to the bit to that check on the whole scene on one process,
  /// without gathering: each rank checks the vertices, surface edges and tets of its own
  /// objects against its own and its ghost objects (a body that holds one of its
  /// vertices, or that one of its edges crosses, overlaps its box, so it is owned or a
  /// ghost), in a VerifyMesh of those objects in global order (so that ties go the same
  /// way), rebuilt after a ghost-set change or a migration. The crossing pass's threshold
  /// and the percentiles are taken over all ranks while the check runs
  /// (VerifyReduction), the parts merged by one MPI_Allreduce (merge_verify_part). Every
  /// rank gets the result. `full` adds interior vertices and surface crossings (and self
  /// checks where the scene has self-collisions) to the surface vertices, inverted tets
  /// and speeds. Collective.
  VerifyFrame verify(bool full);

  /// Wall time per phase accumulated since the last call, and the steps it covers.
  PhaseTimes take_times(std::int64_t& steps);

  /// The construction's stages, in order, with this rank's wall seconds in each (waits
  /// at the collectives inside a stage included): where the set-up time goes.
  const std::vector<std::pair<const char*, double>>& setup_stages() const { return setup_stages_; }
  /// The C heap in use on this rank at the end of each set-up stage [bytes]
  /// (heap_in_use_bytes, -1 where unknown), in setup_stages' order.
  const std::vector<double>& setup_heap() const { return setup_heap_; }

  /// Collisions already present at the initial positions (objects that start
  /// overlapping): the first step pushes them apart at (depth / dt).
  std::int64_t initial_overlaps() const { return initial_overlaps_; }
  double initial_overlap_depth() const { return initial_overlap_depth_; }

  /// Median edge length of all tets of the scene [m].
  double median_edge() const { return median_edge_; }
  /// The detector's cell size: the scene's mean tet edge, summed from each rank's objects [m].
  double cell_size() const { return collision_settings_.cell_size; }

  /// Object -> rank of the current partition.
  const std::vector<int>& partition() const { return partition_; }
  /// Moves objects to the ranks `partition` names, with their state (positions, previous
  /// positions, velocities, friction anchors); the results of later steps do not change.
  /// The split objects' parts go to split_hosts of that partition. Collective, between
  /// steps.
  void migrate(const std::vector<int>& partition);

  /// The state of this rank's owned vertices that the next step needs (positions,
  /// previous positions, velocities, friction anchors, the step counters): what
  /// checkpoints save and migration carries.
  StepState snapshot() const;
  /// Installs `s` (rows in this World's owned order) and continues at s.step: ghosts and
  /// halo rebuilt. Collective.
  void restore(const StepState& s);
  /// Every object's box at the current positions (collective).
  std::vector<Box> current_boxes();
  // ---- numerical-failure guard (health.cpp, docs/reliability.md)
  /// This rank's quick check after a step, no communication: 0 fine, 1 an owned vertex
  /// moves faster than `max_speed`, 2 a non-finite position or velocity, 3 an implicit
  /// Euler solve did not converge (that object was left at its last state).
  int local_health(double max_speed) const;
  /// After local_health() reported a problem on some rank: where it is (the vertex with
  /// the lowest global id that is non-finite, or the fastest one; for code 3 the
  /// failed solve of the lowest object), as one message on every rank. Collective.
  std::string diagnose(int code, double max_speed);
  /// Counts inverted tets (det F <= 0) of movable objects; when more than
  /// `max_fraction` of them are, returns a message naming the first (lowest global id).
  /// Collective.
  std::string check_inversions(double max_fraction);
  /// A message naming the object with the most kinetic energy and its fastest vertex, for
  /// a run whose energy exploded. Collective.
  std::string locate_energy();

  void set_rebalance_policy(const RebalancePolicy& p) { rebalance_ = p; }
  /// Repartitions done by the rebalance policy so far.
  std::int64_t repartitions() const { return repartitions_; }
  /// Objects whose forces are shared over ranks (split_forces.hpp), and the most parts
  /// (ranks evaluating them) of one: split_part_count; the same on every rank.
  int split_objects() const { return split_count_; }
  int split_ranks() const { return split_ranks_; }
  /// How many times this rank computed a split object's parts (its owner does, and sends
  /// them to the other ranks that take part: share_split_parts).
  std::int64_t split_parts_computed() const { return split_parts_computed_; }
  /// The parts of split objects this rank was sent by their owners, and their tets: a host
  /// that does not hold an object's mesh gets its part of it, not the whole mesh.
  std::int64_t split_part_meshes_received() const { return split_part_meshes_received_; }
  std::int64_t split_part_tets_received() const { return split_part_tets_received_; }
  /// Bytes this rank sent and received in share_split_parts so far: the part meshes (their
  /// indices, 4 bytes each, and 4 doubles per vertex) and the parts of every tet handed to
  /// a new owner after a migration (4 bytes per tet). Set-up and migrations only, not
  /// per step (split_bytes_sent).
  std::int64_t split_part_bytes_sent() const { return split_part_bytes_[0]; }
  std::int64_t split_part_bytes_received() const { return split_part_bytes_[1]; }
  /// The split objects whose parts of every tet this rank keeps: those it owns.
  std::size_t split_parts_kept() const { return split_parts_.size(); }
  /// Per split object (split_candidates, ascending): the rank that evaluates each part.
  const SplitHosts& split_hosts() const { return split_hosts_; }
  /// Ghost-set rebuilds so far (the halo grows and shrinks as objects move).
  std::int64_t ghost_rebuilds() const;
  /// The ghost-set tests so far and the object boxes this rank received for them (GhostSet).
  std::int64_t ghost_reach_tests() const;
  std::int64_t ghost_boxes_received() const;
  /// Bytes this rank has received through the halo since construction.
  std::int64_t halo_bytes() const;
  /// Rounds of neighbour messages this rank has waited on so far (GhostSet::rounds).
  std::int64_t halo_rounds() const;
  /// Of what this rank sent, the split objects' exchanges since construction (states to
  /// parts, forces to owners) [bytes]; the tets it evaluates now for objects it does not
  /// own.
  std::int64_t split_bytes_sent() const;
  std::int64_t split_helped_tets() const;
  /// Tets of split objects this rank evaluates (its parts, its own objects' included).
  std::int64_t split_evaluated_tets() const;
  /// This rank's parts of other ranks' split objects, and of those the ones that take the
  /// positions from their ghost rows (no positions sent to them).
  int split_helping_parts() const;
  int split_parts_from_ghosts() const;
  /// Records of split objects' points this rank made for their owners since construction
  /// (the bodies they entered are this rank's), and those it received for its own points
  /// (docs/architecture.md, "Contact of a split object").
  std::int64_t delegated_records_sent() const;
  std::int64_t delegated_records_received() const;
  /// The rebalance's contact counts since its last check, per scene object (empty on one
  /// rank, or before the first record): this rank's vertex records, each counted for the
  /// object whose owner made it (its point's object; a split object's point found by the
  /// owner of the body it entered counts for that body). Summed over the ranks they weigh
  /// the objects for the next partition (RankWork::contacts, measured_weights).
  const std::vector<std::int64_t>& measured_contacts() const { return window_contacts_; }
  /// Collisions of this rank whose triangle lies on an object of another rank, last step.
  std::int64_t cross_rank_collisions() const { return cross_collisions_; }

private:
  std::vector<std::pair<const char*, double>> setup_stages_;
  std::vector<double> setup_heap_;
  // The phases of step(), in order.
  void forces_phase();
  void unconstrained_motion();
  void refresh_predicted_ghosts();
  void detection_and_depth();
  void contact_response();
  void refresh_final_ghosts();

  void build_components();
  void release_components();
  // Before forces are evaluated: the split objects' plan (split_forces.hpp), made again
  // when the World was replaced.
  void prepare_split();
  std::vector<std::optional<SplitPartMesh>> share_split_parts(const std::function<bool(std::size_t)>& takes_part);
  void share_ghost_holders();
  void rebuild_ghosts(bool force);
  void follow_ghosts();
  // Drops the meshes of the objects this rank neither owns nor ghosts (Scene::drop_meshes).
  void drop_unneeded_meshes();
  // Hands the pages of the meshes dropped since the last call back to the system
  // (malloc_trim), after the allocations that follow a drop have reused what they could.
  void trim_dropped();
  /// The meshes of single-copy entries made by one rank (SceneObject::maker) go from that
  /// rank to their owner, if another, before the World is built: the owner neither reads
  /// the file again nor generates the primitive again. Collective.
  void hand_over_made_meshes();
  void maybe_rebalance();
  void migrate(const std::vector<int>& partition, SplitHosts hosts);  // with the split objects' hosts of that partition

  MPI_Comm comm_;
  int rank_ = 0, nranks_ = 1;
  const Scene& scene_;
  std::vector<int> partition_;
  World world_;
  CollisionSettings collision_settings_;
  std::unique_ptr<GhostSet> ghosts_;  // the parallel layer's ghost objects and halo (ghosts.hpp)
  RebalancePolicy rebalance_;
  RebalanceHistory rebalance_history_;
  std::int64_t repartitions_ = 0, cross_collisions_ = 0;
  double work_seconds_ = 0;          // forces, detection and depth CPU seconds since the last rebalance check
  std::vector<std::int64_t> window_contacts_;  // per object: colliding surface vertices since then (this rank's records)
  std::unique_ptr<SerialStepper> core_;  // the step's physics on this rank's World (stepper.hpp)
  PhaseTimes times_;
  std::int64_t timed_steps_ = 0;
  std::int64_t step_ = 0;
  double median_edge_ = 0;
  std::int64_t initial_overlaps_ = 0;
  double initial_overlap_depth_ = 0;
  std::unique_ptr<LocalCheck> local_verify_;  // this rank's objects and ghosts in global order (simulator_verify.cpp)
  LocalCheck& local_check();                  // local_verify_, built when missing (collective)
  double verify_median_ = 0;                  // the whole scene's median edge as verify.hpp takes it
  bool verify_median_known_ = false;
  double free_fall_speed_ = 0;
  bool free_fall_known_ = false;
  std::vector<int> split_candidates_;          // objects bigger than a share (split_forces.hpp)
  // Whether the split objects' points are found by the owners of the bodies they enter.
  bool delegates_detection() const {
    return nranks_ > 1 && scene_.sim.split_detection && !scene_.sim.edge_contacts && !split_candidates_.empty();
  }
  SplitHosts split_hosts_;                     // per candidate: the rank of each part (rebalance.hpp)
  bool split_dirty_ = true;                    // the World was replaced since the split plan was made
  int split_count_ = 0, split_ranks_ = 0;      // split objects, the most parts (ranks) of one
  std::int64_t split_doubles_before_ = 0;      // sent by the SplitForces replaced so far
  std::int64_t delegated_before_[2] = {0, 0};  // delegated records sent, received by the cores replaced so far
  std::size_t dropped_bytes_ = 0;              // mesh bytes dropped and not yet trimmed (trim_dropped)
  std::int64_t split_ghost_generation_ = -1;   // GhostSet::rebuilds() when the split's ghost holders were shared
  std::int64_t split_parts_computed_ = 0;
  std::int64_t split_part_meshes_received_ = 0, split_part_tets_received_ = 0;
  std::int64_t split_part_bytes_[2] = {0, 0};  // share_split_parts: sent, received
  std::map<int, std::vector<std::int32_t>> split_parts_;  // object -> its tets' parts (split_part_count of them)
};

}  // namespace softcontact
