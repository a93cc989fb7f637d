#pragma once
// The rotation R of a deformation gradient F, for the corotational model.
//
// F = R S with R a rotation (det R = +1) and S symmetric. For det F > 0 this is the polar
// decomposition, found by Newton's iteration (Higham 1986, "Computing the polar
// decomposition -- with applications", SIAM J. Sci. Stat. Comput. 7(4)):
//
//   X_0 = F,   X_(k+1) = (X_k + X_k^-T) / 2 = (X_k + cof(X_k) / det(X_k)) / 2
//
// All iterates share F's singular vectors; each singular value goes s -> (s + 1/s)/2, so
// the error contracts quadratically, (s - 1) -> (s - 1)^2 / (2 s), whatever the rotation.
// Elements near their rest shape (strains of 1e-3 to 1e-1) converge in 2 to 4 steps, which
// is why no warm start is needed: the count does not depend on how far the element has
// rotated. We stop when the Frobenius norm of the update is below kPolarTolerance: the
// error left is then about tolerance^2 / 2, below rounding.
//
// For det F <= 0 (an inverted or flat element) the polar factor would contain a
// reflection, and the corotational force would then push the element further inside
// out. There, and when Newton has not converged within kPolarMaxIterations (a nearly
// flat element: s ~ 0 takes many halving steps), we use the rotation-variant SVD of
// Irving, Teran, Fedkiw 2004 ("Invertible finite elements for robust simulation of
// large deformation"): F = U diag(s) V^T with det U = det V = +1, the smallest singular
// value carrying the sign of det F, and R = U V^T. For det F > 0 both give the same R.
#include "mat3.hpp"

namespace softcontact::model {

inline constexpr int kPolarMaxIterations = 8;
inline constexpr double kPolarTolerance = 1e-8;

/// One Newton step X -> (X + cof(X)/det(X)) / 2, written as X + D with the update
/// D = cof(X)/(2 det X) - X/2; returns |D|_F^2.
inline double polar_newton_step(const Mat3& x, Mat3& xn) {
  const Mat3 c = cofactor(x);
  const double h = 0.5 / det_from_cofactor(x, c);
  double upd = 0;
  for (int k = 0; k < 9; ++k) {
    const double d = h * c[k] - 0.5 * x[k];
    xn[k] = x[k] + d;
    upd += d * d;
  }
  return upd;
}

/// Newton's iteration from F. Returns false (R unset) for det F <= 0 or no convergence.
/// Convergence is tested from the second step on (one step is never enough, except for
/// an exact rotation, where a second step changes nothing): the kernels skip that test.
inline bool polar_newton(const Mat3& F, Mat3& R) {
  if (!(det(F) > 0)) return false;
  Mat3 x = F, xn;
  for (int it = 0; it < kPolarMaxIterations; ++it) {
    const double upd = polar_newton_step(x, xn);
    x = xn;
    if (it >= 1 && upd <= kPolarTolerance * kPolarTolerance) {
      R = x;
      return true;
    }
  }
  return false;
}

/// Rotation-variant SVD rotation (Irving et al. 2004), for any F (also inverted).
Mat3 rotation_from_svd(const Mat3& F);

/// R of F = R S, R a proper rotation (see the header comment).
inline Mat3 rotation_part(const Mat3& F) {
  Mat3 R;
  return polar_newton(F, R) ? R : rotation_from_svd(F);
}

}  // namespace softcontact::model
