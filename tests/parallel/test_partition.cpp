// The METIS object partition (src/parallel/partition.cpp): graph edges against brute
// force, clusters kept together, balance, determinism, the small cases and the
// empty-part rule.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstdint>
#include <cstring>
#include <numeric>
#include <random>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "softcontact/error.hpp"
#include "softcontact/partition.hpp"
#include "softcontact/ghosts.hpp"
#include "softcontact/primitives.hpp"
#include "softcontact/scene.hpp"
#include "softcontact/split_forces.hpp"

using namespace softcontact;

namespace {

Box box(double x0, double y0, double z0, double x1, double y1, double z1) {
  Box b;
  b.lo[0] = x0, b.lo[1] = y0, b.lo[2] = z0;
  b.hi[0] = x1, b.hi[1] = y1, b.hi[2] = z1;
  return b;
}

Box unit_box(double x, double y, double z) { return box(x, y, z, x + 1, y + 1, z + 1); }

// `n` boxes of edge 0.2..1 with corners in [0, extent]^3, weights 1..1000, reach 0.5.
PartitionInput random_boxes(int n, unsigned seed, double extent = 10.0) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> pos(0.0, extent), size(0.2, 1.0);
  std::uniform_int_distribution<std::int64_t> weight(1, 1000);
  PartitionInput in;
  in.reach = 0.5;
  for (int k = 0; k < n; ++k) {
    const double x = pos(rng), y = pos(rng), z = pos(rng);
    in.box.push_back(box(x, y, z, x + size(rng), y + size(rng), z + size(rng)));
    in.weight.push_back(weight(rng));
  }
  return in;
}

// Edges by testing every pair, with the weight rule of partition.hpp.
std::vector<ObjectEdge> brute_force_edges(const PartitionInput& in) {
  std::vector<ObjectEdge> edges;
  const auto n = static_cast<std::int32_t>(in.box.size());
  for (std::int32_t i = 0; i < n; ++i)
    for (std::int32_t j = i + 1; j < n; ++j) {
      double gap = 0;
      for (int a = 0; a < 3; ++a)
        gap = std::max({gap, in.box[j].lo[a] - in.box[i].hi[a], in.box[i].lo[a] - in.box[j].hi[a]});
      if (gap > in.reach) continue;
      const double closeness = in.reach > 0 ? 1.0 - gap / in.reach : 1.0;
      edges.push_back({i, j, static_cast<std::int32_t>(1 + std::lround(100.0 * closeness))});
    }
  return edges;
}

std::vector<int> parts_used(const std::vector<int>& part, int nparts) {
  std::vector<int> count(static_cast<std::size_t>(nparts), 0);
  for (int p : part) {
    EXPECT_GE(p, 0);
    EXPECT_LT(p, nparts);
    if (p >= 0 && p < nparts) ++count[static_cast<std::size_t>(p)];
  }
  return count;
}

}  // namespace

TEST(ObjectGraph, EdgeWeightsFollowTheGap) {
  PartitionInput in;
  in.reach = 1.0;
  in.box = {unit_box(0, 0, 0),     // 0
            unit_box(1, 0, 0),     // 1: touches 0 (gap 0)
            unit_box(2.5, 0, 0),   // 2: gap 0.5 to 1, 1.5 to 0
            unit_box(4.5, 0, 0),   // 3: gap 1 to 2 (exactly reach: joined, weight 1)
            unit_box(4.5, 2.75, 0)};  // 4: overlaps 3 in x, gap 1.75 in y: too far
  in.weight.assign(in.box.size(), 1);
  const std::vector<ObjectEdge> edges = object_graph_edges(in);
  ASSERT_EQ(edges.size(), 3u);
  EXPECT_EQ(edges[0].i, 0);
  EXPECT_EQ(edges[0].j, 1);
  EXPECT_EQ(edges[0].weight, 101);
  EXPECT_EQ(edges[1].i, 1);
  EXPECT_EQ(edges[1].j, 2);
  EXPECT_EQ(edges[1].weight, 51);
  EXPECT_EQ(edges[2].i, 2);
  EXPECT_EQ(edges[2].j, 3);
  EXPECT_EQ(edges[2].weight, 1);

  in.reach = 0;  // only touching or overlapping boxes are joined
  const std::vector<ObjectEdge> touching = object_graph_edges(in);
  ASSERT_EQ(touching.size(), 1u);
  EXPECT_EQ(touching[0].weight, 101);
}

TEST(ObjectGraph, MatchesBruteForce) {
  // Random boxes plus a column of boxes stacked along z spanning all x (long flat
  // boxes on a coarse level of the grid, and the case that made a sweep along x
  // quadratic): exactly the pairs and weights of the brute-force search, in order.
  PartitionInput in = random_boxes(1500, 7);
  for (int k = 0; k < 300; ++k) {
    in.box.push_back(box(0, 0, 0.05 * k, 10, 0.3, 0.05 * k + 0.04));
    in.weight.push_back(10);
  }
  const std::vector<ObjectEdge> sweep = object_graph_edges(in), brute = brute_force_edges(in);
  ASSERT_EQ(sweep.size(), brute.size());
  for (std::size_t e = 0; e < sweep.size(); ++e) {
    EXPECT_EQ(sweep[e].i, brute[e].i) << "edge " << e;
    EXPECT_EQ(sweep[e].j, brute[e].j) << "edge " << e;
    EXPECT_EQ(sweep[e].weight, brute[e].weight) << "edge " << e;
  }
}

TEST(Partition, SeparatedClustersStayWhole) {
  // 4 clusters, 100 m apart, of 8 unit boxes in a 2x2x2 block (all touching); object k
  // belongs to cluster k % 4, so index order says nothing about the clusters.
  PartitionInput in;
  in.reach = 0.5;
  const double origin[4][2] = {{0, 0}, {100, 0}, {0, 100}, {100, 100}};
  for (int k = 0; k < 32; ++k) {
    const int c = k % 4, m = k / 4;
    in.box.push_back(unit_box(origin[c][0] + (m & 1), origin[c][1] + ((m >> 1) & 1), (m >> 2) & 1));
    in.weight.push_back(100);
  }
  const std::vector<int> part = partition_objects(in, 4);
  ASSERT_EQ(part.size(), 32u);
  std::set<int> cluster_parts;
  for (int c = 0; c < 4; ++c) {
    for (int k = c; k < 32; k += 4) EXPECT_EQ(part[k], part[c]) << "object " << k << " left cluster " << c;
    cluster_parts.insert(part[c]);
  }
  EXPECT_EQ(cluster_parts.size(), 4u) << "each rank gets one cluster";
  const PartitionQuality q = partition_quality(in, part, 4);
  EXPECT_EQ(q.cut_edges, 0);
  EXPECT_EQ(q.cut_weight, 0);
  EXPECT_DOUBLE_EQ(q.imbalance, 1.0);
}

TEST(Partition, BalancesRandomBoxes) {
  // Tolerance: METIS k-way's default load tolerance, ufactor 30 (1.03), plus the
  // granularity of one object, max weight / mean part weight (about 0.04 at 2 parts,
  // 0.16 at 8). A heuristic's target, not a guarantee: at this density (about 290 edges)
  // no case of 200 seeds x {2, 3, 4, 8} parts exceeded it; sparser scenes did, by up to
  // 0.017. The boxes are dense enough that every part count cuts some edges.
  const PartitionInput in = random_boxes(100, 12345, 5.0);
  const std::int64_t total = std::accumulate(in.weight.begin(), in.weight.end(), std::int64_t{0});
  const std::int64_t heaviest = *std::max_element(in.weight.begin(), in.weight.end());
  for (int nparts : {2, 3, 4, 8}) {
    const std::vector<int> part = partition_objects(in, nparts);
    ASSERT_EQ(part.size(), in.box.size());
    const std::vector<int> count = parts_used(part, nparts);
    for (int p = 0; p < nparts; ++p) EXPECT_GT(count[p], 0) << "part " << p << " of " << nparts << " is empty";
    const PartitionQuality q = partition_quality(in, part, nparts);
    EXPECT_LE(q.imbalance, 1.03 + static_cast<double>(heaviest) * nparts / static_cast<double>(total))
        << nparts << " parts";
    // Nearby objects share a rank: the cut is far below that of a round-robin split
    // (which, as the boxes are in random order, cuts about (nparts-1)/nparts of it).
    std::vector<int> round_robin(in.box.size());
    for (std::size_t k = 0; k < round_robin.size(); ++k) round_robin[k] = static_cast<int>(k % nparts);
    const PartitionQuality rr = partition_quality(in, round_robin, nparts);
    EXPECT_LT(q.cut_weight, rr.cut_weight / 2) << nparts << " parts";
    std::printf("  %d parts: imbalance %.4f, cut %lld edges (weight %lld); round robin %lld\n", nparts, q.imbalance,
                static_cast<long long>(q.cut_edges), static_cast<long long>(q.cut_weight),
                static_cast<long long>(rr.cut_weight));
  }
}

TEST(Partition, Deterministic) {
  const PartitionInput in = random_boxes(500, 99);
  for (int nparts : {3, 8, 13}) {
    const std::vector<int> a = partition_objects(in, nparts);
    const PartitionInput copy = in;
    const std::vector<int> b = partition_objects(copy, nparts);
    EXPECT_EQ(a, b) << nparts << " parts";
  }
}

TEST(Partition, OnePartAndFewerObjectsThanParts) {
  const PartitionInput in = random_boxes(20, 3);
  EXPECT_EQ(partition_objects(in, 1), std::vector<int>(20, 0));

  const PartitionInput three = random_boxes(3, 4);
  EXPECT_EQ(partition_objects(three, 5), (std::vector<int>{0, 1, 2}));
  EXPECT_EQ(partition_objects(three, 3), (std::vector<int>{0, 1, 2}));

  EXPECT_TRUE(partition_objects(PartitionInput{}, 4).empty());
}

TEST(Partition, ChainSplitsIntoContiguousHalves) {
  // 16 unit boxes touching end to end along x, stored in shuffled order: the two parts
  // must be the two halves of the chain, one edge cut.
  std::vector<int> position(16);
  for (int k = 0; k < 16; ++k) position[k] = k;
  std::mt19937 rng(2024);
  std::shuffle(position.begin(), position.end(), rng);
  PartitionInput in;
  in.reach = 0;
  for (int k = 0; k < 16; ++k) {
    in.box.push_back(unit_box(position[k], 0, 0));
    in.weight.push_back(50);
  }
  const std::vector<int> part = partition_objects(in, 2);
  std::vector<int> along(16);
  for (int k = 0; k < 16; ++k) along[position[k]] = part[k];
  for (int s = 1; s < 8; ++s) EXPECT_EQ(along[s], along[0]) << "chain position " << s;
  for (int s = 9; s < 16; ++s) EXPECT_EQ(along[s], along[8]) << "chain position " << s;
  EXPECT_NE(along[0], along[8]);
  const PartitionQuality q = partition_quality(in, part, 2);
  EXPECT_EQ(q.cut_edges, 1);
  EXPECT_EQ(q.cut_weight, 101);
  EXPECT_DOUBLE_EQ(q.imbalance, 1.0);
}

TEST(Partition, NoEmptyPartWithSkewedOrZeroWeights) {
  // One object outweighs all others together, and kinematic-like zero-weight objects
  // sit among the heavy ones: every part still gets an object of nonzero weight.
  PartitionInput skewed;
  skewed.reach = 0.1;
  for (int k = 0; k < 6; ++k) {
    skewed.box.push_back(unit_box(1.05 * k, 0, 0));
    skewed.weight.push_back(k == 0 ? 1000000 : 1);
  }
  for (int nparts : {2, 4, 5}) {
    const std::vector<int> part = partition_objects(skewed, nparts);
    const std::vector<int> count = parts_used(part, nparts);
    for (int p = 0; p < nparts; ++p) EXPECT_GT(count[p], 0) << "part " << p << " of " << nparts;
    // The giant has part 0 to itself (peeled off before METIS).
    EXPECT_EQ(part[0], 0);
    EXPECT_EQ(count[0], 1);
  }
  // On 2 parts the chain is cut once, right next to the giant.
  EXPECT_EQ(partition_quality(skewed, partition_objects(skewed, 2), 2).cut_edges, 1);

  PartitionInput zeros;
  zeros.reach = 0.5;
  for (int k = 0; k < 14; ++k) {
    zeros.box.push_back(unit_box(k % 2 == 0 ? 0.5 * k : 0.5 * k + 0.01, 0, 0));
    zeros.weight.push_back(k % 3 == 0 ? 1000 : 0);  // objects 0, 3, 6, 9, 12 carry the work
  }
  for (int nparts : {2, 3, 4, 5}) {
    const std::vector<int> part = partition_objects(zeros, nparts);
    std::vector<int> working(static_cast<std::size_t>(nparts), 0);
    for (std::size_t k = 0; k < part.size(); ++k)
      if (zeros.weight[k] > 0) ++working[static_cast<std::size_t>(part[k])];
    for (int p = 0; p < nparts; ++p) EXPECT_GT(working[p], 0) << "part " << p << " of " << nparts << " has no work";
  }
}

TEST(Partition, TenThousandObjectsLattice) {
  // A 10 x 10 x 100 lattice of touching unit boxes (a tall column: a sweep along x
  // would test ~2000 pairs per box). Every box is joined to its 26 lattice neighbours:
  // ((3a-2)(3b-2)(3c-2) - abc) / 2 edges.
  PartitionInput in;
  in.reach = 0;
  for (int k = 0; k < 100; ++k)
    for (int j = 0; j < 10; ++j)
      for (int i = 0; i < 10; ++i) {
        in.box.push_back(unit_box(i, j, k));
        in.weight.push_back(1 + (i + j + k) % 7);
      }
  const std::vector<ObjectEdge> edges = object_graph_edges(in);
  const std::vector<int> part = partition_objects(in, 16);
  EXPECT_EQ(static_cast<std::int64_t>(edges.size()), (28LL * 28 * 298 - 10000) / 2);
  const std::vector<int> count = parts_used(part, 16);
  for (int p = 0; p < 16; ++p) EXPECT_GT(count[p], 0) << "part " << p;
  const PartitionQuality q = partition_quality(in, part, 16);
  EXPECT_LE(q.imbalance, 1.10);
  std::printf("  10^4 objects, %zu edges, 16 parts: imbalance %.4f, cut %lld edges\n", edges.size(), q.imbalance,
              static_cast<long long>(q.cut_edges));
}

TEST(Partition, RejectsMalformedInput) {
  PartitionInput in = random_boxes(10, 1);
  EXPECT_THROW(partition_objects(in, 0), RuntimeFailure);
  PartitionInput bad = in;
  bad.weight[3] = -1;
  EXPECT_THROW(partition_objects(bad, 2), RuntimeFailure);
  bad = in;
  bad.weight.pop_back();
  EXPECT_THROW(partition_objects(bad, 2), RuntimeFailure);
  bad = in;
  std::swap(bad.box[2].lo[1], bad.box[2].hi[1]);
  EXPECT_THROW(partition_objects(bad, 2), RuntimeFailure);
  bad = in;
  bad.reach = -1;
  EXPECT_THROW(partition_objects(bad, 2), RuntimeFailure);
  EXPECT_THROW(partition_quality(in, std::vector<int>(10, 2), 2), RuntimeFailure);
}

// The tets of one object in parts (objects split for their forces, split_forces.hpp), by
// METIS (up to kSplitMetisMaxTets) and by the coordinate bisection (above; here with the
// limit at 0): every tet in a part in range, every part used and within 5% of an even
// share (METIS' default imbalance tolerance is 3%; the bisection's rounding leaves a
// part within 2 tets of it), the same parts on every call (every rank computes them
// itself), and a cut that is a small fraction of the faces: the vertices on a cut are the
// ones whose corner forces travel one by one. Reference: the interior faces counted by
// brute force (sorted corner triples shared by two tets).
TEST(SplitTetParts, BalancedDeterministicWithASmallCut) {
  const TetMesh m = make_box(1, 1, 0.5, 12, 12, 6);
  const std::size_t nt = m.num_tets();
  ASSERT_GT(nt, std::size_t{4000});
  std::vector<std::array<index_t, 3>> faces;
  std::vector<std::size_t> face_tet;
  for (std::size_t t = 0; t < nt; ++t)
    for (int skip = 0; skip < 4; ++skip) {
      std::array<index_t, 3> f{};
      int k = 0;
      for (int c = 0; c < 4; ++c)
        if (c != skip) f[static_cast<std::size_t>(k++)] = m.tets[4 * t + static_cast<std::size_t>(c)];
      std::sort(f.begin(), f.end());
      faces.push_back(f);
      face_tet.push_back(t);
    }
  std::vector<std::size_t> order(faces.size());
  std::iota(order.begin(), order.end(), std::size_t{0});
  std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return faces[a] < faces[b]; });
  for (const std::size_t metis_max : {kSplitMetisMaxTets, std::size_t{0}})
  for (const int nparts : {1, 2, 3, 4, 7}) {
    SCOPED_TRACE(metis_max > 0 ? "METIS" : "coordinate bisection");
    const std::vector<std::int32_t> part = split_tet_parts(m, nparts, metis_max);
    ASSERT_EQ(part.size(), nt);
    EXPECT_EQ(split_tet_parts(m, nparts, metis_max), part) << "not deterministic";
    std::vector<std::size_t> size(static_cast<std::size_t>(nparts), 0);
    for (std::int32_t p : part) {
      ASSERT_GE(p, 0);
      ASSERT_LT(p, nparts);
      ++size[static_cast<std::size_t>(p)];
    }
    const double share = static_cast<double>(nt) / nparts;
    for (std::size_t s : size) {
      EXPECT_GT(s, 0u) << nparts << " parts";
      EXPECT_LE(static_cast<double>(s), 1.05 * share) << nparts << " parts";
      if (metis_max == 0) EXPECT_LE(std::abs(static_cast<double>(s) - share), 2.0) << nparts << " parts";
    }
    std::size_t interior = 0, cut = 0;
    for (std::size_t k = 0; k + 1 < order.size(); ++k)
      if (faces[order[k]] == faces[order[k + 1]]) {
        ++interior;
        cut += part[face_tet[order[k]]] != part[face_tet[order[k + 1]]] ? 1 : 0;
      }
    ASSERT_GT(interior, nt);
    if (nparts == 1) EXPECT_EQ(cut, 0u);
    else EXPECT_LT(static_cast<double>(cut), 0.1 * static_cast<double>(interior)) << nparts << " parts";
    std::printf("[measured] %s, %d parts: cut %zu of %zu interior faces\n", metis_max > 0 ? "METIS" : "bisection", nparts,
                cut, interior);
  }
}

// The shared cut search (CutSearch) from one process's side: the candidates it computes
// are those of its part, it hands its best to `best` (the smallest cut, the lowest
// candidate on ties), and takes back what `best` returns; when another rank's run
// failed, `best` returns no parts and the partition throws on this rank too, so that no
// rank is left waiting. Reference: its own candidates' cuts by partition_quality.
TEST(Partition, SharedCutSearchHandsItsBestAndTakesTheWinner) {
  const PartitionInput in = random_boxes(300, 11);
  const int nparts = 4;
  // This process is part 1 of 2: it runs candidates 1 and 3.
  std::int64_t handed_cut = -2;
  int handed = -2;
  std::vector<int> handed_parts;
  CutSearch search;
  search.part = 1;
  search.parts = 2;
  search.best = [&](std::int64_t cut, int c, std::vector<int> p) {
    handed_cut = cut;
    handed = c;
    handed_parts = p;
    return p;
  };
  const std::vector<int> got = partition_objects(in, nparts, search);
  ASSERT_TRUE(handed == 1 || handed == 3);
  // Each candidate alone, as the test of the MPI side computes them.
  auto alone = [&](int c) {
    CutSearch only;
    only.part = c;
    only.parts = kMetisCuts;
    only.best = [](std::int64_t, int, std::vector<int> p) { return p; };
    return partition_objects(in, nparts, only);
  };
  const std::int64_t c1 = partition_quality(in, alone(1), nparts).cut_weight;
  const std::int64_t c3 = partition_quality(in, alone(3), nparts).cut_weight;
  EXPECT_EQ(handed, c3 < c1 ? 3 : 1);
  EXPECT_EQ(handed_cut, std::min(c1, c3));
  EXPECT_EQ(got, alone(handed));
  // Another rank's run failed: nothing comes back, and this rank throws as well.
  search.best = [](std::int64_t, int, std::vector<int>) { return std::vector<int>(); };
  try {
    partition_objects(in, nparts, search);
    ADD_FAILURE() << "no exception";
  } catch (const RuntimeFailure& e) {
    EXPECT_NE(std::string(e.what()).find("another rank"), std::string::npos) << e.what();
  }
}

// Recursive coordinate bisection into groups (group_objects): the parts of each group
// are consecutive and at most parts_per_group, and each group's weight is its parts'
// share of the total to within the objects cut at each level (at most one object's
// weight per level: 1000 here).
TEST(PartitionGroups, EachGroupHoldsItsPartsShareOfTheWeight) {
  const PartitionInput in = random_boxes(4000, 21, 30.0);
  std::int64_t total = 0;
  for (std::int64_t w : in.weight) total += w;
  for (const auto& [nparts, per_group, groups_expected] :
       std::vector<std::array<int, 3>>{{32, 8, 4}, {24, 8, 4}, {40, 8, 8}, {8, 8, 1}, {7, 2, 4}, {16, 1, 16}}) {
    const PartGroups g = group_objects(in, nparts, per_group);
    ASSERT_EQ(static_cast<int>(g.first.size()), groups_expected) << nparts << " parts, " << per_group << " per group";
    int next = 0, levels = 0;
    for (int p = nparts; p > per_group; p = (p + 1) / 2) ++levels;
    std::vector<std::int64_t> weight(g.first.size(), 0);
    for (std::size_t k = 0; k < in.weight.size(); ++k) weight[static_cast<std::size_t>(g.group[k])] += in.weight[k];
    for (std::size_t i = 0; i < g.first.size(); ++i) {
      EXPECT_EQ(g.first[i], next);
      EXPECT_GE(g.parts[i], 1);
      EXPECT_LE(g.parts[i], per_group);
      next += g.parts[i];
      const double share = static_cast<double>(total) * g.parts[i] / nparts;
      EXPECT_LE(std::abs(static_cast<double>(weight[i]) - share), 1000.0 * levels)
          << nparts << " parts, group " << i << ": weight " << weight[i] << " for a share of " << share;
    }
    EXPECT_EQ(next, nparts);
  }
  // No more objects than parts: one group.
  PartitionInput few = random_boxes(10, 3);
  EXPECT_EQ(group_objects(few, 16, 2).first.size(), 1u);
}

// The grouped partition against METIS on the whole graph, in 32 parts. On chess500's
// objects at their initial boxes (one pile): the load within 1.10 of the mean (METIS
// allows 1.03 plus one object per part) and a cut no more than 15% above the whole
// graph's (measured 1.04). On 8,000 random boxes filling a cube, the
// worst case seen: the same balance, but a cut 2.17 times the whole graph's, bounded
// here by 2.5 (the bisection's planes cross the densest part of the graph). Up to 8
// parts, exactly the ungrouped partition.
TEST(PartitionGroups, GroupedPartitionBalancesWithACutNearTheWholeGraphs) {
  const Scene chess = load_scene(SOFTCONTACT_INPUTS_DIR "/chess500.yaml");
  PartitionInput pile;
  for (std::size_t k = 0; k < chess.objects.size(); ++k) {
    pile.box.push_back(chess.objects[k].shape->box);
    pile.weight.push_back(static_cast<std::int64_t>(chess.objects[k].shape->tets));
  }
  pile.reach = median_object_size(pile.box);
  const PartitionInput cube = random_boxes(8000, 22, 25.0);
  for (const auto& [in, cut_bound] : {std::pair<const PartitionInput*, double>{&pile, 1.15}, {&cube, 2.5}}) {
    const std::vector<int> grouped = partition_objects_grouped(*in, 32), whole = partition_objects(*in, 32);
    const PartitionQuality qg = partition_quality(*in, grouped, 32), qw = partition_quality(*in, whole, 32);
    EXPECT_LT(qg.imbalance, 1.10);
    EXPECT_LE(static_cast<double>(qg.cut_weight), cut_bound * static_cast<double>(qw.cut_weight))
        << "grouped cut " << qg.cut_weight << ", whole graph " << qw.cut_weight;
    std::printf("grouped: imbalance %.3f, cut %lld; whole graph: imbalance %.3f, cut %lld\n", qg.imbalance,
                static_cast<long long>(qg.cut_weight), qw.imbalance, static_cast<long long>(qw.cut_weight));
    EXPECT_EQ(partition_objects_grouped(*in, 8), partition_objects(*in, 8));
  }
}

namespace {

// 64 bodies (work 500, memory 287,000: 500 tets and 150 vertices of the memory model) in
// a 4 x 4 x 4 cluster of touching unit boxes, and a crowd of 2,000 kinematic boxes (work
// 1, memory 12,832: 6 tets, 8 vertices) in a 20 x 20 x 5 lattice of touching unit boxes
// far away; reach 0.5, so the lattice's neighbours are joined.
PartitionInput bodies_and_crowd() {
  PartitionInput in;
  in.reach = 0.5;
  for (int k = 0; k < 4; ++k)
    for (int j = 0; j < 4; ++j)
      for (int i = 0; i < 4; ++i) {
        in.box.push_back(unit_box(i, j, k));
        in.weight.push_back(500);
        in.memory.push_back(287000);
      }
  for (int k = 0; k < 5; ++k)
    for (int j = 0; j < 20; ++j)
      for (int i = 0; i < 20; ++i) {
        in.box.push_back(unit_box(100 + i, j, k));
        in.weight.push_back(1);
        in.memory.push_back(12832);
      }
  return in;
}

// The crowd's boxes with a lattice neighbour (within reach) on another part: those that
// some other part ghosts. By testing every pair.
double crowd_fraction_ghosted(const PartitionInput& in, const std::vector<int>& part) {
  std::vector<char> ghosted(in.box.size(), 0);
  for (std::size_t i = 64; i < in.box.size(); ++i)
    for (std::size_t j = i + 1; j < in.box.size(); ++j) {
      if (part[i] == part[j] || !in.box[i].within(in.box[j], in.reach)) continue;
      ghosted[i] = ghosted[j] = 1;
    }
  return static_cast<double>(std::count(ghosted.begin(), ghosted.end(), 1)) / static_cast<double>(in.box.size() - 64);
}

}  // namespace

// Memory as a second constraint (PartitionInput::memory). By work alone, METIS puts the
// crowd (work 2,000 of 34,000) on one or two parts, and that part holds most of the
// memory (reference: the memory imbalance of the work-only partition, above 1.5). With
// the memory given, each of 4 parts holds within kMemoryTolerance of the mean memory plus
// one body (0.03 of the mean), the work stays within max(the work-only partition's,
// 1.03) + 0.01 (the rule), and the crowd is cut into compact pieces: at most 35 % of its
// boxes have a neighbour on another part (two planes through a 20 x 20 x 5 lattice: 20 %;
// scattered by balance alone: nearly all).
TEST(PartitionMemory, ACrowdOfKinematicBoxesSpreadsWithoutCostingTheWorksBalance) {
  const PartitionInput in = bodies_and_crowd();
  PartitionInput work_only = in;
  work_only.memory.clear();
  const std::vector<int> by_work = partition_objects(work_only, 4);
  const PartitionQuality q0 = partition_quality(in, by_work, 4);
  EXPECT_GT(q0.memory_imbalance, 1.5) << "the work alone balances the memory: the test proves nothing";
  const std::vector<int> part = partition_objects(in, 4);
  const PartitionQuality q = partition_quality(in, part, 4);
  EXPECT_LE(q.memory_imbalance, kMemoryTolerance + 0.03);
  EXPECT_LE(q.imbalance, std::max(q0.imbalance, 1.03) + 0.01 + 1e-12);
  const double ghosted = crowd_fraction_ghosted(in, part);
  EXPECT_LE(ghosted, 0.35);
  EXPECT_EQ(partition_objects(in, 4), part) << "deterministic";
  std::printf("  by work: imbalance %.4f, memory %.4f; with memory: imbalance %.4f, memory %.4f, crowd ghosted %.3f\n",
              q0.imbalance, q0.memory_imbalance, q.imbalance, q.memory_imbalance, ghosted);
  // The same memory, all of it in one body: no partition can balance it, and the one by
  // work is kept (METIS, asked to, gives up the work's balance).
  PartitionInput giant = in;
  giant.memory[0] = 100 * std::accumulate(in.memory.begin(), in.memory.end(), std::int64_t{0});
  PartitionInput giant_work_only = giant;
  giant_work_only.memory.clear();
  EXPECT_EQ(partition_objects(giant, 4), partition_objects(giant_work_only, 4));
  // Malformed memory: a size that is not the objects', a negative entry.
  PartitionInput bad = in;
  bad.memory.pop_back();
  EXPECT_THROW(partition_objects(bad, 2), RuntimeFailure);
  bad = in;
  bad.memory[5] = -1;
  EXPECT_THROW(partition_objects(bad, 2), RuntimeFailure);
}

// group_objects with memory: the cut of each bisection minimises the larger of the two
// sums' distances from their shares, relative to their totals. Reference: every cut
// position of the sorted objects tried (one bisection, 2 parts of 1 each). 100 light
// objects with little memory along x, then 100 with work like theirs and 100 times the
// memory: the cut by work alone (after object 100) would give one side 1 % of the memory.
TEST(PartitionGroups, WithMemoryTheCutBalancesTheWorseOfTheTwo) {
  PartitionInput in;
  in.reach = 0.5;
  for (int i = 0; i < 200; ++i) {
    in.box.push_back(unit_box(2 * i, 0, 0));
    in.weight.push_back(10);
    in.memory.push_back(i < 100 ? 10 : 1000);
  }
  const PartGroups g = group_objects(in, 2, 1);
  ASSERT_EQ(g.first.size(), 2u);
  std::size_t lower = 0;
  while (lower < 200 && g.group[lower] == 0) ++lower;
  for (std::size_t i = lower; i < 200; ++i) ASSERT_EQ(g.group[i], 1) << "one cut along x";
  const double W = 2000, M = 101000;
  std::size_t best = 1;
  double best_off = 1e300;
  for (std::size_t c = 1; c < 200; ++c) {
    const double w = 10.0 * static_cast<double>(c);
    const double m = c <= 100 ? 10.0 * static_cast<double>(c) : 1000.0 + 1000.0 * static_cast<double>(c - 100);
    const double off = std::max(std::abs(w - W / 2) / W, std::abs(m - M / 2) / M);
    if (off < best_off) {
      best_off = off;
      best = c;
    }
  }
  EXPECT_EQ(lower, best);
  EXPECT_LT(best_off, 0.2);
  PartitionInput work_only = in;
  work_only.memory.clear();
  const PartGroups g0 = group_objects(work_only, 2, 1);
  EXPECT_EQ(std::count(g0.group.begin(), g0.group.end(), 0), 100) << "by work alone: the middle";
}

TEST(PartitionRepair, AFloorAndTwoCubesGetTheBestSplit) {
  // tests/data/scenes/small.yaml by its static weights: a kinematic floor (9) under two
  // touching cubes of 48 tets. The cubes share a face (edge weight 101), each meets the
  // floor only at the edge of reach (weight 1), so the smallest cut puts both cubes on
  // one part: 96 against 9, 1.829 times the mean. The best split, by brute force over the
  // 2^3 assignments, is a cube against a cube and the floor: 57 / 52.5 = 1.0857.
  PartitionInput in;
  in.reach = 0.2;
  in.box = {box(-2, -2, -0.1, 2, 2, 0), box(-0.5, -0.5, 0.2, 0.5, 0.5, 1.2), box(0.5, -0.5, 0.2, 1.5, 0.5, 1.2)};
  in.weight = {9, 48, 48};
  ASSERT_EQ(partition_quality(in, {0, 1, 1}, 2).cut_weight, 2) << "the floor's edges are the cheapest to cut";
  double best = 1e9;
  for (int mask = 0; mask < 8; ++mask)
    best = std::min(best, partition_quality(in, {mask & 1, (mask >> 1) & 1, (mask >> 2) & 1}, 2).imbalance);
  EXPECT_NEAR(best, 57.0 / 52.5, 1e-12);
  const std::vector<int> part = partition_objects(in, 2);
  EXPECT_NE(part[1], part[2]) << "the cubes on different parts";
  EXPECT_NEAR(partition_quality(in, part, 2).imbalance, best, 1e-12);
}

TEST(PartitionRepair, AboveTheTriggerNoSingleMoveLowersTheHeaviestPart) {
  // Few objects on few parts, sparse graphs of clusters (where METIS's smallest cut can
  // leave a part far above the mean): the partition is within kRepairTrigger of the mean,
  // or no object of a heaviest part can move to another part and leave both below that
  // part's load (checked here by trying every move). No giants (every weight below the
  // mean per part), so that every part is METIS's and the repair's.
  std::mt19937 rng(777);
  int checked = 0, above_trigger = 0;
  for (int trial = 0; trial < 1000; ++trial) {
    const int n = 4 + static_cast<int>(rng() % 9), nparts = 2 + static_cast<int>(rng() % 3);
    PartitionInput in;
    in.reach = 0.3;
    std::int64_t total = 0, heaviest = 0;
    for (int k = 0; k < n; ++k) {
      const double x = static_cast<double>(rng() % 4) * 1.1 + 0.02 * (rng() % 5), y = static_cast<double>(rng() % 2) * 1.1;
      in.box.push_back(unit_box(x, y, 0));
      in.weight.push_back(1 + static_cast<std::int64_t>(rng() % 3 == 0 ? rng() % 100 : rng() % 10));
      total += in.weight.back();
      heaviest = std::max(heaviest, in.weight.back());
    }
    if (heaviest * nparts >= total) continue;
    ++checked;
    const std::vector<int> part = partition_objects(in, nparts);
    std::vector<std::int64_t> load(static_cast<std::size_t>(nparts), 0);
    for (int k = 0; k < n; ++k) load[part[k]] += in.weight[k];
    const std::int64_t max_load = *std::max_element(load.begin(), load.end());
    const double imbalance = static_cast<double>(max_load) * nparts / static_cast<double>(total);
    EXPECT_NEAR(imbalance, partition_quality(in, part, nparts).imbalance, 1e-12);
    if (imbalance <= kRepairTrigger) continue;
    ++above_trigger;
    for (int k = 0; k < n; ++k) {
      if (load[part[k]] != max_load) continue;
      for (int to = 0; to < nparts; ++to)
        if (to != part[k])
          EXPECT_GE(std::max(max_load - in.weight[k], load[to] + in.weight[k]), max_load)
              << "trial " << trial << ": object " << k << " (weight " << in.weight[k] << ") could move from part "
              << part[k] << " to " << to << " (imbalance " << imbalance << ")";
    }
  }
  std::printf("  %d partitions checked, %d above the trigger\n", checked, above_trigger);
  EXPECT_GT(checked, 300);
}

// A split object's part as a host gets it (cut_split_parts, sent as part_indices and
// part_vertex_data, rebuilt by part_from_indices and set_part_vertex_data): each part's
// tets are exactly those of its value, ascending; its vertices are their corners, distinct
// and ascending, at their rest positions to the bit; every corner names the tet's own
// vertex; a vertex folds exactly when all its tets are in the part. Reference: brute
// force over the mesh. Parts asked for out of order, a part with no tets, and the
// rebuilt part equal to the cut one.
TEST(SplitTetParts, PartsCutForTheirHostsHoldTheirTetsAndVertices) {
  const TetMesh m = make_box(1, 1, 0.5, 6, 6, 3);
  const std::size_t nt = m.num_tets();
  std::vector<std::int32_t> rank_of = split_tet_parts(m, 3, kSplitMetisMaxTets);
  for (std::int32_t& r : rank_of) r = 2 * r;  // the parts' hosts: ranks 0, 2, 4 (rank 1 hosts nothing)
  const std::vector<std::int32_t> interior = split_interior_parts(m, rank_of);
  const std::vector<std::int32_t> asked{4, 1, 0, 2};
  const std::vector<SplitPartMesh> cuts = cut_split_parts(m, rank_of, interior, asked);
  ASSERT_EQ(cuts.size(), asked.size());
  std::size_t tets_seen = 0;
  for (std::size_t i = 0; i < asked.size(); ++i) {
    const std::int32_t q = asked[i];
    const SplitPartMesh& p = cuts[i];
    SCOPED_TRACE("part " + std::to_string(q));
    std::vector<std::int32_t> tets, verts;
    for (std::size_t t = 0; t < nt; ++t)
      if (rank_of[t] == q) {
        tets.push_back(static_cast<std::int32_t>(t));
        for (int c = 0; c < 4; ++c) verts.push_back(m.tets[4 * t + static_cast<std::size_t>(c)]);
      }
    std::sort(verts.begin(), verts.end());
    verts.erase(std::unique(verts.begin(), verts.end()), verts.end());
    EXPECT_EQ(p.tets, tets);
    EXPECT_EQ(p.verts, verts);
    tets_seen += p.tets.size();
    ASSERT_EQ(p.corners.size(), 4 * p.tets.size());
    ASSERT_EQ(p.points.size(), 3 * p.verts.size());
    ASSERT_EQ(p.fold.size(), p.verts.size());
    for (std::size_t e = 0; e < p.tets.size(); ++e)
      for (int c = 0; c < 4; ++c)
        EXPECT_EQ(p.verts[static_cast<std::size_t>(p.corners[4 * e + static_cast<std::size_t>(c)])],
                  m.tets[4 * static_cast<std::size_t>(p.tets[e]) + static_cast<std::size_t>(c)]);
    for (std::size_t j = 0; j < p.verts.size(); ++j) {
      const auto v = static_cast<std::size_t>(p.verts[j]);
      EXPECT_EQ(std::memcmp(&p.points[3 * j], &m.points[3 * v], 3 * sizeof(double)), 0) << "vertex " << v;
      bool all_here = true;
      for (std::size_t t = 0; t < nt; ++t)
        for (int c = 0; c < 4; ++c)
          if (static_cast<std::size_t>(m.tets[4 * t + static_cast<std::size_t>(c)]) == v) all_here = all_here && rank_of[t] == q;
      EXPECT_EQ(p.fold[j] != 0, all_here) << "vertex " << v;
    }
    if (q == 1) EXPECT_TRUE(p.tets.empty() && p.verts.empty());
    // As a host rebuilds it from the owner's two messages.
    SplitPartMesh got = part_from_indices(part_indices(p));
    EXPECT_EQ(got.tets, p.tets);
    set_part_vertex_data(got, part_vertex_data(p));
    EXPECT_EQ(got.verts, p.verts);
    EXPECT_EQ(got.corners, p.corners);
    EXPECT_EQ(got.fold, p.fold);
    ASSERT_EQ(got.points.size(), p.points.size());
    if (!p.points.empty())  // (memcmp of an empty part's null pointers is undefined)
      EXPECT_EQ(std::memcmp(got.points.data(), p.points.data(), p.points.size() * sizeof(double)), 0);
  }
  EXPECT_EQ(tets_seen, nt);
  EXPECT_GT(std::count(cuts[2].fold.begin(), cuts[2].fold.end(), 0), 0) << "no vertex on a cut: the test proves little";
  // What a host refuses: no count, too few indices, tets or vertices out of order, a
  // corner past the vertices.
  const SplitPartMesh& p = cuts[0];
  const std::size_t nt0 = p.tets.size();
  std::vector<std::int32_t> idx = part_indices(p);
  ASSERT_EQ(idx.size(), 1 + 5 * nt0 + p.verts.size());
  EXPECT_THROW(part_from_indices({}), RuntimeFailure);
  EXPECT_THROW(part_from_indices(std::vector<std::int32_t>(idx.begin(), idx.begin() + static_cast<std::ptrdiff_t>(5 * nt0))),
               RuntimeFailure);
  std::vector<std::int32_t> tets_swapped = idx;
  std::swap(tets_swapped[1], tets_swapped[2]);
  EXPECT_THROW(part_from_indices(tets_swapped), RuntimeFailure);
  std::vector<std::int32_t> verts_swapped = idx;
  std::swap(verts_swapped[1 + nt0], verts_swapped[2 + nt0]);
  EXPECT_THROW(part_from_indices(verts_swapped), RuntimeFailure);
  std::vector<std::int32_t> past = idx;
  past.back() = static_cast<std::int32_t>(p.verts.size());
  EXPECT_THROW(part_from_indices(past), RuntimeFailure);
  SplitPartMesh short_data = part_from_indices(idx);
  EXPECT_THROW(set_part_vertex_data(short_data, std::vector<double>(4 * p.verts.size() - 1, 0.0)), RuntimeFailure);
  EXPECT_THROW(cut_split_parts(m, rank_of, interior, {0, 0}), RuntimeFailure);
}
