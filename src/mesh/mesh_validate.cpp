#include <algorithm>
#include <cmath>
#include <sstream>

#include "softcontact/error.hpp"
#include "softcontact/mesh.hpp"
#include "softcontact/surface.hpp"

namespace softcontact {

double signed_tet_volume(const double* a, const double* b, const double* c, const double* d) {
  const double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
  const double v[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
  const double w[3] = {d[0] - a[0], d[1] - a[1], d[2] - a[2]};
  return (u[0] * (v[1] * w[2] - v[2] * w[1]) - u[1] * (v[0] * w[2] - v[2] * w[0]) +
          u[2] * (v[0] * w[1] - v[1] * w[0])) /
         6.0;
}

namespace {

std::string element_name(std::size_t t, const std::vector<std::int64_t>& ids) {
  std::ostringstream s;
  if (t < ids.size())
    s << "element " << ids[t];
  else
    s << "tetrahedron " << (t + 1);
  return s.str();
}

double longest_edge(const double* p[4]) {
  double l2 = 0;
  for (int i = 0; i < 4; ++i)
    for (int j = i + 1; j < 4; ++j) {
      double s = 0;
      for (int d = 0; d < 3; ++d) s += (p[i][d] - p[j][d]) * (p[i][d] - p[j][d]);
      l2 = std::max(l2, s);
    }
  return std::sqrt(l2);
}

}  // namespace

MeshReport validate_mesh(TetMesh& mesh, const std::string& source, const std::vector<std::int64_t>& element_ids) {
  MeshReport report;
  const std::size_t n = mesh.num_vertices();
  const std::size_t m = mesh.num_tets();
  if (mesh.points.size() % 3 != 0 || mesh.tets.size() % 4 != 0)
    throw InputError(source, 0, "internal: malformed mesh arrays");
  if (m == 0) throw InputError(source, 0, "the mesh has no tetrahedra (expected at least one 4-node tetrahedron)");
  for (std::size_t i = 0; i < n; ++i)
    for (int d = 0; d < 3; ++d)
      if (!std::isfinite(mesh.points[3 * i + d])) {
        std::ostringstream s;
        s << "vertex " << (i + 1) << " has a non-finite coordinate (expected finite x y z)";
        throw InputError(source, 0, s.str());
      }

  std::size_t first_inverted = m;
  for (std::size_t t = 0; t < m; ++t) {
    index_t* tet = mesh.tets.data() + 4 * t;
    for (int c = 0; c < 4; ++c) {
      if (tet[c] < 0 || static_cast<std::size_t>(tet[c]) >= n) {
        std::ostringstream s;
        s << element_name(t, element_ids) << " refers to vertex index " << tet[c]
          << " outside the " << n << " vertices of the mesh";
        throw InputError(source, 0, s.str());
      }
      for (int c2 = 0; c2 < c; ++c2)
        if (tet[c2] == tet[c]) {
          std::ostringstream s;
          s << element_name(t, element_ids) << " uses vertex " << tet[c]
            << " twice (expected four distinct vertices)";
          throw InputError(source, 0, s.str());
        }
    }
    const double* p[4] = {mesh.points.data() + 3 * tet[0], mesh.points.data() + 3 * tet[1],
                          mesh.points.data() + 3 * tet[2], mesh.points.data() + 3 * tet[3]};
    const double vol = signed_tet_volume(p[0], p[1], p[2], p[3]);
    const double l = longest_edge(p);
    if (!(std::abs(6.0 * vol) > 1e-10 * l * l * l)) {
      std::ostringstream s;
      s << element_name(t, element_ids) << " is degenerate (volume " << vol
        << " for longest edge " << l << "; expected a tetrahedron with non-zero volume)";
      throw InputError(source, 0, s.str());
    }
    if (vol < 0) {
      std::swap(tet[2], tet[3]);
      if (first_inverted == m) first_inverted = t;
      ++report.reoriented_tets;
    }
  }
  if (report.reoriented_tets > 0) {
    std::ostringstream s;
    s << source << ": warning: " << report.reoriented_tets
      << " inverted tetrahedra were reoriented (first: " << element_name(first_inverted, element_ids) << ")";
    report.warnings.push_back(s.str());
  }

  // Unreferenced vertices: drop them and compact indices (keeps the relative order).
  std::vector<index_t> remap(n, -1);
  for (index_t v : mesh.tets) remap[v] = 0;
  index_t next = 0;
  std::size_t first_unref = n;
  for (std::size_t i = 0; i < n; ++i) {
    if (remap[i] == 0) {
      remap[i] = next++;
    } else {
      if (first_unref == n) first_unref = i;
      ++report.unreferenced_vertices;
    }
  }
  if (report.unreferenced_vertices > 0) {
    std::vector<double> pts(3 * static_cast<std::size_t>(next));
    for (std::size_t i = 0; i < n; ++i)
      if (remap[i] >= 0)
        for (int d = 0; d < 3; ++d) pts[3 * static_cast<std::size_t>(remap[i]) + d] = mesh.points[3 * i + d];
    mesh.points.swap(pts);
    for (index_t& v : mesh.tets) v = remap[v];
    std::ostringstream s;
    s << source << ": warning: " << report.unreferenced_vertices
      << " vertices are used by no tetrahedron and were removed (first: vertex " << (first_unref + 1) << ")";
    report.warnings.push_back(s.str());
  }

  std::size_t nonmanifold = 0;
  const Surface surf = extract_surface(mesh, &nonmanifold);
  if (nonmanifold > 0) {
    std::ostringstream s;
    s << nonmanifold << " faces are shared by more than two tetrahedra (expected a conforming mesh)";
    throw InputError(source, 0, s.str());
  }
  const ClosednessDefect d = check_closed(surf);
  if (d.open_edges > 0) {
    std::ostringstream s;
    s << "the boundary surface is not closed: " << d.open_edges << " edges are not shared by exactly two "
      << "consistently oriented boundary triangles (first: edge between vertices " << (d.a + 1) << " and "
      << (d.b + 1) << ", used " << d.uses << " times)";
    throw InputError(source, 0, s.str());
  }
  return report;
}

}  // namespace softcontact
