// TetGen .node/.ele reader (format summary in mesh_io.hpp, details in docs/mesh-formats.md).
//
// Both files of one stem are read: X.node gives the points, X.ele the tetrahedra, whose
// point indices use the .node numbering (its first index, 0 or 1, fixes the base).
// Errors name the file and its 1-based line. Counts are checked against the file size
// before memory is reserved from them.
#include <algorithm>
#include <cctype>
#include <filesystem>
#include <limits>
#include <sstream>

#include "softcontact/error.hpp"
#include "softcontact/mesh_io.hpp"
#include "reader_util.hpp"

namespace softcontact {

namespace {

using detail::parse_double;
using detail::parse_int;
using detail::shown;
using detail::split_tokens;
using detail::TextCursor;
using detail::trim;

constexpr std::int64_t kMaxIndex = std::numeric_limits<index_t>::max();

// One TetGen file: records are the non-blank lines with '#' comments removed.
class TetgenFile {
public:
  TetgenFile(const std::string& path, std::string_view bytes) : path_(path), cur_(bytes) {
    if (cur_.data().starts_with("\xEF\xBB\xBF")) cur_.seek(3);  // UTF-8 byte order mark
  }

  /// Tokens of the next record; false at the end of the file.
  bool next_record(std::vector<std::string_view>& tokens) {
    std::string_view line;
    while (cur_.next_line(line)) {
      if (const std::size_t hash = line.find('#'); hash != std::string_view::npos) line = line.substr(0, hash);
      line_text_ = trim(line);
      split_tokens(line, tokens);
      if (!tokens.empty()) return true;
    }
    return false;
  }
  void expect_record(std::vector<std::string_view>& tokens, const std::string& what) {
    if (!next_record(tokens)) fail("unexpected end of file: expected " + what + " (is the file truncated?)");
  }
  [[noreturn]] void fail(const std::string& detail) const { throw InputError(path_, cur_.line(), detail); }
  /// The text of the record last returned, for messages.
  std::string text() const { return shown(line_text_); }
  std::int64_t line() const { return cur_.line(); }
  std::size_t remaining() const { return cur_.remaining(); }
  const std::string& path() const { return path_; }

  std::int64_t integer(std::string_view token, const std::string& what) const {
    std::int64_t v = 0;
    if (!parse_int(token, v)) fail("expected " + what + " (an integer), got '" + shown(token) + "'");
    return v;
  }
  /// Rejects a count that the rest of the file cannot hold at 2 bytes per record (a
  /// character and a line break); a merely truncated file is reported where it ends.
  void check_count(std::int64_t count, const std::string& what) const {
    std::ostringstream s;
    if (static_cast<std::uint64_t>(count) > remaining() / 2 + 1) {
      s << "the " << what << " count " << count << " cannot fit in the " << remaining()
        << " bytes left in the file (corrupt count or truncated file)";
      fail(s.str());
    }
    if (count > kMaxIndex) {
      s << "the " << what << " count " << count << " is larger than the supported maximum " << kMaxIndex;
      fail(s.str());
    }
  }

  /// How many records to reserve for `count`: no more than the rest of the file can hold.
  std::size_t capped(std::int64_t count, std::size_t min_bytes) const {
    return static_cast<std::size_t>(std::min<std::uint64_t>(static_cast<std::uint64_t>(count), remaining() / min_bytes + 1));
  }

private:
  std::string path_;
  TextCursor cur_;
  std::string_view line_text_;
};

struct NodeFile {
  std::vector<double> points;
  std::int64_t base = 0;  // index of the first point: 0 or 1
};

NodeFile read_node_file(const std::string& path, std::string_view bytes) {
  TetgenFile f(path, bytes);
  std::vector<std::string_view> tok;
  f.expect_record(tok, "the header '<#points> <dimension> <#attributes> <boundary markers>'");
  if (tok.size() < 2 || tok.size() > 4)
    f.fail("expected the header '<#points> <dimension> [<#attributes> [<boundary markers>]]', got '" + f.text() + "'");
  const std::int64_t n = f.integer(tok[0], "the number of points");
  if (n <= 0) f.fail("expected a positive number of points, got " + std::to_string(n));
  const std::int64_t dim = f.integer(tok[1], "the dimension");
  if (dim != 3) f.fail("expected dimension 3, got " + std::to_string(dim));
  const std::int64_t nattr = tok.size() > 2 ? f.integer(tok[2], "the number of point attributes") : 0;
  if (nattr < 0 || nattr > 1000) f.fail("expected 0 to 1000 point attributes, got " + std::to_string(nattr));
  const std::int64_t markers = tok.size() > 3 ? f.integer(tok[3], "the boundary-marker flag") : 0;
  if (markers != 0 && markers != 1) f.fail("expected a boundary-marker flag of 0 or 1, got " + std::to_string(markers));
  const std::int64_t header_line = f.line();
  f.check_count(n, "point");

  const std::size_t values = 4 + static_cast<std::size_t>(nattr + markers);
  std::string layout = "'index x y z'";
  if (nattr > 0) layout += " and " + std::to_string(nattr) + " attributes";
  if (markers) layout += " and a boundary marker";

  NodeFile out;
  out.points.reserve(3 * f.capped(n, 8));  // "0 0 0 0\n" at least
  for (std::int64_t i = 0; i < n; ++i) {
    f.expect_record(tok, "point " + std::to_string(i + 1) + " of " + std::to_string(n));
    if (tok.size() != values)
      f.fail("expected " + layout + " (" + std::to_string(values) + " values) for point " + std::to_string(i + 1) +
             " of " + std::to_string(n) + ", got " + std::to_string(tok.size()) + " values: '" + f.text() + "'");
    const std::int64_t index = f.integer(tok[0], "the index of point " + std::to_string(i + 1));
    if (i == 0) {
      if (index != 0 && index != 1) f.fail("expected the first point index to be 0 or 1, got " + std::to_string(index));
      out.base = index;
    } else if (index != out.base + i) {
      f.fail("expected point index " + std::to_string(out.base + i) + " (indices are consecutive), got " +
             std::to_string(index));
    }
    double x[3];
    for (int d = 0; d < 3; ++d)
      if (!parse_double(tok[1 + static_cast<std::size_t>(d)], x[d]))
        f.fail("expected 'x y z' coordinates of point " + std::to_string(index) + ", got '" + shown(tok[1]) + " " +
               shown(tok[2]) + " " + shown(tok[3]) + "'");
    for (std::size_t k = 4; k < values; ++k) {
      double v = 0;
      if (!parse_double(tok[k], v))
        f.fail("expected a number (attribute or boundary marker) of point " + std::to_string(index) + ", got '" +
               shown(tok[k]) + "'");
    }
    out.points.insert(out.points.end(), x, x + 3);
  }
  if (f.next_record(tok))
    f.fail("found more points than the " + std::to_string(n) + " declared on line " + std::to_string(header_line) +
           ": '" + f.text() + "'");
  return out;
}

void read_ele_file(const std::string& path, std::string_view bytes, const NodeFile& nodes, const std::string& node_path,
                   TetMesh& mesh, std::vector<std::int64_t>& element_ids) {
  TetgenFile f(path, bytes);
  std::vector<std::string_view> tok;
  f.expect_record(tok, "the header '<#tetrahedra> <nodes per tetrahedron> <#attributes>'");
  if (tok.size() < 2 || tok.size() > 3)
    f.fail("expected the header '<#tetrahedra> <nodes per tetrahedron> [<#attributes>]', got '" + f.text() + "'");
  const std::int64_t m = f.integer(tok[0], "the number of tetrahedra");
  if (m < 0) f.fail("expected a non-negative number of tetrahedra, got " + std::to_string(m));
  if (m == 0) f.fail("the file declares 0 tetrahedra (expected at least one)");
  const std::int64_t per = f.integer(tok[1], "the number of nodes per tetrahedron");
  if (per == 10)
    f.fail("the file has 10 nodes per tetrahedron (second order); only linear 4-node tetrahedra are supported "
           "(run tetgen without -o2)");
  if (per != 4) f.fail("expected 4 nodes per tetrahedron, got " + std::to_string(per));
  const std::int64_t nattr = tok.size() > 2 ? f.integer(tok[2], "the number of tetrahedron attributes") : 0;
  if (nattr < 0 || nattr > 1000) f.fail("expected 0 to 1000 tetrahedron attributes, got " + std::to_string(nattr));
  const std::int64_t header_line = f.line();
  f.check_count(m, "tetrahedron");

  const std::int64_t n = static_cast<std::int64_t>(nodes.points.size() / 3);
  const std::size_t values = 5 + static_cast<std::size_t>(nattr);
  const std::size_t cap = f.capped(m, 10);  // "0 0 1 2 3\n" at least
  mesh.tets.reserve(4 * cap);
  element_ids.reserve(cap);
  for (std::int64_t i = 0; i < m; ++i) {
    f.expect_record(tok, "tetrahedron " + std::to_string(i + 1) + " of " + std::to_string(m));
    const std::int64_t index = f.integer(tok[0], "the index of tetrahedron " + std::to_string(i + 1));
    if (tok.size() != values)
      f.fail("expected 'index n1 n2 n3 n4'" +
             (nattr > 0 ? " and " + std::to_string(nattr) + " attributes" : std::string()) + " (" +
             std::to_string(values) + " values) for tetrahedron " + std::to_string(index) + ", got " +
             std::to_string(tok.size()) + " values: '" + f.text() + "'");
    for (std::size_t c = 1; c <= 4; ++c) {
      const std::int64_t p = f.integer(tok[c], "a point index of tetrahedron " + std::to_string(index));
      if (p < nodes.base || p >= nodes.base + n)
        f.fail("tetrahedron " + std::to_string(index) + " refers to point " + std::to_string(p) + ", but " + node_path +
               " has points " + std::to_string(nodes.base) + " to " + std::to_string(nodes.base + n - 1));
      mesh.tets.push_back(static_cast<index_t>(p - nodes.base));
    }
    for (std::size_t k = 5; k < values; ++k) {
      double v = 0;
      if (!parse_double(tok[k], v))
        f.fail("expected a number (attribute) of tetrahedron " + std::to_string(index) + ", got '" + shown(tok[k]) + "'");
    }
    element_ids.push_back(index);
  }
  if (f.next_record(tok))
    f.fail("found more tetrahedra than the " + std::to_string(m) + " declared on line " + std::to_string(header_line) +
           ": '" + f.text() + "'");
}

struct EleFile {
  TetMesh mesh;  // tets only
  std::vector<std::int64_t> element_ids;
};

EleFile read_ele(const std::string& path, std::string_view bytes, const NodeFile& nodes, const std::string& node_path) {
  EleFile e;
  read_ele_file(path, bytes, nodes, node_path, e.mesh, e.element_ids);
  return e;
}

TetMesh finish_tetgen(const NodeFile& nodes, EleFile ele, const std::string& ele_path, MeshReport* report) {
  ele.mesh.points = nodes.points;
  MeshReport r = validate_mesh(ele.mesh, ele_path, ele.element_ids);
  if (report) *report = std::move(r);
  return std::move(ele.mesh);
}

}  // namespace

TetMesh read_tetgen(const std::string& path, MeshReport* report) {
  // X.node, X.ele or the bare stem X all name the pair X.node + X.ele.
  std::string ext = std::filesystem::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  const std::string stem = (ext == ".node" || ext == ".ele") ? path.substr(0, path.size() - ext.size()) : path;
  const std::string node_path = stem + ".node";
  const std::string ele_path = stem + ".ele";

  // The .node file is read and checked before the .ele file is opened, so that its errors
  // come first.
  const std::string node_bytes = detail::read_file_bytes(node_path);
  const NodeFile nodes = read_node_file(node_path, node_bytes);
  const std::string ele_bytes = detail::read_file_bytes(ele_path);
  return finish_tetgen(nodes, read_ele(ele_path, ele_bytes, nodes, node_path), ele_path, report);
}

TetMesh read_tetgen_bytes(std::string_view node_bytes, std::string_view ele_bytes, const std::string& node_name,
                          const std::string& ele_name, MeshReport* report) {
  const NodeFile nodes = read_node_file(node_name, node_bytes);
  return finish_tetgen(nodes, read_ele(ele_name, ele_bytes, nodes, node_name), ele_name, report);
}

}  // namespace softcontact
