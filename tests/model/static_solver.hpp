#pragma once
// Test support: static equilibrium f_int(x) + f_ext = 0 on the movable vertices by
// Newton's method with the models' exact tangent stiffness (ElasticForces::tet_stiffness)
// and a sparse LDL^T factorisation (Eigen). For the linear model one step is exact.
#include <Eigen/SparseCholesky>
#include <Eigen/SparseCore>
#include <cmath>
#include <vector>

#include "softcontact/forces.hpp"
#include "softcontact/world.hpp"

namespace softcontact::test_support {

/// Moves World::x to equilibrium under f_ext (n,3) [N]; returns the Newton iterations,
/// or -1 if the update did not fall below tol [m] within max_iter.
inline int solve_static(ElasticForces& ef, World& w, const std::vector<double>& f_ext, double tol, int max_iter = 30) {
  const std::size_t n = w.n_owned;
  std::vector<int> dof(n, -1);
  int nd = 0;
  for (std::size_t i = 0; i < n; ++i)
    if (w.inv_mass[i] != 0) dof[i] = nd++;
  for (int it = 1; it <= max_iter; ++it) {
    std::vector<double> f = f_ext;
    ef.add_forces(w, f, false);
    Eigen::VectorXd r(3 * nd);
    for (std::size_t i = 0; i < n; ++i)
      if (dof[i] >= 0)
        for (int d = 0; d < 3; ++d) r[3 * dof[i] + d] = f[3 * i + d];
    std::vector<Eigen::Triplet<double>> trip;
    double K[144];
    for (std::size_t t = 0; t < w.tet_gid.size(); ++t) {
      ef.tet_stiffness(t, w.x.data(), StiffnessKind::exact, K);
      const index_t* c = &w.tets[4 * t];
      for (int a = 0; a < 4; ++a)
        for (int b = 0; b < 4; ++b) {
          if (dof[c[a]] < 0 || dof[c[b]] < 0) continue;
          for (int i = 0; i < 3; ++i)
            for (int k = 0; k < 3; ++k)
              trip.emplace_back(3 * dof[c[a]] + i, 3 * dof[c[b]] + k, K[12 * (3 * a + i) + 3 * b + k]);
        }
    }
    Eigen::SparseMatrix<double> A(3 * nd, 3 * nd);
    A.setFromTriplets(trip.begin(), trip.end());
    Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> ldlt(A);
    if (ldlt.info() != Eigen::Success) return -1;
    const Eigen::VectorXd dx = ldlt.solve(r);  // K dx = f  (K = -df/dx)
    for (std::size_t i = 0; i < n; ++i)
      if (dof[i] >= 0)
        for (int d = 0; d < 3; ++d) w.x[3 * i + d] += dx[3 * dof[i] + d];
    if (dx.lpNorm<Eigen::Infinity>() < tol) return it;
  }
  return -1;
}

}  // namespace softcontact::test_support
