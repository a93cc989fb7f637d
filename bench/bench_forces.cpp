// Force evaluation per deformation model (docs/benchmarks.md, "Deformation models:
// force evaluation"): ElasticForces::add_forces on a box of 24^3 cells (82,944 tets,
// 15,625 vertices), deformed a little (strains of about 1 %) and rotated by 40 degrees,
// so that every tet is strained and rotated and the corotational polar decomposition
// does real work. Reported: nanoseconds per tet (counter ns_per_tet) for the whole evaluation
// (per-tet kernel plus the per-vertex gather), and on 96 boxes of 864 tets with the same
// total (evaluated object by object, against the two phases over everything). And the
// box split for its forces with its one part on its owner (SplitForces::add, the path of a
// soft floor's owner: the part's kernels, its vertices' sums streamed, the owner's merge),
// against add_forces on the same box. Run with OMP_NUM_THREADS=1 for per-core figures.
#include <benchmark/benchmark.h>

#include <cmath>
#include <string>
#include <vector>

#include "softcontact/forces.hpp"
#include "softcontact/scene.hpp"
#include "softcontact/split_forces.hpp"
#include "softcontact/world.hpp"

using namespace softcontact;

namespace {

constexpr int kCells = 24;

/// One box of kCells^3 cells, or (`many`) the same number of cells as 96 boxes of
/// 6 x 6 x 4 cells (a pile of small objects, the case add_forces evaluates object by
/// object).
Scene box_scene(const char* model, double beta, bool many = false) {
  const std::string cells = std::to_string(kCells);
  const std::string object = many ? "primitive: {type: box, size: [0.25, 0.25, 0.17], cells: [6, 6, 4]}\n"
                                    "    instances: {grid: {count: [8, 12, 1], spacing: [0.3, 0.3, 0.3]}}\n"
                                  : "primitive: {type: box, size: [1, 1, 1], cells: [" + cells + ", " + cells + ", " +
                                        cells + "]}\n";
  const std::string yaml = std::string("simulation: {dt: 1e-4, steps: 1, gravity: [0, 0, 0]}\n"
                                       "materials:\n  - {name: m, model: ") +
                           model + ", young: 1e5, poisson: 0.3, density: 1000, damping: {stiffness: " +
                           std::to_string(beta) + "}}\nobjects:\n  - material: m\n    " + object;
  return load_scene_from_string(yaml, "bench.yaml");
}

// all: add_forces; kernel, gather: one of its two phases; two_phases: both, one after the
// other over every tet and then every vertex (what add_forces does for large objects).
enum class Phase { all, kernel, gather, two_phases };

/// A little deformation, as in a typical step of a simulation: a smooth strain of about
/// 1 % (stretch, shear and a wobble), then a rigid rotation by 40 degrees about a tilted
/// axis (so that the corotational rotations are far from the identity).
void deform(World& w) {
  const double ax[3] = {0.48, 0.6, 0.64};  // unit axis
  const double th = 40 * M_PI / 180, c = std::cos(th), s = std::sin(th);
  for (std::size_t i = 0; i < w.n_local(); ++i) {
    double* p = &w.x[3 * i];
    const double q[3] = {p[0] * (1 + 0.01 * p[2]) + 0.005 * p[1], p[1] + 0.003 * std::sin(7 * p[0]),
                         p[2] * 1.01 + 0.004 * std::sin(5 * p[1])};
    // Rodrigues: q c + (a x q) s + a (a . q)(1 - c)
    const double aq = ax[0] * q[0] + ax[1] * q[1] + ax[2] * q[2];
    const double cr[3] = {ax[1] * q[2] - ax[2] * q[1], ax[2] * q[0] - ax[0] * q[2], ax[0] * q[1] - ax[1] * q[0]};
    for (int d = 0; d < 3; ++d) p[d] = q[d] * c + cr[d] * s + ax[d] * aq * (1 - c);
    for (int d = 0; d < 3; ++d) w.v[3 * i + d] = 0.1 * std::sin(3 * p[d] + d);
  }
}

/// Evicts the caches (writes 64 MiB), as the rest of a simulation step does between two
/// force evaluations (detection, depth and response touch tens of MiB on the torus drop).
void evict_caches() {
  static std::vector<double> junk(8 << 20);
  for (std::size_t k = 0; k < junk.size(); k += 8) junk[k] += 1.0;
  benchmark::DoNotOptimize(junk.data());
  benchmark::ClobberMemory();
}

/// Times `evaluate(f)` per iteration (after evicting the caches with `cold`) and reports
/// nanoseconds per tet of w.
template <class Evaluate>
void time_evaluations(benchmark::State& state, const World& w, bool cold, std::vector<double>& f,
                      const Evaluate& evaluate) {
  for (auto _ : state) {
    if (cold) {
      state.PauseTiming();
      evict_caches();
      state.ResumeTiming();
    }
    evaluate(f);
    benchmark::DoNotOptimize(f.data());
    benchmark::ClobberMemory();
  }
  const double tets = static_cast<double>(w.tet_gid.size());
  state.counters["ns_per_tet"] =
      benchmark::Counter(tets, benchmark::Counter::kIsIterationInvariantRate | benchmark::Counter::kInvert);
  state.counters["tets"] = tets;
}

void forces(benchmark::State& state, const char* model, bool damping, Phase phase = Phase::all, bool many = false,
            bool cold = false) {
  const Scene scene = box_scene(model, damping ? 1e-3 : 0.0, many);
  World w = build_world(scene, block_partition(scene, 1), 0);
  ElasticForces ef(scene, w);
  deform(w);
  std::vector<double> f(3 * w.n_local(), 0.0);
  ef.compute_tet_forces(w, damping);
  time_evaluations(state, w, cold, f, [&](std::vector<double>& out) {
    if (phase == Phase::all) ef.add_forces(w, out, damping);
    if (phase == Phase::kernel || phase == Phase::two_phases) ef.compute_tet_forces(w, damping);
    if (phase == Phase::gather || phase == Phase::two_phases) ef.gather_forces(w, out, damping);
  });
}

/// The box as a split object whose one part is on its owner (rank 0 of one): everything
/// SplitForces::add does on a floor's owner but the exchanges, whose cost is the network's.
/// Its forces are bitwise add_forces' (the split floor's tests in
/// tests/sim/mpi_test_distributed.cpp); the difference in time is the split path's own:
/// the part's World, its stream of vertex sums and the merge.
void split_one_part(benchmark::State& state, const char* model, bool cold) {
  const Scene scene = box_scene(model, 0.0);
  World w = build_world(scene, block_partition(scene, 1), 0);
  SplitObject plan;
  plan.object = 0;
  plan.owner = 0;
  plan.tet_part.assign(w.tet_gid.size(), 0);
  SplitForces split(scene, w, {plan});
  deform(w);
  std::vector<double> f(3 * w.n_local(), 0.0);
  split.add(w, f, false, nullptr);
  time_evaluations(state, w, cold, f, [&](std::vector<double>& out) { split.add(w, out, false, nullptr); });
}

}  // namespace

BENCHMARK_CAPTURE(forces, linear, "linear", false)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(forces, corotational, "corotational", false)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(forces, stvk, "stvk", false)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(forces, neohookean, "neohookean", false)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(forces, mass_spring, "mass_spring", false)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(forces, corotational_damped, "corotational", true)->Unit(benchmark::kMillisecond);

BENCHMARK_CAPTURE(forces, corotational_kernel_only, "corotational", false, Phase::kernel)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(forces, gather_only, "corotational", false, Phase::gather)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(forces, neohookean_96_objects, "neohookean", false, Phase::all, true)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(forces, neohookean_96_objects_two_phases, "neohookean", false, Phase::two_phases, true)
    ->Unit(benchmark::kMillisecond);
// The same after the caches were evicted, as in a simulation step.
BENCHMARK_CAPTURE(forces, neohookean_96_objects_cold, "neohookean", false, Phase::all, true, true)
    ->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(forces, neohookean_96_objects_two_phases_cold, "neohookean", false, Phase::two_phases, true, true)
    ->Unit(benchmark::kMillisecond);

// One large object: add_forces against the split path on one rank, warm and cold.
BENCHMARK_CAPTURE(forces, neohookean_cold, "neohookean", false, Phase::all, false, true)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(split_one_part, neohookean, "neohookean", false)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(split_one_part, neohookean_cold, "neohookean", true)->Unit(benchmark::kMillisecond);

BENCHMARK_MAIN();
