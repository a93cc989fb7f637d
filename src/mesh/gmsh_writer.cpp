// Gmsh MSH 2.2 / 4.1 writer (ASCII or binary) for a tetrahedral mesh: node tags 1..n,
// element tags 1..m, all tets of type 4 in one volume entity (tag 1).
//
// Round trips are exact: ASCII coordinates use the shortest decimal that reads back to
// the same double (std::to_chars), binary ones the double's own 8 bytes. Binary data is
// written in this machine's byte order, announced by the integer 1 after $MeshFormat.
#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cstdio>
#include <cstring>
#include <memory>

#include "softcontact/error.hpp"
#include "softcontact/mesh_io.hpp"

namespace softcontact {

namespace {

class Out {
public:
  void text(std::string_view s) { buf_.append(s); }
  void num(double v) {
    char b[32];
    const auto r = std::to_chars(b, b + sizeof b, v);
    buf_.append(b, r.ptr);
  }
  void num(std::uint64_t v) {
    char b[24];
    const auto r = std::to_chars(b, b + sizeof b, v);
    buf_.append(b, r.ptr);
  }
  template <class T>
  void bin(T v) {
    char b[sizeof(T)];
    std::memcpy(b, &v, sizeof(T));
    buf_.append(b, sizeof(T));
  }
  const std::string& str() const { return buf_; }

private:
  std::string buf_;
};

void write_file(const std::string& path, const std::string& bytes) {
  std::unique_ptr<std::FILE, int (*)(std::FILE*)> f(std::fopen(path.c_str(), "wb"), &std::fclose);
  if (!f) {
    const int err = errno;
    throw RuntimeFailure("cannot write the mesh file '" + path + "': " + std::strerror(err));
  }
  // fclose is checked too: buffered data reaches the disk (or fails to) only there.
  if (std::fwrite(bytes.data(), 1, bytes.size(), f.get()) != bytes.size() || std::fclose(f.release()) != 0) {
    const int err = errno;
    throw RuntimeFailure("cannot write the mesh file '" + path + "': " + std::strerror(err));
  }
}

void write_v22(Out& o, const TetMesh& mesh, bool binary) {
  const std::size_t n = mesh.num_vertices(), m = mesh.num_tets();
  o.text(binary ? "$MeshFormat\n2.2 1 8\n" : "$MeshFormat\n2.2 0 8\n");
  if (binary) {
    o.bin<std::int32_t>(1);
    o.text("\n");
  }
  o.text("$EndMeshFormat\n$Nodes\n");
  o.num(static_cast<std::uint64_t>(n));
  o.text("\n");
  for (std::size_t i = 0; i < n; ++i) {
    const double* x = mesh.points.data() + 3 * i;
    if (binary) {
      o.bin<std::int32_t>(static_cast<std::int32_t>(i + 1));
      for (int d = 0; d < 3; ++d) o.bin(x[d]);
    } else {
      o.num(static_cast<std::uint64_t>(i + 1));
      for (int d = 0; d < 3; ++d) {
        o.text(" ");
        o.num(x[d]);
      }
      o.text("\n");
    }
  }
  o.text(binary ? "\n$EndNodes\n$Elements\n" : "$EndNodes\n$Elements\n");
  o.num(static_cast<std::uint64_t>(m));
  o.text("\n");
  // Two tags per element: physical group 1 and elementary (volume) entity 1.
  if (binary && m > 0) {
    o.bin<std::int32_t>(4);
    o.bin<std::int32_t>(static_cast<std::int32_t>(m));
    o.bin<std::int32_t>(2);
  }
  for (std::size_t t = 0; t < m; ++t) {
    const index_t* tet = mesh.tets.data() + 4 * t;
    if (binary) {
      o.bin<std::int32_t>(static_cast<std::int32_t>(t + 1));
      o.bin<std::int32_t>(1);
      o.bin<std::int32_t>(1);
      for (int c = 0; c < 4; ++c) o.bin<std::int32_t>(tet[c] + 1);
    } else {
      o.num(static_cast<std::uint64_t>(t + 1));
      o.text(" 4 2 1 1");
      for (int c = 0; c < 4; ++c) {
        o.text(" ");
        o.num(static_cast<std::uint64_t>(tet[c]) + 1);
      }
      o.text("\n");
    }
  }
  o.text(binary ? "\n$EndElements\n" : "$EndElements\n");
}

void write_v41(Out& o, const TetMesh& mesh, bool binary) {
  const std::uint64_t n = mesh.num_vertices(), m = mesh.num_tets();
  o.text(binary ? "$MeshFormat\n4.1 1 8\n" : "$MeshFormat\n4.1 0 8\n");
  if (binary) {
    o.bin<std::int32_t>(1);
    o.text("\n");
  }
  o.text("$EndMeshFormat\n");

  // One volume entity (tag 1) with its bounding box, no physical groups and no bounding
  // surfaces, so that Gmsh itself can attach the nodes and elements to an entity.
  double lo[3] = {0, 0, 0}, hi[3] = {0, 0, 0};
  for (std::size_t i = 0; i < n; ++i)
    for (int d = 0; d < 3; ++d) {
      const double x = mesh.points[3 * i + static_cast<std::size_t>(d)];
      lo[d] = i == 0 ? x : std::min(lo[d], x);
      hi[d] = i == 0 ? x : std::max(hi[d], x);
    }
  o.text("$Entities\n");
  if (binary) {
    for (std::uint64_t c : {0, 0, 0, 1}) o.bin<std::uint64_t>(c);
    o.bin<std::int32_t>(1);
    for (double x : {lo[0], lo[1], lo[2], hi[0], hi[1], hi[2]}) o.bin(x);
    o.bin<std::uint64_t>(0);  // numPhysicalTags
    o.bin<std::uint64_t>(0);  // numBoundingSurfaces
    o.text("\n");
  } else {
    o.text("0 0 0 1\n1");
    for (double x : {lo[0], lo[1], lo[2], hi[0], hi[1], hi[2]}) {
      o.text(" ");
      o.num(x);
    }
    o.text(" 0 0\n");
  }
  o.text("$EndEntities\n$Nodes\n");

  // numEntityBlocks numNodes minNodeTag maxNodeTag; then one block on volume 1.
  const std::uint64_t blocks_n = n > 0 ? 1 : 0, blocks_m = m > 0 ? 1 : 0;
  if (binary) {
    for (std::uint64_t v : {blocks_n, n, n > 0 ? std::uint64_t{1} : 0, n}) o.bin<std::uint64_t>(v);
    if (n > 0) {
      o.bin<std::int32_t>(3);
      o.bin<std::int32_t>(1);
      o.bin<std::int32_t>(0);
      o.bin<std::uint64_t>(n);
      for (std::uint64_t i = 1; i <= n; ++i) o.bin<std::uint64_t>(i);
      for (double x : mesh.points) o.bin(x);
    }
    o.text("\n$EndNodes\n$Elements\n");
    for (std::uint64_t v : {blocks_m, m, m > 0 ? std::uint64_t{1} : 0, m}) o.bin<std::uint64_t>(v);
    if (m > 0) {
      o.bin<std::int32_t>(3);
      o.bin<std::int32_t>(1);
      o.bin<std::int32_t>(4);
      o.bin<std::uint64_t>(m);
      for (std::uint64_t t = 0; t < m; ++t) {
        o.bin<std::uint64_t>(t + 1);
        for (int c = 0; c < 4; ++c) o.bin<std::uint64_t>(static_cast<std::uint64_t>(mesh.tets[4 * t + static_cast<std::uint64_t>(c)]) + 1);
      }
    }
    o.text("\n$EndElements\n");
    return;
  }
  o.num(blocks_n);
  o.text(" ");
  o.num(n);
  o.text(n > 0 ? " 1 " : " 0 ");
  o.num(n);
  o.text("\n");
  if (n > 0) {
    o.text("3 1 0 ");
    o.num(n);
    o.text("\n");
    for (std::uint64_t i = 1; i <= n; ++i) {
      o.num(i);
      o.text("\n");
    }
    for (std::uint64_t i = 0; i < n; ++i) {
      for (int d = 0; d < 3; ++d) {
        if (d) o.text(" ");
        o.num(mesh.points[3 * i + static_cast<std::uint64_t>(d)]);
      }
      o.text("\n");
    }
  }
  o.text("$EndNodes\n$Elements\n");
  o.num(blocks_m);
  o.text(" ");
  o.num(m);
  o.text(m > 0 ? " 1 " : " 0 ");
  o.num(m);
  o.text("\n");
  if (m > 0) {
    o.text("3 1 4 ");
    o.num(m);
    o.text("\n");
    for (std::uint64_t t = 0; t < m; ++t) {
      o.num(t + 1);
      for (int c = 0; c < 4; ++c) {
        o.text(" ");
        o.num(static_cast<std::uint64_t>(mesh.tets[4 * t + static_cast<std::uint64_t>(c)]) + 1);
      }
      o.text("\n");
    }
  }
  o.text("$EndElements\n");
}

}  // namespace

void write_gmsh(const std::string& path, const TetMesh& mesh, GmshFormat format) {
  Out o;
  switch (format) {
    case GmshFormat::v22_ascii: write_v22(o, mesh, false); break;
    case GmshFormat::v22_binary: write_v22(o, mesh, true); break;
    case GmshFormat::v41_ascii: write_v41(o, mesh, false); break;
    case GmshFormat::v41_binary: write_v41(o, mesh, true); break;
  }
  write_file(path, o.str());
}

}  // namespace softcontact
