// Which meshes a scene holds (scene.hpp: Placement, Scene::mesh, Scene::drop_meshes): a
// copy made again from its entry's mesh is bitwise the copy placed by the parser, a
// single-copy entry's mesh made again from its file or primitive is the mesh read first, and a
// scene loaded without its copies' meshes knows every object's counts and box all the same.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "softcontact/error.hpp"
#include "softcontact/forces.hpp"
#include "softcontact/mesh_io.hpp"
#include "softcontact/primitives.hpp"
#include "softcontact/scene.hpp"
#include "softcontact/surface.hpp"

using namespace softcontact;

namespace {

// The simulation and material of both test scenes.
const std::string kHeader = R"(simulation:
  dt: auto
  steps: 10
materials:
  - {name: rubber, model: corotational, young: 1.0e5, poisson: 0.3, density: 1000}
objects:
)";

const std::string kScene = kHeader + R"(  - name: floor
    material: rubber
    primitive: {type: plate, size: [3, 3], thickness: 0.1, cells: [6, 6]}
    transform: {translate: [0, 0, -0.05]}
    kinematic: true
  - name: box
    material: rubber
    primitive: {type: box, size: [0.2, 0.2, 0.2], cells: [2, 2, 2]}
    transform: {rotate: {axis: [1, 1, 0], angle: 17}, translate: [-1, -1, 0.3]}
    instances: {grid: {count: [3, 2, 1], spacing: [0.37, 0.41, 0]}}
  - name: ball
    material: rubber
    primitive: {type: sphere, radius: 0.1, resolution: 3}
    instances: {random: {count: 12, seed: 5, rotate: true, region: {min: [-1, -1, 0.6], max: [1, 1, 1.4]}}}
)";

SceneLimits lean() {
  SceneLimits l;
  l.hold_copy_meshes = false;
  return l;
}

Box box_of(const TetMesh& m) {
  Box b = Box::none();
  for (std::size_t i = 0; i < m.num_vertices(); ++i) add_point(b, &m.points[3 * i]);
  return b;
}

}  // namespace

TEST(SceneObjects, CopiesMadeOnDemandAreBitwiseThePlacedOnes) {
  const Scene held = load_scene_from_string(kScene, "scene.yaml");
  const Scene made = load_scene_from_string(kScene, "scene.yaml", lean());
  ASSERT_EQ(held.objects.size(), 1u + 6u + 12u);
  ASSERT_EQ(made.objects.size(), held.objects.size());
  EXPECT_EQ(made.num_vertices(), held.num_vertices());
  EXPECT_EQ(made.num_tets(), held.num_tets());
  // The stable step runs over every copy's own (rotated) tets: the same to the bit.
  EXPECT_EQ(made.sim.dt, held.sim.dt);
  for (std::size_t k = 0; k < held.objects.size(); ++k) {
    const TetMesh& h = held.objects[k].mesh;
    // Only the single-copy floor is held by the lean scene before anyone asks.
    EXPECT_EQ(made.objects[k].mesh.points.empty(), k > 0) << held.objects[k].name;
    const ObjectShape& s = made.shape(k);
    EXPECT_EQ(s.vertices, h.num_vertices());
    EXPECT_EQ(s.tets, h.num_tets());
    EXPECT_EQ(s.triangles, extract_surface(h).num_triangles()) << held.objects[k].name;
    const Box b = box_of(h);
    EXPECT_EQ(s.box.lo, b.lo);
    EXPECT_EQ(s.box.hi, b.hi);
    {
      const Scene::MeshView v = made.view_mesh(k);
      EXPECT_EQ(v.get().points, h.points) << held.objects[k].name;
      EXPECT_EQ(v.get().tets, h.tets);
    }
    EXPECT_EQ(made.objects[k].mesh.points.empty(), k > 0) << "a view must not hold the mesh";
    EXPECT_EQ(made.mesh(k).points, h.points);
    EXPECT_FALSE(made.objects[k].mesh.points.empty()) << "Scene::mesh holds what it made";
  }
}

// An independent reference for the grid copies: copy 0 sits at offset 0, so copy (i, j)
// must be copy 0 plus (i * 0.37, j * 0.41, 0), added once in floating point.
TEST(SceneObjects, GridCopiesAreTheFirstCopyMovedByTheirOffset) {
  const Scene made = load_scene_from_string(kScene, "scene.yaml", lean());
  const TetMesh first = made.mesh(1);
  for (int j = 0; j < 2; ++j)
    for (int i = 0; i < 3; ++i) {
      const TetMesh& m = made.mesh(static_cast<std::size_t>(1 + 3 * j + i));
      const double off[3] = {i * 0.37, j * 0.41, 0 * 0.0};
      ASSERT_EQ(m.points.size(), first.points.size());
      for (std::size_t p = 0; p < m.points.size(); ++p) ASSERT_EQ(m.points[p], first.points[p] + off[p % 3]) << i << " " << j;
    }
}

TEST(SceneObjects, DropMeshesDropsEveryMeshItCanMakeAgain) {
  const Scene held = load_scene_from_string(kScene, "scene.yaml");
  std::vector<char> keep(held.objects.size(), 0);
  keep[3] = 1;
  for (std::size_t k = 0; k < held.objects.size(); ++k) (void)held.surface(k);
  const std::size_t bytes = held.drop_meshes(keep);
  // 18 objects dropped (all but copy 3: the single-copy floor too, made again from its
  // primitive), each with its surface, and the ball entry's mesh (no ball is kept); the
  // box entry's mesh stays for copy 3.
  std::size_t expected = 0;
  const Scene fresh = load_scene_from_string(kScene, "scene.yaml");
  for (std::size_t k = 0; k < fresh.objects.size(); ++k) {
    if (k == 3) continue;
    const TetMesh& m = fresh.objects[k].mesh;
    const Surface s = extract_surface(m);
    expected += m.points.size() * sizeof(double) + m.tets.size() * sizeof(index_t) +
                (s.triangles.size() + s.vertices.size()) * sizeof(index_t);
  }
  const TetMesh& ball = fresh.objects[7].placement.base->get();
  expected += ball.points.size() * sizeof(double) + ball.tets.size() * sizeof(index_t);
  EXPECT_GE(bytes, expected);
  EXPECT_LE(bytes, expected + expected / 4) << "capacity beyond the sizes";
  EXPECT_FALSE(held.objects[3].mesh.points.empty());
  EXPECT_EQ(held.objects[0].placement.kind, Placement::Kind::entry);
  EXPECT_FALSE(held.objects[0].placement.base->held()) << "a single-copy entry's object holds its mesh, not the entry";
  EXPECT_TRUE(held.objects[1].placement.base->held()) << "copy 3 is placed from the box entry's mesh";
  EXPECT_FALSE(held.objects[7].placement.base->held()) << "no ball is kept";
  for (std::size_t k = 0; k < held.objects.size(); ++k) {
    if (k != 3) {
      EXPECT_TRUE(held.objects[k].mesh.points.empty()) << k;
      EXPECT_EQ(held.objects[k].surface, nullptr) << k;
    }
    EXPECT_EQ(held.shape(k).tets, fresh.objects[k].mesh.num_tets());
    EXPECT_EQ(held.mesh(k).points, fresh.objects[k].mesh.points) << k;
    EXPECT_EQ(held.mesh(k).tets, fresh.objects[k].mesh.tets) << k;
    EXPECT_EQ(held.surface(k).triangles, extract_surface(fresh.objects[k].mesh).triangles) << k;
  }
  EXPECT_FALSE(held.objects[0].placement.base->held()) << "made again for the object, not held twice";
}

// A hand-made object (no recipe) is never dropped.
TEST(SceneObjects, DropMeshesKeepsWhatCannotBeMadeAgain) {
  Scene s = load_scene_from_string(kScene, "scene.yaml");
  s.objects[0].placement = Placement{};
  const std::vector<double> points = s.objects[0].mesh.points;
  (void)s.drop_meshes(std::vector<char>(s.objects.size(), 0));
  EXPECT_EQ(s.objects[0].mesh.points, points);
  EXPECT_TRUE(s.objects[1].mesh.points.empty());
}

namespace {

// Writes a scene whose single-copy entry and grid entry read one mesh file, in `dir`.
std::string write_file_scene(const std::filesystem::path& dir, const TetMesh& mesh) {
  std::filesystem::create_directories(dir);
  write_gmsh((dir / "block.msh").string(), mesh, GmshFormat::v41_ascii);
  const std::string path = (dir / "scene.yaml").string();
  std::ofstream(path) << kHeader << R"(  - name: slab
    material: rubber
    mesh: block.msh
    transform: {scale: [2, 1, 0.5], rotate: [10, 20, 30], translate: [0.1, 0.2, 0.3]}
  - name: block
    material: rubber
    mesh: block.msh
    transform: {translate: [0, 0, 1]}
    instances: {grid: {count: [2, 1, 1], spacing: [0.5, 0, 0]}}
)";
  return path;
}

}  // namespace

// A mesh file read again is the mesh first read, to the bit; a file changed during the run
// is a RuntimeFailure that names the object, never another body.
TEST(SceneObjects, MeshFilesReadAgainAreBitwiseTheFirstAndAChangeIsAnError) {
  const auto dir = std::filesystem::path(testing::TempDir()) / "softcontact_scene_objects";
  const std::string path = write_file_scene(dir, make_box(0.3, 0.2, 0.1, 3, 2, 2));
  const Scene fresh = load_scene(path);
  const Scene s = load_scene(path, lean());
  ASSERT_EQ(s.objects.size(), 3u);
  EXPECT_EQ(s.objects[0].placement.kind, Placement::Kind::entry);
  (void)s.drop_meshes({0, 0, 0});
  for (std::size_t k = 0; k < 3; ++k) {
    EXPECT_TRUE(s.objects[k].mesh.points.empty()) << k;
    EXPECT_EQ(s.mesh(k).points, fresh.objects[k].mesh.points) << k;
    EXPECT_EQ(s.mesh(k).tets, fresh.objects[k].mesh.tets) << k;
  }
  (void)s.drop_meshes({0, 0, 0});
  EXPECT_FALSE(s.objects[1].placement.base->held());
  // One vertex moved by a rounding step: not the same mesh.
  TetMesh changed = make_box(0.3, 0.2, 0.1, 3, 2, 2);
  changed.points[4] = std::nextafter(changed.points[4], 1.0);
  write_gmsh((dir / "block.msh").string(), changed, GmshFormat::v41_ascii);
  for (std::size_t k : {0u, 1u}) {
    try {
      (void)s.mesh(k);
      FAIL() << "a changed mesh file was taken for object " << k;
    } catch (const RuntimeFailure& e) {
      EXPECT_NE(std::string(e.what()).find(k == 0 ? "object 'slab' (block.msh)" : "object 'block' (block.msh)"),
                std::string::npos)
          << e.what();
      EXPECT_NE(std::string(e.what()).find("changed"), std::string::npos) << e.what();
    }
  }
  std::filesystem::remove(dir / "block.msh");
  EXPECT_THROW((void)s.mesh(2), RuntimeFailure) << "a removed mesh file";
  std::filesystem::remove_all(dir);
}

namespace {

// Four random entries: two in one region (the second must avoid the first's copies, so
// the two are one group), two in regions of their own, and a grid and a floor between.
const std::string kRegions = kHeader + R"(  - name: floor
    material: rubber
    primitive: {type: plate, size: [9, 3], thickness: 0.1, cells: [9, 3]}
    transform: {translate: [0, 0, -0.05]}
    kinematic: true
  - name: a
    material: rubber
    primitive: {type: sphere, radius: 0.1, resolution: 3}
    instances: {random: {count: 15, seed: 3, rotate: true, region: {min: [-4.5, -1, 0], max: [-2.5, 1, 1]}}}
  - name: grid
    material: rubber
    primitive: {type: box, size: [0.2, 0.2, 0.2], cells: [2, 2, 2]}
    transform: {translate: [-3.5, 0, 0.3]}
    instances: {grid: {count: [2, 2, 1], spacing: [0.3, 0.3, 0]}}
  - name: b
    material: rubber
    primitive: {type: box, size: [0.15, 0.1, 0.2], cells: [1, 1, 2]}
    instances: {random: {count: 12, seed: 4, rotate: true, region: {min: [-4.5, -1, 0], max: [-2.5, 1, 1]}}}
  - name: c
    material: rubber
    primitive: {type: sphere, radius: 0.1, resolution: 3}
    instances: {random: {count: 10, seed: 5, rotate: true, region: {min: [0, -1, 0], max: [1, 1, 0.6]}}}
  - name: d
    material: rubber
    primitive: {type: sphere, radius: 0.12, resolution: 3}
    instances: {random: {count: 8, seed: 6, region: {min: [3, -1, 0], max: [4, 1, 0.6]}}}
)";

// What each of `parts` ranks places of `text` (its SceneLimits::gather argument): every
// part loaded once, its gather returning only its own records.
std::vector<std::vector<double>> placed_by_each(const std::string& text, int parts) {
  std::vector<std::vector<double>> mine(static_cast<std::size_t>(parts));
  for (int p = 0; p < parts; ++p) {
    SceneLimits l = lean();
    l.part = p;
    l.parts = parts;
    l.gather = [&mine, p](const std::vector<double>& v) {
      mine[static_cast<std::size_t>(p)] = v;
      return v;
    };
    try {
      (void)load_scene_from_string(text, "scene.yaml", l);
    } catch (const InputError&) {
      // a part whose own region is full: the real error comes with every part's records
    }
  }
  return mine;
}

// Part p of `parts` loading `text`, its gather giving what MPI_Allgatherv would: every
// part's records in part order.
Scene load_as_part(const std::string& text, int p, int parts, const std::vector<std::vector<double>>& mine) {
  SceneLimits l = lean();
  l.part = p;
  l.parts = parts;
  l.gather = [&mine, p](const std::vector<double>& v) {
    EXPECT_EQ(v, mine[static_cast<std::size_t>(p)]) << "a part places the same again";
    std::vector<double> all;
    for (const auto& m : mine) all.insert(all.end(), m.begin(), m.end());
    return all;
  };
  return load_scene_from_string(text, "scene.yaml", l);
}

}  // namespace

// Random placement shared over ranks (SceneLimits::gather): every part ends with every
// copy bitwise where one part alone places it (the reference: the scene loaded without
// sharing, meshes held), and the independent regions are spread over the parts.
TEST(SceneObjects, RandomPlacementSharedOverPartsIsBitwiseOnePartsPlacement) {
  const Scene one = load_scene_from_string(kRegions, "scene.yaml");
  ASSERT_EQ(one.objects.size(), 1u + 15u + 4u + 12u + 10u + 8u);
  for (int parts : {2, 3, 4, 5}) {
    const auto mine = placed_by_each(kRegions, parts);
    // Three groups ({a, b}, {c}, {d}): each part with a group places something, and no
    // copy is placed twice (18 doubles a copy, 5 an entry).
    std::size_t busy = 0, doubles = 0;
    for (const auto& m : mine) {
      busy += m.empty() ? 0 : 1;
      doubles += m.size();
    }
    EXPECT_EQ(busy, std::min<std::size_t>(static_cast<std::size_t>(parts), 3)) << parts << " parts";
    EXPECT_EQ(doubles, 18u * (15 + 12 + 10 + 8) + 5u * 4) << parts << " parts";
    for (int p = 0; p < parts; ++p) {
      const Scene s = load_as_part(kRegions, p, parts, mine);
      ASSERT_EQ(s.objects.size(), one.objects.size());
      EXPECT_EQ(s.sim.dt, one.sim.dt);
      for (std::size_t k = 0; k < one.objects.size(); ++k) {
        const TetMesh& ref = one.objects[k].mesh;
        const Box b = box_of(ref);
        EXPECT_EQ(s.shape(k).box.lo, b.lo) << parts << " parts, part " << p << ", " << one.objects[k].name;
        EXPECT_EQ(s.shape(k).box.hi, b.hi) << one.objects[k].name;
        EXPECT_EQ(s.view_mesh(k).get().points, ref.points) << parts << " parts, part " << p << ", " << one.objects[k].name;
      }
    }
  }
}

// A full region is reported by every part alike, at its entry's line, whichever part
// placed it: the first full region in scene order, as one part placing all would say.
TEST(SceneObjects, FullRegionIsReportedByEveryPartAtItsEntry) {
  std::string text = kRegions;
  const std::string from = "count: 8, seed: 6", to = "count: 400, seed: 6";  // entry d
  text.replace(text.find(from), from.size(), to);
  const std::string line = std::to_string(1 + std::count(text.begin(), text.begin() + static_cast<std::ptrdiff_t>(text.find("- name: d")), '\n'));
  std::string expected;
  try {
    (void)load_scene_from_string(text, "scene.yaml");
    FAIL() << "400 spheres of radius 0.12 cannot fit a 1 x 2 x 0.6 region";
  } catch (const InputError& e) {
    expected = e.what();
  }
  EXPECT_NE(expected.find("scene.yaml:" + line + ":"), std::string::npos) << expected;
  EXPECT_NE(expected.find("could place only"), std::string::npos) << expected;
  for (int parts : {2, 3}) {
    const auto mine = placed_by_each(text, parts);
    for (int p = 0; p < parts; ++p) {
      try {
        (void)load_as_part(text, p, parts, mine);
        ADD_FAILURE() << "part " << p << " of " << parts << " loaded a scene whose region is full";
      } catch (const InputError& e) {
        EXPECT_EQ(std::string(e.what()), expected) << "part " << p << " of " << parts;
      }
    }
  }
}

// The stable step takes one highest tet frequency per distinct mesh: the copies of an
// entry (grid and random, rotated) are rigid motions of the entry's mesh, so each takes
// the frequency of that mesh, and the parser computes it once per entry, not once per
// copy. Reference: every copy's placed mesh, tet by tet (tet_max_frequency here, not the
// parser's path); placing rounds, so the two agree to a few ulps, not bitwise. Shared
// over two parts (SceneLimits::sum), each part computes its share of the three distinct
// meshes (the box entry, the ball entry, the single cube) and the sum gives every part
// the one-part step bitwise.
TEST(SceneObjects, CopiesOfAnEntryTakeTheFrequencyOfItsMesh) {
  const std::string text = kScene + R"(  - name: cube
    material: rubber
    primitive: {type: box, size: [0.3, 0.2, 0.25], cells: [2, 1, 2]}
    transform: {translate: [1.2, 1.2, 0.3]}
)";
  const Scene one = load_scene_from_string(text, "scene.yaml");
  ASSERT_EQ(one.objects.size(), 1u + 6u + 12u + 1u);
  double wmax = 0;
  for (std::size_t k = 0; k < one.objects.size(); ++k) {
    if (one.objects[k].kinematic()) continue;
    const TetMesh& m = one.objects[k].mesh;
    for (std::size_t t = 0; t < m.num_tets(); ++t) {
      double X[12];
      for (int c = 0; c < 4; ++c)
        for (int d = 0; d < 3; ++d) X[3 * c + d] = m.points[3 * static_cast<std::size_t>(m.tets[4 * t + c]) + d];
      wmax = std::max(wmax, tet_max_frequency(X, one.materials[0]));
    }
  }
  ASSERT_GT(wmax, 0);
  EXPECT_NEAR(stable_time_step(one), 2 / wmax, 1e-12 * (2 / wmax));
  EXPECT_EQ(one.sim.dt, one.sim.dt_safety * stable_time_step(one)) << "the run's step and stable_step agree";

  // Two parts whose `sum` is an MPI_Allreduce, simulated one collective at a time (each
  // part run again up to its next call, the calls before answered with both parts'
  // vectors added). The calls: the single-copy entries' measures (the floor, object 0, made
  // by part 0; the cube, object 19, by part 1; kMadeWords each), then the frequencies of
  // the copies' entries (the box's on part 0, the ball's on part 1; the cube's was
  // measured by its maker), and no more (every object has its shape then).
  struct StopAtCall {};
  std::vector<std::vector<double>> calls[2];
  const auto added = [&calls](std::size_t c) {
    std::vector<double> v = calls[0][c];
    for (std::size_t k = 0; k < v.size(); ++k) v[k] += calls[1][c][k];
    return v;
  };
  const auto run_part = [&](int p, bool record) {
    SceneLimits l = lean();
    l.part = p;
    l.parts = 2;
    std::size_t call = 0;
    l.sum = [&, p, record](std::vector<double>& v) {
      if (call < calls[p].size()) {
        EXPECT_EQ(v, calls[p][call]) << "part " << p << ": the same call again";
        v = added(call++);
        return;
      }
      ASSERT_TRUE(record) << "part " << p << ": a call more than recorded";
      calls[p].push_back(v);
      throw StopAtCall{};
    };
    return load_scene_from_string(text, "scene.yaml", l);
  };
  for (bool stopped = true; stopped;) {
    stopped = false;
    for (int p : {0, 1}) {
      try {
        (void)run_part(p, true);
      } catch (const StopAtCall&) {
        stopped = true;
      }
    }
    ASSERT_EQ(calls[0].size(), calls[1].size()) << "the parts make the same calls";
    ASSERT_LE(calls[0].size(), 3u);
  }
  ASSERT_EQ(calls[0].size(), 2u);
  const auto written = [&](int p, std::size_t c, std::size_t lo, std::size_t hi) {
    std::size_t n = 0;
    for (std::size_t k = lo; k < hi; ++k) n += calls[p][c][k] != 0 ? 1 : 0;
    return n;
  };
  const std::size_t words = calls[0][0].size() / 2;
  ASSERT_EQ(calls[0][0].size(), 2 * words) << "two single-copy entries";
  EXPECT_GT(written(0, 0, 0, words), 0u) << "part 0 measures the floor";
  EXPECT_EQ(written(0, 0, words, 2 * words), 0u) << "part 0 does not make the cube";
  EXPECT_EQ(written(1, 0, 0, words), 0u) << "part 1 does not make the floor";
  EXPECT_GT(written(1, 0, words, 2 * words), 0u) << "part 1 measures the cube";
  ASSERT_EQ(calls[0][1].size(), one.objects.size());
  EXPECT_EQ(written(0, 1, 0, one.objects.size()), 1u) << "part 0: the box entry, once";
  EXPECT_NE(calls[0][1][1], 0) << "the box entry's first copy";
  EXPECT_EQ(written(1, 1, 0, one.objects.size()), 1u) << "part 1: the ball entry, once";
  EXPECT_NE(calls[1][1][7], 0) << "the ball entry's first copy";
  for (int p : {0, 1}) {
    const Scene both = run_part(p, false);
    EXPECT_EQ(both.sim.dt, one.sim.dt) << "part " << p;
    for (std::size_t k = 0; k < one.objects.size(); ++k) {
      EXPECT_EQ(both.objects[k].shape->triangles, extract_surface(one.objects[k].mesh).num_triangles()) << k;
      EXPECT_EQ(both.objects[k].shape->tets, one.objects[k].mesh.num_tets()) << k;
      EXPECT_EQ(both.objects[k].shape->box.lo, box_of(one.objects[k].mesh).lo) << k;
      EXPECT_EQ(both.objects[k].shape->box.hi, box_of(one.objects[k].mesh).hi) << k;
    }
  }
}
