// The partition's search for the smallest cut shared over the ranks (CutSearch,
// partition.hpp; shared_cut_search, rebalance.hpp): on 1 to 4 ranks it must give exactly
// the partition that one process computes alone, which is the candidate (one METIS k-way
// run, seed kMetisSeed + c) of the smallest cut, the lowest c on ties. Reference: each
// candidate computed on its own here, its cut counted by partition_quality.
#include <gtest/gtest.h>
#include <mpi.h>

#include <algorithm>
#include <random>
#include <set>

#include "softcontact/mpi_util.hpp"
#include "softcontact/partition.hpp"
#include "softcontact/rebalance.hpp"

using namespace softcontact;

namespace {

// n objects of random size and weight scattered in a box: many near pairs, so the
// candidates cut differently.
PartitionInput scattered(int n, std::uint64_t seed) {
  std::mt19937_64 g(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  PartitionInput in;
  for (int k = 0; k < n; ++k) {
    const double x = 20 * u(g), y = 20 * u(g), z = 5 * u(g), s = 0.5 + u(g);
    in.box.push_back(Box{{x, y, z}, {x + s, y + s, z + s}});
    in.weight.push_back(100 + static_cast<std::int64_t>(900 * u(g)));
  }
  in.reach = 1.0;
  return in;
}

// Candidate c alone: a search of kMetisCuts parts in which this process is part c and
// keeps its own answer.
std::vector<int> candidate(const PartitionInput& in, int nparts, int c) {
  CutSearch only;
  only.part = c;
  only.parts = kMetisCuts;
  only.best = [](std::int64_t, int, std::vector<int> p) { return p; };
  return partition_objects(in, nparts, only);
}

}  // namespace

TEST(CutSearch, SharedOverRanksIsTheSmallestCutOfTheSerialCandidates) {
  int cases_with_distinct_candidates = 0;
  for (std::uint64_t seed : {1u, 2u, 3u}) {
    const PartitionInput in = scattered(400, seed);
    for (int nparts : {2, 3, 5, 8}) {
      std::int64_t best_cut = -1;
      std::vector<int> best;
      std::set<std::vector<int>> distinct;
      for (int c = 0; c < kMetisCuts; ++c) {
        const std::vector<int> p = candidate(in, nparts, c);
        const std::int64_t cut = partition_quality(in, p, nparts).cut_weight;
        distinct.insert(p);
        if (best_cut < 0 || cut < best_cut) {
          best_cut = cut;
          best = p;
        }
      }
      cases_with_distinct_candidates += distinct.size() > 1 ? 1 : 0;
      const std::vector<int> serial = partition_objects(in, nparts);
      EXPECT_EQ(serial, best) << "seed " << seed << ", " << nparts << " parts";
      const std::vector<int> shared = partition_objects(in, nparts, shared_cut_search(MPI_COMM_WORLD));
      EXPECT_EQ(shared, serial) << "seed " << seed << ", " << nparts << " parts on " << comm_size(MPI_COMM_WORLD)
                                << " ranks";
    }
  }
  // The choice has to matter for the comparison to mean anything.
  EXPECT_GE(cases_with_distinct_candidates, 6);
}

// Groups (partition_objects_over): each rank computes the group holding its part, the
// group's ranks sharing its METIS runs, and one all-gather gives every rank the whole
// partition. Reference: the serial partition_objects_grouped, which computes every group
// in one process. With one part per group the groups are the bisection itself; with two
// (on 3 and 4 ranks) two ranks share a group's search; with 8 (the default) one group on
// up to 8 ranks, the ungrouped partition.
TEST(CutSearch, GroupsSharedOverRanksAreTheSerialGroupedPartition) {
  const int size = comm_size(MPI_COMM_WORLD);
  for (std::uint64_t seed : {4u, 5u}) {
    const PartitionInput in = scattered(600, seed);
    for (int per_group : {1, 2, kPartsPerGroup}) {
      const std::vector<int> shared = partition_objects_over(in, size, MPI_COMM_WORLD, per_group);
      const std::vector<int> serial = partition_objects_grouped(in, size, per_group);
      EXPECT_EQ(shared, serial) << size << " ranks, " << per_group << " parts per group, seed " << seed;
      std::vector<int> used(static_cast<std::size_t>(size), 0);
      for (int p : shared) {
        ASSERT_GE(p, 0);
        ASSERT_LT(p, size);
        used[static_cast<std::size_t>(p)] = 1;
      }
      EXPECT_EQ(std::count(used.begin(), used.end(), 1), size) << "a rank without objects";
    }
    EXPECT_EQ(partition_objects_over(in, size, MPI_COMM_WORLD), partition_objects(in, size));
  }
}
