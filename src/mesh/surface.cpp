#include "softcontact/surface.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>

namespace softcontact {

namespace {
const double* P(const TetMesh& m, index_t i) { return m.points.data() + 3 * static_cast<std::size_t>(i); }
}  // namespace

Surface extract_surface(const TetMesh& mesh, std::size_t* nonmanifold_faces) {
  // Key every face by its sorted vertex triple; sort (face key, tet*4+face) so the
  // result does not depend on hash order, then keep the faces that occur once.
  struct Face {
    FaceKey key;
    std::int64_t slot;  // tet * 4 + face
  };
  const std::size_t m = mesh.num_tets();
  std::vector<Face> faces;
  faces.reserve(4 * m);
  for (std::size_t t = 0; t < m; ++t) {
    const index_t* tet = mesh.tets.data() + 4 * t;
    for (int f = 0; f < 4; ++f) {
      faces.push_back({face_key(tet[kTetFaces[f][0]], tet[kTetFaces[f][1]], tet[kTetFaces[f][2]]),
                       static_cast<std::int64_t>(4 * t + f)});
    }
  }
  std::sort(faces.begin(), faces.end(), [](const Face& x, const Face& y) {
    return !same_face(x.key, y.key) ? face_less(x.key, y.key) : x.slot < y.slot;
  });
  std::vector<std::int64_t> boundary;
  std::size_t nonmanifold = 0;
  for (std::size_t i = 0; i < faces.size();) {
    std::size_t j = i + 1;
    while (j < faces.size() && same_face(faces[j].key, faces[i].key)) ++j;
    if (j - i == 1) boundary.push_back(faces[i].slot);
    if (j - i > 2) ++nonmanifold;
    i = j;
  }
  if (nonmanifold_faces) *nonmanifold_faces = nonmanifold;
  std::sort(boundary.begin(), boundary.end());

  Surface s;
  s.triangles.reserve(3 * boundary.size());
  for (std::int64_t slot : boundary) {
    const index_t* tet = mesh.tets.data() + 4 * (slot / 4);
    const int f = static_cast<int>(slot % 4);
    for (int c = 0; c < 3; ++c) s.triangles.push_back(tet[kTetFaces[f][c]]);
  }
  s.vertices = s.triangles;
  std::sort(s.vertices.begin(), s.vertices.end());
  s.vertices.erase(std::unique(s.vertices.begin(), s.vertices.end()), s.vertices.end());
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
