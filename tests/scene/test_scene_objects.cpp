// Which meshes a scene holds (scene.hpp: Placement, Scene::mesh, Scene::drop_meshes): a
// copy made again from its entry's mesh is bitwise the copy placed by the parser, and a
// scene loaded without its copies' meshes knows every object's counts and box all the same.
#include <gtest/gtest.h>

#include <string>

#include "softcontact/scene.hpp"
#include "softcontact/surface.hpp"

using namespace softcontact;

namespace {

const std::string kScene = R"(simulation:
  dt: auto
  steps: 10
materials:
  - {name: rubber, model: corotational, young: 1.0e5, poisson: 0.3, density: 1000}
objects:
  - name: floor
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

TEST(SceneObjects, DropMeshesKeepsShapesAndWhatCannotBeRemade) {
  const Scene held = load_scene_from_string(kScene, "scene.yaml");
  std::vector<char> keep(held.objects.size(), 0);
  keep[3] = 1;
  for (std::size_t k = 0; k < held.objects.size(); ++k) (void)held.surface(k);
  const std::size_t bytes = held.drop_meshes(keep);
  // 17 copies dropped (the floor has no recipe; copy 3 is kept), each with its surface.
  std::size_t expected = 0;
  const Scene fresh = load_scene_from_string(kScene, "scene.yaml");
  for (std::size_t k = 1; k < fresh.objects.size(); ++k) {
    if (k == 3) continue;
    const TetMesh& m = fresh.objects[k].mesh;
    const Surface s = extract_surface(m);
    expected += m.points.size() * sizeof(double) + m.tets.size() * sizeof(index_t) +
                (s.triangles.size() + s.vertices.size()) * sizeof(index_t);
  }
  EXPECT_GE(bytes, expected);
  EXPECT_FALSE(held.objects[0].mesh.points.empty());
  EXPECT_FALSE(held.objects[3].mesh.points.empty());
  for (std::size_t k = 0; k < held.objects.size(); ++k) {
    if (k != 0 && k != 3) {
      EXPECT_TRUE(held.objects[k].mesh.points.empty()) << k;
      EXPECT_EQ(held.objects[k].surface, nullptr) << k;
    }
    EXPECT_EQ(held.shape(k).tets, fresh.objects[k].mesh.num_tets());
    EXPECT_EQ(held.mesh(k).points, fresh.objects[k].mesh.points) << k;
    EXPECT_EQ(held.surface(k).triangles, extract_surface(fresh.objects[k].mesh).triangles) << k;
  }
}
