#pragma once
// Objects -> MPI ranks with METIS (design.md, "Parallel shape"): a graph whose nodes are
// the objects, weighted by their work, with an edge between two objects whose bounding
// boxes come within `reach` of each other, so that objects likely to touch share a rank
// and few contacts cross ranks. Serial and deterministic: every rank computes the same
// answer from the same (global) input, so nothing has to be communicated.
#include <cstdint>
#include <functional>
#include <vector>

#include "softcontact/box.hpp"
#include "softcontact/mesh.hpp"

namespace softcontact {


struct PartitionInput {
  /// Per object: its work, >= 0 (tets; callers give kinematic objects a small weight).
  /// Zero is allowed; METIS sees such an object as weight 1 (it has to land somewhere)
  /// and the empty-rank rule below does not count it.
  std::vector<std::int64_t> weight;
  /// Per object: the memory its owner holds for it, >= 0 [bytes, or any unit], or empty
  /// (the work alone). A kinematic object costs little work but its vertices cost memory
  /// like any other's. When given and the partition by work leaves the memory of some
  /// part above kMemoryImbalanceTrigger times the mean, METIS partitions again with the
  /// memory as a second constraint (ncon = 2, tolerance kMemoryTolerance), and that
  /// partition is taken if its work imbalance is at most the larger of the first's and
  /// 1.03, plus 0.01, and its memory imbalance lower (see partition_objects).
  std::vector<std::int64_t> memory;
  /// Per object: current bounding box (lo <= hi, finite).
  std::vector<Box> box;
  /// Objects whose boxes are at most this far apart on every axis (boxes grown by
  /// reach/2 each overlap, closed intervals: touching boxes are joined even at 0) [m].
  double reach = 0;
};

/// The load tolerance of the memory constraint: max part memory / mean part memory that
/// METIS aims below (the work's is 1.03, METIS's default ufactor 30). Looser than the
/// work's, which sets the pace: memory only has to fit.
inline constexpr double kMemoryTolerance = 1.10;
/// The memory imbalance of the partition by work above which it is partitioned again
/// with the memory as a second constraint (partition_objects).
inline constexpr double kMemoryImbalanceTrigger = 1.5;
/// The work imbalance of METIS's partition above which objects are moved out of the
/// heaviest part, the cheapest in cut first, until it is within 1.03 or no move lowers
/// it (partition_objects). Below it METIS's cut stands: a pile of 12 objects on 2 ranks at
/// 1.094 balanced to 1.062 had both ranks ghost every object.
inline constexpr double kRepairTrigger = 1.10;

struct PartitionQuality {
  double imbalance = 1;          ///< max part weight / mean part weight (1 is perfect)
  double memory_imbalance = 1;   ///< the same for PartitionInput::memory (1 when not given)
  std::int64_t cut_edges = 0;    ///< graph edges whose ends lie on different parts
  std::int64_t cut_weight = 0;   ///< sum of their edge weights
};

/// One graph edge of the object graph, i < j, weight in [1, 101]:
/// 1 + round(100 * (1 - gap / reach)), gap = largest per-axis distance between the two
/// boxes (0 when they touch or overlap; 101 for every joined pair when reach == 0).
struct ObjectEdge {
  std::int32_t i, j;
  std::int32_t weight;
};

/// The object graph's edges in ascending (i, j) order. The pairs come from
/// boxes_within (box.hpp, a hierarchy of uniform grids): O(n log n + pairs near each
/// other). Until 2026-11-28 a sweep along the axis with the fewest candidates found
/// them: the same edges, but in a pile every box was compared with all those in its
/// slab along that axis (8 chess containers side by side: 8.5 ms for 4,040 objects).
std::vector<ObjectEdge> object_graph_edges(const PartitionInput& in);

/// How ranks share partition_objects' search for the smallest cut: of the kMetisCuts
/// k-way runs (one seed each), this rank computes those c with c % parts == part, and
/// `best` takes this rank's best (its cut, its candidate index c, its parts; a rank with
/// none gives INT64_MAX, INT_MAX and no parts) and returns on every rank the parts of the
/// best over the ranks: the smallest cut, then the lowest c (an MPI_Allreduce and a
/// broadcast: rebalance.cpp). The result is the same as with parts = 1, where every
/// candidate is computed here, and so the same on any rank count. A rank whose METIS run
/// fails gives the cut -1; `best` then returns no parts on every rank, and every rank
/// throws (none is left waiting).
struct CutSearch {
  int part = 0;
  int parts = 1;
  std::function<std::vector<int>(std::int64_t cut, int candidate, std::vector<int> parts)> best;
};

/// The number of k-way runs partition_objects compares (seeds kMetisSeed + c, c < this).
inline constexpr int kMetisCuts = 4;

/// Objects -> parts 0..nparts-1, identical on every rank and every call.
///
/// METIS_PartGraphKway on the object graph (edge-cut objective, default load tolerance
/// ufactor 30, i.e. 1.03 plus the granularity of single objects, C numbering, adjacency
/// built in ascending object order), run kMetisCuts times with the seeds kMetisSeed + c
/// and one cut each; the smallest cut wins (the lowest c on ties). `search` spreads the
/// runs over the ranks (CutSearch); the answer does not depend on it. Recursive
/// bisection (METIS_PartGraphRecursive) is not used, at any part count. Measured on random scenes of 100 objects, 2..8 parts, weights 1..1000:
/// the better of one k-way and one recursive run cut 5% less than k-way alone, the best
/// of four k-way runs 9% less; recursive bisection balanced worse from 5 parts up
/// (imbalance up to 1.18 where k-way stayed below 1.09); and with heavy-tailed weights
/// it left parts empty, printing "***Cannot bisect a graph with 0 vertices!" to stdout.
///
/// Before METIS, giants are peeled off: taking objects heaviest first (lowest index on
/// ties), one whose weight is at least the mean weight per part of what is left (the
/// total not yet peeled over the parts not yet given out) gets a part of its own, parts
/// 0, 1, ... in that order, while two or more parts are left. Sharing its part could
/// only raise the largest load; METIS, left to place it, bisects degenerate graphs (and
/// prints "***Cannot bisect a graph with 0 vertices!" to stdout on every rank). The
/// other objects go to the remaining parts by METIS on the graph they induce.
///
/// nparts == 1: all zeros. n <= nparts objects: object k on part k (so with fewer
/// objects than parts, parts n..nparts-1 are empty). Objects without edges are placed
/// by METIS like the others (balance only). If there are at least nparts objects of
/// nonzero weight, no part is left without one: while a part is empty, the lightest
/// nonzero object (lowest index on ties) of the heaviest part holding two or more of
/// them (lowest part on ties) moves to the lowest-numbered empty part. Zero-weight
/// objects do not count: a part may hold only those, or none.
///
/// With PartitionInput::memory given, each METIS problem (the objects left after the
/// giants, or a group's) is partitioned by the work first; only where that leaves the
/// memory of some part above kMemoryImbalanceTrigger times the mean is it partitioned
/// again with both constraints (the same kMetisCuts runs), and kept if its work imbalance
/// is at most max(the first's, 1.03) + 0.01 and its memory imbalance lower. Memory only
/// has to fit, and two constraints cost cut; and METIS, asked to balance a memory it
/// cannot (an object split over ranks, whose owner holds all its vertices), gives up the
/// work's balance for it (inputs/archway.yaml on 4 ranks: 1.03 to 1.39). The scenes
/// shipped keep their partitions on 2, 4 and 8 ranks (docs/benchmarks.md, "memory as a
/// second constraint").
///
/// Where METIS's smallest cut leaves the work of a part above kRepairTrigger times the
/// mean (few objects, whose granularity no split within 1.03 fits), objects move out of
/// the heaviest part one at a time, while some move leaves both the part it leaves and
/// the part it joins below the heaviest part's load: the move adding the least cut
/// weight (its edges into the part it leaves minus those into the part it joins), then
/// the one leaving the lower larger load, then the lowest object and part; moves that
/// raise the memory's largest part above the larger of its current load and
/// kMemoryImbalanceTrigger times the mean (kMemoryTolerance where the memory was a
/// constraint: what METIS balanced stays balanced) are not made; it stops at 1.03, or
/// after 16 moves per part (a repair for few objects: each move is a pass over them). A
/// greedy repair, not an optimum: above kRepairTrigger (and without memory), no single
/// move out of the heaviest part lowers it (tests/parallel/test_partition.cpp,
/// "PartitionRepair").
///
/// Weights whose total would overflow METIS' idx_t are scaled down (each kept >= 1).
/// Throws RuntimeFailure for malformed input (sizes, negative weight, non-finite or
/// inverted box, nparts < 1) or when METIS fails.
std::vector<int> partition_objects(const PartitionInput& in, int nparts, const CutSearch& search = {});

/// Parts that one METIS graph covers at most when the objects are partitioned in groups
/// (partition_objects_grouped): up to this many parts, the whole scene is one graph.
inline constexpr int kPartsPerGroup = 8;

/// The groups of partition_objects_grouped: per object its group; per group its first
/// part and its number of parts (the groups' parts are consecutive, ascending by group).
struct PartGroups {
  std::vector<int> group;
  std::vector<int> first, parts;
};

/// Recursive coordinate bisection of the objects into groups of at most
/// `parts_per_group` parts: the parts are halved (the lower half floor(parts / 2)), and
/// the objects, sorted by the centre of their box along the axis where the centres
/// spread widest (ties: object index), are cut where the running sum of their weights
/// (each at least 1) comes nearest the lower half's share of the total (at least one
/// object each side; with PartitionInput::memory given, where the larger of the two
/// sums' distances from their shares, each relative to its total, is smallest); until
/// each range of parts fits in a group. One group holding every object when nparts <= parts_per_group or there are no more objects than parts.
/// O(n log n) per level, log2(nparts / parts_per_group) levels; identical on every rank.
PartGroups group_objects(const PartitionInput& in, int nparts, int parts_per_group = kPartsPerGroup);

/// Per group, its objects ascending (one pass over the objects).
std::vector<std::vector<std::int32_t>> group_members(const PartGroups& groups);

/// The input restricted to `members` (in their order), with the same reach.
PartitionInput group_input(const PartitionInput& in, const std::vector<std::int32_t>& members);

/// Objects -> parts for many parts: group_objects, then each group's objects by
/// partition_objects into the group's parts (their own graph, a group's part numbers
/// offset by its first part). The same as partition_objects for nparts <= parts_per_group.
/// The graph and METIS then cost per group what they cost for parts_per_group ranks,
/// however many parts there are, and a run's ranks can share the groups
/// (partition_objects_over, rebalance.hpp); the price is the cut along the bisection's
/// planes, which METIS does not choose. This serial form computes every group.
std::vector<int> partition_objects_grouped(const PartitionInput& in, int nparts, int parts_per_group = kPartsPerGroup);

/// Up to this many tets a split object's parts come from METIS, above it from a
/// coordinate bisection (split_tet_parts): METIS takes about 1.2 microseconds and 160 to
/// 180 bytes per tet on every rank taking part (2.5 s and 352 MiB at 2.07 million tets,
/// 11.4 s and 1.4 GiB at 9.6 million), the bisection a ninth of the time and 36 bytes per
/// tet, for parts whose cuts cross cells (inputs/soft_floor.yaml on 8 ranks: 16 % more
/// bytes in the parts' messages). docs/benchmarks.md, "a split object's parts by
/// coordinate bisection".
inline constexpr std::size_t kSplitMetisMaxTets = std::size_t{1} << 21;

/// The tets of one mesh in `nparts` parts (objects split over ranks, split_forces.hpp),
/// the same on every rank. Up to `metis_max_tets` tets: METIS_PartMeshDual on the tets'
/// dual graph (tets sharing a face), fixed seed (part sizes within a few % of each other,
/// a small cut). Above: recursive coordinate bisection of the tets' centroids, each range
/// cut across its widest extent into counts proportional to its parts (rounded; ties
/// broken by tet index), O(tets log nparts) time and 36 bytes per tet. Part per tet, in
/// [0, nparts); a part may be empty.
std::vector<std::int32_t> split_tet_parts(const TetMesh& mesh, int nparts, std::size_t metis_max_tets = kSplitMetisMaxTets);

/// Imbalance (max part weight / mean part weight, with the weights as given; 1 when the
/// total is 0) and edge cut of `part` on the graph of object_graph_edges(in).
PartitionQuality partition_quality(const PartitionInput& in, const std::vector<int>& part, int nparts);

}  // namespace softcontact
