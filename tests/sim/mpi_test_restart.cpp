// Checkpoint and restart (docs/reliability.md): a run continued from a checkpoint writes
// exactly the frames (bitwise) an uninterrupted run writes, whether it continues on the
// rank count that wrote the checkpoint or on another one. Runs under mpiexec with 1 to 4
// ranks; the uninterrupted reference runs on rank 0 alone.
#include <gtest/gtest.h>
#include <hdf5.h>
#include <mpi.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "output_compare.hpp"
#include "soft_floor_scenes.hpp"
#include "softcontact/checkpoint.hpp"
#include "softcontact/error.hpp"
#include "softcontact/mpi_util.hpp"
#include "softcontact/rebalance.hpp"
#include "softcontact/run.hpp"
#include "softcontact/scene.hpp"

using namespace softcontact;
namespace fs = std::filesystem;

namespace {

// The MPI pile (boxes, balls, friction: stiction anchors are part of the state), 120
// steps, a frame every 10 and a checkpoint every 40 steps.
Scene pile() {
  Scene s = load_scene(std::string(SOFTCONTACT_TEST_DATA) + "/scenes/pile.yaml");
  s.sim.steps = 120;
  s.sim.output_every = 10;
  s.sim.output_interval = 0;
  s.sim.checkpoint_every = 40;
  s.sim.checkpoint_keep = 3;
  return s;
}

// Copies run directory `from` to `to` without the checkpoints after `step` (what a run
// killed right after writing that checkpoint leaves, plus the frames it wrote since).
void copy_run(const fs::path& from, const fs::path& to, std::int64_t step) {
  fs::remove_all(to);
  fs::copy(from, to, fs::copy_options::recursive);
  for (const auto& e : fs::directory_iterator(to / "checkpoints")) {
    const std::string stem = e.path().stem().string();
    if (std::stoll(stem.substr(stem.find('_') + 1)) > step) fs::remove(e.path());
  }
}

}  // namespace

TEST(Restart, ContinuedRunEqualsUninterruptedOnSameAndOtherRankCounts) {
  const int rank = comm_rank(MPI_COMM_WORLD), n = comm_size(MPI_COMM_WORLD);
  const fs::path dir = test::scratch_dir("sc_restart");
  RunOptions opt;
  opt.quiet = true;
  opt.overwrite = true;
  std::ostringstream log;

  // The references: uninterrupted, on one rank and on all ranks.
  Scene scene = pile();
  if (rank == 0) {
    scene.sim.output_dir = (dir / "one").string();
    const RunSummary r = run_scene(MPI_COMM_SELF, scene, opt, log);
    EXPECT_EQ(r.steps, 120);
    EXPECT_EQ(r.last_checkpoint, checkpoint_path((dir / "one").string(), 120));
  }
  scene.sim.output_dir = (dir / "all").string();
  run_scene(MPI_COMM_WORLD, scene, opt, log);

  // Continue (a) the N-rank run on N ranks from step 40, (b) the 1-rank run on N ranks
  // from step 80: each must reproduce the 1-rank reference bitwise.
  struct Case {
    const char* from;
    std::int64_t step;
    const char* name;
  };
  for (const Case& c : {Case{"all", 40, "same rank count"}, Case{"one", 80, "1 rank, continued on all ranks"}}) {
    const fs::path cont = dir / (std::string("cont_") + c.from);
    if (rank == 0) copy_run(dir / c.from, cont, c.step);
    MPI_Barrier(MPI_COMM_WORLD);
    RestartPoint restart;
    const Scene again = load_restart(MPI_COMM_WORLD, cont.string(), restart);
    EXPECT_EQ(restart.info.step, c.step);
    EXPECT_EQ(restart.info.ranks, std::string(c.from) == "one" ? 1 : n);
    EXPECT_EQ(fs::path(restart.output_dir), cont);
    RunOptions ropt = opt;
    ropt.overwrite = false;  // continuing in place needs no permission
    const RunSummary r = run_scene(MPI_COMM_WORLD, again, ropt, log, &restart);
    EXPECT_EQ(r.first_step, c.step);
    EXPECT_EQ(r.steps, 120 - c.step);
    MPI_Barrier(MPI_COMM_WORLD);
    if (rank == 0) {
      const std::string what = std::string("after a restart (") + c.name + ", " + std::to_string(n) + " ranks)";
      EXPECT_GT(test::expect_same_output(dir / "one", cont, what, 13), 40);
      // The diagnostics continue too: the same rows as the reference, up to the residual
      // penetration (the force balance, ~1e-16, is a sum over ranks in rank order, and
      // the timings are wall times).
      auto rows = [](const fs::path& csv) {
        std::ifstream in(csv);
        std::vector<std::string> out;
        for (std::string line; std::getline(in, line);) {
          std::size_t cut = 0;
          for (int field = 0; field < 10 && cut != std::string::npos; ++field) cut = line.find(',', cut + 1);
          out.push_back(line.substr(0, cut));
        }
        return out;
      };
      EXPECT_EQ(rows(dir / "one" / "diagnostics.csv"), rows(cont / "diagnostics.csv")) << what;
    }
  }
  if (rank == 0) fs::remove_all(dir);
}

// The restart matrix: a run written on A ranks continues on B ranks, bitwise equal to the
// uninterrupted 1-rank run. Each pair runs in the test with max(A, B) ranks, on the first
// A and then the first B ranks of MPI_COMM_WORLD (the rest wait): np2 1->2 and 2->1, np3
// 2->3 and 3->2, np4 4->1 and 1->4.
TEST(Restart, RankCountMatrixIsBitwise) {
  const int rank = comm_rank(MPI_COMM_WORLD), n = comm_size(MPI_COMM_WORLD);
  const fs::path dir = test::scratch_dir("sc_matrix");
  RunOptions opt;
  opt.quiet = true;
  opt.overwrite = true;
  std::ostringstream log;
  Scene scene = pile();
  if (rank == 0) {
    scene.sim.output_dir = (dir / "one").string();
    run_scene(MPI_COMM_SELF, scene, opt, log);
  }
  // The first `k` ranks, or MPI_COMM_NULL on the others.
  auto first = [&](int k) {
    MPI_Comm c = MPI_COMM_NULL;
    MPI_Comm_split(MPI_COMM_WORLD, rank < k ? 0 : MPI_UNDEFINED, rank, &c);
    return c;
  };
  const std::pair<int, int> pairs[] = {{1, 2}, {2, 1}, {2, 3}, {3, 2}, {4, 1}, {1, 4}};
  int ran = 0;
  for (const auto& [a, b] : pairs) {
    if (std::max(a, b) != n) continue;
    ++ran;
    const std::string tag = std::to_string(a) + "to" + std::to_string(b);
    const fs::path written = dir / ("w" + tag), cont = dir / ("c" + tag);
    MPI_Comm ca = first(a), cb = first(b);
    if (ca != MPI_COMM_NULL) {
      Scene s = pile();
      s.sim.output_dir = written.string();
      run_scene(ca, s, opt, log);
    }
    MPI_Barrier(MPI_COMM_WORLD);
    if (rank == 0) copy_run(written, cont, 40);
    MPI_Barrier(MPI_COMM_WORLD);
    if (cb != MPI_COMM_NULL) {
      RestartPoint restart;
      // Loaded as `run` loads it: copies made on demand, the frequencies shared.
      const Scene again = load_restart(cb, cont.string(), restart, copies_made_on_demand(cb));
      EXPECT_EQ(restart.info.step, 40);
      EXPECT_EQ(restart.info.ranks, a);
      RunOptions ropt = opt;
      ropt.overwrite = false;
      const RunSummary r = run_scene(cb, again, ropt, log, &restart);
      EXPECT_EQ(r.first_step, 40);
      EXPECT_EQ(r.steps, 80);
    }
    MPI_Barrier(MPI_COMM_WORLD);
    if (rank == 0)
      EXPECT_GT(test::expect_same_output(dir / "one", cont, "written on " + std::to_string(a) + " ranks, continued on " +
                                                                 std::to_string(b),
                                         13),
                40);
    for (MPI_Comm* c : {&ca, &cb})
      if (*c != MPI_COMM_NULL) MPI_Comm_free(c);
  }
  EXPECT_EQ(ran, n == 1 ? 0 : 2);
  MPI_Barrier(MPI_COMM_WORLD);
  if (rank == 0) fs::remove_all(dir);
}

// Where a split object's parts are evaluated is kept in the checkpoint
// (/run/split_hosts): a restart on the same rank count puts them back where they were,
// also where that differs from what split_hosts would choose from the partition alone.
// A checkpoint without them (written before they were kept) continues with that choice;
// one naming a rank the run did not have is refused, naming the file. The floor of
// soft_floor_twelve is split from 3 ranks on (3 parts). Results are the uninterrupted
// run's to the bit in every case: hosts place work, they never change a result.
TEST(Restart, SameRankCountKeepsTheSplitObjectsHosts) {
  const int rank = comm_rank(MPI_COMM_WORLD), n = comm_size(MPI_COMM_WORLD);
  const fs::path dir = test::scratch_dir("sc_hosts");
  RunOptions opt;
  opt.quiet = true;
  opt.overwrite = true;
  std::ostringstream log;
  Scene scene = test::soft_floor_twelve();
  scene.sim.steps = 60;
  scene.sim.output_every = 20;
  scene.sim.output_interval = 0;
  scene.sim.checkpoint_every = 20;
  scene.sim.checkpoint_keep = 3;
  scene.sim.output_dir = (dir / "all").string();
  const RunSummary full = run_scene(MPI_COMM_WORLD, scene, opt, log);
  if (n < 3) {
    EXPECT_TRUE(full.split_hosts.empty()) << "no split object below 3 ranks";
    MPI_Barrier(MPI_COMM_WORLD);
    if (rank == 0) fs::remove_all(dir);
    return;
  }
  ASSERT_EQ(full.repartitions, 0) << "the hosts below are those of the initial partition";
  ASSERT_EQ(full.split_hosts.size(), 1u);
  ASSERT_EQ(full.split_hosts[0].size(), 3u);
  const std::string written = checkpoint_path((dir / "all").string(), 20);
  const CheckpointInfo info = read_checkpoint_info(MPI_COMM_WORLD, written);
  EXPECT_EQ(info.split_hosts, full.split_hosts);

  // Hosts neither the run's nor the fallback's: part 0 stays on its rank, the other two
  // go to the first pair of ranks that makes a list unlike both.
  const std::vector<int> fallback = split_hosts(scene, info.partition, n)[0], was = full.split_hosts[0];
  std::vector<int> moved;
  for (int a = 0; a < n && moved.empty(); ++a)
    for (int b = 0; b < n && moved.empty(); ++b) {
      const std::vector<int> c{was[0], a, b};
      if (a != b && a != was[0] && b != was[0] && c != fallback && c != was) moved = c;
    }
  ASSERT_EQ(moved.size(), 3u);

  // Rewrites (or, with an empty list, deletes) /run/split_hosts of the continued run's checkpoint.
  auto set_hosts = [&](const fs::path& run, const std::vector<std::int32_t>& values) {
    if (rank != 0) return;
    const hid_t f = H5Fopen(checkpoint_path(run.string(), 20).c_str(), H5F_ACC_RDWR, H5P_DEFAULT);
    ASSERT_GE(f, 0);
    ASSERT_GE(H5Ldelete(f, "/run/split_hosts", H5P_DEFAULT), 0);
    if (!values.empty()) {
      const hsize_t len = values.size();
      const hid_t space = H5Screate_simple(1, &len, nullptr);
      const hid_t d = H5Dcreate2(f, "/run/split_hosts", H5T_NATIVE_INT32, space, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
      ASSERT_GE(d, 0);
      EXPECT_GE(H5Dwrite(d, H5T_NATIVE_INT32, H5S_ALL, H5S_ALL, H5P_DEFAULT, values.data()), 0);
      H5Dclose(d);
      H5Sclose(space);
    }
    H5Fclose(f);
  };
  struct Case {
    const char* name;
    std::vector<std::int32_t> stored;
    std::vector<int> expected;
  };
  const Case cases[] = {{"hosts moved", {1, 3, moved[0], moved[1], moved[2]}, moved},
                        {"no hosts stored", {}, fallback}};
  for (const Case& c : cases) {
    const fs::path cont = dir / "cont";
    if (rank == 0) copy_run(dir / "all", cont, 20);
    set_hosts(cont, c.stored);
    MPI_Barrier(MPI_COMM_WORLD);
    RestartPoint restart;
    const Scene again = load_restart(MPI_COMM_WORLD, cont.string(), restart);
    EXPECT_EQ(restart.info.split_hosts, c.stored.empty() ? SplitHosts{} : SplitHosts{c.expected}) << c.name;
    RunOptions ropt = opt;
    ropt.overwrite = false;
    const RunSummary r = run_scene(MPI_COMM_WORLD, again, ropt, log, &restart);
    EXPECT_EQ(r.split_hosts, SplitHosts{c.expected}) << c.name;
    MPI_Barrier(MPI_COMM_WORLD);
    if (rank == 0) EXPECT_GT(test::expect_same_output(dir / "all", cont, c.name, 4), 4);
  }

  // A rank past the run's: refused on every rank, naming the file and the dataset.
  const fs::path bad = dir / "bad";
  if (rank == 0) copy_run(dir / "all", bad, 20);
  set_hosts(bad, {1, 3, was[0], was[1], n});
  MPI_Barrier(MPI_COMM_WORLD);
  RestartPoint restart;
  try {
    load_restart(MPI_COMM_WORLD, bad.string(), restart);
    ADD_FAILURE() << "hosts naming rank " << n << " of a run on " << n << " were accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("checkpoint_000000000020.h5"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("/run/split_hosts names rank " + std::to_string(n)), std::string::npos)
        << e.what();
  }
  MPI_Barrier(MPI_COMM_WORLD);
  if (rank == 0) fs::remove_all(dir);
}

TEST(Restart, KeepsOnlyTheNewestCheckpoints) {
  const int rank = comm_rank(MPI_COMM_WORLD);
  const fs::path dir = test::scratch_dir("sc_keep");
  Scene scene = pile();
  scene.sim.steps = 100;
  scene.sim.checkpoint_every = 10;
  scene.sim.checkpoint_keep = 2;
  scene.sim.output_dir = dir.string();
  RunOptions opt;
  opt.quiet = true;
  opt.overwrite = true;
  std::ostringstream log;
  run_scene(MPI_COMM_WORLD, scene, opt, log);
  if (rank == 0) {
    std::vector<std::string> names;
    for (const auto& e : fs::directory_iterator(dir / "checkpoints")) names.push_back(e.path().filename().string());
    std::sort(names.begin(), names.end());
    EXPECT_EQ(names, (std::vector<std::string>{"checkpoint_000000000090.h5", "checkpoint_000000000100.h5"}));
    fs::remove_all(dir);
  }
}

TEST(Restart, RefusesADamagedCheckpointWithAClearMessage) {
  const int rank = comm_rank(MPI_COMM_WORLD);
  const fs::path dir = test::scratch_dir("sc_damaged");
  if (rank == 0) {
    fs::create_directories(dir);
    std::ofstream(dir / "truncated.h5") << "\x89HDF\r\n\x1a\n then nothing useful";
  }
  MPI_Barrier(MPI_COMM_WORLD);
  RestartPoint restart;
  try {
    load_restart(MPI_COMM_WORLD, (dir / "truncated.h5").string(), restart);
    ADD_FAILURE() << "a damaged checkpoint was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("truncated.h5"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("not a readable softcontact checkpoint"), std::string::npos) << e.what();
  }
  try {
    load_restart(MPI_COMM_WORLD, (dir / "none").string(), restart);
    ADD_FAILURE() << "a missing checkpoint was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("no such checkpoint"), std::string::npos) << e.what();
  }
  MPI_Barrier(MPI_COMM_WORLD);
  if (rank == 0) fs::remove_all(dir);
}

namespace {
// Overwrites element (row, col) of dataset `name` of an (rows, cols) checkpoint dataset.
template <class T>
void poke(const fs::path& file, const char* name, hsize_t row, hsize_t col, T value, hid_t type) {
  const hid_t f = H5Fopen(file.c_str(), H5F_ACC_RDWR, H5P_DEFAULT);
  ASSERT_GE(f, 0) << file;
  const hid_t d = H5Dopen2(f, name, H5P_DEFAULT);
  const hid_t space = H5Dget_space(d);
  const hsize_t start[2] = {row, col}, count[2] = {1, 1}, one[1] = {1};
  H5Sselect_hyperslab(space, H5S_SELECT_SET, start, nullptr, count, nullptr);
  const hid_t mem = H5Screate_simple(1, one, nullptr);
  EXPECT_GE(H5Dwrite(d, type, mem, space, H5P_DEFAULT, &value), 0) << name;
  H5Sclose(mem);
  H5Sclose(space);
  H5Dclose(d);
  H5Fclose(f);
}
}  // namespace

// A checkpoint whose per-vertex state is bad (a NaN position, a friction anchor naming
// an object that does not exist) is refused with an InputError naming the file and the
// vertex (exit status 2), not run into a numerical failure or out of bounds. The bad
// vertex is the last one, owned by the last rank: every rank must refuse together (a
// rank that went on would wait forever in the first collective call).
TEST(Restart, RefusesABadStateOnEveryRankTogether) {
  const int rank = comm_rank(MPI_COMM_WORLD);
  const fs::path dir = test::scratch_dir("sc_bad_state");
  Scene scene = pile();
  scene.sim.steps = 20;
  scene.sim.checkpoint_every = 20;
  scene.sim.output_dir = (dir / "run").string();
  RunOptions opt;
  opt.quiet = true;
  opt.overwrite = true;
  std::ostringstream log;
  run_scene(MPI_COMM_WORLD, scene, opt, log);
  const fs::path ckpt = checkpoint_path((dir / "run").string(), 20);
  struct Case {
    const char* dataset;
    const char* expected;
  };
  for (const Case& c : {Case{"/state/x", "has a position (/state/x) that is not finite"},
                        Case{"/state/anchor_object", "has a friction anchor naming an object that does not exist"}}) {
    const fs::path bad = dir / "bad.h5";
    if (rank == 0) {
      fs::copy_file(ckpt, bad, fs::copy_options::overwrite_existing);
      std::int64_t nv = 0;
      {
        RestartPoint r;
        load_restart(MPI_COMM_SELF, bad.string(), r);
        nv = r.info.vertices;
      }
      if (std::string(c.dataset) == "/state/x") poke(bad, c.dataset, nv - 1, 2, std::nan(""), H5T_NATIVE_DOUBLE);
      else poke(bad, c.dataset, nv - 1, 0, std::int32_t{99}, H5T_NATIVE_INT32);
    }
    MPI_Barrier(MPI_COMM_WORLD);
    RestartPoint restart;
    const Scene again = load_restart(MPI_COMM_WORLD, bad.string(), restart);
    const std::string want = "vertex " + std::to_string(restart.info.vertices - 1) + " " + c.expected;
    RunOptions ropt = opt;
    ropt.overwrite = true;
    Scene elsewhere = again;
    elsewhere.sim.output_dir = (dir / "cont").string();
    try {
      run_scene(MPI_COMM_WORLD, elsewhere, ropt, log, &restart);
      ADD_FAILURE() << "a checkpoint with a bad " << c.dataset << " was accepted";
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find("bad.h5"), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find(want), std::string::npos) << e.what();
    }
    MPI_Barrier(MPI_COMM_WORLD);
  }
  if (rank == 0) fs::remove_all(dir);
}

// Continuing a run directory whose mesh.h5 is gone is refused on every rank with one
// InputError naming the file (exit status 2), before anything in the directory changes:
// the frames written stay (frames::resume_frames checks the mesh before it deletes the
// frames past the checkpoint).
TEST(Restart, RefusesToContinueADirectoryWithoutItsMeshAndKeepsItsFrames) {
  const int rank = comm_rank(MPI_COMM_WORLD);
  const fs::path dir = test::scratch_dir("sc_no_mesh");
  Scene scene = pile();
  scene.sim.steps = 40;
  scene.sim.checkpoint_every = 20;
  scene.sim.output_dir = dir.string();
  RunOptions opt;
  opt.quiet = true;
  opt.overwrite = true;
  std::ostringstream log;
  run_scene(MPI_COMM_WORLD, scene, opt, log);
  auto frames = [&] {
    std::size_t n = 0;
    for ([[maybe_unused]] const auto& e : fs::directory_iterator(dir / "frames")) ++n;
    return n;
  };
  std::size_t before = 0;
  if (rank == 0) {
    before = frames();
    EXPECT_EQ(before, 5u);  // steps 0, 10, 20, 30, 40
    fs::remove(dir / "mesh.h5");
  }
  MPI_Barrier(MPI_COMM_WORLD);
  RestartPoint restart;
  const Scene again = load_restart(MPI_COMM_WORLD, checkpoint_path(dir.string(), 20), restart);
  RunOptions ropt = opt;
  ropt.overwrite = false;
  try {
    run_scene(MPI_COMM_WORLD, again, ropt, log, &restart);
    ADD_FAILURE() << "a run directory without mesh.h5 was continued";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find((dir / "mesh.h5").string()), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("cannot continue the output"), std::string::npos) << e.what();
  }
  MPI_Barrier(MPI_COMM_WORLD);
  if (rank == 0) {
    EXPECT_EQ(frames(), before) << "the refused restart deleted frames";
    fs::remove_all(dir);
  }
}
