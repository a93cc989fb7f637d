#pragma once
// Test support for the stability limit: the dense eigenvalues of an object's assembled
// mesh and the one-step matrix of the code's own explicit step (docs/models.md,
// "Stability limit and `dt: auto`").
#include <Eigen/Eigenvalues>
#include <cmath>
#include <vector>

#include "softcontact/forces.hpp"
#include "softcontact/scene.hpp"
#include "stepper.hpp"

namespace softcontact::test_support {

/// Highest frequency [rad/s] of object `obj` assembled (lumped M, rest K), from the dense
/// symmetric eigenproblem M^-1/2 K M^-1/2.
inline double assembled_max_frequency(const Stepper& st, int obj) {
  const World& w = st.w;
  std::vector<Eigen::Index> dof(w.n_owned, -1);
  Eigen::Index n = 0;
  for (std::size_t i = 0; i < w.n_owned; ++i)
    if (w.vertex_object[i] == obj) dof[i] = 3 * n++;
  Eigen::MatrixXd A = Eigen::MatrixXd::Zero(3 * n, 3 * n);
  double K[144];
  for (std::size_t t = 0; t < w.tet_gid.size(); ++t) {
    const index_t* c = &w.tets[4 * t];
    if (w.vertex_object[c[0]] != obj) continue;
    st.forces.tet_stiffness(t, w.x.data(), StiffnessKind::exact, K);
    for (int a = 0; a < 12; ++a)
      for (int b = 0; b < 12; ++b)
        A(dof[c[a / 3]] + a % 3, dof[c[b / 3]] + b % 3) += K[12 * a + b] / std::sqrt(w.mass[c[a / 3]] * w.mass[c[b / 3]]);
  }
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(A, Eigen::EigenvaluesOnly);
  return std::sqrt(es.eigenvalues().maxCoeff());
}

/// Spectral radius of one step of the scene's integrator at `dt`, linearised about the
/// rest state: the matrix is built column by column by stepping the code itself
/// (Stepper: gravity + internal forces + Rayleigh damping, then unconstrained_step) from
/// unit perturbations of the state. Verlet's state is (x^t, x^(t-dt)), with World::v =
/// (x^t - x^(t-dt)) / dt as the step before leaves it; symplectic Euler's is (x^t, v^t).
/// Meant for linear-model scenes without gravity (the step is then exactly a matrix).
inline double step_spectral_radius(Scene s, double dt) {
  s.sim.dt = dt;
  const bool verlet = s.sim.integrator == IntegratorKind::verlet;
  Stepper st(std::move(s));
  const std::vector<double> rest = st.w.x;
  const auto n = static_cast<Eigen::Index>(3 * st.w.n_owned);
  const double eps = 1e-3;  // [m]; the forces are linear, so any size gives the same matrix
  Eigen::MatrixXd G(2 * n, 2 * n);
  for (Eigen::Index j = 0; j < 2 * n; ++j) {
    Eigen::VectorXd z = Eigen::VectorXd::Zero(2 * n);
    z(j) = eps;
    for (Eigen::Index k = 0; k < n; ++k) {
      const auto u = static_cast<std::size_t>(k);
      st.w.x[u] = rest[u] + z(k);
      if (verlet) {
        st.w.x_prev[u] = rest[u] + z(n + k);
        st.w.v[u] = (st.w.x[u] - st.w.x_prev[u]) / dt;
      } else {
        st.w.x_prev[u] = st.w.x[u];
        st.w.v[u] = z(n + k);
      }
    }
    st.step();
    for (Eigen::Index k = 0; k < n; ++k) {
      const auto u = static_cast<std::size_t>(k);
      G(k, j) = (st.w.x[u] - rest[u]) / eps;
      G(n + k, j) = (verlet ? st.w.x_prev[u] - rest[u] : st.w.v[u]) / eps;
    }
  }
  const Eigen::EigenSolver<Eigen::MatrixXd> es(G, false);
  return es.eigenvalues().cwiseAbs().maxCoeff();
}

}  // namespace softcontact::test_support
