#include "collision_topology.hpp"

#include <algorithm>
#include <array>
#include <cmath>

#include "parallel.hpp"
#include "thickness.hpp"
#include "softcontact/surface.hpp"

namespace softcontact::collide {

namespace {

struct FaceRecord {
  FaceKey key;    // vertex indices, ascending
  index_t owner;  // tet, or -(triangle + 1) for a surface triangle
  int slot;       // face j of the tet; -1 for a triangle
};

bool key_less(const FaceRecord& a, const FaceRecord& b) {
  if (!same_face(a.key, b.key)) return face_less(a.key, b.key);
  return a.owner > b.owner;  // tets (>= 0) before triangles (< 0), then by index; a fixed order
}

// Tet faces with their neighbours: sort all tet faces and surface triangles by vertex
// triple; a run of two tet faces is an interior face, a tet face with a triangle is a
// boundary face; anything else (a face of three or more tets, a face without either) is
// left open. Objects share no vertex, so no face matches across objects: each object is
// matched on its own (its records in one buffer per thread, reused), in parallel, each
// writing only its own tets' entries; open faces are counted per object and added in
// slot order.
void build_faces(const World& w, CollisionTopology& t) {
  const std::size_t m = w.tets.size() / 4;
  t.face_neighbour.assign(4 * m, kOpenFace);
  t.boundary_mask.assign(m, 0);
  std::vector<std::int64_t> open(t.objects.size(), 0);
  // Every buffer is sized for the largest object before the parallel loop, which then
  // allocates nothing: an exhausted memory is a std::bad_alloc here, reported as such, not
  // an exception escaping an OpenMP region (std::terminate).
  std::size_t largest = 0;
  for (const ObjectInfo& o : t.objects) largest = std::max(largest, 4 * o.tets.size() + o.triangles.size());
  std::vector<std::vector<FaceRecord>> buffers;
  reset_buffers(buffers);
  for (auto& b : buffers) b.reserve(largest);
  parallel_for_dynamic(t.objects.size(), [&](std::size_t k, int thread) {
    const ObjectInfo& o = t.objects[k];
    std::vector<FaceRecord>& faces = buffers[static_cast<std::size_t>(thread)];
    faces.clear();
    for (index_t e : o.tets) {
      const index_t* v = &w.tets[4 * static_cast<std::size_t>(e)];
      for (int j = 0; j < 4; ++j) {
        index_t c[3], n = 0;
        for (int q = 0; q < 4; ++q)
          if (q != j) c[n++] = v[q];
        faces.push_back({face_key(c[0], c[1], c[2]), e, j});
      }
    }
    for (index_t r : o.triangles) {
      const index_t* v = &w.triangles[3 * static_cast<std::size_t>(r)];
      faces.push_back({face_key(v[0], v[1], v[2]), -r - 1, -1});
    }
    std::sort(faces.begin(), faces.end(), key_less);
    for (std::size_t a = 0; a < faces.size();) {
      std::size_t b = a;
      while (b < faces.size() && same_face(faces[b].key, faces[a].key)) ++b;
      int ntets = 0;
      index_t triangle = 0;
      bool has_triangle = false;
      for (std::size_t q = a; q < b; ++q) {
        if (faces[q].slot >= 0)
          ++ntets;
        else if (!has_triangle) {
          has_triangle = true;
          triangle = faces[q].owner;
        }
      }
      if (ntets == 2 && !has_triangle) {
        const FaceRecord &f = faces[a], &g = faces[a + 1];
        t.face_neighbour[4 * static_cast<std::size_t>(f.owner) + f.slot] = g.owner;
        t.face_neighbour[4 * static_cast<std::size_t>(g.owner) + g.slot] = f.owner;
      } else {
        for (std::size_t q = a; q < b; ++q) {
          if (faces[q].slot < 0) continue;
          const std::size_t e = static_cast<std::size_t>(faces[q].owner);
          t.boundary_mask[e] |= static_cast<std::uint8_t>(1u << faces[q].slot);
          if (ntets == 1 && has_triangle)
            t.face_neighbour[4 * e + faces[q].slot] = triangle;
          else
            ++open[k];
        }
      }
      a = b;
    }
  });
  for (std::int64_t c : open) t.open_faces += c;
}

// Distinct mesh edges as a sorted adjacency (CSR) and their mean length.
void build_edges(const World& w, CollisionTopology& t) {
  const std::size_t n = w.n_local(), m = w.tets.size() / 4;
  std::vector<std::uint64_t> pairs;
  pairs.reserve(6 * m);
  for (std::size_t e = 0; e < m; ++e)
    for (const auto& ed : kTetEdges) {
      auto a = static_cast<std::uint64_t>(w.tets[4 * e + ed[0]]), b = static_cast<std::uint64_t>(w.tets[4 * e + ed[1]]);
      if (a > b) std::swap(a, b);
      if (a != b) pairs.push_back(a << 32 | b);
    }
  std::sort(pairs.begin(), pairs.end());
  pairs.erase(std::unique(pairs.begin(), pairs.end()), pairs.end());
  t.edge_begin.assign(n + 1, 0);
  double length = 0;
  for (std::uint64_t p : pairs) {
    const auto a = static_cast<index_t>(p >> 32), b = static_cast<index_t>(p & 0xffffffffu);
    ++t.edge_begin[static_cast<std::size_t>(a) + 1];
    ++t.edge_begin[static_cast<std::size_t>(b) + 1];
    double l2 = 0;
    for (int d = 0; d < 3; ++d) {
      const double dx = w.x[3 * static_cast<std::size_t>(a) + d] - w.x[3 * static_cast<std::size_t>(b) + d];
      l2 += dx * dx;
    }
    length += std::sqrt(l2);
  }
  t.mean_edge_length = pairs.empty() ? 0 : length / static_cast<double>(pairs.size());
  for (std::size_t v = 0; v < n; ++v) t.edge_begin[v + 1] += t.edge_begin[v];
  t.edge_to.resize(t.edge_begin[n]);
  std::vector<std::size_t> fill(t.edge_begin.begin(), t.edge_begin.end() - 1);
  // Row v receives its neighbours from pairs (v, b) and (a, v), interleaved: sort each row.
  for (std::uint64_t p : pairs) {
    const auto a = static_cast<index_t>(p >> 32), b = static_cast<index_t>(p & 0xffffffffu);
    t.edge_to[fill[static_cast<std::size_t>(a)]++] = b;
    t.edge_to[fill[static_cast<std::size_t>(b)]++] = a;
  }
  for (std::size_t v = 0; v < n; ++v)
    std::sort(t.edge_to.begin() + static_cast<std::ptrdiff_t>(t.edge_begin[v]),
              t.edge_to.begin() + static_cast<std::ptrdiff_t>(t.edge_begin[v + 1]));
}

}  // namespace

CollisionTopology build_collision_topology(const World& w) {
  CollisionTopology t;
  const std::size_t n = w.n_local(), m = w.tets.size() / 4, s = w.triangles.size() / 3;

  // Slots: the objects present, ascending.
  std::vector<std::int32_t> present(w.vertex_object.begin(), w.vertex_object.end());
  std::sort(present.begin(), present.end());
  present.erase(std::unique(present.begin(), present.end()), present.end());
  std::vector<std::int32_t> slot_of(w.layout.size() + 1, -1);
  for (std::size_t k = 0; k < present.size(); ++k) {
    slot_of[static_cast<std::size_t>(present[k])] = static_cast<std::int32_t>(k);
    t.objects.emplace_back();
    t.objects.back().object = present[k];
  }
  t.vertex_slot.resize(n);
  for (std::size_t v = 0; v < n; ++v) {
    t.vertex_slot[v] = slot_of[static_cast<std::size_t>(w.vertex_object[v])];
    t.objects[static_cast<std::size_t>(t.vertex_slot[v])].vertices.push_back(static_cast<index_t>(v));
  }
  t.tet_slot.resize(m);
  for (std::size_t e = 0; e < m; ++e) {
    t.tet_slot[e] = t.vertex_slot[static_cast<std::size_t>(w.tets[4 * e])];
    t.objects[static_cast<std::size_t>(t.tet_slot[e])].tets.push_back(static_cast<index_t>(e));
  }
  t.triangle_slot.resize(s);
  t.surface.assign(n, 0);
  t.tri_begin.assign(n + 1, 0);
  for (std::size_t r = 0; r < s; ++r) {
    t.triangle_slot[r] = t.vertex_slot[static_cast<std::size_t>(w.triangles[3 * r])];
    t.objects[static_cast<std::size_t>(t.triangle_slot[r])].triangles.push_back(static_cast<index_t>(r));
    for (int c = 0; c < 3; ++c) {
      const auto v = static_cast<std::size_t>(w.triangles[3 * r + c]);
      t.surface[v] = 1;
      ++t.tri_begin[v + 1];
    }
  }
  for (std::size_t v = 0; v < n; ++v) t.tri_begin[v + 1] += t.tri_begin[v];
  t.tri_of.resize(t.tri_begin[n]);
  {
    std::vector<std::size_t> fill(t.tri_begin.begin(), t.tri_begin.end() - 1);
    for (std::size_t r = 0; r < s; ++r)  // triangles in ascending order: rows come out ascending
      for (int c = 0; c < 3; ++c) t.tri_of[fill[static_cast<std::size_t>(w.triangles[3 * r + c])]++] = static_cast<index_t>(r);
  }
  for (ObjectInfo& o : t.objects) {
    for (index_t v : o.vertices)
      if (t.surface[static_cast<std::size_t>(v)]) o.surface_vertices.push_back(v);
    o.thickness = principal_thickness(w.x.data(), o.vertices);
  }
  build_edges(w, t);
  build_faces(w, t);
  for (std::size_t e = 0; e < m; ++e)
    for (int c = 0; c < 4; ++c)
      if (t.surface[static_cast<std::size_t>(w.tets[4 * e + c])]) t.boundary_mask[e] |= static_cast<std::uint8_t>(16u << c);
  return t;
}

}  // namespace softcontact::collide
