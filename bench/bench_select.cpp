// kth_smallest (mpi_util.hpp): the exact selection over ranks that gives the median edge
// and the in-run check's percentiles, here on one process (MPI_COMM_SELF), so that its
// local work and its number of rounds show without the network: the radix selection (8
// rounds of 256 counts) against the bit bisection it replaced (64 rounds of one count,
// each scanning every value), kept here only for the ratio.
#include <benchmark/benchmark.h>
#include <mpi.h>

#include <cstdint>
#include <cstring>
#include <limits>
#include <random>
#include <vector>

#include "softcontact/mpi_util.hpp"

namespace {

std::vector<double> lengths(std::size_t n) {
  std::mt19937_64 gen(7);
  std::lognormal_distribution<double> len(-4.0, 0.3);  // edge lengths around 2 cm
  std::vector<double> v(n);
  for (double& x : v) x = len(gen);
  return v;
}

// The replaced algorithm: bisection on the bit pattern, one MPI_Allreduce of one count a round.
double bisection(MPI_Comm comm, const std::vector<double>& values, std::int64_t k) {
  std::vector<std::uint64_t> bits(values.size());
  for (std::size_t i = 0; i < values.size(); ++i) std::memcpy(&bits[i], &values[i], sizeof(double));
  std::uint64_t lo = 0, hi = std::numeric_limits<std::uint64_t>::max();
  while (lo < hi) {
    const std::uint64_t mid = lo + (hi - lo) / 2;
    std::int64_t below = 0;
    for (std::uint64_t b : bits) below += b <= mid ? 1 : 0;
    MPI_Allreduce(MPI_IN_PLACE, &below, 1, MPI_INT64_T, MPI_SUM, comm);
    if (below > k) hi = mid;
    else lo = mid + 1;
  }
  double x = 0;
  std::memcpy(&x, &lo, sizeof x);
  return x;
}

void BM_KthSmallestRadix(benchmark::State& state) {
  const std::vector<double> v = lengths(static_cast<std::size_t>(state.range(0)));
  for (auto _ : state) benchmark::DoNotOptimize(softcontact::kth_smallest(MPI_COMM_SELF, v, state.range(0) / 2));
  state.SetItemsProcessed(state.iterations() * state.range(0));
}
BENCHMARK(BM_KthSmallestRadix)->Arg(10000)->Arg(100000)->Arg(1000000)->Unit(benchmark::kMicrosecond);

void BM_KthSmallestBisection(benchmark::State& state) {
  const std::vector<double> v = lengths(static_cast<std::size_t>(state.range(0)));
  const double radix = softcontact::kth_smallest(MPI_COMM_SELF, v, state.range(0) / 2);
  if (bisection(MPI_COMM_SELF, v, state.range(0) / 2) != radix) state.SkipWithError("the two selections differ");
  for (auto _ : state) benchmark::DoNotOptimize(bisection(MPI_COMM_SELF, v, state.range(0) / 2));
  state.SetItemsProcessed(state.iterations() * state.range(0));
}
BENCHMARK(BM_KthSmallestBisection)->Arg(10000)->Arg(100000)->Arg(1000000)->Unit(benchmark::kMicrosecond);

}  // namespace

int main(int argc, char** argv) {
  MPI_Init(&argc, &argv);
  benchmark::Initialize(&argc, argv);
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  MPI_Finalize();
  return 0;
}
