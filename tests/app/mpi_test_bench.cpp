// The scene benchmark on several ranks (src/app/bench.cpp): the per-phase spread over
// ranks. Runs under mpiexec with 1 to 4 ranks (ctest mpi.npN).
#include <gtest/gtest.h>
#include <mpi.h>

#include <sstream>
#include <string>

#include "softcontact/bench.hpp"
#include "softcontact/mpi_util.hpp"
#include "softcontact/scene.hpp"

using namespace softcontact;

// The MPI pile (objects of every rank in contact across the partition), 12 timed steps.
// Per phase, a rank's own seconds per step: the mean over ranks is at most their
// largest, and the largest at most the mean over steps of each step's max over ranks
// (a sum of maxima bounds the maximum of sums); on one rank all three are equal. The
// table names the line on more than one rank.
TEST(BenchRanks, PhaseSpreadOverRanksLiesBetweenTheMeanAndTheStepsMaxima) {
  const int n = comm_size(MPI_COMM_WORLD);
  const Scene scene = load_scene(std::string(SOFTCONTACT_TEST_DATA) + "/scenes/pile.yaml");
  BenchOptions opt;
  opt.steps = 12;
  opt.warmup = 2;
  opt.quiet = true;
  std::ostringstream log;
  const BenchResult r = run_bench(MPI_COMM_WORLD, scene, opt, log);
  ASSERT_EQ(r.ranks, n);
  bool any = false;
  for (auto member : {&PhaseTimes::forces, &PhaseTimes::integrate, &PhaseTimes::detect, &PhaseTimes::depth,
                      &PhaseTimes::contact, &PhaseTimes::comm, &PhaseTimes::output}) {
    double steps_max = 0;
    for (const BenchStep& s : r.steps) steps_max += s.seconds.*member;
    steps_max /= static_cast<double>(r.steps.size());
    const double most = r.phase_rank_max.*member, mean = r.phase_rank_mean.*member;
    EXPECT_GE(mean, 0.0);
    EXPECT_LE(mean, most * (1 + 1e-12));
    EXPECT_LE(most, steps_max * (1 + 1e-12));
    if (n == 1) {
      EXPECT_DOUBLE_EQ(most, steps_max);
      EXPECT_DOUBLE_EQ(mean, steps_max);
    }
    any = any || most > 0;
  }
  EXPECT_TRUE(any);
  // More ranks: each rank's own times, not the steps' maxima (ranks never time alike to
  // the last bit in every phase).
  if (n > 1) {
    bool below = false;
    for (auto member : {&PhaseTimes::forces, &PhaseTimes::detect, &PhaseTimes::depth, &PhaseTimes::contact})
      below = below || r.phase_rank_mean.*member < r.phase_rank_max.*member;
    EXPECT_TRUE(below) << "the mean over ranks equals their largest in every phase";
  }
  EXPECT_GT(r.phase_rank_max.forces, 0.0);
  EXPECT_GT(r.phase_rank_max.detect, 0.0);
  std::ostringstream table;
  print_bench_table(table, r);
  EXPECT_EQ(table.str().find("per phase, a rank's ms per step") != std::string::npos, n > 1) << table.str();
}
