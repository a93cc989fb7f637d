// The distributed step against one rank (issue: rank- and thread-independent results).
// Runs under mpiexec with 1 to 4 ranks (ctest mpi.npN). In each test rank 0 first runs
// the scene alone (MPI_COMM_SELF, one thread): the reference. Then all ranks run it
// together, objects partitioned with METIS, and rank 0 compares positions and contact
// forces gathered by global vertex id: they must be bitwise equal, not close.
#include <gtest/gtest.h>
#include <hdf5.h>
#include <mpi.h>
#include <omp.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <random>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>

#include <unistd.h>

#include "softcontact/rebalance.hpp"
#include "softcontact/run.hpp"
#include "softcontact/diagnostics.hpp"
#include "softcontact/ghosts.hpp"
#include "softcontact/mesh_io.hpp"
#include "softcontact/mpi_util.hpp"
#include "softcontact/primitives.hpp"
#include "softcontact/scene.hpp"
#include "softcontact/simulator.hpp"
#include "softcontact/split_forces.hpp"
#include "softcontact/stepper.hpp"
#include "softcontact/verify.hpp"
#include "output_compare.hpp"
#include "soft_floor_scenes.hpp"

using namespace softcontact;
using test::Edit;
using test::soft_floor_edited;
using test::soft_floor_twelve;

namespace {

const Scene& pile() {
  static const Scene s = load_scene(std::string(SOFTCONTACT_TEST_DATA) + "/scenes/pile.yaml");
  return s;
}

constexpr int kSteps = 120, kEvery = 10;

// Positions and contact forces of every vertex in global order (on rank 0; empty
// elsewhere), gathered from the owners, and the step's colliding points summed over the
// ranks (the diagnostics' `contacts`: each point counted once, by its owner).
struct Snapshot {
  std::vector<double> x, f;
  std::int64_t points = 0;
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
  const std::int64_t points = sim.collision_stats().colliding_points;
  MPI_Reduce(&points, &s.points, 1, MPI_INT64_T, MPI_SUM, 0, comm);
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

const Scene& soft_floor() {
  static const Scene s = load_scene(std::string(SOFTCONTACT_TEST_DATA) + "/scenes/soft_floor.yaml");
  return s;
}

// soft_floor with its balls 3 m higher: no rank but the floor's owner is near the floor,
// so none holds it as a ghost, and its parts need the positions sent.
const Scene& soft_floor_far() {
  static const Scene s = soft_floor_edited({{"0.09]}", "3.09]}", 2}});
  return s;
}

// At step 55 on more than one rank, every object moves to the next rank (the split
// objects change owner, and their parts are evaluated by other ranks); returns 1 then.
int migrate_at_step_55(Simulator& sim, int step) {
  const int n = comm_size(MPI_COMM_WORLD);
  if (step != 55 || n == 1) return 0;
  std::vector<int> next = sim.partition();
  for (int& r : next) r = (r + 1) % n;
  sim.migrate(next);
  return 1;
}

// Over all ranks: the parts evaluated off their object's owner, and those of them that
// read the positions from ghost rows (collective).
std::pair<int, int> helping_parts(const Simulator& sim) {
  int p[2] = {sim.split_helping_parts(), sim.split_parts_from_ghosts()};
  MPI_Allreduce(MPI_IN_PLACE, p, 2, MPI_INT, MPI_SUM, MPI_COMM_WORLD);
  return {p[0], p[1]};
}

// The reference: rank 0 alone, one thread, a snapshot every kEvery steps.
const std::vector<Snapshot>& reference(const Scene& scene = pile()) {
  static std::map<const Scene*, std::vector<Snapshot>> refs;
  const auto found = refs.find(&scene);
  if (found != refs.end()) return found->second;
  std::vector<Snapshot>& ref = refs[&scene];
  if (comm_rank(MPI_COMM_WORLD) == 0) {
    omp_set_num_threads(1);
    Simulator sim(MPI_COMM_SELF, scene);
    for (int s = 1; s <= kSteps; ++s) {
      sim.step();
      if (s % kEvery == 0) ref.push_back(gather(MPI_COMM_SELF, sim));
    }
  }
  return ref;
}

// Runs `scene` (the pile unless given) on every rank with `threads` threads and compares
// each snapshot with the reference; `between(sim, step)` may act on the simulator after
// each step.
template <class F>
void expect_identical(int threads, F&& between, std::int64_t* cross_out = nullptr, const Scene& scene = pile()) {
  const std::vector<Snapshot>& ref = reference(scene);
  MPI_Barrier(MPI_COMM_WORLD);
  omp_set_num_threads(threads);
  Simulator sim(MPI_COMM_WORLD, scene);
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
      EXPECT_EQ(got.points, ref[k].points) << "colliding points differ from one rank's at step " << s;
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

namespace {

// Four single-copy entries read from one mesh file (a box of 3 x 3 x 3 cells, each entry
// moved and rotated by its own transform), 0.8 m apart, two on each of two kinematic
// plates 0.4 m apart: no box reaches another box or the other plate, so a rank holds the
// boxes it owns or ghosts (those on a plate it owns) and no other. Loaded as `run`
// loads it (copies_made_on_demand: collective). Rank 0 writes the file.
const Scene& file_singles() {
  static const Scene s = [] {
    const auto dir = std::filesystem::temp_directory_path() / "softcontact_mpi_file_singles";
    if (comm_rank(MPI_COMM_WORLD) == 0) {
      std::filesystem::create_directories(dir);
      write_gmsh((dir / "box.msh").string(), make_box(0.2, 0.2, 0.2, 3, 3, 3), GmshFormat::v41_binary);
      std::ofstream(dir / "scene.yaml") << R"(simulation:
  dt: auto
  steps: 120
  output: {directory: out, every: 10}
materials:
  - {name: rubber, model: corotational, young: 1.0e5, poisson: 0.3, density: 1000}
objects:
  - {name: left, material: rubber, primitive: {type: plate, size: [1.2, 1], thickness: 0.1, cells: [3, 2]}, transform: {translate: [-0.8, 0, -0.05]}, kinematic: true}
  - {name: a, material: rubber, mesh: box.msh, transform: {translate: [-1.2, 0, 0.004]}}
  - {name: b, material: rubber, mesh: box.msh, transform: {rotate: [0, 0, 30], translate: [-0.4, 0, 0.004]}}
  - {name: c, material: rubber, mesh: box.msh, transform: {scale: [1, 1, 0.5], translate: [0.4, 0, 0.004]}}
  - {name: d, material: rubber, mesh: box.msh, transform: {rotate: {axis: [0, 0, 1], angle: 45}, translate: [1.2, 0, 0.004]}, velocity: [0, 0, -0.5]}
  - {name: right, material: rubber, primitive: {type: plate, size: [1.2, 1], thickness: 0.1, cells: [3, 2]}, transform: {translate: [0.8, 0, -0.05]}, kinematic: true}
)";
    }
    MPI_Barrier(MPI_COMM_WORLD);
    return load_scene((dir / "scene.yaml").string(), copies_made_on_demand(MPI_COMM_WORLD));
  }();
  return s;
}

}  // namespace

// Single-copy entries' meshes are dropped where neither owned nor ghosted, and a rank that
// comes to ghost or own one (a migration brings it) takes it from the rank that holds it
// (fetch_object_meshes): no rank reads a mesh file while the Simulator runs, and
// positions and contact forces are one rank's to the bit, before and after every object
// moves to the next rank.
TEST(Distributed, SingleCopyMeshesFetchedAfterAMigrationAreBitwiseOneRanks) {
  const Scene& scene = file_singles();
  const int n = comm_size(MPI_COMM_WORLD);
  (void)reference(scene);  // one rank's run, reading what it needs
  const std::uint64_t reads_before = mesh_files_read();
  ASSERT_EQ(scene.objects.size(), 6u);
  for (std::size_t k = 0; k < 6; ++k) ASSERT_EQ(scene.objects[k].placement.kind, Placement::Kind::entry) << k;
  std::int64_t dropped_then_owned = 0, wrongly_held = 0;
  std::vector<char> empty_before(scene.objects.size(), 0);
  expect_identical(
      1,
      [&](Simulator& sim, int s) {
        const World& w = sim.world();
        for (std::size_t k = 0; k < scene.objects.size(); ++k) {
          const int obj = static_cast<int>(k);
          const bool needed = w.owns_object(obj) ||
                              std::count(w.ghost_objects.begin(), w.ghost_objects.end(), obj) > 0;
          if (n > 1 && !needed && !scene.objects[k].mesh.points.empty()) ++wrongly_held;
          if (s == 35) empty_before[k] = scene.objects[k].mesh.points.empty() ? 1 : 0;
        }
        if (s == 35 && n > 1) {
          std::vector<int> next = sim.partition();
          for (int& r : next) r = (r + 1) % n;
          sim.migrate(next);
          for (std::size_t k = 0; k < scene.objects.size(); ++k)
            if (empty_before[k] && sim.world().owns_object(static_cast<int>(k))) {
              ++dropped_then_owned;
              EXPECT_FALSE(scene.objects[k].mesh.points.empty()) << "object " << k << " owned without its mesh";
            }
        }
      },
      nullptr, scene);
  auto reads = static_cast<std::int64_t>(mesh_files_read() - reads_before);
  MPI_Allreduce(MPI_IN_PLACE, &reads, 1, MPI_INT64_T, MPI_SUM, MPI_COMM_WORLD);
  EXPECT_EQ(reads, 0) << "a rank read a mesh file while the Simulator ran";
  MPI_Allreduce(MPI_IN_PLACE, &dropped_then_owned, 1, MPI_INT64_T, MPI_SUM, MPI_COMM_WORLD);
  MPI_Allreduce(MPI_IN_PLACE, &wrongly_held, 1, MPI_INT64_T, MPI_SUM, MPI_COMM_WORLD);
  EXPECT_EQ(wrongly_held, 0) << "a rank held a single-copy mesh it neither owned nor ghosted";
  // On 2+ ranks some object moves to a rank that had dropped it: its mesh comes from its
  // old owner.
  if (n > 1) EXPECT_GT(dropped_then_owned, 0) << "no mesh was made again: the test proves nothing";
  if (comm_rank(MPI_COMM_WORLD) == 0)
    std::cout << "[measured] single-copy meshes made again for their new owner after the migration: " << dropped_then_owned << "\n";
}

// Each rank builds and holds only the meshes of its own objects and its ghosts (scene
// loaded as `run` loads it: copies made on demand), and the results are the reference's
// (a scene that held every mesh, on one rank) to the bit.
TEST(Distributed, EachRankHoldsOnlyTheMeshesItNeeds) {
  const std::vector<Snapshot>& ref = reference();
  for (const bool hold : {false, true}) {
    SCOPED_TRACE(hold ? "scene loaded with every mesh (the Simulator drops)" : "scene loaded as run loads it");
    SceneLimits limits;
    limits.hold_copy_meshes = hold;
    const Scene scene = load_scene(std::string(SOFTCONTACT_TEST_DATA) + "/scenes/pile.yaml", limits);
    omp_set_num_threads(1);
    Simulator sim(MPI_COMM_WORLD, scene);
    double mean = 0, median = 0;
    scene_edge_lengths(pile(), mean, median);  // every mesh on this rank
    EXPECT_EQ(sim.median_edge(), median) << "the median over ranks (kth_smallest) is the whole scene's";
    EXPECT_EQ(sim.cell_size(), mean) << "the mean from each rank's objects' sums is the whole scene's";
    const int n = comm_size(MPI_COMM_WORLD);
    for (int s = 1; s <= 60; ++s) {
      sim.step();
      if (s % 20 != 0) continue;
      const World& w = sim.world();
      std::size_t held = 0;
      for (std::size_t k = 0; k < scene.objects.size(); ++k) {
        const bool needed = w.owns_object(static_cast<int>(k)) ||
                            std::count(w.ghost_objects.begin(), w.ghost_objects.end(), static_cast<int>(k)) > 0;
        const bool remakable = scene.objects[k].placement.can_remake();
        const bool has = !scene.objects[k].mesh.points.empty();
        held += has ? 1 : 0;
        if (needed) EXPECT_TRUE(has) << "object " << k << " at step " << s;
        else if (remakable) EXPECT_FALSE(has) << "object " << k << " is neither owned nor ghosted here (step " << s << ")";
      }
      // A rank may own or ghost every object of this small pile (rank 2 of 3 does), but
      // not every rank does.
      auto all_held = static_cast<std::int64_t>(held);
      MPI_Allreduce(MPI_IN_PLACE, &all_held, 1, MPI_INT64_T, MPI_SUM, MPI_COMM_WORLD);
      if (n > 1) EXPECT_LT(all_held, static_cast<std::int64_t>(n * scene.objects.size())) << "every rank holds every mesh";
      const Snapshot got = gather(MPI_COMM_WORLD, sim);
      if (comm_rank(MPI_COMM_WORLD) == 0) {
        const Snapshot& want = ref[static_cast<std::size_t>(s / kEvery - 1)];
        ASSERT_EQ(got.x.size(), want.x.size());
        EXPECT_EQ(std::memcmp(got.x.data(), want.x.data(), got.x.size() * sizeof(double)), 0) << "step " << s;
      }
    }
  }
}

// kth_smallest against all ranks' values gathered and sorted (NaN last): equal for every
// k, for values with duplicates, zeros of both signs, a spread of magnitudes, a few NaNs,
// and every rank holding a different count; NaN on every rank for k = the total.
TEST(Distributed, KthSmallestIsNthElementOfAllRanksValues) {
  const int rank = comm_rank(MPI_COMM_WORLD), n = comm_size(MPI_COMM_WORLD);
  std::mt19937_64 gen(static_cast<std::uint64_t>(17 + rank));
  std::vector<double> mine(static_cast<std::size_t>(50 + 31 * rank));
  for (double& v : mine) {
    const auto r = gen();
    v = r % 7 == 0 ? (r % 2 ? -0.0 : 0.0) : r % 5 == 0 ? 0.25 : r % 23 == 0 ? std::nan("")
        : std::ldexp(static_cast<double>(r >> 11), -40 - static_cast<int>(r % 20));
  }
  const std::vector<double> all = allgather_doubles(MPI_COMM_WORLD, mine);
  const auto total = static_cast<std::int64_t>(all.size());
  std::vector<double> sorted = all;
  std::sort(sorted.begin(), sorted.end(), [](double a, double b) { return !std::isnan(a) && (std::isnan(b) || a < b); });
  std::int64_t nans = 0, wrong = 0;
  for (std::int64_t k = 0; k < total; ++k) {
    const double got = kth_smallest(MPI_COMM_WORLD, mine, k), want = sorted[static_cast<std::size_t>(k)];
    nans += std::isnan(want) ? 1 : 0;
    if (std::isnan(want) ? !std::isnan(got) : got != want) {
      ++wrong;
      ADD_FAILURE() << "k = " << k << ": " << got << ", expected " << want;
    }
  }
  EXPECT_EQ(wrong, 0);
  EXPECT_GT(nans, 0) << "no NaN among the values: the test proves less";
  EXPECT_TRUE(std::isnan(kth_smallest(MPI_COMM_WORLD, mine, total))) << "k = the total";
}

// allgather_doubles: every rank's values in rank order on every rank, rank 0 giving none.
TEST(Distributed, AllgatherDoublesConcatenatesInRankOrder) {
  const int rank = comm_rank(MPI_COMM_WORLD), n = comm_size(MPI_COMM_WORLD);
  std::vector<double> mine;
  for (int i = 0; i < rank; ++i) mine.push_back(100.0 * rank + i);
  std::vector<double> expected;
  for (int r = 0; r < n; ++r)
    for (int i = 0; i < r; ++i) expected.push_back(100.0 * r + i);
  EXPECT_EQ(allgather_doubles(MPI_COMM_WORLD, mine), expected);
}

// Random placement shared over the ranks (copies_made_on_demand: each rank places the
// groups of regions given to it, the placements all-gathered): every rank ends with every
// copy's box and mesh bitwise those of placing the whole scene alone (the reference: the
// scene loaded without sharing, every mesh held). Five regions, one of them holding two
// entries, so that 1 to 4 ranks each place some and one rank places a group of two.
TEST(Distributed, RandomPlacementOverRanksIsBitwiseOneRanks) {
  std::string text = "simulation: {dt: auto, steps: 10}\n"
                     "materials:\n  - {name: rubber, model: corotational, young: 1.0e5, poisson: 0.3, density: 1000}\n"
                     "objects:\n"
                     "  - {name: floor, material: rubber, kinematic: true, transform: {translate: [0, 0, -0.05]},\n"
                     "     primitive: {type: plate, size: [12, 3], thickness: 0.1, cells: [12, 3]}}\n";
  for (int k = 0; k < 5; ++k) {
    const std::string x0 = std::to_string(-5.5 + 2.2 * k), x1 = std::to_string(-4.0 + 2.2 * k);
    const std::string region = "region: {min: [" + x0 + ", -1, 0], max: [" + x1 + ", 1, 1]}";
    text += "  - {name: s" + std::to_string(k) + ", material: rubber, primitive: {type: sphere, radius: 0.1, resolution: 3},\n"
            "     instances: {random: {count: " + std::to_string(6 + 3 * k) + ", seed: " + std::to_string(11 + k) +
            ", rotate: true, " + region + "}}}\n";
    if (k == 2)
      text += "  - {name: b, material: rubber, primitive: {type: box, size: [0.15, 0.1, 0.2], cells: [1, 1, 2]},\n"
              "     instances: {random: {count: 9, seed: 3, rotate: true, " + region + "}}}\n";
  }
  const Scene one = load_scene_from_string(text, "scene.yaml");
  const Scene shared = load_scene_from_string(text, "scene.yaml", copies_made_on_demand(MPI_COMM_WORLD));
  ASSERT_EQ(shared.objects.size(), one.objects.size());
  ASSERT_EQ(one.objects.size(), 1u + 6 + 9 + 12 + 9 + 15 + 18);
  EXPECT_EQ(shared.sim.dt, one.sim.dt);
  for (std::size_t k = 0; k < one.objects.size(); ++k) {
    const TetMesh& ref = one.objects[k].mesh;
    Box b = Box::none();
    for (std::size_t i = 0; i < ref.num_vertices(); ++i) add_point(b, &ref.points[3 * i]);
    EXPECT_EQ(shared.shape(k).box.lo, b.lo) << one.objects[k].name;
    EXPECT_EQ(shared.shape(k).box.hi, b.hi) << one.objects[k].name;
    EXPECT_EQ(shared.view_mesh(k).get().points, ref.points) << one.objects[k].name;
  }
}

// A soft floor holding more than half of the tets (tests/data/scenes/soft_floor.yaml):
// on 2 to 4 ranks its forces are shared by every rank (split_forces.hpp), each rank
// evaluating a METIS part of its tets, and the owner folding the corner forces in tet
// order. Positions and contact forces must be one rank's to the bit, every 10 steps, also
// across a migration of every object to the next rank (the floor changes owner, and its
// parts are evaluated by other ranks) and with two threads per rank.
TEST(Distributed, SoftFloorSplitOverRanksIsBitwiseOneRanks) {
  const int n = comm_size(MPI_COMM_WORLD);
  EXPECT_EQ(split_candidates(soft_floor(), n), n > 1 ? std::vector<int>{0} : std::vector<int>{});
  // The floor's parts by METIS (the default for its size) and by the coordinate bisection.
  static const Scene bisected = [] {
    Scene s = soft_floor();
    s.sim.split_parts = SplitParts::bisection;
    return s;
  }();
  for (const int threads : {1, 2, 0}) {
    const Scene& scene = threads > 0 ? soft_floor() : bisected;
    SCOPED_TRACE(threads > 0 ? std::to_string(threads) + " thread(s) per rank" : "split_parts: bisection, 1 thread");
    int split_steps = 0, migrations = 0;
    std::int64_t computed = 0, received = 0;
    std::size_t kept = 0;
    bool owner = false;
    expect_identical(
        std::max(threads, 1),
        [&](Simulator& sim, int s) {
          // Every rank holds the floor (its owner, or a ghost under the balls): all share it,
          // and every part off the owner takes the floor's positions from its ghost rows.
          if (sim.split_objects() == 1 && sim.split_ranks() == n) ++split_steps;
          computed = sim.split_parts_computed();
          received = sim.split_part_meshes_received();
          kept = sim.split_parts_kept();
          owner = sim.partition()[0] == comm_rank(MPI_COMM_WORLD);
          const auto [helping, from_ghosts] = helping_parts(sim);
          EXPECT_EQ(helping, n - 1) << "step " << s;
          EXPECT_EQ(from_ghosts, n - 1) << "step " << s;
          migrations += migrate_at_step_55(sim, s);
        },
        nullptr, scene);
    EXPECT_EQ(split_steps, n > 1 ? kSteps : 0) << "the floor was not split at every step";
    EXPECT_EQ(migrations, n > 1 ? 1 : 0);
    // The floor's parts computed once, by its first owner; its owner after the migration
    // took them from it.
    MPI_Allreduce(MPI_IN_PLACE, &computed, 1, MPI_INT64_T, MPI_SUM, MPI_COMM_WORLD);
    EXPECT_EQ(computed, n > 1 ? 1 : 0) << "the parts computed by one rank only";
    // Every rank but the owner was sent its part, at the start and again after the
    // migration, though it holds the floor as a ghost (n - 1 parts each time); only the
    // owner keeps the parts of every tet.
    EXPECT_EQ(kept, n > 1 && owner ? 1u : 0u) << "parts of every tet kept here";
    MPI_Allreduce(MPI_IN_PLACE, &received, 1, MPI_INT64_T, MPI_SUM, MPI_COMM_WORLD);
    EXPECT_EQ(received, 2 * (n - 1)) << "part meshes sent";
  }
}

namespace {
// soft_floor with its balls moved half a floor cell, so that they land on the floor's
// vertices and press some of them into the balls (the test scene's balls land between
// them, and no floor point ever enters a ball).
const Scene& soft_floor_on_vertices() {
  static const Scene s = soft_floor_edited({{"translate: [-0.3, -0.15, 0.09]", "translate: [-0.35, -0.2, 0.09]", 1},
                                            {"translate: [-0.3, 0.15, 0.09]", "translate: [-0.35, 0.2, 0.09]", 1}});
  return s;
}
}  // namespace

// A split floor's points inside a ball are found by the ball's owner, which holds the
// floor as a ghost, and sent to the floor's owner (CollisionDetector::delegate;
// docs/architecture.md, "Contact of a split object"). Positions, contact forces and the
// colliding points summed over the ranks (each counted once, by the floor's owner) are one
// rank's at every snapshot, also across a migration of every object to the next rank;
// every record sent arrives; records of floor points exist (else the test proves
// nothing), and on more than one rank some of them came from another rank.
TEST(Distributed, SplitFloorsPointsInsideBallsAreFoundByTheBallsOwners) {
  const int n = comm_size(MPI_COMM_WORLD);
  const Scene& scene = soft_floor_on_vertices();
  std::int64_t counts[3] = {0, 0, 0};  // floor records over the run; delegated records sent, received
  int migrations = 0;
  expect_identical(
      1,
      [&](Simulator& sim, int s) {
        for (const Collision& c : sim.collisions()) counts[0] += c.object == 0 ? 1 : 0;
        counts[1] = sim.delegated_records_sent();
        counts[2] = sim.delegated_records_received();
        migrations += migrate_at_step_55(sim, s);
      },
      nullptr, scene);
  MPI_Allreduce(MPI_IN_PLACE, counts, 3, MPI_INT64_T, MPI_SUM, MPI_COMM_WORLD);
  EXPECT_GT(counts[0], 0) << "no floor point entered a ball: the test proves nothing";
  EXPECT_EQ(counts[1], counts[2]) << "delegated records sent and received over the ranks";
  if (n > 1) EXPECT_GT(counts[1], 0) << "no floor record was made by a ball's owner";
  EXPECT_LE(counts[1], counts[0]);
  EXPECT_EQ(migrations, n > 1 ? 1 : 0);
  if (comm_rank(MPI_COMM_WORLD) == 0)
    std::cout << "[measured] " << n << " ranks: " << counts[0] << " floor records over " << kSteps << " steps, "
              << counts[1] << " of them made by the balls' owners\n";
}

// The split floor's delegated records under the coupled closure (every rank's rows
// gathered and solved together) with mutual pairs on (each rank sends its neighbours the
// keys of its records whose heavy vertex is a ghost, after the delegated records have
// reached the floor's owner). Positions, contact forces and colliding points one rank's
// at every snapshot, across a migration of every object. No mutual pair of this scene
// contradicts (none is settled: the keys travel, the settle changes nothing), and the
// floor never touches itself, so self-contact of a split object is not tested here.
TEST(Distributed, SplitFloorsDelegatedRecordsUnderTheCoupledClosureAreBitwiseOneRanks) {
  const int n = comm_size(MPI_COMM_WORLD);
  static const Scene scene = [] {
    Scene s = soft_floor_on_vertices();
    s.sim.mutual_pairs = true;
    s.sim.contact_closure = ContactClosure::coupled;
    return s;
  }();
  std::int64_t delegated = 0;
  int migrations = 0;
  expect_identical(
      1,
      [&](Simulator& sim, int s) {
        delegated = sim.delegated_records_sent();
        migrations += migrate_at_step_55(sim, s);
      },
      nullptr, scene);
  MPI_Allreduce(MPI_IN_PLACE, &delegated, 1, MPI_INT64_T, MPI_SUM, MPI_COMM_WORLD);
  if (n > 1) EXPECT_GT(delegated, 0) << "no floor record was made by a ball's owner";
  EXPECT_EQ(migrations, n > 1 ? 1 : 0);
}

// The rebalance's contact counts (Simulator::measured_contacts, RankWork::contacts) weigh
// an object by the records its owner makes: a vertex record counts for its point's object,
// but a split floor's point found by the owner of the ball it entered counts for that ball
// (split_detection, docs/architecture.md, "Contact of a split object"), and for the floor
// when the floor's owner finds it (split_detection: false). The reference is worked out
// from one rank's records of the same 120 steps with that rule; summed over the ranks the
// counts must equal it object by object (every record counted once, on one rank: the
// records a ball's owner sends the floor's owner are counted there, not twice).
TEST(Distributed, RebalanceCountsASplitFloorsRecordForTheObjectWhoseOwnerFoundIt) {
  const int n = comm_size(MPI_COMM_WORLD);
  std::int64_t floor_records[2] = {0, 0};  // the floor's count in the reference, delegated and not
  for (const bool delegate : {true, false}) {
    SCOPED_TRACE(delegate ? "split_detection: true" : "split_detection: false");
    Scene scene = soft_floor_on_vertices();
    scene.sim.split_detection = delegate;
    scene.sim.rebalance_every = 10 * kSteps;  // no check in the run, which would restart the counts
    const std::size_t no = scene.objects.size();
    std::vector<std::int64_t> want(no, 0);
    if (comm_rank(MPI_COMM_WORLD) == 0) {
      omp_set_num_threads(1);
      Simulator one(MPI_COMM_SELF, scene);
      for (int s = 1; s <= kSteps; ++s) {
        one.step();
        for (const Collision& c : one.collisions()) {
          if (c.point2 >= 0) continue;
          const int k = one.world().vertex_object[static_cast<std::size_t>(c.point)];
          ++want[static_cast<std::size_t>(delegate && k == 0 ? c.other_object : k)];
        }
      }
      EXPECT_TRUE(one.measured_contacts().empty()) << "one rank keeps no counts: it never rebalances";
      floor_records[delegate ? 0 : 1] = want[0];
    }
    MPI_Barrier(MPI_COMM_WORLD);
    Simulator sim(MPI_COMM_WORLD, scene);
    for (int s = 1; s <= kSteps; ++s) sim.step();
    if (n == 1) continue;
    std::vector<std::int64_t> got = sim.measured_contacts();
    got.resize(no, 0);
    MPI_Reduce(comm_rank(MPI_COMM_WORLD) == 0 ? MPI_IN_PLACE : got.data(), got.data(), static_cast<int>(no), MPI_INT64_T,
               MPI_SUM, 0, MPI_COMM_WORLD);
    if (comm_rank(MPI_COMM_WORLD) == 0)
      for (std::size_t k = 0; k < no; ++k) EXPECT_EQ(got[k], want[k]) << "object " << k << " (" << scene.objects[k].name << ")";
  }
  if (comm_rank(MPI_COMM_WORLD) == 0) {
    EXPECT_EQ(floor_records[0], 0) << "with the detection delegated, no record counts for the floor";
    EXPECT_GT(floor_records[1], 0) << "no floor point entered a ball: the test proves nothing";
    std::cout << "[measured] " << floor_records[1] << " floor records over " << kSteps << " steps\n";
  }
}

// A floor of 35 % of the tets (soft_floor_twelve) on 4 ranks is cut into 3 parts, not 4:
// each of about half an even share, one on its owner, the others on the ranks the
// partition kept room on (partition_at's hosts; after a migration by hand, split_hosts).
// Positions and contact forces one rank's to the bit, also across a migration of every
// object to the next rank; every floor tet evaluated by exactly one rank (the ranks'
// evaluated tets sum to the floor's, counted from the scene), by at most 3 ranks; and
// the tets each rank evaluates (its other objects' and its floor tets) within 1.25 of
// the mean (whole balls of 192 tets against a mean of 888: 1.13 is the best split).
TEST(Distributed, FloorInFewerPartsThanRanksIsBitwiseOneRanks) {
  const int n = comm_size(MPI_COMM_WORLD);
  const Scene& scene = soft_floor_twelve();
  const auto floor_tets = static_cast<std::int64_t>(scene.shape(0).tets);
  const double share = 100.0 * static_cast<double>(floor_tets) / static_cast<double>(scene.num_tets());
  ASSERT_GT(share, 100.0 / 3) << "a candidate from 3 ranks on";
  ASSERT_LE(share, 37.5) << "three parts on 4 ranks";
  const int parts = n >= 3 ? std::min(n, 3) : 0;
  EXPECT_EQ(split_candidates(scene, n), n >= 3 ? std::vector<int>{0} : std::vector<int>{});
  int checked = 0, migrations = 0;
  expect_identical(
      1,
      [&](Simulator& sim, int s) {
        EXPECT_EQ(sim.split_objects(), parts > 0 ? 1 : 0);
        EXPECT_EQ(sim.split_ranks(), parts);
        if (s % 20 == 0) {
          std::int64_t own = 0;  // tets of this rank's objects other than the floor
          for (int k : sim.world().owned_objects)
            if (k != 0 || parts == 0) own += static_cast<std::int64_t>(sim.scene().shape(static_cast<std::size_t>(k)).tets);
          const std::int64_t floor_here = sim.split_evaluated_tets();
          if (parts > 0 && sim.partition()[0] == comm_rank(MPI_COMM_WORLD))
            EXPECT_GT(floor_here, 0) << "step " << s << ": the floor's owner evaluates a part of it";
          std::int64_t sums[3] = {floor_here, floor_here > 0 ? 1 : 0, own + floor_here};
          std::int64_t most = own + floor_here;
          MPI_Allreduce(MPI_IN_PLACE, sums, 3, MPI_INT64_T, MPI_SUM, MPI_COMM_WORLD);
          MPI_Allreduce(MPI_IN_PLACE, &most, 1, MPI_INT64_T, MPI_MAX, MPI_COMM_WORLD);
          if (parts > 0) {
            EXPECT_EQ(sums[0], floor_tets) << "step " << s << ": floor tets evaluated over the ranks";
            EXPECT_LE(sums[1], parts) << "step " << s << ": ranks evaluating floor tets";
            EXPECT_GE(sums[1], parts - 1) << "step " << s;  // two parts may share a rank, not more
          }
          EXPECT_EQ(sums[2], static_cast<std::int64_t>(scene.num_tets())) << "step " << s;
          const double imbalance = static_cast<double>(most) * n / static_cast<double>(sums[2]);
          if (n > 1) EXPECT_LT(imbalance, 1.25) << "step " << s;
          if (s == 20 && comm_rank(MPI_COMM_WORLD) == 0)
            std::cout << "[measured] " << n << " ranks: floor tets on " << sums[1] << " ranks, tets per rank max / mean "
                      << imbalance << "\n";
          ++checked;
        }
        migrations += migrate_at_step_55(sim, s);
      },
      nullptr, scene);
  EXPECT_EQ(checked, kSteps / 20);
  EXPECT_EQ(migrations, n > 1 ? 1 : 0);
}

// A partition handed to the Simulator with its split hosts (a restart on another rank
// count passes partition_at's): the parts go where the hosts say, not where
// split_hosts' fallback would put them. Here the floor's (3 parts on 4 ranks; on 3,
// one per rank in rank order) other parts are moved to two ranks that split_hosts' fallback would not take both of, and each rank evaluates
// floor tets exactly when it is one of them; hosts of another shape are refused.
TEST(Distributed, GivenPartitionTakesItsSplitHosts) {
  const int n = comm_size(MPI_COMM_WORLD), rank = comm_rank(MPI_COMM_WORLD);
  const Scene& scene = soft_floor_twelve();
  SplitHosts hosts;
  const std::vector<int> partition = partition_at(scene, scene_boxes(scene), n, {}, MPI_COMM_WORLD, &hosts);
  if (n < 3) {
    EXPECT_TRUE(hosts.empty()) << "no split object below 3 ranks";
    return;
  }
  ASSERT_EQ(hosts.size(), 1u);
  ASSERT_EQ(hosts[0].size(), 3u);
  if (n == 3) {  // as many parts as ranks: one per rank in rank order, nothing to choose
    EXPECT_EQ(hosts[0], (std::vector<int>{0, 1, 2}));
    return;
  }
  ASSERT_EQ(hosts[0][0], partition[0]) << "part 0 on the owner";
  // Two ranks other than the owner, not the pair split_hosts would choose.
  const SplitHosts fallback = split_hosts(scene, partition, n);
  std::vector<int> others;
  for (int r = 0; r < n; ++r)
    if (r != partition[0]) others.push_back(r);
  std::vector<int> chosen;
  for (std::size_t a = 0; a < others.size() && chosen.empty(); ++a)
    for (std::size_t b = a + 1; b < others.size() && chosen.empty(); ++b) {
      const std::vector<int> c{partition[0], others[a], others[b]};
      if (!std::is_permutation(c.begin(), c.end(), fallback[0].begin())) chosen = c;
    }
  ASSERT_EQ(chosen.size(), 3u);
  SplitHosts given{chosen};
  Simulator sim(MPI_COMM_WORLD, scene, partition, given);
  sim.step();
  const bool host = std::find(chosen.begin(), chosen.end(), rank) != chosen.end();
  EXPECT_EQ(sim.split_evaluated_tets() > 0, host) << "rank " << rank << ", hosts " << chosen[0] << " " << chosen[1]
                                                  << " " << chosen[2];
  std::int64_t floor_tets = sim.split_evaluated_tets();
  MPI_Allreduce(MPI_IN_PLACE, &floor_tets, 1, MPI_INT64_T, MPI_SUM, MPI_COMM_WORLD);
  EXPECT_EQ(floor_tets, static_cast<std::int64_t>(scene.shape(0).tets));
  SplitHosts off_owner{{chosen[1], chosen[0], chosen[2]}}, short_list{{chosen[0], chosen[1]}};
  EXPECT_THROW(Simulator(MPI_COMM_WORLD, scene, partition, off_owner), RuntimeFailure);
  EXPECT_THROW(Simulator(MPI_COMM_WORLD, scene, partition, short_list), RuntimeFailure);
}

// The floor's parts where no rank but its owner is near it: no part holds it as a ghost,
// so the owner sends every part its positions, and the results are one rank's to the bit,
// also across a migration of every object to the next rank. No host holds the floor's
// mesh: each was sent its part of it (its tets and their vertices) by the owner, and the
// parts sent, with the owner's own, hold each of the floor's tets once. Only the owner
// keeps the parts of the floor's tets: the owner after the migration takes them from the
// first one, which keeps them no more, so they are computed once. The bytes of these
// messages (bench's set-up figure) are counted alike by their senders and receivers.
TEST(Distributed, SoftFloorSplitWithoutGhostsIsBitwiseOneRanks) {
  const int n = comm_size(MPI_COMM_WORLD), rank = comm_rank(MPI_COMM_WORLD);
  const std::int64_t floor_tets = static_cast<std::int64_t>(soft_floor_far().shape(0).tets);
  int checked = 0, migrations = 0;
  std::int64_t received_before = 0, tets_before = 0;  // part meshes here, their tets on all ranks, so far
  std::int64_t bytes_before[2] = {0, 0};              // the parts' bytes sent and received here, so far
  std::int64_t sim_parts_computed = 0;
  expect_identical(
      1,
      [&](Simulator& sim, int s) {
        if (s == 1 || s == 56) {
          // Every part evaluated here: sent by the owner (on a host), or the owner's own.
          const bool owner = sim.partition()[0] == rank;
          const std::int64_t received = sim.split_part_meshes_received() - received_before;
          EXPECT_EQ(received, n > 1 && !owner ? 1 : 0) << "step " << s;
          EXPECT_EQ(sim.scene().objects[0].mesh.points.empty(), n > 1 && !owner)
              << "step " << s << ": the floor's mesh held off its owner";
          EXPECT_EQ(sim.split_parts_kept(), n > 1 && owner ? 1u : 0u) << "step " << s;
          std::int64_t tets[2] = {sim.split_part_tets_received(), owner ? sim.split_evaluated_tets() : 0};
          MPI_Allreduce(MPI_IN_PLACE, tets, 2, MPI_INT64_T, MPI_SUM, MPI_COMM_WORLD);
          if (n > 1) EXPECT_EQ(tets[0] - tets_before + tets[1], floor_tets) << "step " << s;
          received_before = sim.split_part_meshes_received();
          tets_before = tets[0];
          // The bytes of those messages, counted by their senders and their receivers: the
          // same in all; an owner receives nothing but, after the migration, the parts of
          // every tet (4 bytes each) from the first owner.
          const std::int64_t got = sim.split_part_bytes_received() - bytes_before[1];
          EXPECT_EQ(got, n > 1 && owner && s == 56 ? 4 * floor_tets : owner ? 0 : got) << "step " << s;
          if (n > 1 && !owner) EXPECT_GT(got, 0) << "step " << s;
          std::int64_t bytes[2] = {sim.split_part_bytes_sent() - bytes_before[0], got};
          bytes_before[0] = sim.split_part_bytes_sent();
          bytes_before[1] = sim.split_part_bytes_received();
          MPI_Allreduce(MPI_IN_PLACE, bytes, 2, MPI_INT64_T, MPI_SUM, MPI_COMM_WORLD);
          EXPECT_EQ(bytes[0], bytes[1]) << "step " << s;
        }
        migrations += migrate_at_step_55(sim, s);
        sim_parts_computed = sim.split_parts_computed();
        if (s % 20 != 0) return;
        const auto [helping, from_ghosts] = helping_parts(sim);
        EXPECT_EQ(helping, n - 1) << "step " << s;
        EXPECT_EQ(from_ghosts, 0) << "step " << s;
        ++checked;
      },
      nullptr, soft_floor_far());
  EXPECT_EQ(checked, kSteps / 20);
  EXPECT_EQ(migrations, n > 1 ? 1 : 0);
  std::int64_t computed = sim_parts_computed;
  MPI_Allreduce(MPI_IN_PLACE, &computed, 1, MPI_INT64_T, MPI_SUM, MPI_COMM_WORLD);
  EXPECT_EQ(computed, n > 1 ? 1 : 0) << "the parts computed by the first owner only";
}

// The floor's elastic energy and inverted tets when it is split: its owner holds no rest
// data of the whole floor (ElasticForces' held_elsewhere) and measures it from the floor's
// rest mesh. The diagnostics must be one rank's to the bit (the floor is pressed by the
// balls by then: its energy is not zero).
TEST(Distributed, SplitFloorsElasticEnergyIsOneRanksToTheBit) {
  const Scene& scene = soft_floor();
  Simulator one(MPI_COMM_SELF, scene);
  Simulator all(MPI_COMM_WORLD, scene);
  for (int s = 1; s <= 60; ++s) {
    one.step();
    all.step();
    if (s % 20 != 0) continue;
    StepDiagnostics a, b;
    one.measure(a, nullptr);
    all.measure(b, nullptr);
    EXPECT_GT(a.elastic_energy, 0.0);
    EXPECT_EQ(std::memcmp(&a.elastic_energy, &b.elastic_energy, sizeof(double)), 0)
        << "step " << s << ": " << b.elastic_energy << " on " << comm_size(MPI_COMM_WORLD) << " ranks, "
        << a.elastic_energy << " on one";
    EXPECT_EQ(a.inverted_elements, b.inverted_elements) << "step " << s;
    EXPECT_EQ(std::memcmp(&a.kinetic_energy, &b.kinetic_energy, sizeof(double)), 0) << "step " << s;
  }
  EXPECT_EQ(all.split_objects(), comm_size(MPI_COMM_WORLD) > 1 ? 1 : 0);
}

// What the floor's owner sends its parts per evaluation of the forces (the start and
// each step): per vertex of each other part (a vertex of one of its tets), the velocity
// (3 doubles: the floor has stiffness damping) and, only to a part that does not hold the
// floor as a ghost, the position (3 more). The reference counts the parts' vertices from
// the floor's mesh and its parts (split_tet_parts: by METIS, the default for a floor of
// this size, and by the coordinate bisection with `split_parts: bisection`), not from the
// split's plan.
TEST(Distributed, SplitOwnerSendsPositionsOnlyToPartsWithoutTheGhost) {
  const int n = comm_size(MPI_COMM_WORLD), rank = comm_rank(MPI_COMM_WORLD);
  if (n == 1) GTEST_SKIP() << "nothing is split on one rank";
  constexpr int kRun = 12;
  for (const bool far : {false, true})
  for (const SplitParts how : {SplitParts::automatic, SplitParts::bisection}) {
    SCOPED_TRACE(far ? "balls far above the floor" : "balls on the floor");
    SCOPED_TRACE(how == SplitParts::bisection ? "split_parts: bisection" : "split_parts: auto");
    Scene scene = far ? soft_floor_far() : soft_floor();
    scene.sim.split_parts = how;
    Simulator sim(MPI_COMM_WORLD, scene);
    for (int s = 0; s < kRun; ++s) sim.step();
    ASSERT_EQ(sim.ghost_rebuilds(), 1) << "the ghost set changed: the reference below assumes it did not";
    const int owner = sim.partition()[0];
    const TetMesh& floor = scene.mesh(0);
    const std::vector<std::int32_t> part = split_tet_parts(floor, n, how == SplitParts::bisection ? 0 : kSplitMetisMaxTets);
    std::int64_t vertices = 0;  // sum over the parts q != owner of the vertices of q's tets
    for (int q = 0; q < n; ++q) {
      if (q == owner) continue;
      std::vector<char> touched(floor.num_vertices(), 0);
      for (std::size_t t = 0; t < floor.num_tets(); ++t)
        if (part[t] == q)
          for (int c = 0; c < 4; ++c) touched[static_cast<std::size_t>(floor.tets[4 * t + c])] = 1;
      vertices += std::count(touched.begin(), touched.end(), 1);
    }
    // The owner's figure on every rank, so that rank 0 (which alone prints) reports it.
    std::int64_t sent = rank == owner ? sim.split_bytes_sent() : 0;
    MPI_Allreduce(MPI_IN_PLACE, &sent, 1, MPI_INT64_T, MPI_SUM, MPI_COMM_WORLD);
    const std::int64_t per_vertex = far ? 6 : 3;
    EXPECT_EQ(sent, (kRun + 1) * per_vertex * vertices * static_cast<std::int64_t>(sizeof(double)))
        << "owner rank " << owner << ", " << vertices << " vertices in the other parts";
  }
}

// The waits a step adds to a network's latency: a step that keeps its ghost set waits on
// its neighbours 7 times, the two position updates of the halo and the contact
// response's 5 exchanges (docs/architecture.md, "Parallel step"; 9 times before
// 2026-11-29, and each exchange was then two messages: sizes, then bytes), and not at
// all on a rank without neighbours.
TEST(Distributed, AStepWaitsOnItsNeighboursSevenTimes) {
  const int n = comm_size(MPI_COMM_WORLD);
  if (n == 1) GTEST_SKIP() << "no neighbours on one rank";
  Simulator sim(MPI_COMM_WORLD, pile());
  ASSERT_EQ(sim.split_objects(), 0) << "a split object adds its exchanges: the count below assumes none";
  std::int64_t counted = 0, with_neighbours = 0;
  for (int s = 1; s <= kSteps; ++s) {
    const std::int64_t rounds = sim.halo_rounds(), rebuilds = sim.ghost_rebuilds();
    sim.step();
    if (sim.ghost_rebuilds() != rebuilds) continue;  // a rebuild sends the whole rows again
    const std::int64_t step_rounds = sim.halo_rounds() - rounds;
    EXPECT_TRUE(step_rounds == 0 || step_rounds == 7) << "step " << s << ": " << step_rounds << " rounds";
    ++counted;
    with_neighbours += step_rounds == 7;
  }
  MPI_Allreduce(MPI_IN_PLACE, &with_neighbours, 1, MPI_INT64_T, MPI_SUM, MPI_COMM_WORLD);
  EXPECT_GT(counted, kSteps / 2) << "most steps rebuilt the ghost set: the test proves little";
  EXPECT_GT(with_neighbours, 0) << "no rank had neighbours: the test proves nothing";
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
    sim.migrate(s == 35 ? next : initial_partition(sim.scene(), n));
    ++migrations;
  });
  EXPECT_EQ(migrations, 2);
}

namespace {

// The check of the whole scene on one process, every 5 steps of a one-rank run (rank 0
// alone, one thread): verify_frame on verify_mesh_of(scene) with the run's positions and
// velocities (the path of `softcontact verify`, no rank-local mesh), and the run's own
// Simulator::verify(true) for what only the run knows (deep_by_record).
struct WholeCheck {
  VerifyFrame whole, run;
};
const std::vector<WholeCheck>& whole_scene_checks() {
  static std::vector<WholeCheck> checks;
  static bool done = false;
  if (done) return checks;
  done = true;
  if (comm_rank(MPI_COMM_WORLD) != 0) return checks;
  const Scene& scene = pile();
  const VerifyMesh mesh = verify_mesh_of(scene);
  VerifyOptions opt;
  opt.interior = opt.crossings = true;
  opt.self = scene.sim.self_collisions;
  opt.free_fall_speed = free_fall_speed(scene);
  omp_set_num_threads(1);
  Simulator sim(MPI_COMM_SELF, scene);
  for (int s = 1; s <= kSteps; ++s) {
    sim.step();
    if (s % 5 != 0) continue;
    const World& w = sim.world();
    std::vector<double> x(w.x.size()), v(w.v.size());
    for (std::size_t i = 0; i < w.n_local(); ++i)
      for (std::size_t d = 0; d < 3; ++d) {
        x[3 * static_cast<std::size_t>(w.vertex_gid[i]) + d] = w.x[3 * i + d];
        v[3 * static_cast<std::size_t>(w.vertex_gid[i]) + d] = w.v[3 * i + d];
      }
    WholeCheck c;
    c.whole = verify_frame(mesh, x.data(), v.data(), opt);
    c.whole.step = s;
    c.whole.time = sim.time();
    c.run = sim.verify(true);
    checks.push_back(c);
  }
  return checks;
}

}  // namespace

// The in-run check split over the ranks (Simulator::verify: each rank checks its own
// objects against its own and ghost objects, the parts merged) equals the check of the
// whole scene on one process (whole_scene_checks) to the bit, every field, every 5 steps,
// across ghost-set changes and a migration of every object at step 35; so does
// residual_surface_depth. The pile has surface vertices inside other bodies and surface
// crossings at some of those steps (no interior vertex inside), so the figures compared
// are not just 0.
TEST(Distributed, InRunCheckWithoutGatherEqualsTheWholeScenesCheck) {
  const int n = comm_size(MPI_COMM_WORLD);
  const std::vector<WholeCheck>& ref = whole_scene_checks();
  std::size_t k = 0;
  std::int64_t inside = 0, interior = 0, crossings = 0;
  expect_identical(1, [&](Simulator& sim, int s) {
    if (s == 35) {
      std::vector<int> next = sim.partition();
      for (int& r : next) r = (r + 1) % n;
      sim.migrate(next);
    }
    if (s % 5 != 0) return;
    const VerifyFrame got = sim.verify(true);
    const double residual = sim.residual_surface_depth();
    if (comm_rank(MPI_COMM_WORLD) == 0) {
      ASSERT_LT(k, ref.size());
      // The one-rank run's own check is the whole scene's too, and the split one is both.
      VerifyFrame whole = ref[k].whole;
      std::copy_n(ref[k].run.deep_by_record, kRecordStatuses, whole.deep_by_record);
      EXPECT_EQ(std::memcmp(&ref[k].run, &whole, sizeof whole), 0)
          << "one rank, step " << s << "\n  run:   " << to_json(ref[k].run) << "\n  whole: " << to_json(whole);
      EXPECT_EQ(std::memcmp(&got, &whole, sizeof whole), 0)
          << n << " ranks, step " << s << "\n  split: " << to_json(got) << "\n  whole: " << to_json(whole);
      EXPECT_EQ(residual, whole.surface_depth()) << "step " << s;
      inside += whole.surface.count;
      interior += whole.interior.count;
      crossings += whole.crossings.count;
    }
    ++k;
  });
  if (comm_rank(MPI_COMM_WORLD) == 0) {
    EXPECT_EQ(k, ref.size());
    EXPECT_GT(inside, 0);
    EXPECT_GT(crossings, 0);
    std::cout << "[measured] over " << k << " checks: " << inside << " surface vertices inside, " << interior
              << " interior ones, " << crossings << " crossings\n";
  }
}

TEST(Distributed, RebalancePolicyRepartitionsWithoutChangingResults) {
  std::int64_t repartitions = 0;
  expect_identical(1, [&](Simulator& sim, int s) {
    if (s == 1) sim.set_rebalance_policy(RebalancePolicy{25, 0.0, 0.0});  // any imbalance triggers
    repartitions = sim.repartitions();
  });
  if (comm_size(MPI_COMM_WORLD) > 1) EXPECT_GE(repartitions, 4);
}

TEST(Distributed, Hdf5WrittenByAllRanksEqualsOneRankDatasetByDataset) {
  const int rank = comm_rank(MPI_COMM_WORLD), n = comm_size(MPI_COMM_WORLD);
  const std::filesystem::path dir = test::scratch_dir("sc_dist");
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
    EXPECT_GT(test::expect_same_output(dir / "one", dir / "all", "between 1 and " + std::to_string(n) + " ranks", 3), 10);
    std::filesystem::remove_all(dir);
  }
}
