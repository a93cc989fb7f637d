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
  double max_imbalance = 1.25;      ///< repartition when max/mean of the per-rank work passes this
  double max_cross_fraction = 0.5;  ///< ... or when this fraction of the collisions crosses ranks
};

/// The partition METIS gives the scene's objects at their initial positions: nodes
/// weighted by tets (kinematic objects by a tenth of their surface triangles), edges
/// between objects closer than the median object size. Identical on every rank.
std::vector<int> initial_partition(const Scene& scene, int nranks);

/// The same partition at the object boxes `boxes` (objects that have moved; a box with
/// a non-finite corner counts as a point at the origin). Identical on every rank.
std::vector<int> partition_at(const Scene& scene, std::vector<Box> boxes,
                              int nranks);

/// This rank's figures since the last check: seconds of forces, detection and depth (the
/// response waits for other ranks, so it is left out), and its collisions, of which
/// `cross` have their triangle on another rank's object.
struct RankWork {
  double seconds = 0;
  std::int64_t cross = 0, collisions = 0;
};

/// Whether `step` is one of the policy's checks (a positive multiple of check_every).
bool rebalance_due(const RebalancePolicy& policy, std::int64_t step);

/// At a step rebalance_due() names: when the work per rank is out of balance or too many
/// collisions cross ranks, METIS partitions the current boxes and
/// the new parts are relabelled to keep objects where they are (rank 0 logs it). Returns
/// true with `next` set when it repartitioned (`next` may equal `current`). Every rank
/// takes the same decision. Collective.
bool rebalance(MPI_Comm comm, const Scene& scene, const World& w,
               const std::vector<int>& current, const RebalancePolicy& policy, std::int64_t step, const RankWork& work,
               std::vector<int>& next);

/// Moves every owned object whose rank changes from `current` to `next`, whole, with its
/// state `now` (rows in w's owned order): returns the World of partition `next` (at the
/// scene's initial positions, for the models' rest shapes) and, in `then`, the state in
/// its owned order. Collective (MPI_Alltoallv).
World migrate_objects(MPI_Comm comm, const Scene& scene, const World& w,
                      const StepState& now, const std::vector<int>& current, const std::vector<int>& next,
                      StepState& then);

}  // namespace softcontact
