#include <gtest/gtest.h>

#include <map>
#include <random>
#include <set>

#include "softcontact/error.hpp"
#include "softcontact/primitives.hpp"
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

// extract_surface against a count of every face by its vertex set (std::map): the
// boundary is each face whose set occurs once, in slot order (tet, then face 0..3) and
// oriented as kTetFaces lists it; the non-manifold count is the sets occurring more than
// twice; the vertices are those of the boundary, ascending. On primitives, on a box
// with a tet repeated (its faces then occur twice or, on the boundary, twice instead of
// once) and on random tets over few vertices (faces shared by many tets).
TEST(Surface, BoundaryIsEveryFaceThatOccursOnceInTetOrder) {
  auto reference = [](const TetMesh& m, std::size_t& nonmanifold) {
    std::map<std::set<index_t>, int> count;
    auto face = [&](std::size_t t, int f) {
      const index_t* tet = &m.tets[4 * t];
      return std::set<index_t>{tet[kTetFaces[f][0]], tet[kTetFaces[f][1]], tet[kTetFaces[f][2]]};
    };
    for (std::size_t t = 0; t < m.num_tets(); ++t)
      for (int f = 0; f < 4; ++f) ++count[face(t, f)];
    Surface s;
    std::set<index_t> on;
    for (std::size_t t = 0; t < m.num_tets(); ++t)
      for (int f = 0; f < 4; ++f)
        if (count[face(t, f)] == 1)
          for (int c = 0; c < 3; ++c) {
            s.triangles.push_back(m.tets[4 * t + static_cast<std::size_t>(kTetFaces[f][c])]);
            on.insert(s.triangles.back());
          }
    s.vertices.assign(on.begin(), on.end());
    nonmanifold = 0;
    for (const auto& [key, k] : count) nonmanifold += k > 2 ? 1 : 0;
    return s;
  };
  std::vector<std::pair<std::string, TetMesh>> cases;
  cases.emplace_back("box", make_box(1, 2, 3, 3, 4, 5));
  cases.emplace_back("torus", make_torus(1, 0.3, 12, 6));
  TetMesh repeated = make_box(1, 1, 1, 2, 2, 2);
  repeated.tets.insert(repeated.tets.end(), repeated.tets.begin() + 8, repeated.tets.begin() + 12);
  cases.emplace_back("box with tet 2 repeated", repeated);
  std::mt19937 rng(7);
  for (int vertices : {6, 12, 40}) {
    TetMesh m;
    m.points.assign(3 * static_cast<std::size_t>(vertices), 0.0);
    std::uniform_int_distribution<index_t> pick(0, vertices - 1);
    for (int t = 0; t < 300; ++t) {
      std::set<index_t> four;
      while (four.size() < 4) four.insert(pick(rng));
      std::vector<index_t> tet(four.begin(), four.end());
      std::shuffle(tet.begin(), tet.end(), rng);
      m.tets.insert(m.tets.end(), tet.begin(), tet.end());
    }
    cases.emplace_back("300 random tets over " + std::to_string(vertices) + " vertices", m);
  }
  std::size_t boundary_faces = 0, shared_faces = 0;
  for (const auto& [name, m] : cases) {
    SCOPED_TRACE(name);
    std::size_t nonmanifold = 0, expected_nonmanifold = 0;
    const Surface s = extract_surface(m, &nonmanifold);
    const Surface r = reference(m, expected_nonmanifold);
    EXPECT_EQ(s.triangles, r.triangles);
    EXPECT_EQ(s.vertices, r.vertices);
    EXPECT_EQ(nonmanifold, expected_nonmanifold);
    boundary_faces += r.num_triangles();
    shared_faces += expected_nonmanifold;
  }
  // The cases hold both kinds of face (else the comparison shows little).
  EXPECT_GT(boundary_faces, 100u);
  EXPECT_GT(shared_faces, 50u);
  TetMesh bad = make_box(1, 1, 1, 1, 1, 1);
  bad.tets[5] = -1;
  EXPECT_THROW(extract_surface(bad), RuntimeFailure);
}
