#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "softcontact/error.hpp"
#include "softcontact/mesh_io.hpp"
#include "softcontact/surface.hpp"

using namespace softcontact;

namespace {

std::string data(const std::string& name) { return std::string(SOFTCONTACT_TEST_DATA) + "/meshes/" + name; }

template <class F>
std::string input_error(F&& f) {
  try {
    f();
  } catch (const InputError& e) {
    return e.what();
  }
  ADD_FAILURE() << "expected an InputError";
  return {};
}

#define EXPECT_CONTAINS(text, part) EXPECT_NE((text).find(part), std::string::npos) << "message: " << (text)

void expect_unit_cube(const TetMesh& m) {
  EXPECT_EQ(m.num_vertices(), 8u);
  EXPECT_EQ(m.num_tets(), 6u);
  EXPECT_NEAR(tet_volume_sum(m), 1.0, 1e-14);
  const Surface s = extract_surface(m);
  EXPECT_EQ(s.num_triangles(), 12u);
  EXPECT_EQ(check_closed(s).open_edges, 0u);
}

}  // namespace

TEST(TetGen, ReadsZeroBasedFilesWithAttributesMarkersAndComments) {
  MeshReport report;
  const TetMesh m = read_tetgen(data("cube0.node"), &report);
  expect_unit_cube(m);
  EXPECT_TRUE(report.warnings.empty());
  // Point 6 (0-based) is (1,1,1); it is the Kuhn diagonal, shared by all tets.
  EXPECT_EQ(m.points[3 * 6], 1.0);
  EXPECT_EQ(m.points[3 * 6 + 1], 1.0);
  EXPECT_EQ(m.points[3 * 6 + 2], 1.0);
  EXPECT_EQ(m.tets[3], 6);
}

TEST(TetGen, ReadsOneBasedFilesByEitherNameOrStem) {
  const TetMesh a = read_tetgen(data("cube1.node"));
  expect_unit_cube(a);
  EXPECT_EQ(a.tets[0], 0);  // point 1 is vertex 0
  EXPECT_EQ(read_tetgen(data("cube1.ele")).tets, a.tets);
  EXPECT_EQ(read_tetgen(data("cube1")).tets, a.tets);
  EXPECT_EQ(read_tetgen(data("cube0.ele")).tets, a.tets);  // same mesh, other base
}

TEST(TetGen, PointIndexOutOfRangeNamesTetAndRange) {
  const std::string msg = input_error([] { read_tetgen(data("range.ele")); });
  EXPECT_CONTAINS(msg, "range.ele:3: tetrahedron 1 refers to point 8, but ");
  EXPECT_CONTAINS(msg, "range.node has points 0 to 7");
}

TEST(TetGen, SecondOrderTetsAreRejected) {
  const std::string msg = input_error([] { read_tetgen(data("tet10.node")); });
  EXPECT_CONTAINS(msg, "tet10.ele:1: the file has 10 nodes per tetrahedron");
  EXPECT_CONTAINS(msg, "only linear 4-node tetrahedra are supported");
}

TEST(TetGen, BadCoordinateTokenNamesLineAndPoint) {
  const std::string msg = input_error([] { read_tetgen(data("badtok.node")); });
  EXPECT_CONTAINS(msg, "badtok.node:5: expected 'x y z' coordinates of point 3, got '1 x 0'");
}

TEST(TetGen, MorePointsThanDeclared) {
  const std::string msg = input_error([] { read_tetgen(data("extra.node")); });
  EXPECT_CONTAINS(msg, "extra.node:11: found more points than the 8 declared on line 2");
}

TEST(TetGen, TruncatedEleFile) {
  const std::string msg = input_error([] { read_tetgen(data("truncated.ele")); });
  EXPECT_CONTAINS(msg, "truncated.ele:4: unexpected end of file: expected tetrahedron 4 of 6");
  EXPECT_CONTAINS(msg, "truncated");
}

TEST(TetGen, ZeroTetsAreRejected) {
  const std::string msg = input_error([] { read_tetgen(data("zero.node")); });
  EXPECT_CONTAINS(msg, "zero.ele:1: the file declares 0 tetrahedra (expected at least one)");
}

TEST(TetGen, HugeCountIsRejectedBeforeAllocating) {
  const auto dir = std::filesystem::path(testing::TempDir()) / "softcontact_tetgen";
  std::filesystem::create_directories(dir);
  const std::string path = (dir / "huge.node").string();
  {
    std::ofstream out(path);
    out << "# corrupt count\n99999999999 3 0 0\n1 0 0 0\n";
  }
  const std::string msg = input_error([&] { read_tetgen(path); });
  EXPECT_CONTAINS(msg, path + ":2: the point count 99999999999 cannot fit");
}

TEST(TetGen, MissingEleFileNamesIt) {
  const std::string msg = input_error([] { read_tetgen(data("unknown.node")); });
  EXPECT_CONTAINS(msg, "unknown.node: cannot open the mesh file");
  const auto dir = std::filesystem::path(testing::TempDir()) / "softcontact_tetgen";
  std::filesystem::create_directories(dir);
  std::filesystem::copy_file(data("cube1.node"), dir / "lonely.node", std::filesystem::copy_options::overwrite_existing);
  const std::string msg2 = input_error([&] { read_tetgen((dir / "lonely.node").string()); });
  EXPECT_CONTAINS(msg2, "lonely.ele: cannot open the mesh file");
}
