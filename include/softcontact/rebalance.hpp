#pragma once
// Objects over ranks as the run goes (docs/architecture.md, "Migration"): the initial
// METIS partition of the scene's objects, the rebalance policy that repartitions at the
// current boxes when the work per rank drifts apart, and the migration that moves the
// objects changing rank with their state. The parallel layer; the Simulator calls it
// between steps.
#include <mpi.h>

#include <cstdint>
#include <vector>

#include "softcontact/partition.hpp"
#include "softcontact/scene.hpp"
#include "softcontact/step_state.hpp"
#include "softcontact/surface.hpp"
#include "softcontact/world.hpp"

namespace softcontact {

/// When a run repartitions its objects (docs/architecture.md, "Migration").
struct RebalancePolicy {
  std::int64_t check_every = 200;   ///< steps between checks (0: never)
  /// Repartition when max/mean of the per-rank work passes this. Below 1 (which a scene
  /// file cannot ask for: the tests' setting) every check repartitions, without the
  /// margin after a repartition that moved nothing (rebalance_wanted).
  double max_imbalance = 1.25;
  double max_cross_fraction = 0.5;  ///< ... or when this fraction of the collisions crosses ranks
  /// Node weights of the repartition: measured cost (measured_weights), or the static
  /// work alone (tets; what the initial partition uses).
  bool measured_weights = true;
  /// The least reach of the partition's graph [m] (partition_at's min_reach): the
  /// Simulator sets the ghosts' first skin, the detector's cell.
  double min_reach = 0;
};

/// The policy a scene asks for (`simulation.rebalance`, docs/formats.md).
RebalancePolicy rebalance_policy(const Simulation& sim);

/// The partition METIS gives the scene's objects at their initial positions: nodes
/// weighted by tets (kinematic objects by a tenth of their surface triangles) and by the
/// memory their owner holds for them (a second constraint), edges between objects closer
/// than the median object size or `min_reach`, whichever is larger. Identical on every
/// rank. With a
/// communicator (collective then), its ranks share the work (partition_objects_over):
/// past kPartsPerGroup ranks each rank partitions only its group's objects; within a
/// group the ranks share METIS's search for the smallest cut (CutSearch, partition.hpp).
/// The same answer on any rank count.
/// Which rank evaluates each part of each split object: per object of split_candidates
/// (ascending), one rank per part (split_part_count parts, split_forces.hpp).
using SplitHosts = std::vector<std::vector<int>>;

/// `hosts` (optional): where the split objects' parts go (partition_at).
std::vector<int> initial_partition(const Scene& scene, int nranks, MPI_Comm comm = MPI_COMM_NULL,
                                   SplitHosts* hosts = nullptr, double min_reach = 0);

/// The same partition at the object boxes `boxes` (objects that have moved; a box with
/// a non-finite corner counts as a point at the origin). Identical on every rank.
/// `weights`: the nodes' weights (measured_weights: the objects', then the split objects'
/// parts'); empty: the static work (tets, a tenth of the surface triangles for kinematic
/// objects; a split object the work of one of its parts, which its owner evaluates). A
/// split object cut into fewer parts than ranks (split_part_count) adds its other parts
/// as nodes of that work (its tets / parts, or their measured share), at its box;
/// `hosts` (optional) gets, per split object, its owner (part 0) and the ranks where
/// those nodes landed, so that the ranks that evaluate the parts are those the partition
/// kept room on (one part per rank in rank order for an object with as many parts as
/// ranks).
///
/// The second constraint, memory (PartitionInput::memory, tolerance kMemoryTolerance):
/// owned_state_bytes (memory.hpp) of an object's tets and vertices; for a split object's
/// owner, of all its vertices plus its part's share of tets and vertices, and for each
/// other part's node that share. A kinematic object weighs little work but its vertices'
/// memory, so that no rank is given most of them (docs/benchmarks.md, "memory as a
/// second constraint").
///
/// The graph joins objects within max(median object size, min_reach) of each other: a
/// rank ghosts the objects within its skin (at first the detector's cell, ghosts.hpp) of
/// its own, so objects that near each other must be joined, or METIS, free to place
/// them by balance alone, scatters them and every rank ghosts most of them.
std::vector<int> partition_at(const Scene& scene, std::vector<Box> boxes,
                              int nranks, std::vector<std::int64_t> weights = {}, MPI_Comm comm = MPI_COMM_NULL,
                              SplitHosts* hosts = nullptr, double min_reach = 0);

/// Split hosts from a partition alone, where the partition that kept room for the parts
/// is not at hand (a partition given to the Simulator, a restart, a migration by hand):
/// one part per rank in rank order for an object with as many parts as ranks; with
/// fewer, part 0 to the owner and each other part in turn to the rank with the least
/// static work so far (its objects in `partition`, a split object at one part of its
/// tets, then the parts given out before; ties: the lowest rank). Identical on every
/// rank.
SplitHosts split_hosts(const Scene& scene, const std::vector<int>& partition, int nranks);

/// What a partition gives each rank by the static weights the initial partition balances:
/// per rank, its work (its objects' static work; a split object's parts at its static
/// work / parts on each rank that evaluates one, `hosts`) and its memory (owned_state_bytes:
/// an owned object's tets and vertices; a split object's owner all its vertices and a
/// part's share, each other host rank a part's share). Ghosts are not counted. The
/// imbalances are max / mean (1 when the total is 0).
struct PartitionLoads {
  std::vector<double> work, memory;
  double work_imbalance = 1, memory_imbalance = 1;
};
PartitionLoads partition_loads(const Scene& scene, const std::vector<int>& partition, const SplitHosts& hosts,
                               int nranks);

/// Whether `hosts` can stand for split_hosts(scene, partition, nranks): one list per split
/// object, as many parts, part 0 on the object's owner, every rank in [0, nranks). What
/// the Simulator and a restart check hosts handed to them against.
bool split_hosts_fit(const Scene& scene, const std::vector<int>& partition, int nranks, const SplitHosts& hosts);

/// The CutSearch of the ranks of `comm` (none for MPI_COMM_NULL or one rank): each runs
/// its candidates, the best is found by two MPI_Allreduce and broadcast by its rank.
CutSearch shared_cut_search(MPI_Comm comm);

/// partition_objects_grouped over the ranks of `comm` (collective; one part per rank,
/// nparts == its size): each rank computes only the group holding its own part, with
/// that group's ranks sharing the METIS runs (shared_cut_search on a communicator of
/// the group), and one MPI_Allgatherv (4 bytes per object) gives every rank the whole
/// partition. The answer is partition_objects_grouped's on any rank count. With one
/// group, partition_objects with shared_cut_search(comm); without a communicator (or
/// one rank), the serial form. A METIS failure in any group throws on every rank.
std::vector<int> partition_objects_over(const PartitionInput& in, int nparts, MPI_Comm comm,
                                        int parts_per_group = kPartsPerGroup);

/// The static work of object k: its tets; a kinematic object (no forces, only its share
/// of detection) a tenth of its surface triangles.
std::int64_t static_work(const Scene& scene, std::size_t k);

/// The work of a split object that its owner does beyond its part, in tets per vertex:
/// merging the parts' corner forces into each vertex and sending the parts their state
/// (split_forces.hpp). Measured on soft_floor on 4 ranks (oversubscribed on 2 cores):
/// the floor's owner took 1.9 ms per step more in forces than the other ranks for its
/// 17,405 vertices, where a tet took about 0.09 ms per thousand.
inline constexpr double kMergeWorkPerVertex = 1.0;

/// kMergeWorkPerVertex times object k's vertices, rounded: the owner's share of a split
/// object's work beyond its part (partition_loads, the partition's node weights).
std::int64_t merge_work(const Scene& scene, std::size_t k);

/// Partition weights from measured cost, by object, in microseconds (at least 1):
///
/// 1. A cost model fitted to every rank's measurement: T_r = a S_r + b C_r, with T_r the
///    seconds rank r measured (forces, detection and depth since the last check), S_r
///    the static work + 1 of its objects in `part` and C_r their colliding surface
///    vertices over the same steps (`contacts`, per object, summed over ranks; empty:
///    none). Least squares over the ranks; a fit with a <= 0, b < 0 or not finite (too
///    few ranks, noise) falls back to b = 0 (a = sum S T / sum S^2).
/// 2. Each rank's seconds spread over its objects in proportion to a (s_k + 1) + b c_k
///    (as LAMMPS' `balance ... weight time` does by atom, here with the model's shares):
///    the parts' predicted costs are exactly the measured seconds, and within a rank the
///    objects in contact weigh more than those at rest.
///
/// The parts of split objects cut into fewer parts than ranks, but the owner's, follow
/// the objects (one weight each, after the objects', as partition_at takes them): their
/// static work counts on the rank evaluating them (`hosts`, those of the run; empty:
/// split_hosts of `part`) in step 1 and their share of its seconds is their weight.
/// Objects split into a part per rank have no node: their parts' static work E (the same
/// on every rank) is in every S_r, and the share a E of each rank's model is withheld
/// from its nodes (step 2 spreads its seconds over a S + a E + b C), so that what every
/// rank pays alike is not charged to the objects of the ranks with the fewest. When some
/// rank measured no time (non-positive or not finite), every weight is the static work
/// + 1 (no mixing of units). Identical on every rank given the same input (arithmetic in
/// object and rank order).
std::vector<std::int64_t> measured_weights(const Scene& scene, const std::vector<int>& part,
                                           const std::vector<double>& rank_seconds,
                                           const std::vector<std::int64_t>& contacts = {},
                                           const SplitHosts& hosts = {});

/// This rank's figures since the last check: CPU seconds of forces, detection and depth
/// (process CPU time, so that ranks sharing a core on an oversubscribed node are not
/// charged for each other; the response waits for other ranks, so it is left out), and
/// its collisions, of which `cross` have their triangle on another rank's object.
struct RankWork {
  double seconds = 0;
  std::int64_t cross = 0, collisions = 0;
  /// Per scene object: colliding surface vertices of this rank's records (vertex records
  /// by their point's object, but a split object's by the body its point is in, whose
  /// owner finds them) summed over the steps since the last check; empty: none.
  std::vector<std::int64_t> contacts;
};

/// Whether `step` is one of the policy's checks (a positive multiple of check_every).
bool rebalance_due(const RebalancePolicy& policy, std::int64_t step);

/// What the rebalance remembers between checks: the fraction of the collisions crossing
/// ranks that the current partition achieved, measured over the steps after it was made.
struct RebalanceHistory {
  bool measure_cross = false;  ///< a repartition since the last check: this check measures what it achieved
  double achieved_cross = 0;   ///< the cross-rank fraction of the current partition (0 before any)
  /// The work imbalance at the last repartition when it moved no object (the partition
  /// is what METIS makes of the weights as they were); 0 when it moved some, or before any.
  double unmoved_imbalance = 0;
};

/// Margin by which the cross-rank fraction must exceed what the current partition
/// achieved before it triggers a repartition again.
inline constexpr double kCrossRetryMargin = 0.1;

/// Margin by which the work imbalance must exceed the one at a repartition that moved no
/// object before it triggers a repartition again.
inline constexpr double kImbalanceRetryMargin = 0.1;

/// A repartition for the work (not for the cross-rank fraction) is taken only where the
/// measured weights predict its slowest rank at least this fraction below the current
/// partition's slowest (predicted_max_load of each); else no object moves, and the
/// partition counts as one that moved nothing (RebalanceHistory::unmoved_imbalance).
inline constexpr double kRepartitionGain = 0.05;

/// The largest sum of node weights (measured_weights' order: the objects, then the
/// split objects' parts) that `part` and the parts' `hosts` (empty: split_hosts') put on
/// one rank. Throws RuntimeFailure where they do not fit.
double predicted_max_load(const Scene& scene, const std::vector<int>& part, const SplitHosts& hosts,
                          const std::vector<std::int64_t>& weights, int nranks);

/// The decision at a check, from the reduced figures (the same on every rank): the work
/// imbalance (max / mean) above the policy's, or the cross-rank fraction above the
/// policy's and above what the current partition achieved plus kCrossRetryMargin. A
/// partition that cannot bring the fraction down (every body of a pile on one floor
/// touches the floor's rank) is not redone for it at every check. The first check after
/// a repartition records what it achieved (in `h`). Likewise the work imbalance, when
/// the last repartition moved no object (three objects, one of them split, whose cost
/// METIS cannot share out more evenly): it triggers again only above that repartition's
/// imbalance plus kImbalanceRetryMargin.
bool rebalance_wanted(const RebalancePolicy& policy, double imbalance, double cross, RebalanceHistory& h);

/// At a step rebalance_due() names: when rebalance_wanted(), METIS partitions the current
/// boxes with the measured weights (measured_weights of every rank's seconds) and the new
/// parts are relabelled to keep objects where they are (rank 0 logs it). Returns true
/// with `next` set when it repartitioned (`next` may equal `current`). Every rank takes
/// the same decision. Collective. `hosts` (optional): the split objects' current hosts
/// (empty: split_hosts of `current`), and on return with true the next ones.
bool rebalance(MPI_Comm comm, const Scene& scene, const World& w,
               const std::vector<int>& current, const RebalancePolicy& policy, std::int64_t step, const RankWork& work,
               std::vector<int>& next, RebalanceHistory& history, SplitHosts* hosts = nullptr);

/// Moves every owned object whose rank changes from `current` to `next`, whole, with its
/// state `now` (rows in w's owned order): returns the World of partition `next` (at the
/// scene's initial positions, for the models' rest shapes) and, in `then`, the state in
/// its owned order. Collective (MPI_Alltoallv).
World migrate_objects(MPI_Comm comm, const Scene& scene, const World& w,
                      const StepState& now, const std::vector<int>& current, const std::vector<int>& next,
                      StepState& then);

}  // namespace softcontact
