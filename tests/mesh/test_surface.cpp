#include <gtest/gtest.h>

#include "softcontact/surface.hpp"

using namespace softcontact;

// Unit cube split into 6 tets around the diagonal 0-6 (Kuhn / Freudenthal split).
static TetMesh kuhn_cube() {
  TetMesh m;
  m.points = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0, 0, 0, 1, 1, 0, 1, 1, 1, 1, 0, 1, 1};
  m.tets = {0, 1, 2, 6, 0, 2, 3, 6, 0, 3, 7, 6, 0, 7, 4, 6, 0, 4, 5, 6, 0, 5, 1, 6};
  return m;
}

TEST(Surface, KuhnCubeIsClosedOutwardAndEnclosesUnitVolume) {
  TetMesh m = kuhn_cube();
  std::swap(m.tets[4 * 2 + 1], m.tets[4 * 2 + 2]);  // invert tet 3 of 6
  const MeshReport r = validate_mesh(m, "kuhn_cube");
  EXPECT_EQ(r.reoriented_tets, 1u);
  ASSERT_EQ(r.warnings.size(), 1u);
  EXPECT_NE(r.warnings[0].find("tetrahedron 3"), std::string::npos) << r.warnings[0];
  const Surface s = extract_surface(m);
  EXPECT_EQ(s.num_triangles(), 12u);  // two triangles per cube face
  EXPECT_EQ(check_closed(s).open_edges, 0u);
  EXPECT_NEAR(tet_volume_sum(m), 1.0, 1e-14);
  EXPECT_NEAR(enclosed_volume(m, s), 1.0, 1e-14);  // divergence theorem
  EXPECT_EQ(s.vertices.size(), 8u);
}

TEST(Surface, VertexNormalsOfCubeCornerPointOutward) {
  TetMesh m = kuhn_cube();
  validate_mesh(m, "kuhn_cube");
  const Surface s = extract_surface(m);
  const auto n = vertex_normals(m, s);
  // Corner 6 = (1,1,1): its area-weighted normal has all components positive.
  for (int d = 0; d < 3; ++d) EXPECT_GT(n[3 * 6 + d], 0.1);
  // Corner 0 = (0,0,0): all negative.
  for (int d = 0; d < 3; ++d) EXPECT_LT(n[d], -0.1);
}
