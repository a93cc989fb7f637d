// Point in tetrahedron: agreement with barycentric coordinates away from the faces, and
// the tie rule on faces, edges and vertices shared by several tets of a conforming mesh.
#include <gtest/gtest.h>

#include <random>

#include "collide/point_in_tet.hpp"
#include "softcontact/primitives.hpp"

using namespace softcontact;
using namespace softcontact::collide;

namespace {

// How many tets of the mesh take p (boundary faces marked from the mesh itself).
int owners(const TetMesh& m, const std::vector<unsigned>& boundary, const V3& p) {
  int n = 0;
  for (std::size_t t = 0; t < m.num_tets(); ++t)
    n += point_in_tet(m.points.data(), &m.tets[4 * t], boundary[t], p) == TetSide::inside;
  return n;
}

// Boundary mask per tet: faces that no other tet shares (bits 0..3), corners on such a
// face (bits 4..7).
std::vector<unsigned> boundary_masks(const TetMesh& m) {
  std::vector<unsigned> mask(m.num_tets(), 0);
  for (std::size_t t = 0; t < m.num_tets(); ++t)
    for (int j = 0; j < 4; ++j) {
      std::array<index_t, 3> f{};
      int k = 0;
      for (int c = 0; c < 4; ++c)
        if (c != j) f[k++] = m.tets[4 * t + c];
      std::sort(f.begin(), f.end());
      bool shared = false;
      for (std::size_t u = 0; u < m.num_tets() && !shared; ++u) {
        if (u == t) continue;
        int common = 0;
        for (int c = 0; c < 4; ++c) common += std::binary_search(f.begin(), f.end(), m.tets[4 * u + c]);
        shared = common == 3;
      }
      if (!shared) mask[t] |= 1u << j;
    }
  // Corners on a boundary face of any tet are surface vertices.
  std::vector<char> surface(m.num_vertices(), 0);
  for (std::size_t t = 0; t < m.num_tets(); ++t)
    for (int j = 0; j < 4; ++j)
      if (mask[t] & (1u << j))
        for (int c = 0; c < 4; ++c)
          if (c != j) surface[static_cast<std::size_t>(m.tets[4 * t + c])] = 1;
  for (std::size_t t = 0; t < m.num_tets(); ++t)
    for (int c = 0; c < 4; ++c)
      if (surface[static_cast<std::size_t>(m.tets[4 * t + c])]) mask[t] |= 16u << c;
  return mask;
}

}  // namespace

// Away from the faces the answer is the sign of the barycentric coordinates (computed
// here by Cramer's rule), for either orientation of the tet.
TEST(CollisionPointInTet, AgreesWithBarycentricCoordinates) {
  std::mt19937_64 g(7);
  std::uniform_real_distribution<double> u(-1, 1);
  int inside = 0;
  for (int trial = 0; trial < 2000; ++trial) {
    std::vector<double> x(12);
    for (double& c : x) c = u(g);
    const index_t tet[4] = {0, 1, 2, 3}, flipped[4] = {1, 0, 2, 3};
    const V3 a = load(x.data(), 0), b = load(x.data(), 1), c = load(x.data(), 2), d = load(x.data(), 3);
    const double v = orient(a, b, c, d);
    if (std::abs(v) < 1e-3) continue;
    // Half the points: combinations of the corners with weights in [-0.1, 1) (mostly
    // inside); the other half anywhere in the cube.
    V3 p = {u(g), u(g), u(g)};
    if (trial % 2) {
      double wsum = 0, wt[4];
      for (double& wi : wt) wsum += (wi = 0.45 + 0.55 * u(g));
      p = {0, 0, 0};
      for (int k = 0; k < 4; ++k) p = p + (wt[k] / wsum) * load(x.data(), k);
    }
    const double l[4] = {orient(p, b, c, d) / v, orient(a, p, c, d) / v, orient(a, b, p, d) / v, orient(a, b, c, p) / v};
    const double lmin = std::min({l[0], l[1], l[2], l[3]});
    if (std::abs(lmin) < 1e-9) continue;  // too near a face for the reference to be sure
    const TetSide expect = lmin > 0 ? TetSide::inside : TetSide::outside;
    EXPECT_EQ(point_in_tet(x.data(), tet, 0, p), expect);
    EXPECT_EQ(point_in_tet(x.data(), flipped, 0, p), expect);
    inside += expect == TetSide::inside;
  }
  EXPECT_GT(inside, 300);
}

TEST(CollisionPointInTet, FlatTetIsDegenerate) {
  const std::vector<double> x = {0, 0, 0, 1, 0, 0, 0, 1, 0, 0.3, 0.3, 1e-14};
  const index_t tet[4] = {0, 1, 2, 3};
  EXPECT_EQ(point_in_tet(x.data(), tet, 0, {0.2, 0.2, 0}), TetSide::degenerate);
}

// Points on interior faces, edges and vertices of a 2 x 2 x 2-cell box (48 tets): every
// point of a grid of step 1/16 strictly inside the box is taken by exactly one tet
// (dyadic coordinates make the orientation tests exact, so the points really are on the
// faces); points on the box's surface by at most one (none on the open faces of the box,
// where the boundary rule applies alone).
TEST(CollisionPointInTet, TieRuleGivesEachPointToOneTet) {
  const TetMesh m = make_box(1, 1, 1, 2, 2, 2);
  const std::vector<unsigned> boundary = boundary_masks(m);
  int interior = 0, on_surface = 0;
  for (int i = -8; i <= 8; ++i)
    for (int j = -8; j <= 8; ++j)
      for (int k = -8; k <= 8; ++k) {
        const V3 p = {i / 16.0, j / 16.0, k / 16.0};
        const int n = owners(m, boundary, p);
        const bool surface = std::abs(i) == 8 || std::abs(j) == 8 || std::abs(k) == 8;
        if (surface) {
          EXPECT_LE(n, 1) << p[0] << " " << p[1] << " " << p[2];
          ++on_surface;
        } else {
          EXPECT_EQ(n, 1) << p[0] << " " << p[1] << " " << p[2];
          ++interior;
        }
      }
  EXPECT_EQ(interior, 15 * 15 * 15);
  EXPECT_GT(on_surface, 0);
  // The centre is a vertex shared by 24 tets; the mid-points of the cell faces lie on the
  // Kuhn diagonals.
  EXPECT_EQ(owners(m, boundary, {0, 0, 0}), 1);
  EXPECT_EQ(owners(m, boundary, {0.25, 0.25, 0.25}), 1);
  // Points inside the box's faces (not on an edge of their triangles): not inside.
  EXPECT_EQ(owners(m, boundary, {0.5, 0.1, 0.3}), 0);
  EXPECT_EQ(owners(m, boundary, {-0.2, -0.5, 0.35}), 0);
  EXPECT_EQ(owners(m, boundary, {0.1, 0.4, -0.5}), 0);
}

// The same on a curved, irregular mesh: points on the segments between random pairs of
// vertices of a sphere mesh, half-way (on faces and edges when the two vertices share
// one), are taken at most once, and exactly once when strictly inside by a margin.
TEST(CollisionPointInTet, TieRuleOnSphereVertices) {
  const TetMesh m = make_sphere(1, 4);
  const std::vector<unsigned> boundary = boundary_masks(m);
  // Every interior vertex of the mesh lies on the faces of all tets around it.
  int tested = 0;
  for (std::size_t v = 0; v < m.num_vertices(); ++v) {
    const V3 p = load(m.points.data(), static_cast<index_t>(v));
    if (std::sqrt(norm2(p)) > 0.99) continue;  // on the surface
    EXPECT_EQ(owners(m, boundary, p), 1) << "vertex " << v;
    ++tested;
  }
  EXPECT_GT(tested, 10);
}
