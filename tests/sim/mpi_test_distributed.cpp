// The distributed step against one rank (issue: rank- and thread-independent results).
// Runs under mpiexec with 1 to 4 ranks (ctest mpi.npN). In each test rank 0 first runs
// the scene alone (MPI_COMM_SELF, one thread): the reference. Then all ranks run it
// together, objects partitioned with METIS, and rank 0 compares positions and contact
// forces gathered by global vertex id: they must be bitwise equal, not close.
#include <gtest/gtest.h>
#include <hdf5.h>
#include <mpi.h>
#include <omp.h>

#include <cstring>
#include <filesystem>
#include <sstream>

#include <unistd.h>

#include "softcontact/run.hpp"
#include "softcontact/mpi_util.hpp"
#include "softcontact/scene.hpp"
#include "softcontact/simulator.hpp"

using namespace softcontact;

namespace {

const Scene& pile() {
  static const Scene s = load_scene(std::string(SOFTCONTACT_TEST_DATA) + "/scenes/pile.yaml");
  return s;
}

constexpr int kSteps = 120, kEvery = 10;

// Positions and contact forces of every vertex in global order (on rank 0; empty
// elsewhere), gathered from the owners.
struct Snapshot {
  std::vector<double> x, f;
};

Snapshot gather(MPI_Comm comm, Simulator& sim) {
  const World& w = sim.world();
  const std::vector<double>& force = sim.contact_force();
  std::vector<double> rows;  // gid, x, f per owned vertex
  for (std::size_t i = 0; i < w.n_owned; ++i) {
    rows.push_back(static_cast<double>(w.vertex_gid[i]));
    for (int d = 0; d < 3; ++d) rows.push_back(w.x[3 * i + static_cast<std::size_t>(d)]);
    for (int d = 0; d < 3; ++d) rows.push_back(force[3 * i + static_cast<std::size_t>(d)]);
  }
  const int n = comm_size(comm);
  int mine = static_cast<int>(rows.size());
  std::vector<int> counts(static_cast<std::size_t>(n)), disp(static_cast<std::size_t>(n));
  MPI_Gather(&mine, 1, MPI_INT, counts.data(), 1, MPI_INT, 0, comm);
  int total = 0;
  for (int r = 0; r < n; ++r) {
    disp[static_cast<std::size_t>(r)] = total;
    total += counts[static_cast<std::size_t>(r)];
  }
  std::vector<double> all(static_cast<std::size_t>(total));
  MPI_Gatherv(rows.data(), mine, MPI_DOUBLE, all.data(), counts.data(), disp.data(), MPI_DOUBLE, 0, comm);
  Snapshot s;
  if (comm_rank(comm) != 0) return s;
  const auto nv = static_cast<std::size_t>(w.global_vertices);
  s.x.assign(3 * nv, 0.0);
  s.f.assign(3 * nv, 0.0);
  for (std::size_t k = 0; k < all.size(); k += 7) {
    const auto g = static_cast<std::size_t>(all[k]);
    for (std::size_t d = 0; d < 3; ++d) {
      s.x[3 * g + d] = all[k + 1 + d];
      s.f[3 * g + d] = all[k + 4 + d];
    }
  }
  return s;
}

// The reference: rank 0 alone, one thread, a snapshot every kEvery steps.
const std::vector<Snapshot>& reference() {
  static std::vector<Snapshot> ref;
  static bool done = false;
  if (!done) {
    if (comm_rank(MPI_COMM_WORLD) == 0) {
      omp_set_num_threads(1);
      Simulator sim(MPI_COMM_SELF, pile());
      for (int s = 1; s <= kSteps; ++s) {
        sim.step();
        if (s % kEvery == 0) ref.push_back(gather(MPI_COMM_SELF, sim));
      }
    }
    done = true;
  }
  return ref;
}

// Runs the pile on every rank with `threads` threads and compares each snapshot with the
// reference; `between(sim, step)` may act on the simulator after each step.
template <class F>
void expect_identical(int threads, F&& between, std::int64_t* cross_out = nullptr) {
  const std::vector<Snapshot>& ref = reference();
  MPI_Barrier(MPI_COMM_WORLD);
  omp_set_num_threads(threads);
  Simulator sim(MPI_COMM_WORLD, pile());
  std::int64_t cross = 0;
  std::size_t k = 0;
  for (int s = 1; s <= kSteps; ++s) {
    sim.step();
    cross += sim.cross_rank_collisions();
    between(sim, s);
    if (s % kEvery != 0) continue;
    const Snapshot got = gather(MPI_COMM_WORLD, sim);
    if (comm_rank(MPI_COMM_WORLD) == 0) {
      ASSERT_EQ(got.x.size(), ref[k].x.size());
      // memcmp: bitwise, so that -0.0 against 0.0 or a NaN would count as a difference.
      EXPECT_EQ(std::memcmp(got.x.data(), ref[k].x.data(), got.x.size() * sizeof(double)), 0)
          << "positions differ from one rank at step " << s << " (" << comm_size(MPI_COMM_WORLD) << " ranks, " << threads
          << " threads)";
      EXPECT_EQ(std::memcmp(got.f.data(), ref[k].f.data(), got.f.size() * sizeof(double)), 0)
          << "contact forces differ from one rank at step " << s;
    }
    ++k;
  }
  omp_set_num_threads(1);
  MPI_Allreduce(MPI_IN_PLACE, &cross, 1, MPI_INT64_T, MPI_SUM, MPI_COMM_WORLD);
  if (cross_out) *cross_out = cross;
}

}  // namespace

TEST(Distributed, PileIsBitwiseIdenticalToOneRankOneThread) {
  std::int64_t cross = 0;
  expect_identical(1, [](Simulator&, int) {}, &cross);
  // The test means something only if contacts cross ranks: balls between boxes of
  // different ranks.
  if (comm_size(MPI_COMM_WORLD) > 1) EXPECT_GT(cross, 0) << "no collision crossed ranks: the test proves nothing";
  if (comm_rank(MPI_COMM_WORLD) == 0) std::cout << "[measured] cross-rank collision records over the run: " << cross << "\n";
}

TEST(Distributed, PileWithTwoThreadsPerRankIsBitwiseIdentical) {
  expect_identical(2, [](Simulator&, int) {});
}

TEST(Distributed, MigrationDuringTheRunDoesNotChangeResults) {
  const int n = comm_size(MPI_COMM_WORLD);
  std::int64_t migrations = 0;
  expect_identical(1, [&](Simulator& sim, int s) {
    if (s != 35 && s != 75) return;
    // Every object to the next rank (all objects move), then back to METIS's choice.
    std::vector<int> next = sim.partition();
    for (int& r : next) r = (r + 1) % n;
    sim.migrate(s == 35 ? next : initial_partition(sim.scene(), extract_surfaces(sim.scene()), n));
    ++migrations;
  });
  EXPECT_EQ(migrations, 2);
}

TEST(Distributed, RebalancePolicyRepartitionsWithoutChangingResults) {
  std::int64_t repartitions = 0;
  expect_identical(1, [&](Simulator& sim, int s) {
    if (s == 1) sim.set_rebalance_policy(RebalancePolicy{25, 0.0, 0.0});  // any imbalance triggers
    repartitions = sim.repartitions();
  });
  if (comm_size(MPI_COMM_WORLD) > 1) EXPECT_GE(repartitions, 4);
}

namespace {

// Every dataset of a file, by path.
herr_t collect(hid_t, const char* name, const H5O_info_t* info, void* data) {
  if (info->type == H5O_TYPE_DATASET) static_cast<std::vector<std::string>*>(data)->push_back(name);
  return 0;
}

std::vector<char> raw(hid_t file, const std::string& path, std::string& type_desc) {
  const hid_t d = H5Dopen2(file, path.c_str(), H5P_DEFAULT);
  if (d < 0) return {};
  const hid_t ft = H5Dget_type(d);
  const hid_t t = H5Tget_native_type(ft, H5T_DIR_ASCEND);
  const hid_t s = H5Dget_space(d);
  const auto n = static_cast<std::size_t>(H5Sget_simple_extent_npoints(s));
  std::vector<char> buf(n * H5Tget_size(t));
  H5Dread(d, t, H5S_ALL, H5S_ALL, H5P_DEFAULT, buf.data());
  hsize_t dims[4] = {0, 0, 0, 0};
  const int nd = H5Sget_simple_extent_dims(s, dims, nullptr);
  std::ostringstream o;
  o << H5Tget_class(ft) << ':' << H5Tget_size(ft) << ':';
  for (int i = 0; i < nd; ++i) o << dims[i] << ',';
  type_desc = o.str();
  H5Sclose(s);
  H5Tclose(t);
  H5Tclose(ft);
  H5Dclose(d);
  return buf;
}

}  // namespace

TEST(Distributed, Hdf5WrittenByAllRanksEqualsOneRankDatasetByDataset) {
  const int rank = comm_rank(MPI_COMM_WORLD), n = comm_size(MPI_COMM_WORLD);
  long tag = rank == 0 ? static_cast<long>(getpid()) : 0;
  MPI_Bcast(&tag, 1, MPI_LONG, 0, MPI_COMM_WORLD);
  const std::filesystem::path dir = std::filesystem::temp_directory_path() / ("sc_dist_" + std::to_string(tag));
  RunOptions opt;
  opt.quiet = true;
  opt.overwrite = true;
  std::ostringstream log;
  Scene scene = pile();
  if (rank == 0) {
    scene.sim.output_dir = (dir / "one").string();
    run_scene(MPI_COMM_SELF, scene, opt, log);
  }
  scene.sim.output_dir = (dir / "all").string();
  run_scene(MPI_COMM_WORLD, scene, opt, log);
  if (rank == 0) {
    const hid_t a = H5Fopen((dir / "one" / "frames.h5").c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
    const hid_t b = H5Fopen((dir / "all" / "frames.h5").c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
    ASSERT_GE(a, 0);
    ASSERT_GE(b, 0);
    std::vector<std::string> pa, pb;
    H5Ovisit2(a, H5_INDEX_NAME, H5_ITER_INC, collect, &pa, H5O_INFO_BASIC);
    H5Ovisit2(b, H5_INDEX_NAME, H5_ITER_INC, collect, &pb, H5O_INFO_BASIC);
    EXPECT_EQ(pa, pb) << "the two files hold different groups and datasets";
    int datasets = 0;
    for (const std::string& p : pa) {
      std::string ta, tb;
      const std::vector<char> da = raw(a, p, ta), db = raw(b, p, tb);
      EXPECT_EQ(ta, tb) << p;
      ++datasets;
      if (p.size() >= 10 && p.compare(p.size() - 10, 10, "owner_rank") == 0) continue;  // the one field that differs
      EXPECT_TRUE(da == db) << p << " differs between 1 and " << n << " ranks";
    }
    EXPECT_GT(datasets, 10);
    H5Fclose(a);
    H5Fclose(b);
    std::filesystem::remove_all(dir);
  }
}
