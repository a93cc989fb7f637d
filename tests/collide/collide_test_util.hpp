#pragma once
// Helpers shared by the collision tests: scenes from YAML, moving objects, the
// brute-force reference (every surface vertex against every tet of every other object).
#include <array>
#include <random>
#include <cmath>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "collide/collision_topology.hpp"
#include "collide/point_in_tet.hpp"
#include "softcontact/collision.hpp"
#include "softcontact/scene.hpp"
#include "softcontact/world.hpp"
#include "../random_objects.hpp"

namespace softcontact::test {

inline const char* kMaterials = R"(
simulation: {dt: 0.001, steps: 1}
materials:
  - {name: m, young: 1e5, poisson: 0.3, density: 1000}
)";

/// A World (one rank) from the `objects:` part of a scene.
inline World world_from_objects(const std::string& objects) {
  const Scene s = load_scene_from_string(std::string(kMaterials) + "objects:\n" + objects, "test.yaml");
  return build_world(s, block_partition(s, 1), 0);
}

/// A random scene: `n` objects (tori, spheres, boxes) at random positions in a small
/// region so that many overlap, with random orientations, then every vertex jittered
/// (which also inverts and flattens some tets).
inline World random_scene(std::uint64_t seed, int n, double jitter) {
  std::mt19937_64 g(seed);
  const std::string yaml = random_objects_yaml(g, n);
  World w = world_from_objects(yaml);
  std::uniform_real_distribution<double> u(-jitter, jitter);
  for (double& c : w.x) c += u(g);
  return w;
}

inline void translate_object(World& w, int object, const std::array<double, 3>& t) {
  for (std::size_t v = 0; v < w.n_local(); ++v)
    if (w.vertex_object[v] == object)
      for (int d = 0; d < 3; ++d) w.x[3 * v + d] += t[d];
}

/// Objects 0 .. n-1 of a scene drifting through each other: step() moves each by `speed`
/// [m] in its own random direction and jitters every vertex by up to `jitter` [m].
struct Drift {
  std::mt19937_64 g;
  std::uniform_real_distribution<double> u{-1, 1};
  std::vector<std::array<double, 3>> v;
  double jitter;
  Drift(std::uint64_t seed, int n, double speed, double jitter_) : g(seed), jitter(jitter_) {
    for (int o = 0; o < n; ++o) {
      std::array<double, 3> d{u(g), u(g), u(g)};
      const double len = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
      for (double& c : d) c *= speed / len;
      v.push_back(d);
    }
  }
  void step(World& w) {
    for (std::size_t o = 0; o < v.size(); ++o) translate_object(w, static_cast<int>(o), v[o]);
    for (double& c : w.x) c += jitter * u(g);
  }
};

/// (point, other object) of every surface vertex strictly inside a tet of another object.
inline std::set<std::pair<index_t, std::int32_t>> brute_force_pairs(const World& w) {
  const collide::CollisionTopology topo = collide::build_collision_topology(w);
  std::set<std::pair<index_t, std::int32_t>> out;
  const std::size_t m = w.tets.size() / 4;
  for (std::size_t v = 0; v < w.n_local(); ++v) {
    if (!topo.surface[v]) continue;
    const collide::V3 p = collide::load(w.x.data(), static_cast<index_t>(v));
    if (!collide::finite(p)) continue;
    for (std::size_t e = 0; e < m; ++e) {
      if (w.tet_object[e] == w.vertex_object[v]) continue;
      if (collide::point_in_tet(w.x.data(), &w.tets[4 * e], topo.boundary_mask[e], p) == collide::TetSide::inside)
        out.insert({static_cast<index_t>(v), w.tet_object[e]});
    }
  }
  return out;
}

inline std::set<std::pair<index_t, std::int32_t>> record_pairs(const std::vector<Collision>& c) {
  std::set<std::pair<index_t, std::int32_t>> out;
  for (const Collision& r : c)
    if (r.point2 < 0) out.insert({r.point, r.other_object});  // vertex records (edge contacts: test_edge_contacts.cpp)
  return out;
}

inline bool all_finite(const std::vector<Collision>& c) {
  for (const Collision& r : c)
    for (int d = 0; d < 3; ++d)
      if (!std::isfinite(r.depth[d]) || !std::isfinite(r.weight[d])) return false;
  return true;
}

/// Sum_j omega_j x~_j over T_i.
inline std::array<double, 3> weighted_point(const World& w, const Collision& c) {
  std::array<double, 3> q{0, 0, 0};
  for (int j = 0; j < 3; ++j)
    for (int d = 0; d < 3; ++d) q[d] += c.weight[j] * w.x[3 * static_cast<std::size_t>(c.triangle[j]) + d];
  return q;
}

}  // namespace softcontact::test
