// The object partition every rank computes at set-up and at each repartition
// (initial_partition: the node weights, split objects included, the object graph and
// METIS k-way) as a function of the number of objects. Every rank does this for the
// whole scene, so its cost per rank grows with the scene, not with the rank's share: it
// must stay near-linear in the objects (docs/scaling.md).
//
// The scene is synthetic: N objects of 300 tets on a cubic lattice of spacing 1.2 object
// sizes (each near its six neighbours), plus one floor under them holding as many tets
// as all of them together, so that on more than two ranks it is a split candidate.
// Objects carry only their shapes (counts and box), which is all the partition reads.
#include <benchmark/benchmark.h>

#include <cmath>
#include <random>

#include "softcontact/partition.hpp"
#include "softcontact/rebalance.hpp"
#include "softcontact/split_forces.hpp"

using namespace softcontact;

namespace {

Scene lattice(int n) {
  Scene s;
  s.materials.resize(1);
  const int side = static_cast<int>(std::ceil(std::cbrt(static_cast<double>(n))));
  s.objects.resize(static_cast<std::size_t>(n) + 1);
  ObjectShape floor;
  floor.tets = static_cast<std::size_t>(n) * 300;
  floor.vertices = floor.tets / 4;
  floor.triangles = floor.tets / 10;
  floor.box = Box{{-1.0, -1.0, -1.5}, {1.2 * side + 1, 1.2 * side + 1, -0.5}};
  s.objects[0].shape = floor;
  for (int k = 0; k < n; ++k) {
    const int ix = k % side, iy = (k / side) % side, iz = k / (side * side);
    ObjectShape o;
    o.vertices = 100;
    o.tets = 300;
    o.triangles = 200;
    o.box = Box{{1.2 * ix, 1.2 * iy, 1.2 * iz}, {1.2 * ix + 1, 1.2 * iy + 1, 1.2 * iz + 1}};
    s.objects[static_cast<std::size_t>(k) + 1].shape = o;
  }
  return s;
}

// state.range(0) objects into state.range(1) parts.
void BM_InitialPartition(benchmark::State& state) {
  const Scene scene = lattice(static_cast<int>(state.range(0)));
  const int parts = static_cast<int>(state.range(1));
  for (auto _ : state) {
    std::vector<int> p = initial_partition(scene, parts);
    benchmark::DoNotOptimize(p.data());
  }
  state.SetComplexityN(state.range(0));
}

// The lattice's objects as the partition's input: their boxes and tets, reach 1.
PartitionInput lattice_input(int n) {
  const Scene scene = lattice(n);
  PartitionInput in;
  for (const SceneObject& o : scene.objects) {
    in.box.push_back(o.shape->box);
    in.weight.push_back(static_cast<std::int64_t>(o.shape->tets));
  }
  in.reach = 1.0;
  return in;
}

// The object graph's edges alone (boxes_within plus the weights), on the lattice and on
// a dense pile: n boxes of 0.6 to 1.4 at random in a cube holding about 1.5 per unit of
// volume, reach 1 (each box near about 96 others; seed fixed).
void BM_ObjectGraphLattice(benchmark::State& state) {
  const PartitionInput in = lattice_input(static_cast<int>(state.range(0)));
  for (auto _ : state) benchmark::DoNotOptimize(object_graph_edges(in).data());
  state.SetComplexityN(state.range(0));
}

void BM_ObjectGraphPile(benchmark::State& state) {
  const int n = static_cast<int>(state.range(0));
  const double side = std::cbrt(n / 1.5);
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> pos(0.0, side), size(0.6, 1.4);
  PartitionInput in;
  in.reach = 1.0;
  for (int k = 0; k < n; ++k) {
    Box b;
    for (int d = 0; d < 3; ++d) {
      b.lo[d] = pos(rng);
      b.hi[d] = b.lo[d] + size(rng);
    }
    in.box.push_back(b);
    in.weight.push_back(1);
  }
  for (auto _ : state) benchmark::DoNotOptimize(object_graph_edges(in).data());
  state.SetComplexityN(state.range(0));
}

// The bisection into groups of 8 parts that every rank computes past 8 ranks
// (group_objects): the lattice's objects into state.range(1) parts.
void BM_GroupObjects(benchmark::State& state) {
  const PartitionInput in = lattice_input(static_cast<int>(state.range(0)));
  const int parts = static_cast<int>(state.range(1));
  for (auto _ : state) benchmark::DoNotOptimize(group_objects(in, parts).group.data());
  state.SetComplexityN(state.range(0));
}

// The split candidates alone (split_mask): one pass over the objects.
void BM_SplitMask(benchmark::State& state) {
  const Scene scene = lattice(static_cast<int>(state.range(0)));
  for (auto _ : state) {
    std::vector<char> m = split_mask(scene, 8);
    benchmark::DoNotOptimize(m.data());
  }
  state.SetComplexityN(state.range(0));
}

}  // namespace

BENCHMARK(BM_InitialPartition)
    ->Args({1000, 8})
    ->Args({4000, 8})
    ->Args({16000, 8})
    ->Args({64000, 8})
    ->Args({16000, 64})
    ->Unit(benchmark::kMillisecond);
BENCHMARK(BM_ObjectGraphLattice)->Arg(4000)->Arg(64000)->Arg(512000)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_ObjectGraphPile)->Arg(4000)->Arg(64000)->Arg(512000)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_GroupObjects)->Args({64000, 64})->Args({512000, 1024})->Unit(benchmark::kMillisecond);
BENCHMARK(BM_SplitMask)->Arg(1000)->Arg(16000)->Arg(256000)->Unit(benchmark::kMicrosecond);

BENCHMARK_MAIN();
