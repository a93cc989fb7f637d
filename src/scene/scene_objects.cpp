// Which meshes a rank holds (scene.hpp: Placement, Scene::mesh, Scene::drop_meshes): every
// object's shape is known everywhere, its mesh only where it is needed, made again from
// its entry's mesh when it is needed later (docs/architecture.md, "Who holds which mesh").
#include <utility>

#include "softcontact/error.hpp"
#include "softcontact/box.hpp"
#include "softcontact/scene.hpp"
#include "softcontact/surface.hpp"

namespace softcontact {

// The arithmetic of every copy's placement, here only: the scene parser places copies
// through it, so that a mesh made again is bitwise the one placed first.
TetMesh Placement::place() const {
  if (!can_remake()) return {};
  const TetMesh& b = *base;
  TetMesh m = b;
  const auto& R = rotation;
  for (std::size_t i = 0; i < b.num_vertices(); ++i) {
    const double* q = &b.points[3 * i];
    double* x = &m.points[3 * i];
    if (kind == Kind::offset) {
      // as transformed(base, {1, 1, 1}, identity, offset) in placement.cpp always did
      const double s[3] = {q[0] * 1.0, q[1] * 1.0, q[2] * 1.0};
      for (int r = 0; r < 3; ++r)
        x[r] = (r == 0 ? 1.0 : 0.0) * s[0] + (r == 1 ? 1.0 : 0.0) * s[1] + (r == 2 ? 1.0 : 0.0) * s[2] + offset[r];
    } else {
      const double p[3] = {q[0] - centre[0], q[1] - centre[1], q[2] - centre[2]};
      for (int r = 0; r < 3; ++r) x[r] = R[3 * r] * p[0] + R[3 * r + 1] * p[1] + R[3 * r + 2] * p[2] + offset[r];
    }
  }
  return m;
}

std::size_t Scene::num_vertices() const {
  std::size_t n = 0;
  for (const auto& o : objects) n += o.shape ? o.shape->vertices : o.mesh.num_vertices();
  return n;
}

std::size_t Scene::num_tets() const {
  std::size_t n = 0;
  for (const auto& o : objects) n += o.shape ? o.shape->tets : o.mesh.num_tets();
  return n;
}

const TetMesh& Scene::mesh(std::size_t k) const {
  const SceneObject& o = objects[k];
  if (o.mesh.points.empty() && o.placement.can_remake()) o.mesh = o.placement.place();
  return o.mesh;
}

Scene::MeshView Scene::view_mesh(std::size_t k) const {
  const SceneObject& o = objects[k];
  if (o.mesh.points.empty() && o.placement.can_remake()) return MeshView(o.placement.place());
  return MeshView(&o.mesh);
}

const Surface& Scene::surface(std::size_t k) const {
  const SceneObject& o = objects[k];
  if (!o.surface) o.surface = std::make_shared<const Surface>(extract_surface(mesh(k)));
  return *o.surface;
}

const ObjectShape& Scene::shape(std::size_t k) const {
  const SceneObject& o = objects[k];
  if (!o.shape) {
    const MeshView v = view_mesh(k);
    const TetMesh& m = v.get();
    ObjectShape s;
    s.vertices = m.num_vertices();
    s.tets = m.num_tets();
    s.triangles = o.surface ? o.surface->num_triangles() : extract_surface(m).num_triangles();
    for (std::size_t i = 0; i < m.num_vertices(); ++i) add_point(s.box, &m.points[3 * i]);
    o.shape = s;
  }
  return *o.shape;
}

void Scene::describe_objects() const {
  for (std::size_t k = 0; k < objects.size(); ++k) (void)shape(k);
}

std::size_t Scene::drop_meshes(const std::vector<char>& keep) const {
  SC_ASSERT(keep.size() == objects.size());
  describe_objects();
  std::size_t bytes = 0;
  for (std::size_t k = 0; k < objects.size(); ++k) {
    const SceneObject& o = objects[k];
    if (keep[k] || !o.placement.can_remake()) continue;
    bytes += o.mesh.points.capacity() * sizeof(double) + o.mesh.tets.capacity() * sizeof(index_t);
    if (o.surface) bytes += (o.surface->triangles.capacity() + o.surface->vertices.capacity()) * sizeof(index_t);
    o.mesh = TetMesh();
    o.surface.reset();
  }
  return bytes;
}

}  // namespace softcontact
