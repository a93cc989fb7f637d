#include "softcontact/surface.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <string>

#include "softcontact/error.hpp"

namespace softcontact {

namespace {
const double* P(const TetMesh& m, index_t i) { return m.points.data() + 3 * static_cast<std::size_t>(i); }
}  // namespace

Surface extract_surface(const TetMesh& mesh, std::size_t* nonmanifold_faces) {
  // Faces are matched by their sorted vertex triple (face_key). They are bucketed by
  // their smallest vertex, a counting sort linear in the faces, and each bucket (the faces
  // whose smallest vertex is one vertex: a few dozen) is sorted by the other two; a key
  // that occurs once is a boundary face. The boundary is then emitted in slot order (tet,
  // then face 0..3), which no sort decides. Until 2026-12-02 all 4 m faces were sorted
  // at once, O(m log m): 10 % of reading and setting up soft_floor on one rank
  // (docs/benchmarks.md, "surface extraction without sorting every face").
  const std::size_t m = mesh.num_tets();
  index_t top = -1;
  for (index_t v : mesh.tets) {
    if (v < 0) throw RuntimeFailure("extract_surface: a tet names vertex " + std::to_string(v));
    top = std::max(top, v);
  }
  const std::size_t n = static_cast<std::size_t>(top) + 1;
  auto key_of = [&](std::size_t slot) {
    const index_t* tet = mesh.tets.data() + 4 * (slot / 4);
    const int* f = kTetFaces[slot % 4];
    return face_key(tet[f[0]], tet[f[1]], tet[f[2]]);
  };
  std::vector<std::size_t> begin(n + 1, 0);
  for (std::size_t slot = 0; slot < 4 * m; ++slot) ++begin[static_cast<std::size_t>(key_of(slot)[0]) + 1];
  for (std::size_t v = 0; v < n; ++v) begin[v + 1] += begin[v];
  struct Rest {  // a face's two larger vertices, and its slot
    index_t b, c;
    std::size_t slot;
  };
  std::vector<Rest> faces(4 * m);
  {
    std::vector<std::size_t> at(begin.begin(), begin.end() - 1);
    for (std::size_t slot = 0; slot < 4 * m; ++slot) {
      const FaceKey k = key_of(slot);
      faces[at[static_cast<std::size_t>(k[0])]++] = {k[1], k[2], slot};
    }
  }
  std::vector<char> boundary(4 * m, 0);
  std::size_t nonmanifold = 0, count = 0;
  for (std::size_t v = 0; v < n; ++v) {
    Rest* const first = faces.data() + begin[v];
    Rest* const last = faces.data() + begin[v + 1];
    std::sort(first, last, [](const Rest& x, const Rest& y) { return x.b != y.b ? x.b < y.b : x.c < y.c; });
    for (Rest* i = first; i != last;) {
      Rest* j = i + 1;
      while (j != last && j->b == i->b && j->c == i->c) ++j;
      if (j - i == 1) {
        boundary[i->slot] = 1;
        ++count;
      }
      if (j - i > 2) ++nonmanifold;
      i = j;
    }
  }
  if (nonmanifold_faces) *nonmanifold_faces = nonmanifold;

  Surface s;
  s.triangles.reserve(3 * count);
  std::vector<char> on(n, 0);
  for (std::size_t slot = 0; slot < 4 * m; ++slot) {
    if (!boundary[slot]) continue;
    const index_t* tet = mesh.tets.data() + 4 * (slot / 4);
    for (int c = 0; c < 3; ++c) {
      const index_t v = tet[kTetFaces[slot % 4][c]];
      s.triangles.push_back(v);
      on[static_cast<std::size_t>(v)] = 1;
    }
  }
  for (std::size_t v = 0; v < n; ++v)
    if (on[v]) s.vertices.push_back(static_cast<index_t>(v));
  return s;
}

ClosednessDefect check_closed(const Surface& surface) {
  // Directed edges (a,b): a closed oriented surface has each exactly once, and its twin
  // (b,a) exactly once.
  std::vector<std::pair<index_t, index_t>> e;
  e.reserve(surface.triangles.size());
  for (std::size_t t = 0; t < surface.num_triangles(); ++t)
    for (int c = 0; c < 3; ++c)
      e.emplace_back(surface.triangles[3 * t + c], surface.triangles[3 * t + (c + 1) % 3]);
  std::vector<std::pair<index_t, index_t>> und(e.size());
  std::transform(e.begin(), e.end(), und.begin(), [](auto p) {
    return p.first < p.second ? p : std::make_pair(p.second, p.first);
  });
  std::sort(e.begin(), e.end());
  std::sort(und.begin(), und.end());
  ClosednessDefect d;
  for (std::size_t i = 0; i < und.size();) {
    std::size_t j = i + 1;
    while (j < und.size() && und[j] == und[i]) ++j;
    bool ok = (j - i == 2);
    if (ok) {
      // both directions present once
      auto fwd = std::equal_range(e.begin(), e.end(), und[i]);
      ok = (fwd.second - fwd.first == 1);
    }
    if (!ok) {
      if (d.open_edges == 0) {
        d.a = und[i].first;
        d.b = und[i].second;
        d.uses = static_cast<int>(j - i);
      }
      ++d.open_edges;
    }
    i = j;
  }
  return d;
}

std::vector<double> vertex_normals(const TetMesh& mesh, const Surface& surface) {
  std::vector<double> n(mesh.points.size(), 0.0);
  // Triangle normals (length = 2 * area) gathered per vertex: loop over triangles in
  // order, so the sum order is fixed.
  for (std::size_t t = 0; t < surface.num_triangles(); ++t) {
    const index_t* tri = surface.triangles.data() + 3 * t;
    const double *a = P(mesh, tri[0]), *b = P(mesh, tri[1]), *c = P(mesh, tri[2]);
    const double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
    const double v[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
    const double cr[3] = {u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]};
    for (int k = 0; k < 3; ++k)
      for (int d = 0; d < 3; ++d) n[3 * static_cast<std::size_t>(tri[k]) + d] += cr[d];
  }
  for (std::size_t i = 0; i < mesh.num_vertices(); ++i) {
    const double len = std::sqrt(n[3 * i] * n[3 * i] + n[3 * i + 1] * n[3 * i + 1] + n[3 * i + 2] * n[3 * i + 2]);
    if (len > 0)
      for (int d = 0; d < 3; ++d) n[3 * i + d] /= len;
  }
  return n;
}

double enclosed_volume(const TetMesh& mesh, const Surface& surface) {
  double v = 0;
  for (std::size_t t = 0; t < surface.num_triangles(); ++t) {
    const index_t* tri = surface.triangles.data() + 3 * t;
    const double *a = P(mesh, tri[0]), *b = P(mesh, tri[1]), *c = P(mesh, tri[2]);
    v += a[0] * (b[1] * c[2] - b[2] * c[1]) + a[1] * (b[2] * c[0] - b[0] * c[2]) + a[2] * (b[0] * c[1] - b[1] * c[0]);
  }
  return v / 6.0;
}

double tet_volume_sum(const TetMesh& mesh) {
  double v = 0;
  for (std::size_t t = 0; t < mesh.num_tets(); ++t) {
    const index_t* tet = mesh.tets.data() + 4 * t;
    v += signed_tet_volume(P(mesh, tet[0]), P(mesh, tet[1]), P(mesh, tet[2]), P(mesh, tet[3]));
  }
  return v;
}

}  // namespace softcontact
