// Which meshes a rank holds (scene.hpp: Placement, Scene::mesh, Scene::drop_meshes): every
// object's shape is known everywhere, its mesh only where it is needed, made again from
// its entry's mesh when it is needed later (docs/architecture.md, "Who holds which mesh").
#include <cstring>
#include <functional>
#include <map>
#include <stdexcept>
#include <utility>

#include "softcontact/error.hpp"
#include "softcontact/box.hpp"
#include "softcontact/scene.hpp"
#include "softcontact/surface.hpp"

namespace softcontact {

std::uint64_t mesh_digest(const TetMesh& m) {
  std::uint64_t h = 14695981039346656037ull;
  auto add = [&h](const void* data, std::size_t bytes) {
    const auto* c = static_cast<const unsigned char*>(data);
    std::size_t i = 0;
    for (; i + 8 <= bytes; i += 8) {
      std::uint64_t w;
      std::memcpy(&w, c + i, 8);
      h = (h ^ w) * 1099511628211ull;
    }
    for (; i < bytes; ++i) h = (h ^ c[i]) * 1099511628211ull;
  };
  const std::uint64_t n[2] = {m.points.size(), m.tets.size()};
  add(n, sizeof n);
  add(m.points.data(), m.points.size() * sizeof(double));
  add(m.tets.data(), m.tets.size() * sizeof(index_t));
  return h;
}

namespace {
std::size_t mesh_bytes(const TetMesh& m) {
  return m.points.capacity() * sizeof(double) + m.tets.capacity() * sizeof(index_t);
}
}  // namespace

const std::shared_ptr<const ObjectTraits>& default_object_traits() {
  static const std::shared_ptr<const ObjectTraits> none = std::make_shared<const ObjectTraits>();
  return none;
}

EntryMesh::EntryMesh(std::string source, std::uint64_t digest, std::function<TetMesh()> remake)
    : source_(std::move(source)), remake_(std::move(remake)), digest_(digest) {}

std::shared_ptr<const EntryMesh> EntryMesh::held(std::string source, TetMesh placed, std::function<TetMesh()> remake) {
  std::shared_ptr<EntryMesh> e(new EntryMesh(std::move(source), mesh_digest(placed), std::move(remake)));
  e->held_ = std::make_unique<TetMesh>(std::move(placed));
  return e;
}

std::shared_ptr<const EntryMesh> EntryMesh::recipe(std::string source, const TetMesh& placed, std::function<TetMesh()> remake) {
  if (!remake) return held(std::move(source), placed, nullptr);
  return std::shared_ptr<const EntryMesh>(new EntryMesh(std::move(source), mesh_digest(placed), std::move(remake)));
}

std::shared_ptr<const EntryMesh> EntryMesh::made_elsewhere(std::string source, std::uint64_t digest,
                                                           std::function<TetMesh()> remake) {
  if (!remake) throw std::logic_error("EntryMesh::made_elsewhere of " + source + " without a way to make it");
  return std::shared_ptr<const EntryMesh>(new EntryMesh(std::move(source), digest, std::move(remake)));
}

TetMesh EntryMesh::remade() const {
  TetMesh m;
  try {
    m = remake_();
  } catch (const std::exception& e) {
    throw RuntimeFailure("the mesh of " + source_ + " could not be made again during the run: " + e.what());
  }
  if (mesh_digest(m) != digest_)
    throw RuntimeFailure("the mesh of " + source_ + " differs from the one read when the scene was loaded (the " +
                         "file changed during the run): keep mesh files unchanged while a run uses them");
  return m;
}

const TetMesh& EntryMesh::get() const {
  if (!held_) held_ = std::make_unique<TetMesh>(remade());
  return *held_;
}

TetMesh EntryMesh::make() const { return held_ ? *held_ : remade(); }

std::size_t EntryMesh::drop() const {
  if (!held_ || !remake_) return 0;
  const std::size_t bytes = mesh_bytes(*held_);
  held_.reset();
  return bytes;
}

// The arithmetic of every copy's placement, here only: the scene parser places copies
// through it, so that a mesh made again is bitwise the one placed first.
TetMesh Placement::place() const {
  if (!can_remake()) return {};
  if (kind == Kind::entry) return base->make();
  const TetMesh& b = base->get();
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

namespace {
ObjectShape shape_of(const TetMesh& m, std::size_t triangles) {
  ObjectShape s;
  s.vertices = m.num_vertices();
  s.tets = m.num_tets();
  s.triangles = triangles;
  for (std::size_t i = 0; i < m.num_vertices(); ++i) add_point(s.box, &m.points[3 * i]);
  return s;
}
}  // namespace

const ObjectShape& Scene::shape(std::size_t k) const {
  const SceneObject& o = objects[k];
  if (!o.shape) {
    const MeshView v = view_mesh(k);
    const TetMesh& m = v.get();
    o.shape = shape_of(m, o.surface ? o.surface->num_triangles() : extract_surface(m).num_triangles());
  }
  return *o.shape;
}

void Scene::describe_objects() const {
  for (std::size_t k = 0; k < objects.size(); ++k) (void)shape(k);
}

void Scene::describe_objects(int part, int parts, const std::function<void(std::vector<double>&)>& sum) const {
  if (parts <= 1 || !sum) return describe_objects();
  // The objects without a shape yet. Every part holds the same scene, so every part
  // builds the same list, and the k-th of it is counted on part k % parts.
  std::vector<std::size_t> todo;
  for (std::size_t k = 0; k < objects.size(); ++k)
    if (!objects[k].shape && !objects[k].surface) todo.push_back(k);
  if (todo.empty()) return describe_objects();  // the same list on every part: none calls sum
  std::vector<double> triangles(todo.size(), 0.0);
  for (std::size_t i = static_cast<std::size_t>(part); i < todo.size(); i += static_cast<std::size_t>(parts))
    triangles[i] = static_cast<double>(extract_surface(view_mesh(todo[i]).get()).num_triangles());
  sum(triangles);  // 0 + n is n: each count as one part made it (exact below 2^53)
  for (std::size_t i = 0; i < todo.size(); ++i)
    objects[todo[i]].shape = shape_of(view_mesh(todo[i]).get(), static_cast<std::size_t>(triangles[i]));
  describe_objects();  // those with a surface already
}

std::size_t Scene::drop_meshes(const std::vector<char>& keep) const {
  SC_ASSERT(keep.size() == objects.size());
  describe_objects();
  std::size_t bytes = 0;
  std::map<const EntryMesh*, bool> bases;  // entry mesh -> a kept copy is placed from it
  for (std::size_t k = 0; k < objects.size(); ++k) {
    const SceneObject& o = objects[k];
    if (o.placement.base) bases[o.placement.base.get()] |= keep[k] && o.placement.is_copy();
    if (keep[k] || !o.placement.can_remake()) continue;
    bytes += mesh_bytes(o.mesh);
    if (o.surface) bytes += (o.surface->triangles.capacity() + o.surface->vertices.capacity()) * sizeof(index_t);
    o.mesh = TetMesh();
    o.surface.reset();
  }
  for (const auto& [base, needed] : bases)
    if (!needed) bytes += base->drop();
  return bytes;
}

std::vector<std::uint64_t> Scene::object_digests(int part, int parts,
                                                 const std::function<void(std::vector<double>&)>& sum) const {
  if (parts < 1 || !sum) part = 0, parts = 1;
  const std::size_t n = objects.size();
  // Two exact integers below 2^32 per object, written by one part and zero on the others,
  // so the sum over the parts is exact.
  std::vector<double> halves(2 * n, 0.0);
  for (std::size_t k = static_cast<std::size_t>(part); k < n; k += static_cast<std::size_t>(parts)) {
    // A dropped single-copy mesh by its entry's digest (what it would be made again as:
    // EntryMesh checks that), any other from the mesh held or placed here.
    const SceneObject& o = objects[k];
    const Placement& p = o.placement;
    const bool dropped_single = o.mesh.points.empty() && p.kind == Placement::Kind::entry && p.base;
    const std::uint64_t d = dropped_single ? p.base->digest() : mesh_digest(view_mesh(k).get());
    halves[2 * k] = static_cast<double>(d >> 32);
    halves[2 * k + 1] = static_cast<double>(d & 0xffffffffull);
  }
  if (parts > 1) sum(halves);
  std::vector<std::uint64_t> digests(n);
  for (std::size_t k = 0; k < n; ++k)
    digests[k] = (static_cast<std::uint64_t>(halves[2 * k]) << 32) | static_cast<std::uint64_t>(halves[2 * k + 1]);
  return digests;
}

}  // namespace softcontact
