// Choosing a mesh reader by file extension, and the small text utilities the readers share.
#include <algorithm>
#include <atomic>
#include <cctype>
#include <cerrno>
#include <charconv>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <memory>

#include "softcontact/error.hpp"
#include "softcontact/mesh_io.hpp"
#include "reader_util.hpp"

namespace softcontact {

namespace detail {

std::string read_file_bytes(const std::string& path) {
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec))
    throw InputError(path, 0, "is a directory (expected a mesh file)");
  // fopen rather than ifstream: errno gives the reason (missing, permission denied).
  std::unique_ptr<std::FILE, int (*)(std::FILE*)> f(std::fopen(path.c_str(), "rb"), &std::fclose);
  if (!f) {
    const int err = errno;
    throw InputError(path, 0, std::string("cannot open the mesh file: ") + std::strerror(err));
  }
  std::string bytes;
  char buf[1 << 16];
  for (;;) {
    const std::size_t got = std::fread(buf, 1, sizeof buf, f.get());
    bytes.append(buf, got);
    if (got < sizeof buf) break;
  }
  if (std::ferror(f.get())) {
    const int err = errno;
    throw InputError(path, 0, std::string("cannot read the mesh file: ") + std::strerror(err));
  }
  return bytes;
}

bool TextCursor::next_line(std::string_view& line) {
  if (pos_ >= data_.size()) return false;
  const std::size_t nl = data_.find('\n', pos_);
  const std::size_t end = nl == std::string_view::npos ? data_.size() : nl;
  line = data_.substr(pos_, end - pos_);
  if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
  pos_ = nl == std::string_view::npos ? data_.size() : nl + 1;
  ++line_;
  return true;
}

std::string_view TextCursor::take(std::size_t n) {
  n = std::min(n, remaining());
  const std::string_view s = data_.substr(pos_, n);
  pos_ += n;
  return s;
}

void TextCursor::skip_blank_bytes() {
  while (pos_ < data_.size() &&
         (data_[pos_] == ' ' || data_[pos_] == '\t' || data_[pos_] == '\r' || data_[pos_] == '\n'))
    ++pos_;
}

static bool is_blank(char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\n' || c == '\f' || c == '\v'; }

std::string_view trim(std::string_view s) {
  while (!s.empty() && is_blank(s.front())) s.remove_prefix(1);
  while (!s.empty() && is_blank(s.back())) s.remove_suffix(1);
  return s;
}

void split_tokens(std::string_view line, std::vector<std::string_view>& out) {
  out.clear();
  std::size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && is_blank(line[i])) ++i;
    const std::size_t start = i;
    while (i < line.size() && !is_blank(line[i])) ++i;
    if (i > start) out.push_back(line.substr(start, i - start));
  }
}

bool parse_int(std::string_view token, std::int64_t& value) {
  if (token.size() > 1 && token.front() == '+') token.remove_prefix(1);
  const char* end = token.data() + token.size();
  const auto r = std::from_chars(token.data(), end, value);
  return r.ec == std::errc() && r.ptr == end && !token.empty();
}

bool parse_double(std::string_view token, double& value) {
  if (token.size() > 1 && token.front() == '+') token.remove_prefix(1);
  const char* end = token.data() + token.size();
  const auto r = std::from_chars(token.data(), end, value, std::chars_format::general);
  return r.ec == std::errc() && r.ptr == end && !token.empty();
}

std::string shown(std::string_view text) {
  constexpr std::size_t kMax = 60;
  std::string s;
  for (std::size_t i = 0; i < text.size() && i < kMax; ++i) {
    const unsigned char c = static_cast<unsigned char>(text[i]);
    s += (std::isprint(c) || c == ' ') ? static_cast<char>(c) : '?';
  }
  if (text.size() > kMax) s += "...";
  return s;
}

}  // namespace detail

namespace {

std::string lower_extension(const std::string& path) {
  std::string ext = std::filesystem::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return ext;
}

}  // namespace

namespace {
std::atomic<std::uint64_t> files_read{0};
}

std::uint64_t mesh_files_read() { return files_read.load(); }

TetMesh read_mesh(const std::string& path, MeshReport* report) {
  ++files_read;
  const std::string ext = lower_extension(path);
  if (ext == ".msh") return read_gmsh(path, report);
  if (ext == ".node" || ext == ".ele") return read_tetgen(path, report);
  throw InputError(path, 0,
                   "unknown mesh format '" + (ext.empty() ? std::string("(no extension)") : ext) +
                       "' (expected .msh for Gmsh 2.2/4.1, or .node/.ele for TetGen)");
}

namespace {
void put_bytes(std::vector<char>& b, const void* data, std::size_t n) {
  const auto* c = static_cast<const char*>(data);
  b.insert(b.end(), c, c + n);
}
void put_u64(std::vector<char>& b, std::uint64_t v) { put_bytes(b, &v, sizeof v); }
void get_bytes(const std::vector<char>& b, std::size_t& at, void* data, std::size_t n) {
  if (n > b.size() || at > b.size() - n) throw RuntimeFailure("a mesh's bytes end before the mesh does");
  if (n > 0) std::memcpy(data, b.data() + at, n);
  at += n;
}
std::uint64_t get_u64(const std::vector<char>& b, std::size_t& at) {
  std::uint64_t v = 0;
  get_bytes(b, at, &v, sizeof v);
  return v;
}
// A count read back, checked against the bytes left (each item takes `item` bytes).
std::size_t get_count(const std::vector<char>& b, std::size_t& at, std::size_t item) {
  const std::uint64_t n = get_u64(b, at);
  if (n > (b.size() - at) / item) throw RuntimeFailure("a mesh's bytes end before the mesh does");
  return static_cast<std::size_t>(n);
}
}  // namespace

void append_mesh_bytes(std::vector<char>& bytes, const TetMesh& mesh, const MeshReport* report) {
  put_u64(bytes, mesh.num_vertices());
  put_u64(bytes, mesh.num_tets());
  put_bytes(bytes, mesh.points.data(), mesh.points.size() * sizeof(double));
  put_bytes(bytes, mesh.tets.data(), mesh.tets.size() * sizeof(index_t));
  const MeshReport none;
  const MeshReport& r = report ? *report : none;
  put_u64(bytes, r.reoriented_tets);
  put_u64(bytes, r.unreferenced_vertices);
  put_u64(bytes, r.warnings.size());
  for (const std::string& w : r.warnings) {
    put_u64(bytes, w.size());
    put_bytes(bytes, w.data(), w.size());
  }
}

TetMesh take_mesh_bytes(const std::vector<char>& bytes, std::size_t& at, MeshReport* report) {
  TetMesh m;
  const std::uint64_t nv64 = get_u64(bytes, at);
  if (nv64 > bytes.size() / (3 * sizeof(double))) throw RuntimeFailure("a mesh's bytes end before the mesh does");
  const auto nv = static_cast<std::size_t>(nv64);
  const std::uint64_t nt = get_u64(bytes, at);
  m.points.resize(3 * nv);
  get_bytes(bytes, at, m.points.data(), m.points.size() * sizeof(double));
  if (nt > (bytes.size() - at) / (4 * sizeof(index_t))) throw RuntimeFailure("a mesh's bytes end before the mesh does");
  m.tets.resize(4 * static_cast<std::size_t>(nt));
  get_bytes(bytes, at, m.tets.data(), m.tets.size() * sizeof(index_t));
  MeshReport r;
  r.reoriented_tets = static_cast<std::size_t>(get_u64(bytes, at));
  r.unreferenced_vertices = static_cast<std::size_t>(get_u64(bytes, at));
  const std::size_t nw = get_count(bytes, at, sizeof(std::uint64_t));
  for (std::size_t i = 0; i < nw; ++i) {
    std::string w(get_count(bytes, at, 1), '\0');
    get_bytes(bytes, at, w.data(), w.size());
    r.warnings.push_back(std::move(w));
  }
  if (report) *report = std::move(r);
  return m;
}

}  // namespace softcontact
