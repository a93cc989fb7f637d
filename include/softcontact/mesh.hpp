#pragma once
// A tetrahedral mesh of one object, in the object's own (local) vertex numbering.
// Layout follows design.md: interleaved xyz per vertex, four vertex indices per tet.
#include <array>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

namespace softcontact {

using index_t = std::int32_t;   ///< local index (vertex, tet, triangle) within one object or rank
using gid_t = std::int64_t;     ///< global id: never changes, unique across the whole scene

/// Corner pairs of the six edges of a tet (corners 0..3), in the one order every part of
/// the code uses (rest lengths, mesh edges, edge statistics).
inline constexpr int kTetEdges[6][2] = {{0, 1}, {0, 2}, {0, 3}, {1, 2}, {1, 3}, {2, 3}};

/// A triangle or tet face by its three vertex indices in ascending order: the key by which
/// faces are matched (surface extraction, tet-face neighbours). Compared element by
/// element: std::array's == on integers is a call to memcmp, which dominated those sorts.
using FaceKey = std::array<index_t, 3>;

inline FaceKey face_key(index_t a, index_t b, index_t c) {
  if (a > b) std::swap(a, b);
  if (b > c) std::swap(b, c);
  if (a > b) std::swap(a, b);
  return {a, b, c};
}
inline bool same_face(const FaceKey& a, const FaceKey& b) { return a[0] == b[0] && a[1] == b[1] && a[2] == b[2]; }
inline bool face_less(const FaceKey& a, const FaceKey& b) {
  return a[0] != b[0] ? a[0] < b[0] : a[1] != b[1] ? a[1] < b[1] : a[2] < b[2];
}

struct TetMesh {
  std::vector<double> points;    ///< (n,3) interleaved x,y,z [m]
  std::vector<index_t> tets;     ///< (m,4) vertex indices, positive orientation after validation

  std::size_t num_vertices() const { return points.size() / 3; }
  std::size_t num_tets() const { return tets.size() / 4; }
};

/// Signed volume of the tet (a,b,c,d): det[b-a, c-a, d-a] / 6. Positive orientation
/// means (b-a) x (c-a) points towards d.
double signed_tet_volume(const double* a, const double* b, const double* c, const double* d);

/// What validation found and repaired (counts), for logs and tests.
struct MeshReport {
  std::size_t reoriented_tets = 0;           ///< inverted tets whose orientation was flipped
  std::size_t unreferenced_vertices = 0;     ///< vertices no tet uses (removed)
  std::vector<std::string> warnings;         ///< one line each, already naming the file
};

/// Checks a freshly read mesh and repairs what can be repaired, in place.
///  - no tets, an index out of range, a repeated vertex in a tet, a non-finite coordinate,
///    a degenerate tet (|volume| <= 1e-12 * (longest edge)^3): InputError naming `source`
///    and the element (1-based, in file order; `element_ids` gives the file's own numbers
///    when not empty);
///  - inverted tets are reoriented (two vertices swapped) with a warning;
///  - unreferenced vertices are removed (indices compacted) with a warning;
///  - a boundary that is not closed (a boundary edge shared by other than two boundary
///    triangles, or a face shared by more than two tets): InputError.
MeshReport validate_mesh(TetMesh& mesh, const std::string& source,
                         const std::vector<std::int64_t>& element_ids = {});

}  // namespace softcontact
