// The tet-face adjacency and the mesh edges of the collision topology
// (build_collision_topology) against a search over every face and edge of the whole world
// at once.
#include <gtest/gtest.h>

#include <omp.h>

#include <algorithm>
#include <array>
#include <map>
#include <cmath>
#include <random>
#include <set>
#include <string>
#include <vector>

#include "collide/collision_topology.hpp"
#include "collide_test_util.hpp"

using namespace softcontact;
using namespace softcontact::collide;

namespace {

struct Expected {
  std::vector<index_t> neighbour;
  std::vector<std::uint8_t> mask;
  std::int64_t open = 0;
};

// Every tet face and surface triangle of the world in one map keyed by its sorted vertex
// triple (no object boundaries): two tet faces are neighbours; one tet face and a
// triangle, a boundary face with that triangle (the first in row order); anything else
// is open. Mask bits: the boundary faces (bit j) and the corners on the surface (16 << c).
Expected brute_force(const World& w) {
  const std::size_t m = w.tets.size() / 4, s = w.triangles.size() / 3;
  std::map<std::array<index_t, 3>, std::vector<std::pair<index_t, int>>> at;  // (tet, face) or (-(row + 1), -1)
  for (std::size_t e = 0; e < m; ++e)
    for (int j = 0; j < 4; ++j) {
      std::array<index_t, 3> k{};
      int n = 0;
      for (int q = 0; q < 4; ++q)
        if (q != j) k[n++] = w.tets[4 * e + q];
      std::sort(k.begin(), k.end());
      at[k].push_back({static_cast<index_t>(e), j});
    }
  std::vector<char> surface(w.n_local(), 0);
  for (std::size_t r = 0; r < s; ++r) {
    std::array<index_t, 3> k{w.triangles[3 * r], w.triangles[3 * r + 1], w.triangles[3 * r + 2]};
    for (index_t v : k) surface[static_cast<std::size_t>(v)] = 1;
    std::sort(k.begin(), k.end());
    at[k].push_back({-static_cast<index_t>(r) - 1, -1});
  }
  Expected x;
  x.neighbour.assign(4 * m, kOpenFace);
  x.mask.assign(m, 0);
  for (const auto& [key, list] : at) {
    std::vector<std::pair<index_t, int>> tets;
    index_t triangle = 0;
    int triangles = 0;
    for (const auto& f : list)
      if (f.second >= 0) tets.push_back(f);
      else if (triangles++ == 0) triangle = f.first;
    if (tets.size() == 2 && triangles == 0) {
      x.neighbour[4 * static_cast<std::size_t>(tets[0].first) + static_cast<std::size_t>(tets[0].second)] = tets[1].first;
      x.neighbour[4 * static_cast<std::size_t>(tets[1].first) + static_cast<std::size_t>(tets[1].second)] = tets[0].first;
      continue;
    }
    for (const auto& [e, j] : tets) {
      x.mask[static_cast<std::size_t>(e)] |= static_cast<std::uint8_t>(1u << j);
      if (tets.size() == 1 && triangles > 0) x.neighbour[4 * static_cast<std::size_t>(e) + static_cast<std::size_t>(j)] = triangle;
      else ++x.open;
    }
  }
  for (std::size_t e = 0; e < m; ++e)
    for (int c = 0; c < 4; ++c)
      if (surface[static_cast<std::size_t>(w.tets[4 * e + c])]) x.mask[e] |= static_cast<std::uint8_t>(16u << c);
  return x;
}

// Every distinct tet edge (a, b), a < b, in one ordered set; each vertex's neighbours
// ascending; the mean length added in ascending (a, b) order.
struct ExpectedEdges {
  std::vector<std::size_t> begin;
  std::vector<index_t> to;
  double mean = 0;
};
ExpectedEdges brute_force_edges(const World& w) {
  std::set<std::pair<index_t, index_t>> pairs;
  for (std::size_t e = 0; e < w.tets.size() / 4; ++e)
    for (int a = 0; a < 4; ++a)
      for (int b = a + 1; b < 4; ++b) {
        const index_t u = w.tets[4 * e + a], v = w.tets[4 * e + b];
        if (u != v) pairs.insert({std::min(u, v), std::max(u, v)});
      }
  std::vector<std::vector<index_t>> rows(w.n_local());
  double length = 0;
  for (const auto& [a, b] : pairs) {
    rows[static_cast<std::size_t>(a)].push_back(b);
    rows[static_cast<std::size_t>(b)].push_back(a);
    double l2 = 0;
    for (std::size_t d = 0; d < 3; ++d) {
      const double dx = w.x[3 * static_cast<std::size_t>(a) + d] - w.x[3 * static_cast<std::size_t>(b) + d];
      l2 += dx * dx;
    }
    length += std::sqrt(l2);
  }
  ExpectedEdges x;
  x.begin.push_back(0);
  for (std::vector<index_t>& r : rows) {
    std::sort(r.begin(), r.end());
    x.to.insert(x.to.end(), r.begin(), r.end());
    x.begin.push_back(x.to.size());
  }
  x.mean = pairs.empty() ? 0 : length / static_cast<double>(pairs.size());
  return x;
}

void expect_matches(const World& w, const char* what) {
  const Expected x = brute_force(w);
  const ExpectedEdges xe = brute_force_edges(w);
  for (int threads : {1, 2, 3}) {
    omp_set_num_threads(threads);
    const CollisionTopology t = build_collision_topology(w);
    EXPECT_EQ(t.face_neighbour, x.neighbour) << what << ", " << threads << " threads";
    EXPECT_EQ(t.boundary_mask, x.mask) << what << ", " << threads << " threads";
    EXPECT_EQ(t.open_faces, x.open) << what << ", " << threads << " threads";
    EXPECT_EQ(t.edge_begin, xe.begin) << what << ", " << threads << " threads";
    EXPECT_EQ(t.edge_to, xe.to) << what << ", " << threads << " threads";
    EXPECT_EQ(t.mean_edge_length, xe.mean) << what << ", " << threads << " threads (to the bit)";
  }
  omp_set_num_threads(1);
}

}  // namespace

// Twelve random tori, spheres and boxes on one rank; then rank 0 of 3 with the others'
// objects as ghosts (local indices no longer in object order); then with three surface
// triangles removed (three boundary faces left open) and one tet duplicated (each of its
// faces then open in every tet that has it). Every entry equal on 1, 2 and 3 threads, and
// the mean edge length to the bit.
TEST(CollisionTopology, FaceNeighboursMatchASearchOverTheWholeWorld) {
  std::mt19937_64 g(77);
  const std::string yaml = test::random_objects_yaml(g, 12);
  const Scene s = load_scene_from_string(std::string(test::kMaterials) + "objects:\n" + yaml, "test.yaml");
  const World one = build_world(s, block_partition(s, 1), 0);
  expect_matches(one, "one rank");
  EXPECT_EQ(build_collision_topology(one).open_faces, 0);

  World part = build_world(s, block_partition(s, 3), 0);
  std::vector<int> ghosts;
  for (int o = 0; o < static_cast<int>(s.objects.size()); ++o)
    if (std::find(part.owned_objects.begin(), part.owned_objects.end(), o) == part.owned_objects.end()) ghosts.push_back(o);
  ASSERT_FALSE(ghosts.empty());
  ASSERT_LT(part.owned_objects.size(), s.objects.size());
  set_ghost_objects(part, s, ghosts);
  ASSERT_GT(part.ghost_objects.size(), 0u);
  expect_matches(part, "rank 0 of 3 with ghosts");

  World broken = one;
  for (int k = 0; k < 3; ++k) broken.triangles.erase(broken.triangles.begin() + 3 * (10 + 40 * k), broken.triangles.begin() + 3 * (11 + 40 * k));
  broken.tets.insert(broken.tets.end(), broken.tets.begin() + 4 * 5, broken.tets.begin() + 4 * 6);
  const Expected x = brute_force(broken);
  // Three open boundary faces; each face of the doubled tet open in all its tets (3 if
  // interior, 2 with its triangle).
  EXPECT_GE(x.open, 3 + 4 * 2);
  expect_matches(broken, "triangles removed, a tet doubled");
}

namespace {

// Every piece of two topologies, to the bit.
void expect_same(const CollisionTopology& a, const CollisionTopology& b, const std::string& what) {
  ASSERT_EQ(a.objects.size(), b.objects.size()) << what;
  for (std::size_t k = 0; k < a.objects.size(); ++k) {
    EXPECT_EQ(a.objects[k].object, b.objects[k].object) << what;
    EXPECT_EQ(a.objects[k].vertices, b.objects[k].vertices) << what;
    EXPECT_EQ(a.objects[k].surface_vertices, b.objects[k].surface_vertices) << what;
    EXPECT_EQ(a.objects[k].tets, b.objects[k].tets) << what;
    EXPECT_EQ(a.objects[k].triangles, b.objects[k].triangles) << what;
    EXPECT_EQ(a.objects[k].thickness, b.objects[k].thickness) << what;
  }
  EXPECT_EQ(a.face_neighbour, b.face_neighbour) << what;
  EXPECT_EQ(a.boundary_mask, b.boundary_mask) << what;
  EXPECT_EQ(a.open_faces, b.open_faces) << what;
  EXPECT_EQ(a.edge_begin, b.edge_begin) << what;
  EXPECT_EQ(a.edge_to, b.edge_to) << what;
  EXPECT_EQ(a.mean_edge_length, b.mean_edge_length) << what;
  EXPECT_EQ(a.surface, b.surface) << what;
  EXPECT_EQ(a.tri_begin, b.tri_begin) << what;
  EXPECT_EQ(a.tri_of, b.tri_of) << what;
}

std::int64_t matched(const std::vector<std::int32_t>& from) {
  return std::count_if(from.begin(), from.end(), [](std::int32_t j) { return j >= 0; });
}

}  // namespace

// A detector rebuilt after a ghost-set change or a migration takes the faces and edges of
// the objects that stayed from the topology before (build_collision_topology's
// `previous`). Reference: the same World's topology built from nothing, and the search
// over the whole world (expect_matches). Cases on 12 random objects over 3 ranks: rank 0's
// ghost set changed (some ghosts kept at new local indices, some dropped, some new); rank
// 1's World after rank 0's (owned objects that were ghosts, ghosts that were owned);
// from a World whose objects were all held differently (a doubled tet, removed triangles:
// nothing may be taken); and the whole world from itself.
TEST(CollisionTopology, PiecesTakenFromAnEarlierWorldAreTheSameAsBuiltAgain) {
  std::mt19937_64 g(78);
  const std::string yaml = test::random_objects_yaml(g, 12);
  const Scene s = load_scene_from_string(std::string(test::kMaterials) + "objects:\n" + yaml, "test.yaml");
  const std::vector<int> ranks = block_partition(s, 3);
  auto others = [&](int rank, int keep_every, int phase) {
    std::vector<int> ghosts;
    for (int o = 0; o < static_cast<int>(s.objects.size()); ++o)
      if (ranks[static_cast<std::size_t>(o)] != rank && (o + phase) % keep_every != 0) ghosts.push_back(o);
    return ghosts;
  };
  World w0 = build_world(s, ranks, 0);
  set_ghost_objects(w0, s, others(0, 3, 0));  // objects 1, 2, 4, 5, ... of the other ranks
  ASSERT_GE(w0.ghost_objects.size(), 4u);
  const CollisionTopology before = build_collision_topology(w0);

  World w0b = w0;
  set_ghost_objects(w0b, s, others(0, 3, 1));  // drops some ghosts, adds others, keeps the rest
  for (int threads : {1, 2, 3}) {
    omp_set_num_threads(threads);
    const CollisionTopology taken = build_collision_topology(w0b, &before);
    const std::vector<std::int32_t> from = matching_slots(taken, before);
    // Owned objects and the kept ghosts are taken (some at new local indices), new ghosts not.
    EXPECT_GT(matched(from), static_cast<std::int64_t>(w0b.owned_objects.size()));
    EXPECT_LT(matched(from), static_cast<std::int64_t>(from.size()));
    expect_same(taken, build_collision_topology(w0b), "a changed ghost set, " + std::to_string(threads) + " threads");
  }
  omp_set_num_threads(1);
  expect_matches(w0b, "a changed ghost set");

  World w1 = build_world(s, ranks, 1);
  set_ghost_objects(w1, s, others(1, 1000, 1));  // every object of the other ranks
  {
    const CollisionTopology taken = build_collision_topology(w1, &before);
    EXPECT_GT(matched(matching_slots(taken, before)), 0);
    expect_same(taken, build_collision_topology(w1), "another rank's World");
  }

  const World one = build_world(s, block_partition(s, 1), 0);
  World broken = one;
  broken.triangles.erase(broken.triangles.begin() + 3 * 10, broken.triangles.begin() + 3 * 11);
  broken.tets.insert(broken.tets.end(), broken.tets.begin() + 4 * 5, broken.tets.begin() + 4 * 6);
  const CollisionTopology whole = build_collision_topology(one);
  {
    const CollisionTopology taken = build_collision_topology(broken, &whole);
    // Object 0 lost a triangle and holds a tet out of its range: not taken; the others are.
    const std::vector<std::int32_t> from = matching_slots(taken, whole);
    EXPECT_EQ(from[0], -1);
    EXPECT_EQ(matched(from), static_cast<std::int64_t>(from.size()) - 1);
    expect_same(taken, build_collision_topology(broken), "a World with a doubled tet");
    const CollisionTopology back = build_collision_topology(one, &taken);
    expect_same(back, whole, "the whole world from the broken one");
  }
  expect_same(build_collision_topology(one, &whole), whole, "the whole world from itself");
}
