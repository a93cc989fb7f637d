#include "collision_topology.hpp"

#include <algorithm>
#include <array>
#include <cmath>

#include "parallel.hpp"
#include "thickness.hpp"
#include "softcontact/error.hpp"
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

// Tet faces with their neighbours. Objects share no vertex, so no face matches across
// objects: each object is matched on its own, in parallel, writing only its own tets'
// entries. Within an object its tet faces and surface triangles are grouped by their
// smallest vertex (a bucket per vertex of the object's range; a face's key is its sorted
// vertex triple) and each bucket, about four faces, sorted by key: no sort of a whole
// object's faces (the rebuild of every ghost set pays this). A run of two tet faces is
// an interior face, a tet face with a triangle is a boundary face (with the run's first
// triangle in key_less order); anything else (a face of three or more tets, a face
// without either) is left open. An object that `before` held numbered alike (`from`)
// copies its entries from there instead, moved to its new tets and triangles. Then per
// tet, bit j of the mask for each face with no neighbour tet; and the faces left open
// counted.
void build_faces(const World& w, CollisionTopology& t, const CollisionTopology* before,
                 const std::vector<std::int32_t>& from) {
  const std::size_t m = w.tets.size() / 4;
  t.face_neighbour.assign(4 * m, kOpenFace);
  t.boundary_mask.assign(m, 0);
  auto tet_face = [&](index_t e, int j) {
    const index_t* v = &w.tets[4 * static_cast<std::size_t>(e)];
    index_t c[3], k = 0;
    for (int q = 0; q < 4; ++q)
      if (q != j) c[k++] = v[q];
    return face_key(c[0], c[1], c[2]);
  };
  auto triangle_face = [&](index_t r) {
    const index_t* v = &w.triangles[3 * static_cast<std::size_t>(r)];
    return face_key(v[0], v[1], v[2]);
  };
  // Every buffer is sized for the largest object before the parallel loop, which then
  // allocates nothing: an exhausted memory is a std::bad_alloc here, reported as such, not
  // an exception escaping an OpenMP region (std::terminate).
  std::size_t most_faces = 0, widest = 0;
  for (std::size_t k = 0; k < t.objects.size(); ++k) {
    const ObjectInfo& o = t.objects[k];
    if (from[k] >= 0) continue;  // taken from `before`
    most_faces = std::max(most_faces, 4 * o.tets.size() + o.triangles.size());
    if (!o.vertices.empty())
      widest = std::max(widest, static_cast<std::size_t>(o.vertices.back() - o.vertices.front()) + 1);
  }
  std::vector<std::vector<FaceRecord>> face_buffers;
  std::vector<std::vector<std::size_t>> begin_buffers;
  reset_buffers(face_buffers);
  reset_buffers(begin_buffers);
  for (auto& b : face_buffers) b.resize(most_faces);
  for (auto& b : begin_buffers) b.resize(widest + 1);
  parallel_for_dynamic(t.objects.size(), [&](std::size_t k, int thread) {
    const ObjectInfo& o = t.objects[k];
    if (o.vertices.empty()) return;
    if (from[k] >= 0) {
      // The same faces as before, the neighbours moved with the object's tets and
      // triangles (each a contiguous range in both Worlds: matching_slots).
      const ObjectInfo& b = before->objects[static_cast<std::size_t>(from[k])];
      if (o.tets.empty()) return;
      const index_t dt = o.tets.front() - b.tets.front();
      const index_t ds = o.triangles.empty() ? 0 : o.triangles.front() - b.triangles.front();
      const auto* src = &before->face_neighbour[4 * static_cast<std::size_t>(b.tets.front())];
      auto* dst = &t.face_neighbour[4 * static_cast<std::size_t>(o.tets.front())];
      for (std::size_t q = 0; q < 4 * o.tets.size(); ++q) {
        const index_t f = src[q];
        dst[q] = f >= 0 ? f + dt : (f == kOpenFace ? f : f - ds);  // triangle r is -(r + 1)
      }
      return;
    }
    std::vector<FaceRecord>& faces = face_buffers[static_cast<std::size_t>(thread)];
    std::vector<std::size_t>& begin = begin_buffers[static_cast<std::size_t>(thread)];
    const index_t v0 = o.vertices.front();
    const auto nv = static_cast<std::size_t>(o.vertices.back() - v0) + 1;  // the object's range of vertices
    auto bucket = [&](const FaceKey& key) {
      SC_ASSERT(key[0] >= v0 && static_cast<std::size_t>(key[0] - v0) < nv);  // objects share no vertex
      return static_cast<std::size_t>(key[0] - v0);
    };
    std::fill(begin.begin(), begin.begin() + static_cast<std::ptrdiff_t>(nv + 1), std::size_t{0});
    for (index_t e : o.tets)
      for (int j = 0; j < 4; ++j) ++begin[bucket(tet_face(e, j)) + 1];
    for (index_t r : o.triangles) ++begin[bucket(triangle_face(r)) + 1];
    for (std::size_t v = 0; v < nv; ++v) begin[v + 1] += begin[v];
    for (index_t e : o.tets)
      for (int j = 0; j < 4; ++j) {
        const FaceKey key = tet_face(e, j);
        faces[begin[bucket(key)]++] = {key, e, j};
      }
    for (index_t r : o.triangles) {
      const FaceKey key = triangle_face(r);
      faces[begin[bucket(key)]++] = {key, -r - 1, -1};
    }
    // begin[v] is now the end of bucket v (the start of bucket v + 1).
    for (std::size_t v = 0, lo = 0; v < nv; lo = begin[v++]) {
      const std::size_t hi = begin[v];
      if (hi - lo > 1) std::sort(faces.begin() + static_cast<std::ptrdiff_t>(lo), faces.begin() + static_cast<std::ptrdiff_t>(hi), key_less);
      for (std::size_t a = lo; a < hi;) {
        std::size_t b = a;
        while (b < hi && same_face(faces[b].key, faces[a].key)) ++b;
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
        } else if (ntets == 1 && has_triangle) {
          for (std::size_t q = a; q < b; ++q)
            if (faces[q].slot >= 0) t.face_neighbour[4 * static_cast<std::size_t>(faces[q].owner) + faces[q].slot] = triangle;
        }
        a = b;
      }
    }
  });
  // A face was given a tet only as an interior face: every other face is a boundary face.
  parallel_for(m, [&](std::size_t e, int) {
    for (int j = 0; j < 4; ++j)
      if (t.face_neighbour[4 * e + static_cast<std::size_t>(j)] < 0) t.boundary_mask[e] |= static_cast<std::uint8_t>(1u << j);
  });
  t.open_faces = std::count(t.face_neighbour.begin(), t.face_neighbour.end(), kOpenFace);
}

// Distinct mesh edges as a sorted adjacency (CSR) and their mean length. Each vertex's
// row is built from its tets directly: the other end of every tet edge at it (an edge
// once per tet that has it), then sorted and made unique, rows in parallel (each writes
// only its own). No sort of the whole world's edges (the rebuild of every ghost set pays
// this). The vertices of an object that `before` held numbered alike (`from`) copy their
// rows from there, moved to the new indices; their tets are skipped. The mean length
// adds the edges (a, b), a < b, in ascending (a, b) order, row by row: the order, and so
// the bits, of a sorted list of all pairs.
void build_edges(const World& w, CollisionTopology& t, const CollisionTopology* before,
                 const std::vector<std::int32_t>& from) {
  const std::size_t n = w.n_local(), m = w.tets.size() / 4;
  // A vertex of an object taken from `before`: its row there (the same row, every entry
  // moved by the object's shift, which the entries share: an edge joins one object's vertices).
  auto taken = [&](std::size_t v) { return from[static_cast<std::size_t>(t.vertex_slot[v])] >= 0; };
  auto old_row = [&](std::size_t v, index_t& shift) {
    const std::size_t k = static_cast<std::size_t>(t.vertex_slot[v]);
    const ObjectInfo& b = before->objects[static_cast<std::size_t>(from[k])];
    shift = t.objects[k].vertices.front() - b.vertices.front();
    return static_cast<std::size_t>(static_cast<index_t>(v) - shift);
  };
  std::vector<std::size_t> begin(n + 1, 0);
  for (std::size_t e = 0; e < m; ++e) {
    if (from[static_cast<std::size_t>(t.tet_slot[e])] >= 0) continue;
    for (const auto& ed : kTetEdges) {
      const auto a = static_cast<std::size_t>(w.tets[4 * e + ed[0]]), b = static_cast<std::size_t>(w.tets[4 * e + ed[1]]);
      if (a == b) continue;
      ++begin[a + 1];
      ++begin[b + 1];
    }
  }
  for (std::size_t v = 0; v < n; ++v) begin[v + 1] += begin[v];
  std::vector<index_t> to(begin[n]);
  {
    std::vector<std::size_t> fill(begin.begin(), begin.end() - 1);
    for (std::size_t e = 0; e < m; ++e) {
      if (from[static_cast<std::size_t>(t.tet_slot[e])] >= 0) continue;
      for (const auto& ed : kTetEdges) {
        const index_t a = w.tets[4 * e + ed[0]], b = w.tets[4 * e + ed[1]];
        if (a == b) continue;
        to[fill[static_cast<std::size_t>(a)]++] = b;
        to[fill[static_cast<std::size_t>(b)]++] = a;
      }
    }
  }
  std::vector<std::size_t> distinct(n, 0);
  parallel_for(n, [&](std::size_t v, int) {
    if (taken(v)) {
      index_t shift = 0;
      const std::size_t u = old_row(v, shift);
      distinct[v] = before->edge_begin[u + 1] - before->edge_begin[u];
      return;
    }
    const auto first = to.begin() + static_cast<std::ptrdiff_t>(begin[v]);
    const auto last = to.begin() + static_cast<std::ptrdiff_t>(begin[v + 1]);
    std::sort(first, last);
    distinct[v] = static_cast<std::size_t>(std::unique(first, last) - first);
  });
  // Each row's distinct entries, or its row taken from `before`, into an array of the
  // exact size.
  t.edge_begin.assign(n + 1, 0);
  for (std::size_t v = 0; v < n; ++v) t.edge_begin[v + 1] = t.edge_begin[v] + distinct[v];
  t.edge_to.assign(t.edge_begin[n], 0);
  parallel_for(n, [&](std::size_t v, int) {
    index_t* out = t.edge_to.data() + t.edge_begin[v];
    if (!taken(v)) {
      std::copy_n(to.data() + begin[v], distinct[v], out);
      return;
    }
    index_t shift = 0;
    const std::size_t u = old_row(v, shift);
    const index_t* row = before->edge_to.data() + before->edge_begin[u];
    for (std::size_t q = 0; q < distinct[v]; ++q) out[q] = row[q] + shift;
  });
  std::vector<index_t>().swap(to);
  double length = 0;
  std::size_t pairs = 0;
  for (std::size_t a = 0; a < n; ++a)
    for (std::size_t q = t.edge_begin[a]; q < t.edge_begin[a + 1]; ++q) {
      const auto b = static_cast<std::size_t>(t.edge_to[q]);
      if (b < a) continue;
      double l2 = 0;
      for (int d = 0; d < 3; ++d) {
        const double dx = w.x[3 * a + d] - w.x[3 * b + d];
        l2 += dx * dx;
      }
      length += std::sqrt(l2);
      ++pairs;
    }
  t.mean_edge_length = pairs == 0 ? 0 : length / static_cast<double>(pairs);
}

bool contiguous(const std::vector<index_t>& list) {  // ascending and distinct
  return list.empty() || static_cast<std::size_t>(list.back() - list.front()) + 1 == list.size();
}

bool numbered_alike(const ObjectInfo& a, const ObjectInfo& b) {
  return a.object == b.object && !a.vertices.empty() && a.vertices.size() == b.vertices.size() &&
         a.tets.size() == b.tets.size() && a.triangles.size() == b.triangles.size() && contiguous(a.vertices) &&
         contiguous(b.vertices) && contiguous(a.tets) && contiguous(b.tets) && contiguous(a.triangles) &&
         contiguous(b.triangles);
}

}  // namespace

std::vector<std::int32_t> matching_slots(const CollisionTopology& now, const CollisionTopology& before) {
  std::vector<std::int32_t> from(now.objects.size(), -1);
  std::size_t j = 0;  // both in ascending object order
  for (std::size_t k = 0; k < now.objects.size(); ++k) {
    while (j < before.objects.size() && before.objects[j].object < now.objects[k].object) ++j;
    if (j < before.objects.size() && numbered_alike(now.objects[k], before.objects[j])) from[k] = static_cast<std::int32_t>(j);
  }
  return from;
}

CollisionTopology build_collision_topology(const World& w, const CollisionTopology* previous) {
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
  const std::vector<std::int32_t> from =
      previous ? matching_slots(t, *previous) : std::vector<std::int32_t>(t.objects.size(), -1);
  build_edges(w, t, previous, from);
  build_faces(w, t, previous, from);
  for (std::size_t e = 0; e < m; ++e)
    for (int c = 0; c < 4; ++c)
      if (t.surface[static_cast<std::size_t>(w.tets[4 * e + c])]) t.boundary_mask[e] |= static_cast<std::uint8_t>(16u << c);
  return t;
}

}  // namespace softcontact::collide
