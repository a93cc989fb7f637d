#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <numbers>
#include <string>
#include <vector>

#include "softcontact/error.hpp"
#include "softcontact/primitives.hpp"
#include "softcontact/surface.hpp"

using namespace softcontact;

namespace {

constexpr double kPi = std::numbers::pi;

const double* P(const TetMesh& m, index_t i) { return m.points.data() + 3 * static_cast<std::size_t>(i); }

// Tet quality 6 sqrt(2) V / l_rms^3: 1 for a regular tet, 0.657 for the Kuhn tets of a
// cube, -> 0 for slivers and needles.
double min_quality(const TetMesh& m) {
  double q = 1e300;
  for (std::size_t t = 0; t < m.num_tets(); ++t) {
    const index_t* tet = m.tets.data() + 4 * t;
    const double* p[4] = {P(m, tet[0]), P(m, tet[1]), P(m, tet[2]), P(m, tet[3])};
    double l2 = 0;
    for (int i = 0; i < 4; ++i)
      for (int j = i + 1; j < 4; ++j)
        for (int d = 0; d < 3; ++d) l2 += (p[i][d] - p[j][d]) * (p[i][d] - p[j][d]);
    const double lrms = std::sqrt(l2 / 6);
    q = std::min(q, 6 * std::sqrt(2.0) * signed_tet_volume(p[0], p[1], p[2], p[3]) / (lrms * lrms * lrms));
  }
  return q;
}

// Smallest distance between two distinct vertices (sweep over the vertices sorted by x).
double min_vertex_distance(const TetMesh& m) {
  std::vector<index_t> order(m.num_vertices());
  for (std::size_t i = 0; i < order.size(); ++i) order[i] = static_cast<index_t>(i);
  std::sort(order.begin(), order.end(), [&](index_t a, index_t b) { return P(m, a)[0] < P(m, b)[0]; });
  double best = 1e300;
  for (std::size_t i = 0; i < order.size(); ++i)
    for (std::size_t j = i + 1; j < order.size() && P(m, order[j])[0] - P(m, order[i])[0] < best; ++j) {
      const double *a = P(m, order[i]), *b = P(m, order[j]);
      best = std::min(best, std::sqrt((a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) +
                                      (a[2] - b[2]) * (a[2] - b[2])));
    }
  return best;
}

// What every generated mesh must satisfy: nothing for validate_mesh to repair, every tet
// positive, conforming (no face in more than two tets), a closed outward surface
// enclosing the tets' volume, no coincident vertices, the expected Euler characteristic
// of the surface (2 for a ball, 0 for a torus: the seam is welded). Returns the surface.
Surface expect_valid(const TetMesh& mesh, int euler, double size) {
  TetMesh copy = mesh;
  const MeshReport r = validate_mesh(copy, "generated");
  EXPECT_EQ(r.reoriented_tets, 0u);
  EXPECT_EQ(r.unreferenced_vertices, 0u);
  EXPECT_TRUE(r.warnings.empty());
  EXPECT_EQ(copy.points, mesh.points);
  EXPECT_EQ(copy.tets, mesh.tets);
  std::size_t nonpositive = 0;
  for (std::size_t t = 0; t < mesh.num_tets(); ++t) {
    const index_t* tet = mesh.tets.data() + 4 * t;
    if (!(signed_tet_volume(P(mesh, tet[0]), P(mesh, tet[1]), P(mesh, tet[2]), P(mesh, tet[3])) > 0)) ++nonpositive;
  }
  EXPECT_EQ(nonpositive, 0u);
  std::size_t nonmanifold = 1;
  const Surface s = extract_surface(mesh, &nonmanifold);
  EXPECT_EQ(nonmanifold, 0u);
  EXPECT_EQ(check_closed(s).open_edges, 0u);
  const double v = tet_volume_sum(mesh);
  EXPECT_NEAR(enclosed_volume(mesh, s), v, 1e-12 * v);
  // Closed triangulated surface: E = 3F/2, so chi = V - F/2.
  EXPECT_EQ(static_cast<long>(s.vertices.size()) - static_cast<long>(s.num_triangles() / 2), euler);
  EXPECT_GT(min_vertex_distance(mesh), 1e-3 * size);
  return s;
}

double rel_error(double v, double exact) { return std::abs(v - exact) / exact; }

// Every boundary vertex satisfies on_surface, and every vertex that does is a boundary
// vertex (so the boundary is exactly the analytic surface's vertices).
void expect_boundary_is(const TetMesh& m, const Surface& s, const std::function<bool(const double*)>& on_surface) {
  std::vector<char> boundary(m.num_vertices(), 0);
  for (index_t v : s.vertices) boundary[static_cast<std::size_t>(v)] = 1;
  std::size_t off = 0, missed = 0;
  for (std::size_t v = 0; v < m.num_vertices(); ++v) {
    const bool on = on_surface(P(m, static_cast<index_t>(v)));
    if (boundary[v] && !on) ++off;
    if (!boundary[v] && on) ++missed;
  }
  EXPECT_EQ(off, 0u) << "boundary vertices off the analytic surface";
  EXPECT_EQ(missed, 0u) << "interior vertices on the analytic surface";
}

// Counts of the disk/ball layout documented in primitives.hpp.
int rings(int across) { return std::max(1, (across + 2) / 4); }
int block(int across) { return std::max(1, across - 2 * rings(across)); }

}  // namespace

TEST(Primitives, BoxCountsVolumeAndFlatFaces) {
  const double lx = 0.3, ly = 0.2, lz = 0.1;
  const int nx = 3, ny = 4, nz = 5;
  const TetMesh m = make_box(lx, ly, lz, nx, ny, nz);
  EXPECT_EQ(m.num_vertices(), static_cast<std::size_t>((nx + 1) * (ny + 1) * (nz + 1)));
  EXPECT_EQ(m.num_tets(), static_cast<std::size_t>(6 * nx * ny * nz));
  const Surface s = expect_valid(m, 2, lz);
  EXPECT_EQ(s.num_triangles(), static_cast<std::size_t>(4 * (nx * ny + ny * nz + nz * nx)));
  EXPECT_NEAR(tet_volume_sum(m), lx * ly * lz, 1e-14 * lx * ly * lz);
  // Faces at exactly +-l/2; the box is centred (sum of coordinates is zero by symmetry).
  expect_boundary_is(m, s, [&](const double* x) {
    return std::abs(x[0]) == lx / 2 || std::abs(x[1]) == ly / 2 || std::abs(x[2]) == lz / 2;
  });
  for (int d = 0; d < 3; ++d) {
    double lo = 1e300, hi = -1e300;
    for (std::size_t v = 0; v < m.num_vertices(); ++v) {
      lo = std::min(lo, m.points[3 * v + d]);
      hi = std::max(hi, m.points[3 * v + d]);
    }
    EXPECT_EQ(lo, -hi);
  }
  // Cubic cells: every tet is a Kuhn tet of a cube, quality 6 sqrt(2) (1/6) / (10/6)^1.5.
  const TetMesh cube = make_box(1.0, 1.0, 1.0, 4, 4, 4);
  EXPECT_NEAR(min_quality(cube), std::sqrt(2.0) / std::pow(10.0 / 6.0, 1.5), 1e-12);
}

TEST(Primitives, ThinBoxIsAValidPlate) {
  // A membrane-like plate, 1 m x 1 m x 1 mm in one layer of cells.
  const TetMesh m = make_box(1.0, 1.0, 1e-3, 10, 10, 1);
  expect_valid(m, 2, 1e-3);
  EXPECT_NEAR(tet_volume_sum(m), 1e-3, 1e-14 * 1e-3);
  EXPECT_GT(min_quality(m), 0.0);
}

TEST(Primitives, CylinderIsValidOnItsSurfaceAndConverges) {
  const double r = 0.05, h = 0.1, exact = kPi * r * r * h;
  double err[2];
  for (int level = 0; level < 2; ++level) {
    const int radial = 4 << level, axial = 8 << level;  // cells about r/radial = h/axial
    const TetMesh m = make_cylinder(r, h, radial, axial);
    const std::size_t n = static_cast<std::size_t>(block(2 * radial)), k = static_cast<std::size_t>(rings(2 * radial));
    EXPECT_EQ(m.num_vertices(), ((n + 1) * (n + 1) + 4 * n * k) * static_cast<std::size_t>(axial + 1));
    EXPECT_EQ(m.num_tets(), 6 * (n * n + 4 * n * k) * static_cast<std::size_t>(axial));
    const Surface s = expect_valid(m, 2, r / radial);
    // Caps: two triangles per quad of the disk; side: 4n quads around per layer.
    EXPECT_EQ(s.num_triangles(), 4 * (n * n + 4 * n * k) + 8 * n * static_cast<std::size_t>(axial));
    expect_boundary_is(m, s, [&](const double* x) {
      return std::abs(std::hypot(x[0], x[1]) - r) <= 1e-12 * r || std::abs(x[2]) == h / 2;
    });
    err[level] = rel_error(tet_volume_sum(m), exact);
    // Measured min quality 0.407 (radial 4) and 0.422 (radial 8).
    EXPECT_GT(min_quality(m), 0.38);
  }
  // Inscribed regular 4n-gon cross-section: error 1 - sin(2 pi/4n)/(2 pi/4n), measured
  // 2.55e-2 (radial 4) and 6.41e-3 (radial 8): O(h^2).
  EXPECT_LT(err[0], 0.03);
  EXPECT_LT(err[1], 0.007);
  EXPECT_LT(err[1], 0.3 * err[0]);
}

TEST(Primitives, SphereIsValidOnItsSurfaceAndConverges) {
  const double r = 0.02, exact = 4.0 / 3.0 * kPi * r * r * r;
  double err[2];
  for (int level = 0; level < 2; ++level) {
    const int cells = 8 << level;
    const TetMesh m = make_sphere(r, cells);
    const std::size_t n = static_cast<std::size_t>(block(cells)), k = static_cast<std::size_t>(rings(cells));
    EXPECT_EQ(m.num_vertices(), (n + 1) * (n + 1) * (n + 1) + (6 * n * n + 2) * k);
    EXPECT_EQ(m.num_tets(), 6 * (n * n * n + 6 * n * n * k));
    const Surface s = expect_valid(m, 2, 2 * r / cells);
    EXPECT_EQ(s.num_triangles(), 12 * n * n);
    expect_boundary_is(m, s, [&](const double* x) {
      return std::abs(std::sqrt(x[0] * x[0] + x[1] * x[1] + x[2] * x[2]) - r) <= 1e-12 * r;
    });
    err[level] = rel_error(tet_volume_sum(m), exact);
    // Measured min quality 0.346 (cells 8) and 0.321 (cells 16), tending to about 0.28.
    EXPECT_GT(min_quality(m), 0.3);
  }
  // Inscribed polyhedron with 6 n^2 quads: measured 6.51e-2 (cells 8) and 1.67e-2 (16).
  EXPECT_LT(err[0], 0.07);
  EXPECT_LT(err[1], 0.02);
  EXPECT_LT(err[1], 0.3 * err[0]);
}

TEST(Primitives, TorusIsValidWeldedOnItsSurfaceAndConverges) {
  const double R = 0.1, a = 0.04, exact = 2 * kPi * kPi * R * a * a;
  double err[2];
  for (int level = 0; level < 2; ++level) {
    // Cells about as long around the ring (2 pi R / around) as across (2 a / tube).
    const int tube = 8 << level, around = 64 << level;
    const TetMesh m = make_torus(R, a, around, tube);
    const std::size_t n = static_cast<std::size_t>(block(tube)), k = static_cast<std::size_t>(rings(tube));
    EXPECT_EQ(m.num_vertices(), ((n + 1) * (n + 1) + 4 * n * k) * static_cast<std::size_t>(around));
    EXPECT_EQ(m.num_tets(), 6 * (n * n + 4 * n * k) * static_cast<std::size_t>(around));
    const Surface s = expect_valid(m, 0, 2 * a / tube);
    EXPECT_EQ(s.num_triangles(), 8 * n * static_cast<std::size_t>(around));
    expect_boundary_is(m, s, [&](const double* x) {
      return std::abs(std::hypot(std::hypot(x[0], x[1]) - R, x[2]) - a) <= 1e-12 * a;
    });
    err[level] = rel_error(tet_volume_sum(m), exact);
    // Measured min quality 0.364 at both levels.
    EXPECT_GT(min_quality(m), 0.33);
  }
  // Mostly the tube's inscribed 16-gon / 32-gon: measured 2.71e-2 and 6.81e-3.
  EXPECT_LT(err[0], 0.03);
  EXPECT_LT(err[1], 0.0075);
  EXPECT_LT(err[1], 0.3 * err[0]);
}

TEST(Primitives, CoarsestMeshesAreValid) {
  // The minimum counts: the torus with 3 cells around still welds into a ring.
  expect_valid(make_box(1, 1, 1, 1, 1, 1), 2, 1.0);
  expect_valid(make_cylinder(1, 1, 1, 1), 2, 0.1);
  expect_valid(make_sphere(1, 2), 2, 0.1);
  const TetMesh torus = make_torus(1, 0.5, 3, 2);
  expect_valid(torus, 0, 0.1);
  EXPECT_GT(min_quality(torus), 0.0);
}

TEST(Primitives, AreDeterministic) {
  const TetMesh a = make_torus(1.0, 0.4, 12, 5), b = make_torus(1.0, 0.4, 12, 5);
  EXPECT_EQ(a.points, b.points);  // bitwise: same arithmetic in the same order
  EXPECT_EQ(a.tets, b.tets);
  const TetMesh c = make_sphere(1.0, 7), d = make_sphere(1.0, 7);
  EXPECT_EQ(c.points, d.points);
  EXPECT_EQ(c.tets, d.tets);
}

TEST(Primitives, InvalidArgumentsThrowInputError) {
  const auto expect_input_error = [](const std::function<void()>& f, const std::string& needle) {
    try {
      f();
      ADD_FAILURE() << "no InputError, expected one mentioning '" << needle << "'";
    } catch (const InputError& e) {
      EXPECT_NE(e.detail().find("expected"), std::string::npos) << e.what();
      EXPECT_NE(e.detail().find(needle), std::string::npos) << e.what();
    }
  };
  const double nan = std::nan(""), inf = HUGE_VAL;
  expect_input_error([] { make_box(0, 1, 1, 1, 1, 1); }, "lx=0");
  expect_input_error([] { make_box(1, -1, 1, 1, 1, 1); }, "ly=-1");
  expect_input_error([&] { make_box(1, 1, nan, 1, 1, 1); }, "lz=nan");
  expect_input_error([] { make_box(1, 1, 1, 1, 0, 1); }, "ny=0");
  expect_input_error([] { make_box(1, 1, 1, 100000, 100000, 100000); }, "tets");
  expect_input_error([] { make_cylinder(0, 1, 1, 1); }, "r=0");
  expect_input_error([&] { make_cylinder(1, inf, 1, 1); }, "h=inf");
  expect_input_error([] { make_cylinder(1, 1, 0, 1); }, "radial=0");
  expect_input_error([] { make_cylinder(1, 1, 1, -2); }, "axial=-2");
  expect_input_error([] { make_cylinder(1, 1, 2000000000, 1); }, "vertices");
  expect_input_error([] { make_sphere(-0.5, 4); }, "r=-0.5");
  expect_input_error([] { make_sphere(1, 1); }, "cells=1");
  expect_input_error([] { make_sphere(1, 2000000000); }, "vertices");
  expect_input_error([] { make_torus(1, 1, 8, 4); }, "a < R");
  expect_input_error([] { make_torus(1, 2, 8, 4); }, "a=2");
  expect_input_error([] { make_torus(0, 0.5, 8, 4); }, "R=0");
  expect_input_error([] { make_torus(1, 0.5, 2, 4); }, "around=2");
  expect_input_error([] { make_torus(1, 0.5, 8, 1); }, "tube=1");
}
