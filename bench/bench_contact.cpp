// The contact response alone (eqs 5, 6, 15, 16 + friction + position correction) as a
// function of the number of collisions: the paper's Fig. 6 says the cost is linear.
// Collision records are synthetic: points and triangles drawn from a 50K-vertex world
// (the size of the paper's chess scene), sorted by point as the detector delivers them.
#include <benchmark/benchmark.h>

#include <algorithm>
#include <random>

#include "softcontact/contact.hpp"

using namespace softcontact;

namespace {

struct Fixture {
  World world;
  Scene scene;
  std::vector<Collision> collisions;
};

Fixture make_fixture(int n_collisions) {
  constexpr int kVertices = 50400;
  std::mt19937_64 g(42);
  auto u = [&] { return static_cast<double>(g() >> 11) * 0x1.0p-53; };
  Fixture f;
  World& w = f.world;
  w.n_owned = kVertices;
  w.layout.resize(2);
  for (int i = 0; i < kVertices; ++i) {
    w.vertex_gid.push_back(i);
    w.vertex_object.push_back(i % 2);
    w.mass.push_back(0.01 + 0.01 * u());
    w.inv_mass.push_back(i % 97 == 0 ? 0.0 : 1.0 / w.mass.back());
  }
  w.x.resize(3 * kVertices);
  for (double& x : w.x) x = u();
  w.x_prev = w.x;
  w.v.assign(3 * kVertices, 0.0);
  f.scene.materials.resize(1);
  f.scene.friction.assign(1, std::vector<Friction>(1, Friction{0.5, 0.4}));
  f.scene.objects.resize(2);
  index_t patch_point = 0, patch_tri = 0;
  // Contact patches as detection finds them: runs of 16 neighbouring points (object
  // vertex ids are contiguous) pressing into neighbouring triangles of another object.
  for (int q = 0; q < n_collisions; ++q) {
    if (q % 16 == 0) {
      patch_point = static_cast<index_t>(g() % (kVertices - 64));
      patch_tri = static_cast<index_t>(g() % (kVertices - 64));
    }
    Collision c;
    c.point = patch_point + 2 * (q % 16);
    const index_t t0 = patch_tri + 2 * (q % 16);
    c.triangle = {t0, t0 + 1, t0 + 3};
    const double a = u(), b = u(), cc = u(), s = a + b + cc;
    c.weight = {a / s, b / s, cc / s};
    c.depth = {1e-4 * (u() - 0.5), 1e-4 * (u() - 0.5), 1e-4 * u()};
    c.point_gid = c.point;
    c.object = 0;
    c.other_object = 1;
    f.collisions.push_back(c);
  }
  std::sort(f.collisions.begin(), f.collisions.end(),
            [](const Collision& a, const Collision& b) { return a.point < b.point; });
  return f;
}

void BM_ContactResponse(benchmark::State& state) {
  Fixture f = make_fixture(static_cast<int>(state.range(0)));
  ContactResponse solver(f.scene, f.world);
  ContactStats stats;
  // Positions drift by the (tiny) corrections from one iteration to the next; the work
  // per call does not depend on them.
  for (auto _ : state) {
    solver.respond(f.world, f.collisions, 1e-3, stats);
    benchmark::DoNotOptimize(f.world.x.data());
  }
  state.counters["collisions"] = static_cast<double>(f.collisions.size());
  state.counters["ns_per_collision"] =
      benchmark::Counter(static_cast<double>(f.collisions.size()), benchmark::Counter::kIsIterationInvariantRate |
                                                                       benchmark::Counter::kInvert);
}

}  // namespace

BENCHMARK(BM_ContactResponse)->Arg(250)->Arg(500)->Arg(1000)->Arg(2500)->Arg(5000)->Arg(10000)->Arg(20000)
    ->Unit(benchmark::kMicrosecond);

BENCHMARK_MAIN();
