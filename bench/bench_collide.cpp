// Collision detection and penetration depth on 200 tori (the paper's 200-tori scene has
// 80K tets and about 2,500 contacts; method.md, "What the paper reports"). Run on one
// core: OMP_NUM_THREADS=1 (tools/env.sh sets it).
//
// Every torus is make_torus(R = 0.1, a = 0.04, around = 13, tube = 2): 390 tets and 104
// vertices (52 on the surface), so 78,000 tets and 20,800 vertices in all. Two layouts:
//  - pile: centred on an 8 x 5 x 5 lattice 0.1625 m apart with uniformly random
//    orientations (fixed seed). Each torus's box overlaps those of its 26 neighbours and
//    its tube passes through theirs here and there: 2,564 colliding points. A dense
//    case: 85 % of the surface vertices are near another torus and nearly every tet
//    has foreign points near it.
//  - chains: 10 chains of 20 links (the paper's chained tori, without the membrane):
//    each link touches only its two neighbours, 1,154 colliding points, most tets far
//    from any contact.
//
// Reported: the whole detect() call as the time, its detection phase (broad and narrow)
// and penetration-depth phase as the counters detection_ms and depth_ms, and the counts.
// Each layout runs as the shipped default (vertex-in-tet between bodies), with edge
// contacts (CollisionSettings::edge_contacts: the edge search is part of depth_ms), with
// self-contact (self_collisions) and with both. The edge rows find their candidate pairs
// every call (edge_skin = 0: the cost of a step in which the skin is used up); the
// *_EdgesKept rows keep them (the default skin; the positions never move here, so after
// the warm-up call each call only tests the kept pairs: the cost of the other steps).
#include <benchmark/benchmark.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <random>
#include <vector>

#include "softcontact/collision.hpp"
#include "softcontact/primitives.hpp"
#include "softcontact/scene.hpp"
#include "softcontact/world.hpp"

using namespace softcontact;

namespace {

constexpr double kPi = 3.14159265358979323846;

// Uniform random rotation (Shoemake's quaternion method) from three uniforms in [0, 1).
std::array<double, 9> random_rotation(double u1, double u2, double u3) {
  const double a = std::sqrt(1 - u1), b = std::sqrt(u1);
  const double qw = a * std::sin(2 * kPi * u2), qx = a * std::cos(2 * kPi * u2);
  const double qy = b * std::sin(2 * kPi * u3), qz = b * std::cos(2 * kPi * u3);
  return {1 - 2 * (qy * qy + qz * qz), 2 * (qx * qy - qz * qw),     2 * (qx * qz + qy * qw),
          2 * (qx * qy + qz * qw),     1 - 2 * (qx * qx + qz * qz), 2 * (qy * qz - qx * qw),
          2 * (qx * qz - qy * qw),     2 * (qy * qz + qx * qw),     1 - 2 * (qx * qx + qy * qy)};
}

double unit(std::mt19937_64& g) { return static_cast<double>(g() >> 11) * 0x1.0p-53; }

Scene torus_scene() {
  Scene s;
  Material m;
  m.name = "m";
  m.young = 1e5;
  m.poisson = 0.3;
  m.density = 1000;
  s.materials.push_back(m);
  return s;
}

void place(Scene& s, const TetMesh& mesh, const std::array<double, 9>& r, const double* c) {
  SceneObject o;
  o.name = "torus";
  o.mesh = mesh;
  for (std::size_t v = 0; v < mesh.num_vertices(); ++v) {
    const double* p = &mesh.points[3 * v];
    for (int d = 0; d < 3; ++d)
      o.mesh.points[3 * v + d] = c[d] + r[3 * d] * p[0] + r[3 * d + 1] * p[1] + r[3 * d + 2] * p[2];
  }
  s.objects.push_back(std::move(o));
}

Scene torus_pile_scene(double spacing) {
  const TetMesh torus = make_torus(0.1, 0.04, 13, 2);
  Scene s = torus_scene();
  std::mt19937_64 g(20070601);
  for (int i = 0; i < 8; ++i)
    for (int j = 0; j < 5; ++j)
      for (int k = 0; k < 5; ++k) {
        const double u1 = unit(g), u2 = unit(g), u3 = unit(g);
        const double c[3] = {i * spacing, j * spacing, k * spacing};
        place(s, torus, random_rotation(u1, u2, u3), c);
      }
  return s;
}

World torus_pile(double spacing) {
  const Scene s = torus_pile_scene(spacing);
  return build_world(s, block_partition(s, 1), 0);
}

// 10 chains of 20 links along x, 0.4 m apart; links alternate between the xy and the xz
// plane, each tilted by a few degrees at random about x, and consecutive centres are
// `pitch` apart: 2 (R - a) = 0.12 would make the tubes touch, more pulls them into each
// other (every link overlaps its two neighbours).
World torus_chains(double pitch) {
  const TetMesh torus = make_torus(0.1, 0.04, 13, 2);
  Scene s = torus_scene();
  std::mt19937_64 g(20070601);
  for (int j = 0; j < 10; ++j)
    for (int i = 0; i < 20; ++i) {
      const double tilt = (unit(g) - 0.5) * 0.2 + (i % 2 ? kPi / 2 : 0);  // about x
      const double c = std::cos(tilt), sn = std::sin(tilt);
      const std::array<double, 9> r = {1, 0, 0, 0, c, -sn, 0, sn, c};
      const double centre[3] = {i * pitch, j * 0.4, 0};
      place(s, torus, r, centre);
    }
  return build_world(s, block_partition(s, 1), 0);
}

// Lattice spacing [m]: chosen once by scanning 0.120 .. 0.200 for the count nearest
// 2,500 colliding points (0.200 gives 890, 0.160 gives 2,745).
constexpr double kSpacing = 0.1625;
// Chain pitch [m]: the tubes of consecutive links overlap by 2a - |2R - pitch| = 0.03.
constexpr double kPitch = 0.15;

enum class Layout { pile, chains };

const World& scene(Layout s) {
  static const World pile = torus_pile(kSpacing);
  static const World chains = torus_chains(kPitch);
  return s == Layout::pile ? pile : chains;
}

// One detect() per iteration; its wall time is the iteration time, and the two phases
// (CollisionStats::detection_seconds, depth_seconds) of the same iterations are
// reported as counters, averaged over the iterations: the phase split comes from the
// same runs as the total (the machine is too noisy for separately timed benchmarks to
// add up).
void run(benchmark::State& state, Layout sc, bool edges = false, bool self = false, bool kept = false) {
  const World& w = scene(sc);
  CollisionSettings set;
  set.edge_contacts = edges;
  set.self_collisions = self;
  if (!kept) set.edge_skin = 0;
  CollisionDetector det(w, set);
  std::vector<Collision> c;
  CollisionStats st;
  det.detect(w, nullptr, c, st);  // warm: buffers grown
  double detection = 0, depth = 0;
  for (auto _ : state) {
    const auto t0 = std::chrono::steady_clock::now();
    det.detect(w, nullptr, c, st);
    state.SetIterationTime(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
    detection += st.detection_seconds;
    depth += st.depth_seconds;
    benchmark::DoNotOptimize(c.data());
  }
  state.counters["detection_ms"] = benchmark::Counter(1e3 * detection, benchmark::Counter::kAvgIterations);
  state.counters["depth_ms"] = benchmark::Counter(1e3 * depth, benchmark::Counter::kAvgIterations);
  state.counters["colliding_points"] = static_cast<double>(st.colliding_points);
  state.counters["collisions"] = static_cast<double>(st.collisions);
  state.counters["border_points"] = static_cast<double>(st.border_points);
  state.counters["deep_fallbacks"] = static_cast<double>(st.deep_fallbacks);
  state.counters["surface_searches"] = static_cast<double>(st.surface_searches);
  if (edges) {
    state.counters["edge_crossings"] = static_cast<double>(st.edge_crossings);
    state.counters["edge_contacts"] = static_cast<double>(st.edge_contacts);
    state.counters["edge_pairs"] = static_cast<double>(st.edge_pairs);
  }
  if (self) state.counters["self_collisions"] = static_cast<double>(st.self_collisions);
  state.counters["tets"] = static_cast<double>(w.tets.size() / 4);
  state.counters["vertices"] = static_cast<double>(w.n_local());
}

void BM_Collide_Pile(benchmark::State& s) { run(s, Layout::pile); }
void BM_Collide_Chains(benchmark::State& s) { run(s, Layout::chains); }
void BM_Collide_Pile_Edges(benchmark::State& s) { run(s, Layout::pile, true); }
void BM_Collide_Chains_Edges(benchmark::State& s) { run(s, Layout::chains, true); }
void BM_Collide_Pile_EdgesKept(benchmark::State& s) { run(s, Layout::pile, true, false, true); }
void BM_Collide_Chains_EdgesKept(benchmark::State& s) { run(s, Layout::chains, true, false, true); }
void BM_Collide_Pile_Self(benchmark::State& s) { run(s, Layout::pile, false, true); }
void BM_Collide_Chains_Self(benchmark::State& s) { run(s, Layout::chains, false, true); }
void BM_Collide_Chains_SelfEdges(benchmark::State& s) { run(s, Layout::chains, true, true); }

// Building the detector (its topology: tet-face neighbours, edges, surface hierarchies,
// self-contact culling) for the pile's 78,000 tets: what every ghost rebuild and the
// set-up pay per world (bench's "ghosts" stage).
void BM_Collide_Build(benchmark::State& state) {
  const World& w = scene(Layout::pile);
  CollisionSettings set;
  for (auto _ : state) {
    CollisionDetector det(w, set);
    benchmark::DoNotOptimize(&det);
  }
  state.counters["tets"] = static_cast<double>(w.tets.size() / 4);
}

// A detector built again after a ghost-set change (Simulator::follow_ghosts): rank 0 of
// 2 of the pile owns its first 100 tori and ghosts tori 100-179; then 100-109 leave the
// ghost set and 180-189 enter it (the 70 that stay move to new local indices). Timed: the
// new detector, from the rest positions, built from nothing (_Built) or taking the
// pieces of the 170 objects that stayed from the detector before (_Taken; that one built
// untimed in each iteration, since the new one consumes it).
struct GhostChange {
  World before, after;
  GhostChange() {
    const Scene s = torus_pile_scene(kSpacing);
    std::vector<int> two(s.objects.size(), 1);
    std::fill(two.begin(), two.begin() + 100, 0);
    before = build_world(s, two, 0);
    after = before;
    std::vector<int> g;
    for (int k = 100; k < 180; ++k) g.push_back(k);
    set_ghost_objects(before, s, g);
    for (int& k : g) k += 10;
    set_ghost_objects(after, s, g);
  }
};

void rebuild(benchmark::State& state, bool taken) {
  static const GhostChange c;
  CollisionSettings set;
  for (auto _ : state) {
    CollisionDetector old(c.before, set, c.before.x.data());
    const auto t0 = std::chrono::steady_clock::now();
    CollisionDetector det(c.after, set, c.after.x.data(), nullptr, taken ? &old : nullptr);
    state.SetIterationTime(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
    benchmark::DoNotOptimize(&det);
  }
  state.counters["tets"] = static_cast<double>(c.after.tets.size() / 4);
}
void BM_Collide_Rebuild_Built(benchmark::State& state) { rebuild(state, false); }
void BM_Collide_Rebuild_Taken(benchmark::State& state) { rebuild(state, true); }

}  // namespace

BENCHMARK(BM_Collide_Pile)->UseManualTime()->Unit(benchmark::kMillisecond);
BENCHMARK(BM_Collide_Chains)->UseManualTime()->Unit(benchmark::kMillisecond);
BENCHMARK(BM_Collide_Pile_Edges)->UseManualTime()->Unit(benchmark::kMillisecond);
BENCHMARK(BM_Collide_Chains_Edges)->UseManualTime()->Unit(benchmark::kMillisecond);
BENCHMARK(BM_Collide_Pile_EdgesKept)->UseManualTime()->Unit(benchmark::kMillisecond);
BENCHMARK(BM_Collide_Chains_EdgesKept)->UseManualTime()->Unit(benchmark::kMillisecond);
BENCHMARK(BM_Collide_Pile_Self)->UseManualTime()->Unit(benchmark::kMillisecond);
BENCHMARK(BM_Collide_Chains_Self)->UseManualTime()->Unit(benchmark::kMillisecond);
BENCHMARK(BM_Collide_Chains_SelfEdges)->UseManualTime()->Unit(benchmark::kMillisecond);
BENCHMARK(BM_Collide_Build)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_Collide_Rebuild_Built)->UseManualTime()->Unit(benchmark::kMillisecond);
BENCHMARK(BM_Collide_Rebuild_Taken)->UseManualTime()->Unit(benchmark::kMillisecond);

BENCHMARK_MAIN();
