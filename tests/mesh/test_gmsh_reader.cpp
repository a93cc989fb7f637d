#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>

#include "softcontact/error.hpp"
#include "softcontact/mesh_io.hpp"
#include "softcontact/surface.hpp"

using namespace softcontact;

namespace {

std::string data(const std::string& name) { return std::string(SOFTCONTACT_TEST_DATA) + "/meshes/" + name; }

std::string temp_path(const std::string& name) {
  const auto dir = std::filesystem::path(testing::TempDir()) / "softcontact_mesh_io";
  std::filesystem::create_directories(dir);
  return (dir / name).string();
}

std::string slurp(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

void spit(const std::string& path, const std::string& bytes) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out << bytes;
}

/// The message of the InputError that `f` throws ("" and a test failure if none).
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
  EXPECT_NEAR(enclosed_volume(m, s), 1.0, 1e-14);
}

// A k x k x k grid of unit cells, each split into 6 Kuhn tets (conforming across cells),
// with interior vertices moved by irrational amounts so that coordinates use all 53 bits.
TetMesh kuhn_grid(int k) {
  TetMesh m;
  const int n = k + 1;
  auto id = [n](int i, int j, int l) { return static_cast<index_t>(i + n * (j + n * l)); };
  for (int l = 0; l < n; ++l)
    for (int j = 0; j < n; ++j)
      for (int i = 0; i < n; ++i) {
        const bool interior = i > 0 && j > 0 && l > 0 && i < k && j < k && l < k;
        const double e = interior ? 0.1 * std::sin(1.0 + i + 3.0 * j + 7.0 * l) : 0.0;
        m.points.insert(m.points.end(), {i / 3.0 + e, j / 7.0 - 0.5 * e, l * 1e-3 + e / 1000.0});
      }
  m.points[0] = -0.0;  // signed zero must survive the round trip too
  for (int l = 0; l < k; ++l)
    for (int j = 0; j < k; ++j)
      for (int i = 0; i < k; ++i) {
        const index_t c[8] = {id(i, j, l),         id(i + 1, j, l),     id(i + 1, j + 1, l),     id(i, j + 1, l),
                              id(i, j, l + 1),     id(i + 1, j, l + 1), id(i + 1, j + 1, l + 1), id(i, j + 1, l + 1)};
        const int t[6][4] = {{0, 1, 2, 6}, {0, 2, 3, 6}, {0, 3, 7, 6}, {0, 7, 4, 6}, {0, 4, 5, 6}, {0, 5, 1, 6}};
        for (const auto& tt : t)
          for (int v : tt) m.tets.push_back(c[v]);
      }
  validate_mesh(m, "kuhn_grid");
  return m;
}

const char* format_name(GmshFormat f) {
  switch (f) {
    case GmshFormat::v22_ascii: return "v22_ascii";
    case GmshFormat::v22_binary: return "v22_binary";
    case GmshFormat::v41_ascii: return "v41_ascii";
    case GmshFormat::v41_binary: return "v41_binary";
  }
  return "?";
}

constexpr GmshFormat kAllFormats[] = {GmshFormat::v22_ascii, GmshFormat::v22_binary, GmshFormat::v41_ascii,
                                      GmshFormat::v41_binary};

}  // namespace

// ------------------------------------------------------------------ good files

TEST(Gmsh, ReadsAscii22UnitCube) {
  MeshReport report;
  const TetMesh m = read_gmsh(data("cube_v22.msh"), &report);
  expect_unit_cube(m);
  EXPECT_EQ(report.reoriented_tets, 0u);
  EXPECT_TRUE(report.warnings.empty());
  EXPECT_EQ(m.points[3 * 6 + 0], 1.0);  // node 7 = (1,1,1)
  EXPECT_EQ(m.tets[0], 0);
}

TEST(Gmsh, ReadsAscii41UnitCubeSkippingSectionsAndLowerDimensionalElements) {
  MeshReport report;
  const TetMesh m = read_gmsh(data("cube_v41.msh"), &report);
  expect_unit_cube(m);
  EXPECT_TRUE(report.warnings.empty());
}

TEST(Gmsh, Ascii41ParametricCoordinatesAreReadAndIgnored) {
  const TetMesh m = read_gmsh(data("cube_parametric_v41.msh"));
  expect_unit_cube(m);
}

TEST(Gmsh, MapsNonContiguousNodeTags) {
  const TetMesh m = read_gmsh(data("cube_noncontiguous_v22.msh"));
  expect_unit_cube(m);
  // Vertices keep file order: the first node in the file (tag 70000) is the corner (1,1,1).
  EXPECT_EQ(m.points[0], 1.0);
  EXPECT_EQ(m.points[1], 1.0);
  EXPECT_EQ(m.points[2], 1.0);
  // Every tet uses that corner (the Kuhn diagonal), which is vertex 0 now.
  for (std::size_t t = 0; t < m.num_tets(); ++t) {
    const index_t* tet = m.tets.data() + 4 * t;
    EXPECT_TRUE(tet[0] == 0 || tet[1] == 0 || tet[2] == 0 || tet[3] == 0) << "tet " << t;
  }
}

TEST(Gmsh, SkipsPointsLinesAndTrianglesOfMixedFiles) {
  MeshReport report;
  const TetMesh m = read_gmsh(data("cube_mixed_v22.msh"), &report);
  expect_unit_cube(m);
  EXPECT_TRUE(report.warnings.empty());
}

TEST(Gmsh, InvertedTetIsReorientedWithAWarningNamingItsElement) {
  MeshReport report;
  const TetMesh m = read_gmsh(data("inverted_v22.msh"), &report);
  expect_unit_cube(m);
  EXPECT_EQ(report.reoriented_tets, 1u);
  ASSERT_EQ(report.warnings.size(), 1u);
  EXPECT_CONTAINS(report.warnings[0], "inverted_v22.msh");
  EXPECT_CONTAINS(report.warnings[0], "element 3");
  EXPECT_CONTAINS(report.warnings[0], "reoriented");
}

TEST(Gmsh, UnreferencedNodeIsRemovedWithAWarning) {
  std::string text = slurp(data("cube_v22.msh"));
  const std::size_t at = text.find("$EndNodes");
  text.insert(at, "9 5 5 5\n");
  text.replace(text.find("$Nodes\n8\n"), 9, "$Nodes\n9\n");
  const std::string path = temp_path("unreferenced_v22.msh");
  spit(path, text);
  MeshReport report;
  const TetMesh m = read_gmsh(path, &report);
  expect_unit_cube(m);
  EXPECT_EQ(report.unreferenced_vertices, 1u);
  ASSERT_EQ(report.warnings.size(), 1u);
  EXPECT_CONTAINS(report.warnings[0], path);
  EXPECT_CONTAINS(report.warnings[0], "removed");
}

// ------------------------------------------------------------------ round trips

TEST(Gmsh, RoundTripsAllFourFormatsBitForBit) {
  const TetMesh original = kuhn_grid(3);
  ASSERT_EQ(original.num_tets(), 162u);
  for (GmshFormat f : kAllFormats) {
    SCOPED_TRACE(format_name(f));
    const std::string path = temp_path(std::string("roundtrip_") + format_name(f) + ".msh");
    write_gmsh(path, original, f);
    MeshReport report;
    const TetMesh back = read_gmsh(path, &report);
    EXPECT_TRUE(report.warnings.empty());
    ASSERT_EQ(back.points.size(), original.points.size());
    EXPECT_EQ(std::memcmp(back.points.data(), original.points.data(), sizeof(double) * original.points.size()), 0);
    EXPECT_TRUE(std::signbit(back.points[0]));
    EXPECT_EQ(back.tets, original.tets);
    // And the written file is read the same way through the dispatcher.
    EXPECT_EQ(read_mesh(path).tets, original.tets);
  }
}

TEST(Gmsh, WritesTheHeaderOfEachFormat) {
  const TetMesh m = read_gmsh(data("cube_v22.msh"));
  const std::pair<GmshFormat, const char*> headers[] = {{GmshFormat::v22_ascii, "$MeshFormat\n2.2 0 8\n"},
                                                        {GmshFormat::v22_binary, "$MeshFormat\n2.2 1 8\n"},
                                                        {GmshFormat::v41_ascii, "$MeshFormat\n4.1 0 8\n"},
                                                        {GmshFormat::v41_binary, "$MeshFormat\n4.1 1 8\n"}};
  for (const auto& [f, header] : headers) {
    const std::string path = temp_path(std::string("header_") + format_name(f) + ".msh");
    write_gmsh(path, m, f);
    EXPECT_EQ(slurp(path).rfind(header, 0), 0u) << format_name(f);
  }
  const std::string ascii = slurp(temp_path("header_v22_ascii.msh"));
  EXPECT_CONTAINS(ascii, "\n1 4 2 1 1 1 2 3 7\n");  // element 1: tags 1..n, nodes 1-based
}

TEST(Gmsh, WriteFailureIsARuntimeFailure) {
  const TetMesh m = read_gmsh(data("cube_v22.msh"));
  EXPECT_THROW(write_gmsh(temp_path("no/such/dir/x.msh"), m, GmshFormat::v41_ascii), RuntimeFailure);
}

// ------------------------------------------------------------------ robustness

// Every prefix of every format is either rejected with an InputError or (for the prefix
// that lacks only the final line break) read completely; nothing else may happen.
TEST(Gmsh, EveryTruncationIsAnInputError) {
  const TetMesh m = kuhn_grid(1);
  for (GmshFormat f : kAllFormats) {
    SCOPED_TRACE(format_name(f));
    const std::string full_path = temp_path(std::string("full_") + format_name(f) + ".msh");
    write_gmsh(full_path, m, f);
    const std::string full = slurp(full_path);
    const std::string path = temp_path(std::string("cut_") + format_name(f) + ".msh");
    for (std::size_t len = 0; len < full.size(); ++len) {
      spit(path, full.substr(0, len));
      try {
        const TetMesh back = read_gmsh(path);
        EXPECT_EQ(len, full.size() - 1) << "a prefix of " << len << " bytes was accepted";
        EXPECT_EQ(back.tets, m.tets);
      } catch (const InputError& e) {
        EXPECT_CONTAINS(std::string(e.what()), path);
      }
    }
  }
}

// Corrupted bytes anywhere give an InputError or a valid mesh, never a crash (run under
// AddressSanitizer to check for out-of-bounds reads).
TEST(Gmsh, CorruptBytesNeverCrash) {
  const TetMesh m = kuhn_grid(1);
  std::mt19937 rng(12345);
  const unsigned char values[] = {0x00, 0x01, 0x0a, 0x24, 0x2d, 0x39, 0x7f, 0xff};
  for (GmshFormat f : kAllFormats) {
    SCOPED_TRACE(format_name(f));
    const std::string full_path = temp_path(std::string("orig_") + format_name(f) + ".msh");
    write_gmsh(full_path, m, f);
    const std::string full = slurp(full_path);
    const std::string path = temp_path(std::string("corrupt_") + format_name(f) + ".msh");
    for (int trial = 0; trial < 600; ++trial) {
      std::string bytes = full;
      const int flips = 1 + trial % 3;
      for (int k = 0; k < flips; ++k)
        bytes[rng() % bytes.size()] = static_cast<char>(values[rng() % std::size(values)]);
      spit(path, bytes);
      try {
        const TetMesh back = read_gmsh(path);
        EXPECT_GT(back.num_tets(), 0u);
      } catch (const InputError&) {
      }
    }
  }
}

TEST(Gmsh, HugeBinaryCountIsRejectedBeforeAllocating) {
  const TetMesh m = kuhn_grid(1);
  const std::string path = temp_path("huge_v41_binary.msh");
  write_gmsh(path, m, GmshFormat::v41_binary);
  std::string bytes = slurp(path);
  const std::size_t at = bytes.find("$Nodes\n") + 7 + 8;  // numNodes, after numEntityBlocks
  const std::uint64_t huge = std::uint64_t{1} << 60;
  std::memcpy(bytes.data() + at, &huge, 8);
  spit(path, bytes);
  const std::string msg = input_error([&] { read_gmsh(path); });
  EXPECT_CONTAINS(msg, path);
  EXPECT_CONTAINS(msg, "node count 1152921504606846976 cannot fit");
  EXPECT_CONTAINS(msg, "byte offset");
}

TEST(Gmsh, HugeAsciiCountIsRejectedBeforeAllocating) {
  const std::string msg = input_error([] { read_gmsh(data("huge_count_v22.msh")); });
  EXPECT_CONTAINS(msg, "huge_count_v22.msh:5: ");
  EXPECT_CONTAINS(msg, "node count 99999999999 cannot fit");
}

TEST(Gmsh, TruncatedBinaryNamesByteOffsetAndTruncation) {
  const TetMesh m = kuhn_grid(2);
  const std::string path = temp_path("truncated_v22_binary.msh");
  write_gmsh(path, m, GmshFormat::v22_binary);
  const std::string full = slurp(path);
  spit(path, full.substr(0, full.find("$EndNodes") - 100));
  const std::string msg = input_error([&] { read_gmsh(path); });
  EXPECT_CONTAINS(msg, path + ": ");
  EXPECT_CONTAINS(msg, "node count 27 cannot fit");
  EXPECT_CONTAINS(msg, "truncated");
  spit(path, full.substr(0, full.find("$EndElements") - 30));
  const std::string msg2 = input_error([&] { read_gmsh(path); });
  EXPECT_CONTAINS(msg2, "unexpected end of file in a block of 48 elements of type 4");
  EXPECT_CONTAINS(msg2, "byte offset");
}

TEST(Gmsh, BinaryInOtherByteOrderIsRead) {
  // Byte-swap every binary field of a tiny 2.2 file written by hand (big-endian writer).
  auto be32 = [](std::int32_t v) {
    std::string s(4, '\0');
    for (int i = 0; i < 4; ++i) s[static_cast<std::size_t>(i)] = static_cast<char>((static_cast<std::uint32_t>(v) >> (24 - 8 * i)) & 0xff);
    return s;
  };
  auto be64 = [](double d) {
    std::uint64_t u;
    std::memcpy(&u, &d, 8);
    std::string s(8, '\0');
    for (int i = 0; i < 8; ++i) s[static_cast<std::size_t>(i)] = static_cast<char>((u >> (56 - 8 * i)) & 0xff);
    return s;
  };
  const double p[4][3] = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
  std::string f = "$MeshFormat\n2.2 1 8\n" + be32(1) + "\n$EndMeshFormat\n$Nodes\n4\n";
  for (int i = 0; i < 4; ++i) f += be32(i + 1) + be64(p[i][0]) + be64(p[i][1]) + be64(p[i][2]);
  f += "\n$EndNodes\n$Elements\n1\n" + be32(4) + be32(1) + be32(0) + be32(9) + be32(1) + be32(2) + be32(3) + be32(4);
  f += "\n$EndElements\n";
  const std::string path = temp_path("big_endian_v22.msh");
  spit(path, f);
  const TetMesh m = read_gmsh(path);
  ASSERT_EQ(m.num_tets(), 1u);
  EXPECT_NEAR(tet_volume_sum(m), 1.0 / 6.0, 1e-15);
  EXPECT_EQ(m.points[3], 1.0);
}

// ------------------------------------------------------------------ one broken file per error class

TEST(Gmsh, MissingFileNamesTheFile) {
  const std::string msg = input_error([] { read_gmsh(data("no_such_mesh.msh")); });
  EXPECT_CONTAINS(msg, "no_such_mesh.msh: cannot open the mesh file");
  EXPECT_CONTAINS(msg, "No such file");
}

TEST(Gmsh, TruncatedAsciiFile) {
  const std::string msg = input_error([] { read_gmsh(data("truncated_v22.msh")); });
  EXPECT_CONTAINS(msg, "truncated_v22.msh:11: unexpected end of file: expected node 7 of 8");
  EXPECT_CONTAINS(msg, "truncated");
}

TEST(Gmsh, BadCoordinateTokenNamesLineNodeAndExpectation) {
  const std::string msg = input_error([] { read_gmsh(data("bad_token_v22.msh")); });
  EXPECT_CONTAINS(msg, "bad_token_v22.msh:10: expected 'x y z' coordinates of node 5, got 'abc 0 1'");
}

TEST(Gmsh, BadNodeTagToken41) {
  const std::string msg = input_error([] { read_gmsh(data("bad_token_v41.msh")); });
  EXPECT_CONTAINS(msg, "bad_token_v41.msh:51: expected a node tag of element 9 (a positive integer), got 'six'");
}

TEST(Gmsh, ShortElementLine) {
  const std::string msg = input_error([] { read_gmsh(data("short_element_v22.msh")); });
  EXPECT_CONTAINS(msg, "short_element_v22.msh:20: expected 4 node tags after element 4");
  EXPECT_CONTAINS(msg, "got 3");
}

TEST(Gmsh, MissingNodeNamesElementAndNodeTag) {
  const std::string msg = input_error([] { read_gmsh(data("missing_node_v22.msh")); });
  EXPECT_CONTAINS(msg, "missing_node_v22.msh:19: element 3 refers to node 99, which is not defined in '$Nodes'");
}

TEST(Gmsh, ElementCountLargerThanTheElements) {
  const std::string msg = input_error([] { read_gmsh(data("count_mismatch_v22.msh")); });
  EXPECT_CONTAINS(msg, "count_mismatch_v22.msh:23: expected element 7 of 7");
  EXPECT_CONTAINS(msg, "got '$EndElements'");
}

TEST(Gmsh, NodeCountThatDoesNotMatchTheBlocks41) {
  const std::string msg = input_error([] { read_gmsh(data("count_mismatch_v41.msh")); });
  EXPECT_CONTAINS(msg, "count_mismatch_v41.msh:17: the node blocks hold 8 nodes, but the '$Nodes' header declares 9");
}

TEST(Gmsh, UnsupportedVersionSaysWhichAreSupported) {
  const std::string msg = input_error([] { read_gmsh(data("unsupported_version.msh")); });
  EXPECT_CONTAINS(msg, "unsupported_version.msh:2: unsupported MSH version 3.0");
  EXPECT_CONTAINS(msg, "supported: 2.2 and 4.1");
  const std::string v1 = input_error([] { read_gmsh(data("v1_format.msh")); });
  EXPECT_CONTAINS(v1, "v1_format.msh:1: Gmsh MSH 1 files are not supported");
}

TEST(Gmsh, SecondOrderTetsAreRejectedNamingTheElement) {
  const std::string msg = input_error([] { read_gmsh(data("tet10_v22.msh")); });
  EXPECT_CONTAINS(msg, "tet10_v22.msh:23: element 7 is a 10-node tetrahedron (type 11)");
  EXPECT_CONTAINS(msg, "only linear 4-node tetrahedra (type 4) are supported");
}

TEST(Gmsh, SecondOrderTetsAreRejectedInBinary41) {
  // Patch the element type of the single block in a written file from 4 to 11 and make
  // room for 10 nodes per element by declaring one element only.
  TetMesh m = kuhn_grid(1);
  const std::string path = temp_path("tet10_v41_binary.msh");
  write_gmsh(path, m, GmshFormat::v41_binary);
  std::string bytes = slurp(path);
  const std::size_t block = bytes.find("$Elements\n") + 10 + 32;  // after the section header
  const std::int32_t type = 11;
  std::memcpy(bytes.data() + block + 8, &type, 4);
  const std::uint64_t one = 1;
  std::memcpy(bytes.data() + block + 12, &one, 8);
  spit(path, bytes);
  const std::string msg = input_error([&] { read_gmsh(path); });
  EXPECT_CONTAINS(msg, path);
  EXPECT_CONTAINS(msg, "element 1 is a 10-node tetrahedron (type 11)");
}

TEST(Gmsh, FileWithoutTetsIsRejected) {
  const std::string msg = input_error([] { read_gmsh(data("zero_tets_v22.msh")); });
  EXPECT_CONTAINS(msg, "zero_tets_v22.msh: no 4-node tetrahedra (element type 4)");
  EXPECT_CONTAINS(msg, "2 other elements");
}

TEST(Gmsh, DegenerateTetNamesTheFileElement) {
  const std::string msg = input_error([] { read_gmsh(data("degenerate_v22.msh")); });
  EXPECT_CONTAINS(msg, "degenerate_v22.msh: element 42 is degenerate");
  EXPECT_CONTAINS(msg, "expected a tetrahedron with non-zero volume");
}

TEST(Gmsh, TwoTetsSharingOnlyAnEdgeAreNotClosed) {
  const std::string msg = input_error([] { read_gmsh(data("open_edge_v22.msh")); });
  EXPECT_CONTAINS(msg, "open_edge_v22.msh: the boundary surface is not closed");
  EXPECT_CONTAINS(msg, "edge between vertices 1 and 2, used 4 times");
}

// ------------------------------------------------------------------ dispatch

TEST(MeshIO, DispatchesByExtension) {
  expect_unit_cube(read_mesh(data("cube_v41.msh")));
  expect_unit_cube(read_mesh(data("cube1.node")));
  expect_unit_cube(read_mesh(data("cube0.ele")));
  const std::string msg = input_error([] { read_mesh(data("unknown.obj")); });
  EXPECT_CONTAINS(msg, "unknown.obj: unknown mesh format '.obj'");
  EXPECT_CONTAINS(msg, "expected .msh");
}

TEST(MeshIO, ReportIsFilled) {
  MeshReport report;
  read_mesh(data("inverted_v22.msh"), &report);
  EXPECT_EQ(report.reoriented_tets, 1u);
}
