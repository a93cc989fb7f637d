#include "point_in_tet.hpp"

#include <algorithm>
#include <cmath>

namespace softcontact::collide {

namespace {
// Sign of n . delta for delta = (eps, eps^2, eps^3): the first non-zero component.
inline int perturbed_sign(const V3& n) {
  for (int d = 0; d < 3; ++d)
    if (n[d] != 0) return n[d] > 0 ? 1 : -1;
  return 0;
}
}  // namespace

bool TetFaces::setup(const double* x, const index_t* tet, unsigned boundary_mask) {
  tet_ = tet;
  boundary_ = boundary_mask;
  ready_ = 0;
  for (int c = 0; c < 4; ++c) v_[c] = load(x, tet[c]);
  const double vol6 = orient(v_[0], v_[1], v_[2], v_[3]);
  Box b;
  b.reset();
  for (const V3& c : v_) b.add(c);
  const double ext = b.max_extent();
  if (!(std::abs(vol6) > 6 * kFlatTet * ext * ext * ext)) return false;
  sign_v_ = vol6 > 0 ? 1 : -1;
  return true;
}

void TetFaces::build_face(int j) {
  // Corners of face j in the tet's order, then sorted by vertex index, counting swaps.
  // (c0, c1, c2, j) is an even permutation of (0,1,2,3) for j = 1, 3 and odd for 0, 2
  // (moving j from position j to position 3 takes 3 - j transpositions).
  int c[3], k = 0;
  for (int m = 0; m < 4; ++m)
    if (m != j) c[k++] = m;
  int parity = (3 - j) % 2;
  auto swap_if = [&](int a, int b) {
    if (tet_[c[a]] > tet_[c[b]]) {
      std::swap(c[a], c[b]);
      parity ^= 1;
    }
  };
  swap_if(0, 1);
  swap_if(1, 2);
  swap_if(0, 1);
  sigma_[j] = parity ? -sign_v_ : sign_v_;
  f0_[j] = v_[c[0]];
  n_[j] = cross(v_[c[1]] - f0_[j], v_[c[2]] - f0_[j]);
  tie_[j] = (boundary_ & (1u << j)) ? 0 : perturbed_sign(n_[j]);
  ready_ |= 1u << j;
}

TetSide point_in_tet(const double* x, const index_t* tet, unsigned boundary_mask, const V3& p) {
  TetFaces f;
  if (!f.setup(x, tet, boundary_mask)) return TetSide::degenerate;
  return f.contains(p) ? TetSide::inside : TetSide::outside;
}

}  // namespace softcontact::collide
