#include "softcontact/world.hpp"

#include <algorithm>
#include <cmath>

#include "softcontact/error.hpp"
#include "softcontact/surface.hpp"

namespace softcontact {

std::vector<int> block_partition(const Scene& scene, int nranks) {
  // Prefix sums of tets; object k goes to the rank whose share contains the middle of
  // its tet range, so blocks are contiguous and balanced to within one object.
  const double total = static_cast<double>(scene.num_tets());
  std::vector<int> owner(scene.objects.size(), 0);
  double before = 0;
  for (std::size_t k = 0; k < scene.objects.size(); ++k) {
    const double t = static_cast<double>(scene.shape(k).tets);
    const double mid = before + 0.5 * t;
    owner[k] = std::min(nranks - 1, static_cast<int>(mid / total * nranks));
    before += t;
  }
  return owner;
}

namespace {

// Appends object k (vertices, tets, surface triangles) to the local arrays.
void append_object(World& w, const Scene& scene, int k) {
  const SceneObject& o = scene.objects[static_cast<std::size_t>(k)];
  const TetMesh& m = scene.mesh(static_cast<std::size_t>(k));
  const Surface& s = scene.surface(static_cast<std::size_t>(k));
  const ObjectLayout& L = w.layout[static_cast<std::size_t>(k)];
  const index_t base = static_cast<index_t>(w.vertex_gid.size());
  w.vertex_offset[static_cast<std::size_t>(k)] = base;
  const double rho = scene.materials[o.material].density;
  std::vector<double> mass(m.num_vertices(), 0.0);
  for (std::size_t t = 0; t < m.num_tets(); ++t) {
    const index_t* tet = m.tets.data() + 4 * t;
    const double vol =
        signed_tet_volume(&m.points[3 * tet[0]], &m.points[3 * tet[1]], &m.points[3 * tet[2]], &m.points[3 * tet[3]]);
    w.rest_volume.push_back(vol);
    for (int c = 0; c < 4; ++c) {
      mass[tet[c]] += 0.25 * rho * vol;  // in tet order: a fixed summation order
      w.tets.push_back(base + tet[c]);
    }
    w.tet_gid.push_back(L.tet_begin + static_cast<gid_t>(t));
    w.tet_object.push_back(k);
  }
  for (std::size_t i = 0; i < m.num_vertices(); ++i) {
    const double* p = &m.points[3 * i];
    bool fixed = o.kinematic();
    for (const Box& b : o.fixed()) fixed = fixed || b.contains(p);
    w.vertex_gid.push_back(L.vertex_begin + static_cast<gid_t>(i));
    w.vertex_object.push_back(k);
    w.mass.push_back(mass[i]);
    w.inv_mass.push_back(fixed ? 0.0 : 1.0 / mass[i]);
    for (int d = 0; d < 3; ++d) {
      w.x.push_back(p[d]);
      w.x_prev.push_back(p[d]);
      w.v.push_back(fixed ? 0.0 : o.velocity()[d]);
    }
  }
  for (std::size_t t = 0; t < s.num_triangles(); ++t) {
    for (int c = 0; c < 3; ++c) w.triangles.push_back(base + s.triangles[3 * t + c]);
    w.triangle_gid.push_back(L.triangle_begin + static_cast<gid_t>(t));
  }
}

}  // namespace

World build_world(const Scene& scene, const std::vector<int>& object_rank, int rank) {
  World w;
  w.rank = rank;
  const std::size_t no = scene.objects.size();
  w.layout.resize(no);
  w.vertex_offset.assign(no, -1);
  for (std::size_t k = 0; k < no; ++k) {
    const ObjectShape& m = scene.shape(k);
    ObjectLayout& L = w.layout[k];
    L.vertex_begin = w.global_vertices;
    L.vertex_count = static_cast<gid_t>(m.vertices);
    L.tet_begin = w.global_tets;
    L.tet_count = static_cast<gid_t>(m.tets);
    L.triangle_begin = w.global_triangles;
    L.triangle_count = static_cast<gid_t>(m.triangles);
    L.rank = object_rank[k];
    w.global_vertices += L.vertex_count;
    w.global_tets += L.tet_count;
    w.global_triangles += L.triangle_count;
    if (L.rank == rank) w.owned_objects.push_back(static_cast<int>(k));
  }
  for (int k : w.owned_objects) {
    append_object(w, scene, k);
    w.owned_motion.push_back(scene.objects[static_cast<std::size_t>(k)].motion());
  }
  w.n_owned = w.vertex_gid.size();
  w.m_owned = w.tet_gid.size();
  w.s_owned = w.triangle_gid.size();
  return w;
}

void set_ghost_objects(World& w, const Scene& scene, const std::vector<int>& ghosts) {
  for (int k : w.ghost_objects) w.vertex_offset[static_cast<std::size_t>(k)] = -1;
  const std::size_t n = w.n_owned, m = w.m_owned, s = w.s_owned;
  w.vertex_gid.resize(n);
  w.vertex_object.resize(n);
  w.x.resize(3 * n);
  w.x_prev.resize(3 * n);
  w.v.resize(3 * n);
  w.mass.resize(n);
  w.inv_mass.resize(n);
  w.tets.resize(4 * m);
  w.tet_gid.resize(m);
  w.tet_object.resize(m);
  w.rest_volume.resize(m);
  w.triangles.resize(3 * s);
  w.triangle_gid.resize(s);
  w.ghost_objects = ghosts;
  for (int k : ghosts) {
    SC_ASSERT(!w.owns_object(k));
    append_object(w, scene, k);
  }
}

namespace {
template <class F>
std::vector<GidRun> runs(const World& w, F range) {
  std::vector<GidRun> r;
  for (int k : w.owned_objects) {
    const auto [b, c] = range(w.layout[k]);
    if (c == 0) continue;
    if (!r.empty() && r.back().begin + r.back().count == b)
      r.back().count += c;
    else
      r.push_back({b, c});
  }
  return r;
}
}  // namespace

std::vector<GidRun> owned_vertex_runs(const World& w) {
  return runs(w, [](const ObjectLayout& L) { return std::pair{L.vertex_begin, L.vertex_count}; });
}
std::vector<GidRun> owned_tet_runs(const World& w) {
  return runs(w, [](const ObjectLayout& L) { return std::pair{L.tet_begin, L.tet_count}; });
}
std::vector<GidRun> owned_triangle_runs(const World& w) {
  return runs(w, [](const ObjectLayout& L) { return std::pair{L.triangle_begin, L.triangle_count}; });
}

}  // namespace softcontact
