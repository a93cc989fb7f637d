// Scenes that stress the distribution, run through run_scene as `softcontact run` does,
// against one rank (docs/reliability.md, "Rank and thread independence of the shipped
// scenes"). Runs under mpiexec with 1 to 4 ranks (ctest mpi.npN): rank 0 first runs the
// scene alone (MPI_COMM_SELF), then all ranks run it together; every frame must be bitwise
// equal, dataset by dataset (output_compare.hpp), and so must the physics columns of
// diagnostics.csv.
#include <gtest/gtest.h>
#include <mpi.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "output_compare.hpp"
#include "softcontact/mpi_util.hpp"
#include "softcontact/run.hpp"
#include "softcontact/scene.hpp"

using namespace softcontact;
namespace fs = std::filesystem;

namespace {

struct Runs {
  RunSummary all;                   // the run on every rank of MPI_COMM_WORLD
  std::vector<std::string> one_csv, all_csv;  // diagnostics rows, columns step..inverted_elements (rank 0)
  std::int64_t contacts = 0;        // colliding points summed over the rows of the one-rank run (rank 0)
};

// The rows of a diagnostics CSV cut to its first 12 columns (the timings differ), and the
// sum of its 'contacts' column.
std::vector<std::string> physics_rows(const fs::path& csv, std::int64_t* contacts) {
  std::ifstream in(csv);
  std::vector<std::string> rows;
  std::string line;
  int contacts_col = -1;
  while (std::getline(in, line)) {
    std::vector<std::string> cols;
    std::stringstream s(line);
    for (std::string c; std::getline(s, c, ',');) cols.push_back(c);
    if (rows.empty())
      for (std::size_t i = 0; i < cols.size(); ++i)
        if (cols[i] == "contacts") contacts_col = static_cast<int>(i);
    if (!rows.empty() && contacts && contacts_col >= 0) *contacts += std::stoll(cols[static_cast<std::size_t>(contacts_col)]);
    std::string kept;
    for (std::size_t i = 0; i < cols.size() && i < 12; ++i) kept += cols[i] + ',';
    rows.push_back(kept);
  }
  return rows;
}

// Runs `scene_file` on rank 0 alone, then on all ranks, and compares the outputs.
Runs run_and_compare(const std::string& scene_file, const std::string& tag) {
  const int rank = comm_rank(MPI_COMM_WORLD), n = comm_size(MPI_COMM_WORLD);
  const fs::path dir = test::scratch_dir(tag);
  RunOptions opt;
  opt.quiet = true;
  opt.overwrite = true;
  std::ostringstream log;
  Scene scene = load_scene(std::string(SOFTCONTACT_TEST_DATA) + "/scenes/" + scene_file);
  Runs r;
  if (rank == 0) {
    scene.sim.output_dir = (dir / "one").string();
    run_scene(MPI_COMM_SELF, scene, opt, log);
  }
  MPI_Barrier(MPI_COMM_WORLD);
  scene.sim.output_dir = (dir / "all").string();
  r.all = run_scene(MPI_COMM_WORLD, scene, opt, log);
  if (rank == 0) {
    EXPECT_GT(test::expect_same_output(dir / "one", dir / "all", "between 1 and " + std::to_string(n) + " ranks", 5), 10);
    r.one_csv = physics_rows(dir / "one" / kDiagnosticsCsv, &r.contacts);
    r.all_csv = physics_rows(dir / "all" / kDiagnosticsCsv, nullptr);
    EXPECT_EQ(r.one_csv, r.all_csv) << "diagnostics.csv differs between 1 and " << n << " ranks";
    EXPECT_GE(r.one_csv.size(), 6u);
    fs::remove_all(dir);
  }
  return r;
}

}  // namespace

// Two objects on up to 4 ranks: ranks beyond the second own nothing, yet take part in
// every collective (frames, diagnostics, ghost checks) and change nothing.
TEST(DistributedScenes, MoreRanksThanObjectsIsBitwiseIdenticalToOneRank) {
  const Runs r = run_and_compare("two_objects.yaml", "sc_two_objects");
  if (comm_rank(MPI_COMM_WORLD) == 0) {
    EXPECT_GT(r.contacts, 0) << "the two objects never touched: the test proves nothing";
    std::cout << "[measured] two_objects on " << comm_size(MPI_COMM_WORLD) << " ranks: " << r.contacts
              << " colliding points in the frames' rows, " << r.all.ghost_rebuilds << " ghost-set rebuilds\n";
  }
  // On 2 or more ranks the box and the ball start on different ranks, out of each
  // other's reach: they have to be ghosted on the way in.
  if (comm_size(MPI_COMM_WORLD) > 1) EXPECT_GT(r.all.ghost_rebuilds, 0);
}

// Two balls at 8 m/s along a row of boxes spread over the ranks: the ghost set follows
// them from rank to rank; they collide on different ranks, and objects migrate.
TEST(DistributedScenes, FastObjectsAcrossThePartitionAreBitwiseIdenticalToOneRank) {
  const Runs r = run_and_compare("crossing.yaml", "sc_crossing");
  if (comm_rank(MPI_COMM_WORLD) == 0) {
    EXPECT_GT(r.contacts, 0) << "no collision: the test proves nothing";
    std::cout << "[measured] crossing on " << comm_size(MPI_COMM_WORLD) << " ranks: " << r.contacts
              << " colliding points in the frames' rows, " << r.all.ghost_rebuilds << " ghost-set rebuilds, "
              << r.all.repartitions << " repartitions\n";
  }
  if (comm_size(MPI_COMM_WORLD) > 1) {
    EXPECT_GE(r.all.ghost_rebuilds, 2) << "the ghost set hardly changed";
    // The balls hit each other on different ranks: all collisions cross ranks at the
    // rebalance check of step 1200 (> 50%), which repartitions.
    EXPECT_GE(r.all.repartitions, 1);
  } else {
    EXPECT_EQ(r.all.ghost_rebuilds, 0);
  }
}
