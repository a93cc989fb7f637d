// Gmsh MSH 2.2 and 4.1 reader, ASCII and binary (format summary in mesh_io.hpp, details
// and messages in docs/mesh-formats.md).
//
// Robustness rules, because mesh files come from users and other programs:
//  - every count read from the file is checked against the bytes that remain before any
//    memory is reserved for it, so a corrupt count cannot trigger a huge allocation;
//  - every binary read is bounds-checked; a short file is reported as truncated;
//  - ASCII records are parsed line by line so that errors name the 1-based line; binary
//    payloads have no lines, so their errors name the byte offset and the element.
#include <algorithm>
#include <cstring>
#include <limits>
#include <sstream>
#include <utility>

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

// Gmsh element types (reference manual, "MSH file format"): nodes per element and the
// dimension. Skipping an element in a binary file needs its node count, and telling a
// surface element (skipped) from a volume element (rejected) needs its dimension.
struct ElementKind {
  int nodes;
  int dim;
  const char* name;
};

const ElementKind* element_kind(std::int64_t type) {
  static const ElementKind kinds[] = {
      {0, -1, nullptr},                     // 0: not a type
      {2, 1, "2-node line"},                // 1
      {3, 2, "3-node triangle"},            // 2
      {4, 2, "4-node quadrangle"},          // 3
      {4, 3, "4-node tetrahedron"},         // 4
      {8, 3, "8-node hexahedron"},          // 5
      {6, 3, "6-node prism"},               // 6
      {5, 3, "5-node pyramid"},             // 7
      {3, 1, "3-node line"},                // 8
      {6, 2, "6-node triangle"},            // 9
      {9, 2, "9-node quadrangle"},          // 10
      {10, 3, "10-node tetrahedron"},       // 11
      {27, 3, "27-node hexahedron"},        // 12
      {18, 3, "18-node prism"},             // 13
      {14, 3, "14-node pyramid"},           // 14
      {1, 0, "1-node point"},               // 15
      {8, 2, "8-node quadrangle"},          // 16
      {20, 3, "20-node hexahedron"},        // 17
      {15, 3, "15-node prism"},             // 18
      {13, 3, "13-node pyramid"},           // 19
      {9, 2, "9-node triangle"},            // 20
      {10, 2, "10-node triangle"},          // 21
      {12, 2, "12-node triangle"},          // 22
      {15, 2, "15-node triangle"},          // 23
      {15, 2, "15-node triangle"},          // 24 (incomplete)
      {21, 2, "21-node triangle"},          // 25
      {4, 1, "4-node line"},                // 26
      {5, 1, "5-node line"},                // 27
      {6, 1, "6-node line"},                // 28
      {20, 3, "20-node tetrahedron"},       // 29
      {35, 3, "35-node tetrahedron"},       // 30
      {56, 3, "56-node tetrahedron"},       // 31
  };
  static const ElementKind hex64{64, 3, "64-node hexahedron"};
  static const ElementKind hex125{125, 3, "125-node hexahedron"};
  if (type >= 1 && type < static_cast<std::int64_t>(std::size(kinds))) return &kinds[type];
  if (type == 92) return &hex64;
  if (type == 93) return &hex125;
  return nullptr;
}

constexpr const char* kKnownTypes = "known types: 1-31, 92, 93";

template <class T>
T load(std::string_view bytes, std::size_t at, bool swap) {
  unsigned char b[sizeof(T)];
  std::memcpy(b, bytes.data() + at, sizeof(T));
  if (swap) std::reverse(b, b + sizeof(T));
  T v;
  std::memcpy(&v, b, sizeof(T));
  return v;
}

// Node tags are arbitrary positive integers; vertices are numbered in file order. Compact
// tags (the usual 1..n) use a direct table, sparse ones a sorted list, so that memory
// stays proportional to the number of nodes whatever the tags are.
class NodeTable {
public:
  void reserve(std::size_t n) { tags_.reserve(n); }
  void add(std::int64_t tag) { tags_.push_back(tag); }
  std::size_t size() const { return tags_.size(); }
  std::int64_t tag(std::size_t i) const { return tags_[i]; }

  /// Builds the lookup; returns a tag that occurs twice, or 0 when all are unique.
  std::int64_t finish() {
    const std::size_t n = tags_.size();
    const std::int64_t max_tag = n ? *std::max_element(tags_.begin(), tags_.end()) : 0;
    dense_.clear();
    sorted_.clear();
    if (static_cast<std::uint64_t>(max_tag) <= 2 * static_cast<std::uint64_t>(n) + 1024) {
      dense_.assign(static_cast<std::size_t>(max_tag) + 1, -1);
      for (std::size_t i = 0; i < n; ++i) {
        index_t& slot = dense_[static_cast<std::size_t>(tags_[i])];
        if (slot >= 0) return tags_[i];
        slot = static_cast<index_t>(i);
      }
    } else {
      sorted_.reserve(n);
      for (std::size_t i = 0; i < n; ++i) sorted_.emplace_back(tags_[i], static_cast<index_t>(i));
      std::sort(sorted_.begin(), sorted_.end());
      for (std::size_t i = 1; i < n; ++i)
        if (sorted_[i].first == sorted_[i - 1].first) return sorted_[i].first;
    }
    return 0;
  }

  /// Vertex index of a node tag, or -1 when no node has that tag.
  index_t find(std::int64_t tag) const {
    if (!sorted_.empty()) {
      auto it = std::lower_bound(sorted_.begin(), sorted_.end(), std::make_pair(tag, index_t{-1}));
      return it != sorted_.end() && it->first == tag ? it->second : -1;
    }
    if (tag < 0 || static_cast<std::uint64_t>(tag) >= dense_.size()) return -1;
    return dense_[static_cast<std::size_t>(tag)];
  }

private:
  std::vector<std::int64_t> tags_;
  std::vector<index_t> dense_;
  std::vector<std::pair<std::int64_t, index_t>> sorted_;
};

class GmshReader {
public:
  GmshReader(const std::string& path, std::string_view data) : path_(path), cur_(data) {}

  void parse();

  TetMesh mesh;
  std::vector<std::int64_t> element_ids;  // the file's tag of each tet

private:
  // ---- error reporting ----
  [[noreturn]] void fail(const std::string& detail) const {
    if (lines_valid_) throw InputError(path_, cur_.line(), detail);
    std::ostringstream s;
    s << detail << " (at byte offset " << item_offset_ << ")";
    throw InputError(path_, 0, s.str());
  }
  [[noreturn]] void fail_line(std::int64_t line, const std::string& detail) const {
    throw InputError(path_, lines_valid_ ? line : 0, detail);
  }

  // ---- ASCII helpers ----
  bool next_content_line(std::string_view& line) {
    while (cur_.next_line(line))
      if (!trim(line).empty()) return true;
    return false;
  }
  /// The next non-blank line; a truncated file or a section that ends early is an error.
  std::string_view expect_line(const std::string& what) {
    std::string_view line;
    if (!next_content_line(line))
      fail("unexpected end of file: expected " + what + " (is the file truncated?)");
    return line;
  }
  std::string_view expect_data_line(const std::string& what) {
    const std::string_view line = expect_line(what);
    if (trim(line).starts_with('$'))
      fail("expected " + what + ", got '" + shown(trim(line)) +
           "' (the section ends before the count given in its header)");
    return line;
  }
  void expect_end(std::string_view end_marker, const std::string& after) {
    std::string_view line;
    if (binary_) cur_.skip_blank_bytes();
    item_offset_ = cur_.offset();
    if (!next_content_line(line))
      fail("unexpected end of file: expected '" + std::string(end_marker) + "' (is the file truncated?)");
    if (trim(line) != end_marker)
      fail("expected '" + std::string(end_marker) + "' after " + after + ", got '" + shown(trim(line)) +
           "' (more entries than the count in the section header?)");
  }
  /// A non-negative integer; `what` describes the expected field for the message.
  std::int64_t count_token(std::string_view token, const std::string& what) {
    std::int64_t v = 0;
    if (!parse_int(token, v) || v < 0) fail("expected " + what + " (a non-negative integer), got '" + shown(token) + "'");
    return v;
  }
  std::int64_t tag_token(std::string_view token, const std::string& what) {
    std::int64_t v = 0;
    if (!parse_int(token, v) || v <= 0) fail("expected " + what + " (a positive integer), got '" + shown(token) + "'");
    return v;
  }

  // ---- binary helpers ----
  /// The next n bytes of a binary payload, or a truncation error naming `what`.
  std::string_view need(std::uint64_t n, const std::string& what) {
    item_offset_ = cur_.offset();
    if (n > cur_.remaining()) {
      std::ostringstream s;
      s << "unexpected end of file in " << what << ": expected " << n << " bytes, only " << cur_.remaining()
        << " remain (is the file truncated?)";
      fail(s.str());
    }
    return cur_.take(static_cast<std::size_t>(n));
  }
  std::int32_t i32(std::string_view b, std::size_t at) const { return load<std::int32_t>(b, at, swap_); }
  std::uint64_t u64(std::string_view b, std::size_t at) const { return load<std::uint64_t>(b, at, swap_); }
  double f64(std::string_view b, std::size_t at) const { return load<double>(b, at, swap_); }
  /// A size_t tag from a 4.1 binary file, checked to be a positive int64.
  std::int64_t binary_tag(std::uint64_t v, const std::string& what) {
    if (v == 0 || v > static_cast<std::uint64_t>(std::numeric_limits<std::int64_t>::max())) {
      std::ostringstream s;
      s << "expected " << what << " (a positive integer), got " << v;
      fail(s.str());
    }
    return static_cast<std::int64_t>(v);
  }

  /// Rejects a count that cannot be honest: each item needs at least `min_bytes` of the
  /// bytes that remain. Called before anything is reserved from the count. ASCII sections
  /// pass 2 (a character and a line break), so that a merely truncated file is reported
  /// where its data ends, and reserve only what the rest of the file can hold (capped()).
  void check_count(std::uint64_t count, std::size_t min_bytes, const std::string& what, std::int64_t limit) {
    std::ostringstream s;
    if (count > cur_.remaining() / min_bytes + 1) {
      s << "the " << what << " count " << count << " cannot fit in the " << cur_.remaining()
        << " bytes left in the file (expected at least " << min_bytes << " bytes each; corrupt count or truncated file)";
      fail(s.str());
    }
    if (count > static_cast<std::uint64_t>(limit)) {
      s << "the " << what << " count " << count << " is larger than the supported maximum " << limit;
      fail(s.str());
    }
  }

  /// How many items to reserve for `count`: no more than the rest of the file can hold
  /// at `min_bytes` per item.
  std::size_t capped(std::uint64_t count, std::size_t min_bytes) const {
    return static_cast<std::size_t>(std::min<std::uint64_t>(count, cur_.remaining() / min_bytes + 1));
  }

  // ---- sections ----
  void read_mesh_format();
  void skip_section(std::string_view header);
  void read_nodes_22();
  void read_elements_22();
  void read_nodes_41();
  void read_elements_41();
  void finish_nodes(std::int64_t header_line);
  void add_tet(std::int64_t element_tag, const std::int64_t node_tags[4]);
  [[noreturn]] void reject_element(std::int64_t element_tag, std::int64_t type, const ElementKind* kind);

  const std::string& path_;
  TextCursor cur_;
  int version_ = 0;     // 22 or 41
  bool binary_ = false;
  bool swap_ = false;   // binary data in the other byte order than this machine's
  bool lines_valid_ = true;  // false once a binary payload was read: offsets replace lines
  std::size_t item_offset_ = 0;  // start of the binary item being read, for messages
  bool have_nodes_ = false;
  bool have_elements_ = false;
  NodeTable nodes_;
  std::size_t skipped_elements_ = 0;
  std::vector<std::string_view> tok_;
};

void GmshReader::parse() {
  if (cur_.data().starts_with("\xEF\xBB\xBF")) cur_.seek(3);  // UTF-8 byte order mark
  std::string_view line;
  if (!next_content_line(line))
    fail_line(0, "the file is empty (expected a Gmsh mesh starting with '$MeshFormat')");
  const std::string_view first = trim(line);
  if (first == "$NOD" || first == "$NOE")
    fail("Gmsh MSH 1 files are not supported (supported: MSH 2.2 and 4.1, ASCII or binary; "
         "export with 'gmsh -format msh41' or 'msh22')");
  if (first != "$MeshFormat")
    fail("expected '$MeshFormat' on the first line (is this a Gmsh .msh file?), got '" + shown(first) + "'");
  read_mesh_format();

  while (true) {
    if (binary_) cur_.skip_blank_bytes();
    item_offset_ = cur_.offset();
    if (!next_content_line(line)) break;
    const std::string_view header = trim(line);
    if (header == "$Nodes") {
      if (have_nodes_) fail("a second '$Nodes' section (expected exactly one)");
      version_ == 22 ? read_nodes_22() : read_nodes_41();
      have_nodes_ = true;
    } else if (header == "$Elements") {
      if (!have_nodes_) fail("'$Elements' comes before '$Nodes' (expected the nodes first)");
      if (have_elements_) fail("a second '$Elements' section (expected exactly one)");
      version_ == 22 ? read_elements_22() : read_elements_41();
      have_elements_ = true;
    } else if (header == "$MeshFormat") {
      fail("a second '$MeshFormat' section (expected exactly one, at the start)");
    } else if (header.starts_with("$End")) {
      fail("unexpected '" + shown(header) + "' (no section with that name is open)");
    } else if (header.starts_with('$')) {
      skip_section(header);
    } else {
      fail("expected a section header such as '$Nodes' or '$Elements', got '" + shown(header) + "'");
    }
  }
  if (!have_nodes_) throw InputError(path_, 0, "no '$Nodes' section (expected nodes and elements)");
  if (!have_elements_) throw InputError(path_, 0, "no '$Elements' section (expected 4-node tetrahedra)");
  if (mesh.num_tets() == 0) {
    std::ostringstream s;
    s << "no 4-node tetrahedra (element type 4) in '$Elements'";
    if (skipped_elements_ > 0) s << "; its " << skipped_elements_ << " other elements (points, lines, surfaces) are skipped";
    throw InputError(path_, 0, s.str());
  }
}

void GmshReader::read_mesh_format() {
  const std::string_view line = expect_line("the format line 'version file-type data-size'");
  split_tokens(line, tok_);
  double version = 0;
  if (tok_.size() != 3 || !parse_double(tok_[0], version))
    fail("expected 'version file-type data-size' (e.g. '4.1 0 8'), got '" + shown(trim(line)) + "'");
  if (version == 2.2) {
    version_ = 22;
  } else if (version == 4.1) {
    version_ = 41;
  } else {
    fail("unsupported MSH version " + shown(tok_[0]) +
         " (supported: 2.2 and 4.1, ASCII or binary; export with 'gmsh -format msh41' or 'msh22')");
  }
  if (tok_[1] == "0") {
    binary_ = false;
  } else if (tok_[1] == "1") {
    binary_ = true;
  } else {
    fail("expected file-type 0 (ASCII) or 1 (binary), got '" + shown(tok_[1]) + "'");
  }
  if (tok_[2] != "8") fail("expected data-size 8 (8-byte doubles and size_t), got '" + shown(tok_[2]) + "'");
  if (binary_) {
    // The writer's integer 1 tells its byte order; either order is accepted.
    item_offset_ = cur_.offset();
    if (cur_.remaining() < 4) fail("unexpected end of file: expected the binary integer 1 after the format line");
    const std::string_view b = cur_.take(4);
    if (load<std::int32_t>(b, 0, false) == 1) {
      swap_ = false;
    } else if (load<std::int32_t>(b, 0, true) == 1) {
      swap_ = true;
    } else {
      fail("expected the binary integer 1 after the format line (byte-order check), got other bytes");
    }
    std::string_view rest;
    if (cur_.next_line(rest) && !trim(rest).empty())
      fail("expected a line break after the binary integer 1, got '" + shown(rest) + "'");
  }
  const std::string_view end = expect_line("'$EndMeshFormat'");
  if (trim(end) != "$EndMeshFormat") fail("expected '$EndMeshFormat', got '" + shown(trim(end)) + "'");
}

void GmshReader::skip_section(std::string_view header) {
  const std::string end_marker = "$End" + std::string(header.substr(1));
  const std::int64_t start_line = cur_.line();
  if (!binary_) {
    std::string_view line;
    while (cur_.next_line(line))
      if (trim(line) == end_marker) return;
  } else {
    // Binary sections are not lines: look for the end marker at the start of a line.
    const std::string_view data = cur_.data();
    std::size_t at = cur_.offset();
    while ((at = data.find(end_marker, at)) != std::string_view::npos) {
      const std::size_t after = at + end_marker.size();
      const bool starts_line = at == cur_.offset() || data[at - 1] == '\n';
      const bool ends_line = after == data.size() || data[after] == '\n' || data[after] == '\r';
      if (starts_line && ends_line) {
        cur_.seek(after);
        lines_valid_ = false;
        return;
      }
      at = after;
    }
  }
  fail_line(start_line, "section '" + shown(header) + "' has no '" + shown(end_marker) + "' (is the file truncated?)");
}

void GmshReader::finish_nodes(std::int64_t header_line) {
  if (const std::int64_t dup = nodes_.finish(); dup != 0) {
    std::ostringstream s;
    s << "node tag " << dup << " is defined more than once in '$Nodes' (expected unique node tags)";
    fail_line(header_line, s.str());
  }
}

void GmshReader::add_tet(std::int64_t element_tag, const std::int64_t node_tags[4]) {
  if (static_cast<std::int64_t>(mesh.num_tets()) >= kMaxIndex) {
    std::ostringstream s;
    s << "more than " << kMaxIndex << " tetrahedra are not supported";
    fail(s.str());
  }
  for (int c = 0; c < 4; ++c) {
    const index_t v = nodes_.find(node_tags[c]);
    if (v < 0) {
      std::ostringstream s;
      s << "element " << element_tag << " refers to node " << node_tags[c] << ", which is not defined in '$Nodes'";
      fail(s.str());
    }
    mesh.tets.push_back(v);
  }
  element_ids.push_back(element_tag);
}

void GmshReader::reject_element(std::int64_t element_tag, std::int64_t type, const ElementKind* kind) {
  std::ostringstream s;
  s << "element " << element_tag << " is a " << kind->name << " (type " << type
    << "); only linear 4-node tetrahedra (type 4) are supported";
  if (std::string_view(kind->name).ends_with("tetrahedron"))  // a higher-order tetrahedron
    s << " (mesh with element order 1)";
  fail(s.str());
}

// ---------------------------------------------------------------- MSH 2.2

void GmshReader::read_nodes_22() {
  const std::int64_t header_line = cur_.line();
  const std::string_view count_line = expect_line("the number of nodes");
  split_tokens(count_line, tok_);
  if (tok_.size() != 1) fail("expected the number of nodes, got '" + shown(trim(count_line)) + "'");
  const std::int64_t n = count_token(tok_[0], "the number of nodes");
  const std::int64_t count_line_no = cur_.line();

  if (binary_) {
    constexpr std::size_t kNodeBytes = 4 + 3 * 8;
    item_offset_ = cur_.offset();
    lines_valid_ = false;
    check_count(static_cast<std::uint64_t>(n), kNodeBytes, "node", kMaxIndex);
    nodes_.reserve(static_cast<std::size_t>(n));
    mesh.points.reserve(3 * static_cast<std::size_t>(n));
    for (std::int64_t i = 0; i < n; ++i) {
      const std::string_view b = need(kNodeBytes, "node " + std::to_string(i + 1) + " of " + std::to_string(n));
      const std::int32_t tag = i32(b, 0);
      if (tag <= 0) fail("node " + std::to_string(i + 1) + " of " + std::to_string(n) + " has tag " +
                         std::to_string(tag) + " (expected a positive integer)");
      nodes_.add(tag);
      for (int d = 0; d < 3; ++d) mesh.points.push_back(f64(b, 4 + 8 * static_cast<std::size_t>(d)));
    }
  } else {
    check_count(static_cast<std::uint64_t>(n), 2, "node", kMaxIndex);
    const std::size_t cap = capped(static_cast<std::uint64_t>(n), 8);  // "1 0 0 0\n" at least
    nodes_.reserve(cap);
    mesh.points.reserve(3 * cap);
    for (std::int64_t i = 0; i < n; ++i) {
      const std::string what = "node " + std::to_string(i + 1) + " of " + std::to_string(n) + " ('node-tag x y z')";
      const std::string_view line = expect_data_line(what);
      split_tokens(line, tok_);
      if (tok_.size() != 4)
        fail("expected 'node-tag x y z' (4 values) for node " + std::to_string(i + 1) + " of " + std::to_string(n) +
             ", got " + std::to_string(tok_.size()) + " values: '" + shown(trim(line)) + "'");
      const std::int64_t tag = tag_token(tok_[0], "the tag of node " + std::to_string(i + 1));
      double x[3];
      for (int d = 0; d < 3; ++d)
        if (!parse_double(tok_[1 + d], x[d]))
          fail("expected 'x y z' coordinates of node " + std::to_string(tag) + ", got '" +
               shown(trim(line.substr(static_cast<std::size_t>(tok_[1].data() - line.data())))) + "'");
      nodes_.add(tag);
      mesh.points.insert(mesh.points.end(), x, x + 3);
    }
  }
  expect_end("$EndNodes", "the " + std::to_string(n) + " nodes declared on line " + std::to_string(count_line_no));
  finish_nodes(header_line);
}

void GmshReader::read_elements_22() {
  const std::string_view count_line = expect_line("the number of elements");
  split_tokens(count_line, tok_);
  if (tok_.size() != 1) fail("expected the number of elements, got '" + shown(trim(count_line)) + "'");
  const std::int64_t m = count_token(tok_[0], "the number of elements");
  const std::int64_t count_line_no = cur_.line();

  if (binary_) {
    item_offset_ = cur_.offset();
    lines_valid_ = false;
    // The smallest element, a point without tags, is 8 bytes: tag and one node.
    check_count(static_cast<std::uint64_t>(m), 8, "element", std::numeric_limits<std::int32_t>::max());
    std::int64_t read = 0;
    while (read < m) {
      const std::string_view h = need(12, "an element block header (type, count, number of tags)");
      const std::int32_t type = i32(h, 0), count = i32(h, 4), ntags = i32(h, 8);
      const ElementKind* kind = element_kind(type);
      if (!kind) fail("unknown element type " + std::to_string(type) + " in an element block header (" + kKnownTypes + ")");
      if (count <= 0 || count > m - read)
        fail("element block of type " + std::to_string(type) + " declares " + std::to_string(count) +
             " elements (expected 1 to " + std::to_string(m - read) + ", the elements left of the " +
             std::to_string(m) + " declared)");
      if (ntags < 0) fail("element block of type " + std::to_string(type) + " declares " + std::to_string(ntags) +
                          " tags per element (expected a non-negative number)");
      const std::uint64_t per = 4 * (1 + static_cast<std::uint64_t>(ntags) + static_cast<std::uint64_t>(kind->nodes));
      if (static_cast<std::uint64_t>(count) > cur_.remaining() / per) {
        item_offset_ = cur_.offset();
        fail("unexpected end of file in a block of " + std::to_string(count) + " elements of type " + std::to_string(type) +
             " (is the file truncated?)");
      }
      if (type != 4 && kind->dim == 3) {
        const std::string_view b = need(per, "an element");
        reject_element(i32(b, 0), type, kind);
      }
      if (type != 4) {
        need(per * static_cast<std::uint64_t>(count), "a block of skipped elements");
        skipped_elements_ += static_cast<std::size_t>(count);
      } else {
        mesh.tets.reserve(mesh.tets.size() + 4 * static_cast<std::size_t>(count));
        for (std::int32_t e = 0; e < count; ++e) {
          const std::string_view b = need(per, "an element");
          const std::int32_t tag = i32(b, 0);
          if (tag <= 0) fail("element tag " + std::to_string(tag) + " (expected a positive integer)");
          std::int64_t nt[4];
          for (int c = 0; c < 4; ++c) nt[c] = i32(b, 4 * (1 + static_cast<std::size_t>(ntags) + static_cast<std::size_t>(c)));
          add_tet(tag, nt);
        }
      }
      read += count;
    }
  } else {
    check_count(static_cast<std::uint64_t>(m), 2, "element", std::numeric_limits<std::int64_t>::max());
    for (std::int64_t i = 0; i < m; ++i) {
      const std::string what = "element " + std::to_string(i + 1) + " of " + std::to_string(m) +
                               " ('elm-tag elm-type num-tags tag... node-tag...')";
      const std::string_view line = expect_data_line(what);
      split_tokens(line, tok_);
      if (tok_.size() < 3) fail("expected " + what + ", got '" + shown(trim(line)) + "'");
      const std::int64_t tag = tag_token(tok_[0], "an element tag");
      const std::string of = " of element " + std::to_string(tag);
      std::int64_t type = 0;
      if (!parse_int(tok_[1], type)) fail("expected the element type" + of + ", got '" + shown(tok_[1]) + "'");
      const std::int64_t ntags = count_token(tok_[2], "the number of tags" + of);
      const ElementKind* kind = element_kind(type);
      if (!kind)
        fail("element " + std::to_string(tag) + " has unknown element type " + std::to_string(type) + " (" +
             kKnownTypes + "; only type 4, the 4-node tetrahedron, is read)");
      if (type != 4 && kind->dim == 3) reject_element(tag, type, kind);
      if (ntags > static_cast<std::int64_t>(tok_.size()) - 3)
        fail("element " + std::to_string(tag) + " declares " + std::to_string(ntags) + " tags, but only " +
             std::to_string(tok_.size() - 3) + " values follow its type");
      const std::size_t have = tok_.size() - 3 - static_cast<std::size_t>(ntags);
      if (have != static_cast<std::size_t>(kind->nodes))
        fail("expected " + std::to_string(kind->nodes) + " node tags after element " + std::to_string(tag) + " (" +
             kind->name + ", type " + std::to_string(type) + ", " + std::to_string(ntags) + " tags), got " +
             std::to_string(have));
      if (type != 4) {
        ++skipped_elements_;
        continue;
      }
      std::int64_t nt[4];
      for (int c = 0; c < 4; ++c) nt[c] = tag_token(tok_[3 + static_cast<std::size_t>(ntags) + static_cast<std::size_t>(c)], "a node tag" + of);
      add_tet(tag, nt);
    }
  }
  expect_end("$EndElements", "the " + std::to_string(m) + " elements declared on line " + std::to_string(count_line_no));
}

// ---------------------------------------------------------------- MSH 4.1

void GmshReader::read_nodes_41() {
  const std::int64_t header_line = cur_.line();
  std::uint64_t num_blocks = 0, num_nodes = 0;
  if (binary_) {
    lines_valid_ = false;
    const std::string_view h = need(32, "the '$Nodes' header (numEntityBlocks numNodes minNodeTag maxNodeTag)");
    num_blocks = u64(h, 0);
    num_nodes = u64(h, 8);
    check_count(num_blocks, 20, "node entity block", std::numeric_limits<std::int64_t>::max());
    check_count(num_nodes, 32, "node", kMaxIndex);
  } else {
    const std::string_view line = expect_data_line("'numEntityBlocks numNodes minNodeTag maxNodeTag'");
    split_tokens(line, tok_);
    if (tok_.size() != 4)
      fail("expected 'numEntityBlocks numNodes minNodeTag maxNodeTag' (4 values), got '" + shown(trim(line)) + "'");
    num_blocks = static_cast<std::uint64_t>(count_token(tok_[0], "numEntityBlocks"));
    num_nodes = static_cast<std::uint64_t>(count_token(tok_[1], "numNodes"));
    count_token(tok_[2], "minNodeTag");
    count_token(tok_[3], "maxNodeTag");
    check_count(num_blocks, 2, "node entity block", std::numeric_limits<std::int64_t>::max());
    check_count(num_nodes, 2, "node", kMaxIndex);
  }
  const std::int64_t count_line = cur_.line();
  // Binary counts were checked exactly; an ASCII node needs at least "1\n0 0 0\n".
  const std::size_t cap = binary_ ? static_cast<std::size_t>(num_nodes) : capped(num_nodes, 8);
  nodes_.reserve(cap);
  mesh.points.reserve(3 * cap);

  std::uint64_t total = 0;
  for (std::uint64_t b = 0; b < num_blocks; ++b) {
    const std::string block = "node block " + std::to_string(b + 1);
    std::int64_t dim = 0, parametric = 0;
    std::uint64_t n = 0;
    if (binary_) {
      const std::string_view h = need(20, "the header of " + block + " (entityDim entityTag parametric numNodesInBlock)");
      dim = i32(h, 0);
      parametric = i32(h, 8);
      n = u64(h, 12);
    } else {
      const std::string_view line = expect_data_line("'entityDim entityTag parametric numNodesInBlock' of " + block);
      split_tokens(line, tok_);
      if (tok_.size() != 4)
        fail("expected 'entityDim entityTag parametric numNodesInBlock' (4 values) for " + block + ", got '" +
             shown(trim(line)) + "'");
      dim = count_token(tok_[0], "entityDim of " + block);
      std::int64_t entity_tag = 0;
      if (!parse_int(tok_[1], entity_tag)) fail("expected the entityTag of " + block + ", got '" + shown(tok_[1]) + "'");
      parametric = count_token(tok_[2], "parametric (0 or 1) of " + block);
      n = static_cast<std::uint64_t>(count_token(tok_[3], "numNodesInBlock of " + block));
    }
    if (dim < 0 || dim > 3) fail("expected entityDim 0 to 3 in " + block + ", got " + std::to_string(dim));
    if (parametric != 0 && parametric != 1)
      fail("expected parametric 0 or 1 in " + block + ", got " + std::to_string(parametric));
    if (n > num_nodes - total)
      fail(block + " declares " + std::to_string(n) + " nodes, more than the " + std::to_string(num_nodes - total) +
           " left of the " + std::to_string(num_nodes) + " in the '$Nodes' header");
    // Parametric nodes carry entityDim extra coordinates (u, v, w), read and ignored.
    const std::size_t values = 3 + static_cast<std::size_t>(parametric ? dim : 0);
    const std::size_t first = nodes_.size();
    if (binary_) {
      const std::string_view tags = need(8 * n, "the node tags of " + block);
      for (std::uint64_t j = 0; j < n; ++j) {
        item_offset_ = static_cast<std::size_t>(tags.data() - cur_.data().data()) + 8 * j;
        nodes_.add(binary_tag(u64(tags, 8 * j), "the tag of node " + std::to_string(j + 1) + " of " + block));
      }
      const std::string_view xyz = need(8 * values * n, "the node coordinates of " + block);
      for (std::uint64_t j = 0; j < n; ++j)
        for (std::size_t d = 0; d < 3; ++d) mesh.points.push_back(f64(xyz, 8 * (values * j + d)));
    } else {
      for (std::uint64_t j = 0; j < n; ++j) {
        const std::string what = "the tag of node " + std::to_string(j + 1) + " of " + block + " (one per line)";
        const std::string_view line = expect_data_line(what);
        split_tokens(line, tok_);
        if (tok_.size() != 1) fail("expected " + what + ", got '" + shown(trim(line)) + "'");
        nodes_.add(tag_token(tok_[0], what));
      }
      const std::string coords = parametric && dim > 0
                                     ? "'x y z' and " + std::to_string(dim) + " parametric coordinates"
                                     : std::string("'x y z' coordinates");
      for (std::uint64_t j = 0; j < n; ++j) {
        const std::string what = coords + " of node " + std::to_string(nodes_.tag(first + j));
        const std::string_view line = expect_data_line(what);
        split_tokens(line, tok_);
        double x[3];
        bool ok = tok_.size() == values;
        for (std::size_t d = 0; ok && d < values; ++d) {
          double v = 0;
          ok = parse_double(tok_[d], v);
          if (d < 3) x[d] = v;
        }
        if (!ok) fail("expected " + what + ", got '" + shown(trim(line)) + "'");
        mesh.points.insert(mesh.points.end(), x, x + 3);
      }
    }
    total += n;
  }
  if (total != num_nodes)
    fail_line(count_line, "the node blocks hold " + std::to_string(total) + " nodes, but the '$Nodes' header declares " +
         std::to_string(num_nodes));
  expect_end("$EndNodes", "the " + std::to_string(num_blocks) + " node blocks");
  finish_nodes(header_line);
}

void GmshReader::read_elements_41() {
  std::uint64_t num_blocks = 0, num_elements = 0;
  if (binary_) {
    lines_valid_ = false;
    const std::string_view h = need(32, "the '$Elements' header (numEntityBlocks numElements minElementTag maxElementTag)");
    num_blocks = u64(h, 0);
    num_elements = u64(h, 8);
    check_count(num_blocks, 20, "element entity block", std::numeric_limits<std::int64_t>::max());
    check_count(num_elements, 16, "element", std::numeric_limits<std::int64_t>::max());
  } else {
    const std::string_view line = expect_data_line("'numEntityBlocks numElements minElementTag maxElementTag'");
    split_tokens(line, tok_);
    if (tok_.size() != 4)
      fail("expected 'numEntityBlocks numElements minElementTag maxElementTag' (4 values), got '" + shown(trim(line)) + "'");
    num_blocks = static_cast<std::uint64_t>(count_token(tok_[0], "numEntityBlocks"));
    num_elements = static_cast<std::uint64_t>(count_token(tok_[1], "numElements"));
    count_token(tok_[2], "minElementTag");
    count_token(tok_[3], "maxElementTag");
    check_count(num_blocks, 2, "element entity block", std::numeric_limits<std::int64_t>::max());
    check_count(num_elements, 2, "element", std::numeric_limits<std::int64_t>::max());
  }
  const std::int64_t count_line = cur_.line();

  std::uint64_t total = 0;
  for (std::uint64_t b = 0; b < num_blocks; ++b) {
    const std::string block = "element block " + std::to_string(b + 1);
    std::int64_t type = 0;
    std::uint64_t n = 0;
    if (binary_) {
      const std::string_view h = need(20, "the header of " + block + " (entityDim entityTag elementType numElementsInBlock)");
      type = i32(h, 8);
      n = u64(h, 12);
    } else {
      const std::string_view line = expect_data_line("'entityDim entityTag elementType numElementsInBlock' of " + block);
      split_tokens(line, tok_);
      if (tok_.size() != 4)
        fail("expected 'entityDim entityTag elementType numElementsInBlock' (4 values) for " + block + ", got '" +
             shown(trim(line)) + "'");
      count_token(tok_[0], "entityDim of " + block);
      std::int64_t entity_tag = 0;
      if (!parse_int(tok_[1], entity_tag)) fail("expected the entityTag of " + block + ", got '" + shown(tok_[1]) + "'");
      if (!parse_int(tok_[2], type)) fail("expected the elementType of " + block + ", got '" + shown(tok_[2]) + "'");
      n = static_cast<std::uint64_t>(count_token(tok_[3], "numElementsInBlock of " + block));
    }
    const ElementKind* kind = element_kind(type);
    if (!kind) fail(block + " has unknown element type " + std::to_string(type) + " (" + kKnownTypes + ")");
    if (n > num_elements - total)
      fail(block + " declares " + std::to_string(n) + " elements, more than the " + std::to_string(num_elements - total) +
           " left of the " + std::to_string(num_elements) + " in the '$Elements' header");
    const std::size_t nodes = static_cast<std::size_t>(kind->nodes);
    if (binary_) {
      const std::uint64_t per = 8 * (1 + nodes);
      if (n > cur_.remaining() / per) {
        item_offset_ = cur_.offset();
        fail("unexpected end of file in " + block + " of " + std::to_string(n) + " elements (is the file truncated?)");
      }
      if (type != 4 && kind->dim == 3 && n > 0) {
        const std::string_view e = need(per, "an element");
        reject_element(binary_tag(u64(e, 0), "an element tag"), type, kind);
      }
      if (type != 4) {
        need(per * n, "the elements of " + block);
        skipped_elements_ += static_cast<std::size_t>(n);
      } else {
        mesh.tets.reserve(mesh.tets.size() + 4 * static_cast<std::size_t>(n));
        for (std::uint64_t j = 0; j < n; ++j) {
          const std::string_view e = need(per, "an element of " + block);
          const std::int64_t tag = binary_tag(u64(e, 0), "an element tag");
          std::int64_t nt[4];
          for (std::size_t c = 0; c < 4; ++c) nt[c] = binary_tag(u64(e, 8 * (1 + c)), "a node tag of element " + std::to_string(tag));
          add_tet(tag, nt);
        }
      }
    } else {
      for (std::uint64_t j = 0; j < n; ++j) {
        const std::string what = "element " + std::to_string(j + 1) + " of " + block + " ('elementTag nodeTag...')";
        const std::string_view line = expect_data_line(what);
        split_tokens(line, tok_);
        if (tok_.empty()) fail("expected " + what + ", got an empty line");
        const std::int64_t tag = tag_token(tok_[0], "an element tag");
        if (type != 4 && kind->dim == 3) reject_element(tag, type, kind);
        if (tok_.size() - 1 != nodes)
          fail("expected " + std::to_string(nodes) + " node tags after element " + std::to_string(tag) + " (" + kind->name +
               ", type " + std::to_string(type) + "), got " + std::to_string(tok_.size() - 1));
        if (type != 4) {
          ++skipped_elements_;
          continue;
        }
        std::int64_t nt[4];
        for (std::size_t c = 0; c < 4; ++c) nt[c] = tag_token(tok_[1 + c], "a node tag of element " + std::to_string(tag));
        add_tet(tag, nt);
      }
    }
    total += n;
  }
  if (total != num_elements)
    fail_line(count_line, "the element blocks hold " + std::to_string(total) + " elements, but the '$Elements' header declares " +
         std::to_string(num_elements));
  expect_end("$EndElements", "the " + std::to_string(num_blocks) + " element blocks");
}

}  // namespace

TetMesh read_gmsh(const std::string& path, MeshReport* report) {
  const std::string bytes = detail::read_file_bytes(path);
  return read_gmsh_bytes(bytes, path, report);
}

TetMesh read_gmsh_bytes(std::string_view bytes, const std::string& name, MeshReport* report) {
  GmshReader reader(name, bytes);
  reader.parse();
  MeshReport r = validate_mesh(reader.mesh, name, reader.element_ids);
  if (report) *report = std::move(r);
  return std::move(reader.mesh);
}

}  // namespace softcontact
