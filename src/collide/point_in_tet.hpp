#pragma once
// Point-in-tetrahedron test by barycentric signs, with a tie rule that gives every point
// of a conforming mesh's interior to exactly one tet.
//
// p is strictly inside tet (v0, v1, v2, v3) when each barycentric coordinate
// lambda_j = V_j(p) / V is positive, V being the signed volume and V_j(p) the volume with
// v_j replaced by p; the sign of V_j(p) says on which side of face j (opposite v_j) p
// lies. To make the two tets that share a face agree bit for bit, the side is computed
// from the face's vertices sorted by index, f0 < f1 < f2:
//     O_j(p) = (p - f0) . n_j,   n_j = (f1 - f0) x (f2 - f0),
// the same floating-point operations on the same numbers in both tets. The vertex v_j
// lies on side sigma_j = sign(V) * parity of (f0, f1, f2, v_j) as a permutation of the
// tet's corners (orient is alternating in its arguments), and the test is
// sign(O_j(p)) == sigma_j for j = 0..3: no division.
//
// Tie rule (p exactly on the plane of a face, O_j(p) == 0):
//  - interior face (shared with another tet): p is moved symbolically by
//    delta = (eps, eps^2, eps^3), eps -> 0+ (simulation of simplicity), so
//    sign(O_j(p + delta)) = sign(n_j.x), or sign(n_j.y) if that is 0, or sign(n_j.z).
//    Both tets see the same n_j, so exactly one of them takes p; since the same delta
//    is used for every face, a point on an edge or at a vertex is also taken by exactly
//    one tet of a conforming mesh (the one containing p + delta).
//  - boundary face: p is on the body's surface, which is not "strictly inside": the tet
//    does not take it. Likewise a point equal to a surface vertex is taken by no tet
//    (two coincident bodies do not penetrate each other). (A point exactly on a boundary
//    *edge*, off its vertices, may still be taken by an interior tet of the edge's fan
//    when p + delta points into the body; its penetration depth is then about 0.)
//
// Exactness: the two tets of a shared face evaluate O_j bit for bit alike, so a point on
// (or within rounding of) a shared face is taken by exactly one of them whatever the
// rounding. A point equal to a mesh vertex gets O == 0 exactly on the faces through
// that vertex (checked by coordinates), so it too is taken once. Only a point within
// rounding of an edge, off the vertices, can see inconsistent signs on the faces around
// the edge (taken by none or by two tets of the fan); the detector keeps one record
// per (point, body) either way.
//
// A tet with |V| <= kFlatTet L^3 (L: largest extent of its box) is degenerate: it takes
// no point and is reported as such.
#include <cstdint>

#include "softcontact/mesh.hpp"
#include "vec3.hpp"

namespace softcontact::collide {

enum class TetSide : std::uint8_t { outside, inside, degenerate };

/// Relative volume below which a tet counts as flat (the threshold of validate_mesh).
inline constexpr double kFlatTet = 1e-12;

/// The four face planes of one tet, tested against many points. setup() only checks the
/// volume; each face plane is built the first time a point needs it (most points fail
/// at the first or second face, so most tets never build all four).
class TetFaces {
public:
  /// `x` (n,3) positions, `tet` its four vertex indices, `boundary_mask` bit j set when
  /// face j (opposite corner j) is on the body's surface and bit 4 + m when corner m is
  /// a surface vertex. False for a degenerate tet.
  bool setup(const double* x, const index_t* tet, unsigned boundary_mask);

  /// Strictly inside, ties resolved as above (setup must have returned true).
  bool contains(const V3& p) {
    // A point equal to corner m lies on the three faces through m: their O is exactly 0
    // (computed, it would be a rounded triple product with a repeated vector).
    int at = -1;
    for (int m = 0; m < 4; ++m)
      if (p[0] == v_[m][0] && p[1] == v_[m][1] && p[2] == v_[m][2]) at = m;
    if (at >= 0 && (boundary_ & (16u << at))) return false;  // a surface vertex: on the surface
    for (int j = 0; j < 4; ++j) {
      if (!(ready_ & (1u << j))) build_face(j);
      const double o = at >= 0 && j != at ? 0.0
                                          : (p[0] - f0_[j][0]) * n_[j][0] + (p[1] - f0_[j][1]) * n_[j][1] +
                                                (p[2] - f0_[j][2]) * n_[j][2];
      const int s = o > 0 ? 1 : (o < 0 ? -1 : tie_[j]);
      if (s != sigma_[j]) return false;
    }
    return true;
  }

private:
  void build_face(int j);
  const index_t* tet_ = nullptr;
  V3 v_[4];
  int sign_v_ = 0;
  unsigned boundary_ = 0, ready_ = 0;
  V3 f0_[4], n_[4];
  int sigma_[4];  // side of the opposite vertex, +-1
  int tie_[4];    // side given to a point on the plane: perturbed sign, or 0 (boundary: never inside)
};

/// One-off test: setup + contains.
TetSide point_in_tet(const double* x, const index_t* tet, unsigned boundary_mask, const V3& p);

}  // namespace softcontact::collide
