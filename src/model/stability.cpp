// The explicit stability limit of one tet (forces.hpp, tet_max_frequency) and the
// damped limit of one mode (damped_stable_step).
//
// Why per element: with lumped masses the global mass matrix is the sum of the element
// masses M_T (a quarter of rho V_T on each corner), and the stiffness the sum of the K_T,
// so for every displacement u
//   u^T K u / u^T M u = sum_T u^T K_T u / sum_T u^T M_T u <= max_T lambda_max(M_T^-1 K_T)
// (Irons' element eigenvalue theorem; Hughes, "The Finite Element Method", Sec. 9.1.2).
// Central differences (position Verlet) and symplectic Euler are stable for
// dt <= 2 / omega_max, so dt <= 2 / max_T omega_T is a guaranteed limit for the
// linearised motion about the rest state, for any element shape and Poisson ratio.
//
// With Rayleigh damping (forces.hpp: -alpha M v - beta K v, explicit, at the velocity
// v^t of the start of the step) each undamped mode u'' = -omega^2 u stays a mode, with
// c = alpha + beta omega^2 = 2 xi omega. One step of either explicit integrator
// (integrator.cpp), h = dt:
//   position Verlet, v^t = (x^t - x^(t-h)) / h (the backward difference the step before
//   left in World::v):
//     x^(t+h) = 2 x^t - x^(t-h) - h^2 omega^2 x^t - h c (x^t - x^(t-h))
//     [x^(t+h)]   [2 - h^2 omega^2 - h c   -(1 - h c)] [x^t    ]
//     [x^t    ] = [1                        0        ] [x^(t-h)]
//   symplectic Euler, v^(t+h) = v^t - h (omega^2 x^t + c v^t), x^(t+h) = x^t + h v^(t+h):
//     [x^(t+h)]   [1 - h^2 omega^2   h (1 - h c)] [x^t]
//     [v^(t+h)] = [-h omega^2        1 - h c    ] [v^t]
// Both matrices have trace 2 - h^2 omega^2 - h c and determinant 1 - h c, so the same
// characteristic polynomial z^2 - (2 - W - C) z + (1 - C), W = h^2 omega^2, C = h c. Its
// roots lie in the closed unit disc iff (Jury / Schur-Cohn) |1 - C| <= 1 and
// |2 - W - C| <= 2 - C, i.e. W >= 0, C >= 0 and W + 2 C <= 4 (which implies C <= 2):
//   h^2 omega^2 + 2 h (alpha + beta omega^2) <= 4
//   <=>  h <= 4 / (c + sqrt(c^2 + 4 omega^2)) = (2 / omega) (sqrt(1 + xi^2) - xi).
// At equality a root is -1 (the highest mode flips sign each step); beyond, it grows.
// The bound falls monotonically with omega (its denominator grows with omega for
// alpha, beta >= 0), so the step that is stable for an object's largest element frequency
// max_T omega_T >= omega_max (Irons, above) is stable for every mode of that object: the
// per-element bound with the object's material stays a guaranteed global bound. Objects
// interact only through contact, so the scene's limit is the smallest over its objects.
#include <Eigen/Eigenvalues>
#include <cmath>
#include <limits>

#include "material_registry.hpp"
#include "softcontact/forces.hpp"

namespace softcontact {

double tet_max_frequency(const double X[12], const Material& m) {
  using namespace model;
  const Mat3 dm = {X[3] - X[0], X[6] - X[0], X[9] - X[0], X[4] - X[1], X[7] - X[1],
                   X[10] - X[1], X[5] - X[2], X[8] - X[2], X[11] - X[2]};
  const double vol = std::abs(det(dm)) / 6;
  const Mat3 c = cofactor(dm);
  const double dd = det_from_cofactor(dm, c);
  Mat3 dm_inv;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) dm_inv[3 * i + j] = c[3 * j + i] / dd;
  // The law's rest stiffness: Hooke's law for the FEM models (they all linearise to it,
  // material_law.hpp), the springs for mass_spring.
  double k[144];
  material_law(m.model).rest_stiffness(X, dm_inv, vol, law_params(m), k);
  const Eigen::Matrix<double, 12, 12> K = Eigen::Map<const Eigen::Matrix<double, 12, 12, Eigen::RowMajor>>(k);
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, 12, 12>> es(K, Eigen::EigenvaluesOnly);
  return std::sqrt(std::max(0.0, es.eigenvalues().maxCoeff()) / (m.density * vol / 4));
}

double damped_stable_step(double omega, double alpha, double beta) {
  // 4 / (c + sqrt(c^2 + 4 omega^2)) rather than (2 / omega)(sqrt(1 + xi^2) - xi): no
  // cancellation for large xi, and 2 / alpha (not 0 / 0) for a rigid mode (omega = 0).
  const double c = alpha + beta * omega * omega;
  const double den = c + std::hypot(c, 2 * omega);
  return den > 0 ? 4 / den : std::numeric_limits<double>::infinity();
}

}  // namespace softcontact
