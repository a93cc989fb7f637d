// Single-copy entries read by one rank each (scene_parser.cpp, MadeOnce): a mesh file that
// only one single-copy entry names, or a primitive, is read (generated) by the rank of its
// object's index, k % ranks; the other ranks learn its counts, box, digest and
// frequencies from that rank and make the mesh only when they need it. Runs under mpiexec
// with 1 to 4 ranks (ctest mpi.npN). The reference is the same scene loaded by this rank
// alone (one part, every mesh held): everything every rank knows must be that, to the bit.
#include <gtest/gtest.h>
#include <mpi.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include "softcontact/error.hpp"
#include "softcontact/forces.hpp"
#include "softcontact/mesh_io.hpp"
#include "softcontact/mpi_util.hpp"
#include "softcontact/primitives.hpp"
#include "softcontact/run.hpp"
#include "softcontact/scene.hpp"
#include "softcontact/simulator.hpp"
#include "softcontact/stepper.hpp"

using namespace softcontact;

namespace {

std::uint64_t bits(double x) {
  std::uint64_t w;
  std::memcpy(&w, &x, sizeof w);
  return w;
}

std::function<void(std::vector<double>&)> sum_world() {
  return [](std::vector<double>& v) {
    MPI_Allreduce(MPI_IN_PLACE, v.data(), static_cast<int>(v.size()), MPI_DOUBLE, MPI_SUM, MPI_COMM_WORLD);
  };
}

// The scene's directory, written by rank 0: three mesh files used once each (one with an
// inverted tet and one with a vertex no tet uses, so that reading them warns), one file
// named by a single-copy entry and a grid entry (read by every rank, shared), primitives
// (a kinematic floor, a sphere, a torus), and a broken file for the error cases.
std::filesystem::path scene_dir() {
  static const std::filesystem::path dir = [] {
    const auto d = std::filesystem::temp_directory_path() / "softcontact_mpi_single_copy_read";
    if (comm_rank(MPI_COMM_WORLD) == 0) {
      std::filesystem::create_directories(d);
      write_gmsh((d / "a.msh").string(), make_box(0.2, 0.2, 0.2, 3, 3, 3), GmshFormat::v41_binary);
      TetMesh b = make_box(0.3, 0.1, 0.2, 3, 1, 2);
      std::swap(b.tets[2], b.tets[3]);  // tet 1 inverted: reoriented, with a warning
      write_gmsh((d / "b.msh").string(), b, GmshFormat::v41_binary);
      TetMesh c = make_box(0.1, 0.2, 0.1, 1, 2, 1);
      c.points.insert(c.points.end(), {5.0, 5.0, 5.0});  // used by no tet: removed, with a warning
      write_gmsh((d / "c.msh").string(), c, GmshFormat::v41_binary);
      write_gmsh((d / "shared.msh").string(), make_box(0.1, 0.1, 0.1, 1, 1, 1), GmshFormat::v41_binary);
      std::ofstream(d / "broken.msh") << "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$Nodes\n1 8 1 8\nnot a number\n";
    }
    MPI_Barrier(MPI_COMM_WORLD);
    return d;
  }();
  return dir;
}

const char* kHead = R"(simulation: {dt: auto, steps: 10}
materials:
  - {name: rubber, model: corotational, young: 1.0e5, poisson: 0.3, density: 1000}
  - {name: stiff, model: neohookean, young: 4.0e6, poisson: 0.4, density: 1200}
objects:
)";

// Object indices: 0 floor, 1 a, 2 b, 3 grid[0..3] (shared.msh), 7 ball, 8 c, 9 single
// shared.msh (named by the grid too: read by every rank), 10 ring, 11 b_again (b.msh
// again: made by its own rank, b.msh's warning given once, at b).
std::string good_scene() {
  return std::string(kHead) + R"(  - {name: floor, material: rubber, kinematic: true, primitive: {type: plate, size: [4, 2], thickness: 0.1, cells: [8, 4]}, transform: {translate: [0, 0, -0.05]}}
  - {name: a, material: rubber, mesh: a.msh, transform: {rotate: [10, 20, 30], translate: [-1.2, 0, 0.2]}}
  - {name: b, material: stiff, mesh: b.msh, transform: {scale: [1, 2, 0.5], translate: [-0.6, 0, 0.2]}, velocity: [0, 0, -1]}
  - {name: grid, material: rubber, mesh: shared.msh, instances: {grid: {count: [2, 2, 1], spacing: [0.3, 0.3, 0]}}, transform: {translate: [0, -0.5, 0.3]}}
  - {name: ball, material: stiff, primitive: {type: sphere, radius: 0.1, resolution: 3}, transform: {translate: [0.8, 0, 0.3]}}
  - {name: c, material: rubber, mesh: c.msh, transform: {translate: [1.2, 0, 0.2]}}
  - {name: single, material: rubber, mesh: shared.msh, transform: {translate: [1.5, 0.5, 0.2]}}
  - {name: ring, material: rubber, primitive: {type: torus, major_radius: 0.2, minor_radius: 0.05, resolution: 2}, transform: {translate: [0, 0.6, 0.2]}}
  - {name: b_again, material: rubber, mesh: b.msh, transform: {translate: [-0.6, 0.6, 0.2]}}
)";
}

std::string write_scene(const std::string& name, const std::string& text) {
  const std::filesystem::path p = scene_dir() / name;
  if (comm_rank(MPI_COMM_WORLD) == 0) std::ofstream(p) << text;
  MPI_Barrier(MPI_COMM_WORLD);
  return p.string();
}

// What load_scene throws (empty: nothing).
std::string error_of(const std::string& path, const SceneLimits& limits) {
  try {
    (void)load_scene(path, limits);
  } catch (const InputError& e) {
    return e.what();
  }
  return {};
}

// What every rank must know as one rank that read every file itself: the objects'
// counts, boxes (bits), digests, meshes (made again where not held), the warnings and
// the stable step.
void expect_as_one_rank(const Scene& one, const Scene& shared) {
  const int rank = comm_rank(MPI_COMM_WORLD), n = comm_size(MPI_COMM_WORLD);
  ASSERT_EQ(shared.objects.size(), one.objects.size());
  EXPECT_EQ(bits(shared.sim.dt), bits(one.sim.dt));
  EXPECT_EQ(stable_step(shared).object, stable_step(one).object);
  EXPECT_EQ(shared.warnings, one.warnings);
  EXPECT_EQ(shared.object_digests(rank, n, sum_world()), one.object_digests());
  for (std::size_t k = 0; k < one.objects.size(); ++k) {
    SCOPED_TRACE(one.objects[k].name);
    const ObjectShape& want = one.shape(k);
    const ObjectShape& got = shared.shape(k);
    EXPECT_EQ(got.vertices, want.vertices);
    EXPECT_EQ(got.tets, want.tets);
    EXPECT_EQ(got.triangles, want.triangles);
    for (int d = 0; d < 3; ++d) {
      EXPECT_EQ(bits(got.box.lo[d]), bits(want.box.lo[d]));
      EXPECT_EQ(bits(got.box.hi[d]), bits(want.box.hi[d]));
    }
    EXPECT_EQ(shared.view_mesh(k).get().points, one.objects[k].mesh.points) << "made again bitwise";
    EXPECT_EQ(shared.view_mesh(k).get().tets, one.objects[k].mesh.tets);
  }
}

}  // namespace

// Every rank knows every object's counts, box, digest and the stable step exactly as one
// rank that read every file, warnings included; each single-copy entry's mesh is held by
// the one rank that made it, and made again from its file, bitwise, where asked for.
TEST(SingleCopyRead, OneRankMakesEachEntryAndEveryRankKnowsItToTheBit) {
  const std::string path = write_scene("good.yaml", good_scene());
  const Scene one = load_scene(path);
  const Scene shared = load_scene(path, copies_made_on_demand(MPI_COMM_WORLD));
  const int rank = comm_rank(MPI_COMM_WORLD), n = comm_size(MPI_COMM_WORLD);
  ASSERT_EQ(one.objects.size(), 12u);
  ASSERT_EQ(shared.objects.size(), one.objects.size());
  ASSERT_EQ(one.warnings.size(), 2u) << "b.msh and c.msh warn when read";
  EXPECT_NE(one.warnings[0].find("b.msh: warning: 1 inverted"), std::string::npos) << one.warnings[0];
  EXPECT_NE(one.warnings[1].find("c.msh: warning: 1 vertices"), std::string::npos) << one.warnings[1];
  const std::vector<std::size_t> made_once = {0, 1, 2, 7, 8, 10, 11};  // single-copy entries' files, primitives
  long held_here = 0;
  for (std::size_t k : made_once) {
    const bool held = !shared.objects[k].mesh.points.empty();
    EXPECT_EQ(held, static_cast<int>(k % static_cast<std::size_t>(n)) == rank) << one.objects[k].name << " made by rank k % ranks only";
    held_here += held ? 1 : 0;
  }
  long held_all = held_here;
  MPI_Allreduce(MPI_IN_PLACE, &held_all, 1, MPI_LONG, MPI_SUM, MPI_COMM_WORLD);
  EXPECT_EQ(held_all, static_cast<long>(made_once.size())) << "each single-copy mesh made by exactly one rank";
  expect_as_one_rank(one, shared);  // after the holding check: it makes the meshes not held
}

// The scene's edge statistics before the partition (scene_edge_statistics): each object's
// edges measured by the rank that made its mesh, or by rank k % ranks, so that no rank
// makes a mesh it does not hold. The median and mean are, to the bit, those of one rank
// measuring every mesh itself (and the mean scene_mean_edge's, which the detector's cell
// was before), and no rank holds one mesh more afterwards.
TEST(SingleCopyRead, EdgeStatisticsBeforeThePartitionAreOneRanksWithoutHoldingAMeshMore) {
  const std::string path = write_scene("good.yaml", good_scene());
  const Scene one = load_scene(path);
  const Scene shared = load_scene(path, copies_made_on_demand(MPI_COMM_WORLD));
  auto held = [](const Scene& s) {
    std::vector<char> h;
    for (const SceneObject& o : s.objects) h.push_back(o.mesh.points.empty() ? 0 : 1);
    return h;
  };
  const std::vector<char> before = held(shared);
  const EdgeStatistics e = scene_edge_statistics(MPI_COMM_WORLD, shared);
  const EdgeStatistics e_one = scene_edge_statistics(MPI_COMM_SELF, one);
  EXPECT_EQ(bits(e.median), bits(e_one.median));
  EXPECT_EQ(bits(e.mean), bits(e_one.mean));
  EXPECT_EQ(bits(e.mean), bits(scene_mean_edge(one)));
  EXPECT_GT(e.median, 0.0);
  EXPECT_EQ(held(shared), before) << "a rank kept a mesh it measured for the moment";
  // On a communicator of one rank (a reference run of the tests), the makers of the other
  // ranks are not its ranks: this rank measures every object.
  const EdgeStatistics e_self = scene_edge_statistics(MPI_COMM_SELF, shared);
  EXPECT_EQ(bits(e_self.median), bits(e_one.median));
  EXPECT_EQ(bits(e_self.mean), bits(e_one.mean));
  EXPECT_EQ(held(shared), before);
}

// A mesh file that cannot be read, named by an entry another rank reads: every rank stops
// with one rank's message, the first error in scene order as one rank alone would report
// it, also when the YAML of a later entry is wrong too, and the YAML error when it comes
// first.
TEST(SingleCopyRead, AnEntryOneRankCannotReadStopsEveryRankWithOneRanksMessage) {
  const std::string head = std::string(kHead) +
                            "  - {name: floor, material: rubber, kinematic: true, primitive: {type: plate, size: [4, 2], "
                            "thickness: 0.1, cells: [8, 4]}}\n";
  const std::string broken = "  - {name: bad, material: rubber, mesh: broken.msh}\n";
  const std::string fine = "  - {name: fine, material: rubber, mesh: a.msh, transform: {translate: [1, 0, 0.3]}}\n";
  const std::string typo = "  - {name: typo, material: rubber, mesh: c.msh, velocty: [0, 0, 1]}\n";
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"broken.yaml", head + broken + fine},            // the broken file: object 1, rank 1 of 2+
      {"broken_then_typo.yaml", head + broken + typo},  // the mesh's error, not the later YAML's
      {"typo_then_broken.yaml", head + typo + broken},  // the YAML's error, before the mesh's
  };
  for (const auto& [name, text] : cases) {
    SCOPED_TRACE(name);
    const std::string path = write_scene(name, text);
    const std::string alone = error_of(path, SceneLimits{});
    const std::string together = error_of(path, copies_made_on_demand(MPI_COMM_WORLD));
    ASSERT_FALSE(alone.empty());
    EXPECT_EQ(together, alone);
    if (name == "typo_then_broken.yaml") EXPECT_NE(alone.find("velocty"), std::string::npos) << alone;
    else EXPECT_NE(alone.find("broken.msh"), std::string::npos) << alone;
    // Every rank stopped with the same message (compared by its length and first bytes).
    long len = static_cast<long>(together.size()), lo = len, hi = len;
    MPI_Allreduce(MPI_IN_PLACE, &lo, 1, MPI_LONG, MPI_MIN, MPI_COMM_WORLD);
    MPI_Allreduce(MPI_IN_PLACE, &hi, 1, MPI_LONG, MPI_MAX, MPI_COMM_WORLD);
    EXPECT_EQ(lo, hi);
  }
}

// The maker of a single-copy mesh hands it to the object's owner when the Simulator is
// built (Simulator::hand_over_made_meshes): the owner neither reads the file nor needs it;
// the ranks that compute parts of a split object's forces take its mesh from the owner
// (fetch_object_meshes).
// Six boxes 2 m apart, falling (none within reach of another: no ghosts), each its own
// file; the files are moved away after the scene is read, so a rank that read one again
// would fail. Every owned box is held, the run takes 20 steps,
// and on 2+ ranks some box is owned by a rank other than its maker.
TEST(SingleCopyRead, TheMakerHandsItsMeshToTheOwner) {
  const int rank = comm_rank(MPI_COMM_WORLD), n = comm_size(MPI_COMM_WORLD);
  const std::filesystem::path dir = scene_dir() / "apart";
  std::string text = kHead;
  for (int k = 0; k < 6; ++k)
    text += "  - {name: b" + std::to_string(k) + ", material: rubber, mesh: b" + std::to_string(k) +
            ".msh, transform: {translate: [" + std::to_string(-5.0 + 2.0 * k) + ", 0, 0.2]}}\n";
  if (rank == 0) {
    std::filesystem::create_directories(dir);
    // b0 has more tets than the other five together (1,296 against 240): on 2+ ranks it
    // is split for its forces, and every rank needs its mesh.
    for (int k = 0; k < 6; ++k)
      write_gmsh((dir / ("b" + std::to_string(k) + ".msh")).string(),
                 k == 0 ? make_box(0.3, 0.3, 0.3, 6, 6, 6) : make_box(0.3, 0.3, 0.3, 2, 2, 2), GmshFormat::v41_binary);
    std::ofstream(dir / "scene.yaml") << text;
  }
  MPI_Barrier(MPI_COMM_WORLD);
  const Scene scene = load_scene((dir / "scene.yaml").string(), copies_made_on_demand(MPI_COMM_WORLD));
  MPI_Barrier(MPI_COMM_WORLD);
  if (rank == 0)
    for (int k = 0; k < 6; ++k)
      std::filesystem::rename(dir / ("b" + std::to_string(k) + ".msh"), dir / ("b" + std::to_string(k) + ".moved"));
  MPI_Barrier(MPI_COMM_WORLD);
  long handed = 0;
  try {
    Simulator sim(MPI_COMM_WORLD, scene);
    for (int s = 0; s < 20; ++s) sim.step();
    EXPECT_EQ(sim.split_objects(), n > 1 ? 1 : 0) << "b0 split over the ranks (its mesh from its owner)";
    for (int k : sim.world().owned_objects) {
      const SceneObject& o = scene.objects[static_cast<std::size_t>(k)];
      EXPECT_FALSE(o.mesh.points.empty()) << o.name << " owned without its mesh";
      if (n > 1) EXPECT_EQ(o.maker, k % n) << o.name;
      if (o.maker >= 0 && o.maker != rank) ++handed;
    }
  } catch (const std::exception& e) {
    ADD_FAILURE() << "rank " << rank << ": " << e.what();
  }
  MPI_Barrier(MPI_COMM_WORLD);
  if (rank == 0)
    for (int k = 0; k < 6; ++k)
      std::filesystem::rename(dir / ("b" + std::to_string(k) + ".moved"), dir / ("b" + std::to_string(k) + ".msh"));
  MPI_Allreduce(MPI_IN_PLACE, &handed, 1, MPI_LONG, MPI_SUM, MPI_COMM_WORLD);
  if (n > 1) EXPECT_GT(handed, 0) << "no mesh went from its maker to another owner: the test proves nothing";
  if (rank == 0) std::cout << "[measured] single-copy meshes handed from their maker to their owner: " << handed << "\n";
}

namespace {

// Three files named by multi-copy entries (SceneLimits::broadcast): g1.msh by a grid,
// g2.msh (an inverted tet: warns) by random copies, g3.msh (a vertex no tet uses: warns)
// by a single entry first, then by a grid. In order of their first entries they are files
// 0, 1, 2: read by ranks 0, 1 % ranks, 2 % ranks.
std::string copies_scene() {
  const std::filesystem::path d = scene_dir();
  if (comm_rank(MPI_COMM_WORLD) == 0) {
    write_gmsh((d / "g1.msh").string(), make_box(0.2, 0.1, 0.1, 2, 1, 1), GmshFormat::v22_ascii);
    TetMesh g2 = make_box(0.1, 0.1, 0.2, 1, 1, 2);
    std::swap(g2.tets[0], g2.tets[1]);  // tet 0 inverted
    write_gmsh((d / "g2.msh").string(), g2, GmshFormat::v41_binary);
    TetMesh g3 = make_box(0.15, 0.15, 0.1, 2, 2, 1);
    g3.points.insert(g3.points.end(), {3.0, 3.0, 3.0});
    write_gmsh((d / "g3.msh").string(), g3, GmshFormat::v41_ascii);
  }
  return std::string(kHead) + R"(  - {name: floor, material: rubber, kinematic: true, primitive: {type: plate, size: [4, 2], thickness: 0.1, cells: [8, 4]}, transform: {translate: [0, 0, -0.05]}}
  - {name: grid1, material: rubber, mesh: g1.msh, instances: {grid: {count: [2, 1, 1], spacing: [0.4, 0, 0]}}, transform: {translate: [-1, 0, 0.3]}}
  - {name: rand, material: stiff, mesh: g2.msh, instances: {random: {count: 3, region: {min: [0.5, -0.5, 0.3], max: [1.5, 0.5, 0.8]}, seed: 4, rotate: true}}}
  - {name: lone, material: rubber, mesh: g3.msh, transform: {translate: [0, 0.7, 0.3]}}
  - {name: grid3, material: rubber, mesh: g3.msh, instances: {grid: {count: [1, 2, 1], spacing: [0, 0.3, 0]}}, transform: {translate: [0, -0.7, 0.3]}}
)";
}

}  // namespace

// Each file that multi-copy entries name is read by one rank and broadcast: the files read
// over all ranks are the scene's three, each rank reading those of its turn, and every
// rank ends with every object's counts, box, digest, mesh, the warnings and the stable
// step of one rank reading every file itself.
TEST(SharedFileRead, EachFileOfMultiCopyEntriesIsReadByOneRank) {
  const int rank = comm_rank(MPI_COMM_WORLD), n = comm_size(MPI_COMM_WORLD);
  const std::string path = write_scene("copies.yaml", copies_scene());
  const std::uint64_t before_one = mesh_files_read();
  const Scene one = load_scene(path);
  EXPECT_EQ(mesh_files_read() - before_one, 3u) << "one rank alone reads each file once";
  const std::uint64_t before = mesh_files_read();
  const Scene shared = load_scene(path, copies_made_on_demand(MPI_COMM_WORLD));
  const auto here = static_cast<long>(mesh_files_read() - before);
  long want_here = 0;
  for (int j = 0; j < 3; ++j) want_here += j % n == rank ? 1 : 0;
  EXPECT_EQ(here, want_here) << "rank " << rank << " reads the files of its turn only";
  long all = here;
  MPI_Allreduce(MPI_IN_PLACE, &all, 1, MPI_LONG, MPI_SUM, MPI_COMM_WORLD);
  EXPECT_EQ(all, 3) << "each file read once over all ranks";

  ASSERT_EQ(one.objects.size(), 9u);
  ASSERT_EQ(one.warnings.size(), 2u) << "g2.msh and g3.msh warn when read";
  EXPECT_NE(one.warnings[0].find("g2.msh: warning: 1 inverted"), std::string::npos) << one.warnings[0];
  EXPECT_NE(one.warnings[1].find("g3.msh: warning: 1 vertices"), std::string::npos) << one.warnings[1];
  expect_as_one_rank(one, shared);
}

// A file that multi-copy entries name and that cannot be read (broken, or missing), the
// second such file (read by rank 1 of 2+): every rank stops with the message of one rank
// alone; a YAML error before it is reported instead.
TEST(SharedFileRead, AFileItsRankCannotReadStopsEveryRankWithOneRanksMessage) {
  (void)copies_scene();  // writes g1.msh
  const std::string head = std::string(kHead) +
                           "  - {name: row, material: rubber, mesh: g1.msh, instances: {grid: {count: [2, 1, 1], "
                           "spacing: [0.4, 0, 0]}}, transform: {translate: [-1, 0, 0.3]}}\n";
  const std::string broken =
      "  - {name: bad, material: rubber, mesh: broken.msh, instances: {grid: {count: [2, 1, 1], spacing: [0.4, 0, 0]}}}\n";
  const std::string missing =
      "  - {name: gone, material: rubber, mesh: missing.msh, instances: {grid: {count: [2, 1, 1], spacing: [0.4, 0, 0]}}}\n";
  const std::string typo = "  - {name: typo, material: rubber, mesh: c.msh, velocty: [0, 0, 1]}\n";
  const std::vector<std::tuple<std::string, std::string, std::string>> cases = {
      {"grid_broken.yaml", head + broken, "broken.msh"},
      {"grid_missing.yaml", head + missing, "does not exist"},
      {"typo_then_grid_broken.yaml", head + typo + broken, "velocty"},
  };
  for (const auto& [name, text, expected] : cases) {
    SCOPED_TRACE(name);
    const std::string path = write_scene(name, text);
    const std::string alone = error_of(path, SceneLimits{});
    const std::string together = error_of(path, copies_made_on_demand(MPI_COMM_WORLD));
    ASSERT_FALSE(alone.empty());
    EXPECT_NE(alone.find(expected), std::string::npos) << alone;
    EXPECT_EQ(together, alone);
  }
}

// A large single-copy mesh's element frequency computed by all ranks together
// (SceneLimits::scatter): the maker sends its tets' corners out in rounds, each rank takes
// the highest frequency of its pieces. The mesh has one tet stiffer than all others (an
// inner vertex moved), and its file lists the tets rotated so that this tet stands first,
// last, at a round's end or start, or in the middle: wherever it lands, every rank's step
// is bitwise the one of a rank that read the file alone, and its frequency is the
// highest of a direct loop over the tets. The same mesh as a grid entry's, which every
// rank holds, has its tets cut into ranges over the ranks without any message.
TEST(SingleCopyRead, ALargeMeshsFrequencyIsSharedOverTheRanksAndIsTheMakersToTheBit) {
  const int rank = comm_rank(MPI_COMM_WORLD), n = comm_size(MPI_COMM_WORLD);
  TetMesh base = make_box(0.3, 0.3, 0.3, 4, 4, 4);  // 384 tets, spacing 0.075
  const Material probe = [] {
    const Scene s = load_scene_from_string(std::string(kHead) + "  - {name: x, material: rubber, primitive: {type: box, size: [1, 1, 1], cells: [1, 1, 1]}}\n",
                                           "probe.yaml");
    return s.materials[0];
  }();
  // The inner vertex nearest (0.15, 0.15, 0.15) pushed by a quarter of a cell along a
  // generic direction: the tets around it differ, and one of them is the stiffest.
  std::size_t centre = 0;
  double best = 1e9;
  for (std::size_t v = 0; v < base.num_vertices(); ++v) {
    double d = 0;
    for (int c = 0; c < 3; ++c) d += std::abs(base.points[3 * v + c] - 0.15);
    if (d < best) best = d, centre = v;
  }
  const double push[3] = {0.019, 0.011, -0.007};
  for (int c = 0; c < 3; ++c) base.points[3 * centre + c] += push[c];
  const std::size_t nt = base.num_tets();
  // Each tet's frequency, by a direct loop (the reference).
  const auto frequencies = [&probe](const TetMesh& m) {
    std::vector<double> f(m.num_tets());
    for (std::size_t t = 0; t < f.size(); ++t) {
      double X[12];
      for (int k = 0; k < 4; ++k)
        for (int c = 0; c < 3; ++c) X[3 * k + c] = m.points[3 * static_cast<std::size_t>(m.tets[4 * t + k]) + c];
      f[t] = tet_max_frequency(X, probe);
    }
    return f;
  };
  const std::vector<double> w = frequencies(base);
  const std::size_t stiffest = static_cast<std::size_t>(std::max_element(w.begin(), w.end()) - w.begin());
  std::vector<double> sorted = w;
  std::sort(sorted.rbegin(), sorted.rend());
  ASSERT_GT(sorted[0], 1.01 * sorted[1]) << "one tet is the stiffest, or the test proves nothing";

  const std::int64_t round = 50;  // 384 tets: 8 rounds, the last of 34
  const std::filesystem::path dir = scene_dir() / "spread";
  for (std::size_t at : {std::size_t{0}, nt - 1, std::size_t{49}, std::size_t{50}, std::size_t{99}, nt / 2 + 3, std::size_t{351}}) {
    SCOPED_TRACE("the stiffest tet at " + std::to_string(at));
    TetMesh m = base;
    // tets rotated so that the stiffest stands at `at`
    const std::size_t shift = (stiffest + nt - at) % nt;
    for (std::size_t t = 0; t < nt; ++t)
      for (int k = 0; k < 4; ++k) m.tets[4 * t + k] = base.tets[4 * ((t + shift) % nt) + k];
    if (rank == 0) {
      std::filesystem::create_directories(dir);
      write_gmsh((dir / "big.msh").string(), m, GmshFormat::v41_binary);
      // the big mesh is object 1: made by rank 1 % ranks; the small box (object 2, coarser:
      // it does not set the step) stays below spread_tets
      std::ofstream(dir / "scene.yaml") << std::string(kHead) +
          "  - {name: floor, material: rubber, kinematic: true, primitive: {type: plate, size: [4, 2], thickness: 0.1, cells: [8, 4]}, transform: {translate: [0, 0, -0.05]}}\n"
          "  - {name: big, material: rubber, mesh: big.msh, transform: {rotate: [0, 0, 30], translate: [0, 0, 0.2]}}\n"
          "  - {name: small, material: rubber, primitive: {type: box, size: [0.1, 0.1, 0.1], cells: [1, 1, 1]}, transform: {translate: [1, 0, 0.2]}}\n";
    }
    MPI_Barrier(MPI_COMM_WORLD);
    const std::string path = (dir / "scene.yaml").string();
    const Scene one = load_scene(path);
    SceneLimits l = copies_made_on_demand(MPI_COMM_WORLD);
    l.spread_tets = 100;
    l.spread_round_tets = round;
    long calls = 0, received = 0;
    l.scatter = [&, inner = l.scatter](const std::vector<double>& all, const std::vector<int>& counts, int root) {
      ++calls;
      EXPECT_EQ(root, 1 % n) << "the maker of object 1 sends";
      if (rank == root) EXPECT_EQ(all.size(), 12u * static_cast<std::size_t>(std::min<std::int64_t>(round, static_cast<std::int64_t>(nt) - round * (calls - 1))));
      std::vector<double> piece = inner(all, counts, root);
      received += static_cast<long>(piece.size());
      return piece;
    };
    const Scene shared = load_scene(path, l);
    EXPECT_EQ(bits(shared.sim.dt), bits(one.sim.dt));
    // The reference: a direct loop over the placed mesh's tets, on one rank.
    const TetMesh& placed = one.objects[1].mesh;
    ASSERT_EQ(placed.num_tets(), nt);
    const std::vector<double> wp = frequencies(placed);
    ASSERT_EQ(static_cast<std::size_t>(std::max_element(wp.begin(), wp.end()) - wp.begin()), at) << "the stiffest tet where it was put";
    const StableStep s = stable_step(one);
    ASSERT_EQ(s.object, 1) << "the big mesh sets the step";
    EXPECT_EQ(bits(s.omega_element), bits(wp[at]));
    EXPECT_EQ(calls, n > 1 ? (static_cast<long>(nt) + round - 1) / round : 0) << "one scatter a round, on more than one rank";
    long all_received = received;
    MPI_Allreduce(MPI_IN_PLACE, &all_received, 1, MPI_LONG, MPI_SUM, MPI_COMM_WORLD);
    EXPECT_EQ(all_received, n > 1 ? 12 * static_cast<long>(nt) : 0) << "each tet's corners to one rank";
    if (n > 1) EXPECT_GE(received, 12 * static_cast<long>(nt) / n - 12 * 8) << "an even share on rank " << rank;
    EXPECT_EQ(shared.objects[1].mesh.points.empty(), rank != 1 % n) << "held by its maker only";
    MPI_Barrier(MPI_COMM_WORLD);

    // The same mesh as a grid entry's (its file read by one rank and broadcast, every rank
    // holds it): the ranks cut its tets into consecutive ranges without sending them, each
    // its range's maximum in a slot of its own after the objects' values.
    if (rank == 0) {
      write_gmsh((dir / "grid.msh").string(), m, GmshFormat::v41_binary);
      std::ofstream(dir / "copies.yaml") << std::string(kHead) +
          "  - {name: floor, material: rubber, kinematic: true, primitive: {type: plate, size: [4, 2], thickness: 0.1, cells: [8, 4]}, transform: {translate: [0, 0, -0.05]}}\n"
          "  - {name: grid, material: rubber, mesh: grid.msh, instances: {grid: {count: [3, 1, 1], spacing: [0.5, 0, 0]}}, transform: {translate: [0, 0, 0.2]}}\n";
    }
    MPI_Barrier(MPI_COMM_WORLD);
    const std::string copies = (dir / "copies.yaml").string();
    const Scene one_grid = load_scene(copies);
    const StableStep sg = stable_step(one_grid);
    ASSERT_EQ(sg.object, 1) << "the grid's first copy sets the step";
    SceneLimits lg = copies_made_on_demand(MPI_COMM_WORLD);
    lg.spread_tets = 100;
    std::vector<std::vector<double>> summed;
    lg.sum = [&summed, inner = lg.sum](std::vector<double>& v) {
      inner(v);
      summed.push_back(v);
    };
    const Scene shared_grid = load_scene(copies, lg);
    EXPECT_EQ(bits(shared_grid.sim.dt), bits(one_grid.sim.dt));
    const std::size_t objects = one_grid.objects.size();
    long with_slots = 0;
    for (const auto& v : summed) {
      if (v.size() != objects + static_cast<std::size_t>(n)) continue;
      ++with_slots;
      double w = 0;
      for (int k = 0; k < n; ++k) {
        EXPECT_GT(v[objects + static_cast<std::size_t>(k)], 0) << "rank " << k << " measured its range";
        w = std::max(w, v[objects + static_cast<std::size_t>(k)]);
      }
      EXPECT_EQ(bits(w), bits(sg.omega_element)) << "the ranges' maximum is the whole mesh's";
      EXPECT_EQ(v[1], 0) << "the grid's value is not computed whole as well";
    }
    EXPECT_EQ(with_slots, n > 1 ? 1 : 0) << "one sum with a slot per rank, on more than one rank";
  }
}
