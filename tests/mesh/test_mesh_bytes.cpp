// append_mesh_bytes / take_mesh_bytes (mesh_io.hpp), the form in which meshes travel
// between ranks: two meshes and a report back bitwise as appended (a -0.0, a NaN and the
// smallest subnormal among the points), one after the other from one buffer; every
// truncation of the buffer is a RuntimeFailure, never a read past its end.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <limits>

#include "softcontact/error.hpp"
#include "softcontact/mesh_io.hpp"
#include "softcontact/primitives.hpp"

using namespace softcontact;

TEST(MeshBytes, TwoMeshesAndAReportComeBackBitwise) {
  TetMesh a = make_box(0.3, 0.2, 0.1, 2, 1, 1);
  a.points[0] = -0.0;
  a.points[1] = std::numeric_limits<double>::quiet_NaN();
  a.points[2] = std::numeric_limits<double>::denorm_min();
  const TetMesh b = make_box(1, 1, 1, 1, 1, 1);
  MeshReport rep;
  rep.reoriented_tets = 3;
  rep.unreferenced_vertices = 1;
  rep.warnings = {"x.msh: warning: 3 inverted tets reoriented", "", "x.msh: warning: 1 vertices used by no tet"};
  std::vector<char> bytes{'h'};  // something before, as in the parser's broadcast
  append_mesh_bytes(bytes, a, &rep);
  append_mesh_bytes(bytes, b);
  std::size_t at = 1;
  MeshReport got_rep;
  const TetMesh got_a = take_mesh_bytes(bytes, at, &got_rep);
  ASSERT_EQ(got_a.points.size(), a.points.size());
  EXPECT_EQ(std::memcmp(got_a.points.data(), a.points.data(), a.points.size() * sizeof(double)), 0);
  EXPECT_EQ(got_a.tets, a.tets);
  EXPECT_EQ(got_rep.reoriented_tets, 3u);
  EXPECT_EQ(got_rep.unreferenced_vertices, 1u);
  EXPECT_EQ(got_rep.warnings, rep.warnings);
  MeshReport none;
  none.warnings = {"stale"};
  const TetMesh got_b = take_mesh_bytes(bytes, at, &none);
  EXPECT_EQ(got_b.points, b.points);
  EXPECT_EQ(got_b.tets, b.tets);
  EXPECT_TRUE(none.warnings.empty()) << "a mesh appended without a report has none";
  EXPECT_EQ(at, bytes.size());
}

TEST(MeshBytes, EveryTruncationIsAnError) {
  MeshReport rep;
  rep.warnings = {"a warning"};
  std::vector<char> whole;
  append_mesh_bytes(whole, make_box(0.1, 0.1, 0.1, 1, 1, 1), &rep);
  int failures = 0;
  for (std::size_t n = 0; n < whole.size(); ++n) {
    const std::vector<char> cut(whole.begin(), whole.begin() + static_cast<std::ptrdiff_t>(n));
    std::size_t at = 0;
    try {
      (void)take_mesh_bytes(cut, at);
    } catch (const RuntimeFailure&) {
      ++failures;
    }
  }
  EXPECT_EQ(failures, static_cast<int>(whole.size()));
  // A count that claims more than the bytes hold (a vertex count near 2^64) is refused
  // before anything is allocated.
  std::vector<char> huge = whole;
  const std::uint64_t lie = std::numeric_limits<std::uint64_t>::max() / 2;
  std::memcpy(huge.data(), &lie, sizeof lie);
  std::size_t at = 0;
  EXPECT_THROW((void)take_mesh_bytes(huge, at), RuntimeFailure);
}
