// The whole-scene passes at the start of a run shared over the ranks (run.cpp): every
// object's mesh digest (the checkpoint fingerprint, Scene::object_digests) and the failure
// guard's scales (guard_scales), object k computed by part k % parts and the parts' vectors
// added as MPI_Allreduce would. Reference: the one-part pass over meshes all held here,
// and mesh_digest of each object's mesh; equal to the bit.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "sim/failure_guard.hpp"
#include "softcontact/checkpoint.hpp"
#include "softcontact/scene.hpp"

using namespace softcontact;

namespace {

using Sum = std::function<void(std::vector<double>&)>;

// A floor and a cube (single-copy), grid and random copies.
const std::string kScene = R"(simulation: {dt: auto, steps: 10}
materials:
  - {name: rubber, model: corotational, young: 1.0e5, poisson: 0.3, density: 1000}
  - {name: stiff, model: linear, young: 1.0e7, poisson: 0.25, density: 2500}
objects:
  - name: floor
    material: stiff
    primitive: {type: plate, size: [3, 3], thickness: 0.1, cells: [6, 6]}
    transform: {translate: [0, 0, -0.05]}
    kinematic: true
  - name: cube
    material: stiff
    primitive: {type: box, size: [0.3, 0.2, 0.25], cells: [2, 1, 2]}
    transform: {rotate: {axis: [0, 1, 1], angle: 23}, translate: [1.2, 1.2, 0.3]}
    velocity: [0, 0, -1.5]
  - name: box
    material: rubber
    primitive: {type: box, size: [0.2, 0.2, 0.2], cells: [2, 2, 2]}
    transform: {rotate: {axis: [1, 1, 0], angle: 17}, translate: [-1, -1, 0.3]}
    instances: {grid: {count: [3, 2, 1], spacing: [0.37, 0.41, 0]}}
  - name: ball
    material: rubber
    primitive: {type: sphere, radius: 0.1, resolution: 3}
    instances: {random: {count: 12, seed: 5, rotate: true, region: {min: [-1, -1, 0.6], max: [1, 1, 1.4]}}}
)";

// What `parts` ranks get from pass(part, parts, sum), with sum an MPI_Allreduce: each
// part's one call recorded first, then every part again with the recorded vectors added
// (in part order). `computed[p]`: the entries part p wrote (non-zero).
template <class T>
std::vector<T> over_parts(int parts, const std::function<T(int, int, const Sum&)>& pass,
                          std::vector<std::size_t>& computed) {
  std::vector<std::vector<double>> calls(static_cast<std::size_t>(parts));
  computed.assign(static_cast<std::size_t>(parts), 0);
  for (int p = 0; p < parts; ++p) {
    int n = 0;
    (void)pass(p, parts, [&](std::vector<double>& v) {
      ++n;
      calls[static_cast<std::size_t>(p)] = v;
      for (double x : v) computed[static_cast<std::size_t>(p)] += x != 0 ? 1 : 0;
    });
    EXPECT_EQ(n, 1) << "part " << p << ": one collective";
  }
  std::vector<T> results;
  for (int p = 0; p < parts; ++p)
    results.push_back(pass(p, parts, [&](std::vector<double>& v) {
      EXPECT_EQ(v, calls[static_cast<std::size_t>(p)]) << "part " << p << ": the same call twice";
      for (std::size_t k = 0; k < v.size(); ++k) {
        v[k] = 0;
        for (const auto& c : calls) v[k] += c[k];
      }
    }));
  return results;
}

}  // namespace

// Digests: each part digests its third (or half) of the objects; on every part the sum
// gives every object's digest, equal to mesh_digest of its mesh, also where this rank has
// dropped the mesh (a single-copy object's taken from its entry, a copy placed for it).
TEST(SharedPasses, ObjectDigestsOverPartsAreEachMeshsDigest) {
  const Scene held = load_scene_from_string(kScene, "scene.yaml");
  ASSERT_EQ(held.objects.size(), 2u + 6u + 12u);
  const std::vector<std::uint64_t> one = held.object_digests();
  ASSERT_EQ(one.size(), held.objects.size());
  for (std::size_t k = 0; k < one.size(); ++k) EXPECT_EQ(one[k], mesh_digest(held.objects[k].mesh)) << "object " << k;
  // Distinct meshes have distinct digests (every copy is placed elsewhere).
  for (std::size_t a = 0; a < one.size(); ++a)
    for (std::size_t b = a + 1; b < one.size(); ++b) EXPECT_NE(one[a], one[b]) << a << ", " << b;

  SceneLimits lean;
  lean.hold_copy_meshes = false;
  const Scene dropped = load_scene_from_string(kScene, "scene.yaml", lean);
  (void)dropped.drop_meshes(std::vector<char>(dropped.objects.size(), 0));
  ASSERT_TRUE(dropped.objects[0].mesh.points.empty()) << "the floor's mesh is dropped";
  ASSERT_TRUE(dropped.objects[1].mesh.points.empty()) << "the cube's mesh is dropped";
  EXPECT_EQ(dropped.object_digests(), one);
  for (int parts : {2, 3}) {
    std::vector<std::size_t> computed;
    const auto results = over_parts<std::vector<std::uint64_t>>(
        parts, [&](int p, int n, const Sum& sum) { return dropped.object_digests(p, n, sum); }, computed);
    for (int p = 0; p < parts; ++p) {
      EXPECT_EQ(results[static_cast<std::size_t>(p)], one) << "part " << p << " of " << parts;
      // Two halves per object, object k on part k % parts.
      const std::size_t mine = (one.size() - static_cast<std::size_t>(p) + static_cast<std::size_t>(parts) - 1) /
                               static_cast<std::size_t>(parts);
      EXPECT_LE(computed[static_cast<std::size_t>(p)], 2 * mine) << "part " << p << " of " << parts;
      EXPECT_GE(computed[static_cast<std::size_t>(p)], 2 * mine - 1) << "part " << p << " of " << parts;
    }
  }
  EXPECT_EQ(scene_fingerprint(dropped, dropped.object_digests(1, 2, nullptr)), scene_fingerprint(held))
      << "without a sum: one part, all objects";

  // A point moved by one ulp changes its object's digest and the fingerprint.
  Scene moved = held;
  moved.objects[7].mesh.points[4] = std::nextafter(moved.objects[7].mesh.points[4], 1e9);
  const std::vector<std::uint64_t> d = moved.object_digests();
  for (std::size_t k = 0; k < d.size(); ++k) EXPECT_EQ(d[k] != one[k], k == 7) << "object " << k;
  EXPECT_NE(scene_fingerprint(moved), scene_fingerprint(held));
}

// The guard's scales from parts equal the one-part pass to the bit: heights along gravity,
// the movable objects' volumes (summed in object order on every part) and tets.
TEST(SharedPasses, GuardScalesOverPartsAreOnePartsToTheBit) {
  const Scene held = load_scene_from_string(kScene, "scene.yaml");
  const GuardScales one = guard_scales(held);
  std::int64_t movable = 0;
  for (const SceneObject& o : held.objects) movable += o.kinematic() ? 0 : static_cast<std::int64_t>(o.mesh.num_tets());
  EXPECT_EQ(one.movable_tets, movable);
  EXPECT_GT(one.release, 0);
  EXPECT_GT(one.max_speed, 0);

  SceneLimits lean;
  lean.hold_copy_meshes = false;
  const Scene dropped = load_scene_from_string(kScene, "scene.yaml", lean);
  (void)dropped.drop_meshes(std::vector<char>(dropped.objects.size(), 0));
  for (int parts : {2, 3}) {
    std::vector<std::size_t> computed;
    const auto results = over_parts<GuardScales>(
        parts, [&](int p, int n, const Sum& sum) { return guard_scales(dropped, p, n, sum); }, computed);
    for (int p = 0; p < parts; ++p) {
      const GuardScales& g = results[static_cast<std::size_t>(p)];
      EXPECT_EQ(g.max_speed, one.max_speed) << "part " << p << " of " << parts;
      EXPECT_EQ(g.release, one.release) << "part " << p << " of " << parts;
      EXPECT_EQ(g.movable_tets, one.movable_tets) << "part " << p << " of " << parts;
      EXPECT_GT(computed[static_cast<std::size_t>(p)], 0u) << "part " << p << " of " << parts;
    }
  }
}
