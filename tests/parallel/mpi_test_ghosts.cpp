// The ghost set's selection (objects_within_reach): only the boxes near a rank travel to
// it, and the set must be the one the definition gives, every object's box (all of them
// assembled on every rank by object_boxes) against every box of the rank's own objects.
// On 1 to 4 ranks (ctest mpi.npN): 60 small boxes scattered by a pseudo-random offset per
// object, dealt to the ranks in slabs with rank 0 left without objects, at eleven reaches
// from none to the whole scene; then one owned vertex moved to infinity (its rank's hull is
// no longer finite, so every box must be sent to it).
#include <gtest/gtest.h>
#include <mpi.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <iostream>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "softcontact/ghosts.hpp"
#include "softcontact/mpi_util.hpp"
#include "softcontact/scene.hpp"
#include "softcontact/world.hpp"

using namespace softcontact;

namespace {

const Scene& scattered_boxes() {
  static const Scene s = load_scene_from_string(R"(
simulation: {dt: 1.0e-4, steps: 1}
materials:
  - {name: soft, model: corotational, young: 1.0e5, poisson: 0.3, density: 1000}
objects:
  - name: box
    material: soft
    primitive: {type: box, size: [0.1, 0.1, 0.1], cells: [1, 1, 1]}
    instances: {grid: {count: [5, 4, 3], spacing: [0.15, 0.15, 0.15]}}
)",
                                                "scattered_boxes.yaml");
  return s;
}

// The definition: every other rank's object with a box (not empty) within `skin` of one
// of this rank's own boxes, from every object's box.
std::vector<int> within_reach_of_every_box(const Scene& scene, const World& w, const std::vector<int>& part, double skin) {
  const std::vector<Box> box = object_boxes(MPI_COMM_WORLD, scene, w);
  std::vector<int> ghosts;
  for (std::size_t b = 0; b < box.size(); ++b) {
    if (part[b] == w.rank || box[b].empty()) continue;
    for (int a : w.owned_objects)
      if (box[static_cast<std::size_t>(a)].within(box[b], skin)) {
        ghosts.push_back(static_cast<int>(b));
        break;
      }
  }
  return ghosts;
}

}  // namespace

TEST(Ghosts, ObjectsWithinReachAreThoseOfEveryBoxAgainstEveryOwnBox) {
  const int n = comm_size(MPI_COMM_WORLD), rank = comm_rank(MPI_COMM_WORLD);
  const Scene& scene = scattered_boxes();
  const std::size_t objects = scene.objects.size();
  ASSERT_EQ(objects, 60u);
  // The same offsets on every rank (one seed).
  std::mt19937 rng(19);
  std::vector<int> part(objects);
  std::vector<double> offset(3 * objects);
  const std::vector<Box> initial = scene_boxes(scene);
  double x0 = initial[0].lo[0];
  for (const Box& b : initial) x0 = std::min(x0, b.lo[0]);
  for (std::size_t k = 0; k < objects; ++k) {
    // The five layers of copies along x to ranks 1.. in slabs (a rank's hull is then
    // its layers, and the nearest boxes of the next rank lie outside it).
    const auto layer = static_cast<std::size_t>(std::lround((initial[k].lo[0] - x0) / 0.15));
    part[k] = n == 1 ? 0 : 1 + static_cast<int>(layer * static_cast<std::size_t>(n - 1) / 5);
    // Across y and z only: the layers' facing sides stay flat (0.05 m apart), so a rank's
    // hull is as near to the next rank's boxes as its nearest box is.
    for (std::size_t d = 1; d < 3; ++d) offset[3 * k + d] = 0.02 * (static_cast<double>(rng() % 1001) / 1000.0 - 0.5);
  }
  World w = build_world(scene, part, rank);
  for (std::size_t i = 0; i < w.n_owned; ++i)
    for (std::size_t d = 0; d < 3; ++d) w.x[3 * i + d] += offset[3 * static_cast<std::size_t>(w.vertex_object[i]) + d];

  // From none (touching boxes only) through the gaps between neighbouring copies (0.05 m
  // across x, 0.03 to 0.07 m across y and z) to the whole scene.
  const std::vector<double> skins = {0.0, 0.005, 0.01, 0.02, 0.03, 0.045, 0.06, 0.08, 0.1, 0.15, 10.0};
  std::vector<std::int64_t> ghosted(skins.size()), wrong(skins.size());
  for (std::size_t j = 0; j < skins.size(); ++j) {
    const std::vector<int> got = objects_within_reach(MPI_COMM_WORLD, w, skins[j]);
    const std::vector<int> want = within_reach_of_every_box(scene, w, part, skins[j]);
    EXPECT_EQ(got, want) << "rank " << rank << ", skin " << skins[j];
    ghosted[j] = static_cast<std::int64_t>(got.size());
    wrong[j] = got == want ? 0 : 1;
  }
  // Only rank 0 prints (tests/test_main.cpp): the other ranks' differences, counted here.
  MPI_Allreduce(MPI_IN_PLACE, ghosted.data(), static_cast<int>(ghosted.size()), MPI_INT64_T, MPI_SUM, MPI_COMM_WORLD);
  MPI_Allreduce(MPI_IN_PLACE, wrong.data(), static_cast<int>(wrong.size()), MPI_INT64_T, MPI_SUM, MPI_COMM_WORLD);
  for (std::size_t j = 0; j < skins.size(); ++j) EXPECT_EQ(wrong[j], 0) << "ranks whose set differs at skin " << skins[j];
  if (n >= 3) {
    // Not all or nothing: at 0.06 m the copies facing across a slab boundary (0.05 m apart).
    EXPECT_EQ(ghosted[5], 0);
    EXPECT_GT(ghosted[6], 0);
    EXPECT_LT(ghosted[6], ghosted.back());
    // At 10 m every object of another rank is within reach of every rank with objects.
    EXPECT_EQ(ghosted.back(), static_cast<std::int64_t>(objects) * (n - 2));
  }
  if (rank == 0) {
    std::cout << "[measured] objects ghosted over all ranks, by reach:";
    for (std::size_t j = 0; j < skins.size(); ++j) std::cout << " " << skins[j] << " m: " << ghosted[j] << ";";
    std::cout << "\n";
  }

  // An owned vertex at infinity: that rank tests every other box (none is within reach
  // of a box that reaches infinity unless the test says so; the definition decides).
  if (rank == n - 1 && w.n_owned > 0) w.x[0] = std::numeric_limits<double>::infinity();
  for (const double skin : {0.02, 0.3}) {
    const std::vector<int> got = objects_within_reach(MPI_COMM_WORLD, w, skin);
    const std::vector<int> want = within_reach_of_every_box(scene, w, part, skin);
    EXPECT_EQ(got, want) << "rank " << rank << ", skin " << skin << ", a vertex at infinity";
    std::int64_t differ = got == want ? 0 : 1;
    MPI_Allreduce(MPI_IN_PLACE, &differ, 1, MPI_INT64_T, MPI_SUM, MPI_COMM_WORLD);
    EXPECT_EQ(differ, 0) << "ranks whose set differs at skin " << skin << ", a vertex at infinity";
  }
}
