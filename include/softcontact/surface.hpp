#pragma once
// Boundary of a tetrahedral mesh: the faces that belong to exactly one tet, oriented
// outward (their normal (x1-x0) x (x2-x0) points out of the body), and area-weighted
// vertex normals (the "smoothed normals" that consistent penetration depth interpolates).
#include <vector>

#include "softcontact/mesh.hpp"

namespace softcontact {

struct Surface {
  std::vector<index_t> triangles;   ///< (s,3) vertex indices, outward orientation
  std::vector<index_t> vertices;    ///< sorted indices of the vertices on the boundary

  std::size_t num_triangles() const { return triangles.size() / 3; }
};

/// Outward faces of a positively oriented tet (a,b,c,d), as positions into tet[0..3].
inline constexpr int kTetFaces[4][3] = {{0, 2, 1}, {0, 1, 3}, {0, 3, 2}, {1, 2, 3}};

/// Result of a closedness check of a surface: 0 when closed. Otherwise the first offending
/// undirected edge (a,b) and how many boundary triangles use it (a closed, consistently
/// oriented surface uses every edge exactly twice, once in each direction).
struct ClosednessDefect {
  std::size_t open_edges = 0;
  index_t a = -1, b = -1;
  int uses = 0;
};

/// Extracts the boundary in a deterministic order (by tet index, then face 0..3).
/// Faces shared by more than two tets are counted in `nonmanifold_faces` (if not null).
Surface extract_surface(const TetMesh& mesh, std::size_t* nonmanifold_faces = nullptr);

/// Checks that every edge of the surface is used by exactly two triangles in opposite
/// directions.
ClosednessDefect check_closed(const Surface& surface);

/// Area-weighted vertex normals (n,3) of the boundary vertices; zero for interior ones.
std::vector<double> vertex_normals(const TetMesh& mesh, const Surface& surface);

/// Volume enclosed by the surface by the divergence theorem: sum over triangles of
/// x0 . (x1 x x2) / 6. Equals the sum of tet volumes for a closed, outward surface.
double enclosed_volume(const TetMesh& mesh, const Surface& surface);

/// Sum of the tets' signed volumes.
double tet_volume_sum(const TetMesh& mesh);

}  // namespace softcontact
