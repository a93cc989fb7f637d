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
#include <Eigen/SparseCholesky>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

#include "material_registry.hpp"
#include "softcontact/forces.hpp"

namespace softcontact {

namespace {

/// Rest stiffness K (12x12, row-major) of the tet with rest corners X under the material's
/// law; returns its volume.
double tet_rest_stiffness(const double X[12], const Material& m, double k[144]) {
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
  material_law(m.model).rest_stiffness(X, dm_inv, vol, law_params(m), k);
  return vol;
}

}  // namespace

double tet_max_frequency(const double X[12], const Material& m) {
  double k[144];
  const double vol = tet_rest_stiffness(X, m, k);
  const Eigen::Matrix<double, 12, 12> K = Eigen::Map<const Eigen::Matrix<double, 12, 12, Eigen::RowMajor>>(k);
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, 12, 12>> es(K, Eigen::EigenvaluesOnly);
  return std::sqrt(std::max(0.0, es.eigenvalues().maxCoeff()) / (m.density * vol / 4));
}

MeshFrequency mesh_max_frequency(const TetMesh& mesh, const Material& m, double omega_element, int lanczos_steps) {
  const std::size_t nv = mesh.num_vertices(), nt = mesh.num_tets();
  const auto n = static_cast<Eigen::Index>(3 * nv);
  // Lumped masses (a quarter of rho V on each corner, in tet order as World sums them) and
  // the lower triangle of the assembled rest stiffness. setFromTriplets adds duplicates in
  // the order given: the matrix does not depend on the threads (there are none here).
  std::vector<double> mass(nv, 0.0);
  std::vector<Eigen::Triplet<double>> entries;
  entries.reserve(78 * nt + static_cast<std::size_t>(n));
  for (Eigen::Index i = 0; i < n; ++i) entries.emplace_back(i, i, 0.0);  // the diagonal of mu I - A is always there
  for (std::size_t t = 0; t < nt; ++t) {
    const index_t* c = &mesh.tets[4 * t];
    double X[12], k[144];
    for (int a = 0; a < 4; ++a)
      for (int d = 0; d < 3; ++d) X[3 * a + d] = mesh.points[3 * static_cast<std::size_t>(c[a]) + d];
    const double vol = tet_rest_stiffness(X, m, k);
    for (int a = 0; a < 4; ++a) mass[static_cast<std::size_t>(c[a])] += 0.25 * m.density * vol;
    for (int a = 0; a < 12; ++a)
      for (int b = 0; b < 12; ++b) {
        const Eigen::Index r = 3 * static_cast<Eigen::Index>(c[a / 3]) + a % 3, s = 3 * static_cast<Eigen::Index>(c[b / 3]) + b % 3;
        if (r >= s) entries.emplace_back(r, s, k[12 * a + b]);
      }
  }
  // A = M^-1/2 K M^-1/2: symmetric, with the eigenvalues omega^2 of M^-1 K. A vertex in no
  // tet has neither mass nor stiffness; its rows stay zero.
  std::vector<double> scale(static_cast<std::size_t>(n));
  for (std::size_t i = 0; i < static_cast<std::size_t>(n); ++i) scale[i] = mass[i / 3] > 0 ? 1 / std::sqrt(mass[i / 3]) : 0;
  for (auto& e : entries)
    e = {e.row(), e.col(), e.value() * scale[static_cast<std::size_t>(e.row())] * scale[static_cast<std::size_t>(e.col())]};
  Eigen::SparseMatrix<double> A(n, n);
  A.setFromTriplets(entries.begin(), entries.end());
  entries = {};

  MeshFrequency f;
  f.element = omega_element;
  f.omega = omega_element;
  if (n == 0) return f;

  // Lanczos without reorthogonalisation from a fixed pseudo-random start: the largest Ritz
  // value theta of the tridiagonal T_k is a lower bound on lambda_max (up to rounding) and
  // only proposes where to certify. Lost orthogonality makes copies of converged Ritz
  // values, never values above the spectrum, so no basis is stored.
  const int k = static_cast<int>(std::min<Eigen::Index>(std::max(lanczos_steps, 1), n));
  Eigen::VectorXd q(n), q_prev = Eigen::VectorXd::Zero(n), w(n);
  std::uint64_t state = 0x9e3779b97f4a7c15ULL;
  for (Eigen::Index i = 0; i < n; ++i) {
    state = state * 6364136223846793005ULL + 1442695040888963407ULL;  // Knuth's MMIX LCG
    q(i) = static_cast<double>(state >> 11) * 0x1.0p-53 - 0.5;
  }
  q /= q.norm();
  Eigen::VectorXd alpha(k), beta(k);
  int steps = 0;
  for (int j = 0; j < k; ++j) {
    w.noalias() = A.selfadjointView<Eigen::Lower>() * q;
    alpha(j) = q.dot(w);
    w -= alpha(j) * q + (j > 0 ? beta(j - 1) : 0.0) * q_prev;
    beta(j) = w.norm();
    ++steps;
    if (!(beta(j) > 1e-14 * std::abs(alpha(j)))) break;  // an invariant subspace: T_j is exact
    q_prev.swap(q);
    q = w / beta(j);
  }
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> tri;
  tri.computeFromTridiagonal(alpha.head(steps), beta.head(steps - 1), Eigen::ComputeEigenvectors);
  const Eigen::Index top = steps - 1;  // eigenvalues come in increasing order
  f.estimate = std::sqrt(std::max(0.0, tri.eigenvalues()(top)));
  f.residual = std::abs(beta(steps - 1) * tri.eigenvectors()(steps - 1, top));
  f.steps = steps;
  const double theta = tri.eigenvalues()(top);
  if (!(theta > 0) || !std::isfinite(theta)) return f;

  // The certificate: mu >= lambda_max(A) iff mu I - A is positive semi-definite, and
  // mu I - A = L D L^T with every pivot of D positive proves it positive definite
  // (Sylvester's law of inertia: D has as many negative entries as A has eigenvalues above
  // mu). The Ritz residual only says that SOME eigenvalue lies within it of theta, not the
  // largest: a start vector nearly orthogonal to the top modes would converge below them,
  // so theta + residual is a candidate, not a bound. Candidates theta (1 + d), d = 2^-10,
  // 2^-8, ..., until one is certified or the element bound is smaller. The computed
  // factor is exact for mu I - A + E with ||E|| <= (n + 1)^2 u mu (Cholesky's backward
  // error, Higham, "Accuracy and Stability of Numerical Algorithms", Thm. 10.3, with
  // ||mu I - A|| <= mu), so mu (1 + 2 (n + 1)^2 u) is what is reported.
  const double rounding = 2 * std::pow(static_cast<double>(n + 1), 2) * std::numeric_limits<double>::epsilon();
  Eigen::SparseMatrix<double> I(n, n);
  I.setIdentity();
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>, Eigen::Lower> ldlt;
  for (double d = 0x1.0p-10; d < 4; d *= 4) {
    const double mu = theta * (1 + d);
    const double bound = mu * (1 + rounding);
    if (!(bound < omega_element * omega_element)) break;
    const Eigen::SparseMatrix<double> B = mu * I - A;
    if (f.tries == 0) ldlt.analyzePattern(B);
    ++f.tries;
    ldlt.factorize(B);
    if (ldlt.info() == Eigen::Success && (ldlt.vectorD().array() > 0).all()) {
      f.omega = std::sqrt(bound);
      f.certified = true;
      break;
    }
  }
  return f;
}

double damped_stable_step(double omega, double alpha, double beta) {
  // 4 / (c + sqrt(c^2 + 4 omega^2)) rather than (2 / omega)(sqrt(1 + xi^2) - xi): no
  // cancellation for large xi, and 2 / alpha (not 0 / 0) for a rigid mode (omega = 0).
  const double c = alpha + beta * omega * omega;
  const double den = c + std::hypot(c, 2 * omega);
  return den > 0 ? 4 / den : std::numeric_limits<double>::infinity();
}

}  // namespace softcontact
