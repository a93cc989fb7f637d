// Static validation against beam theory (docs/validation.md, "Deformation models"):
// equilibrium by Newton's method with the exact tangent (static_solver.hpp).
//
// Poisson ratio 0 throughout: the uniaxial stress state of a bar and the beam theories
// are then exact 3D solutions, with no lateral contraction against the clamped end.
#include <gtest/gtest.h>

#include <cmath>
#include <sstream>
#include <string>

#include "softcontact/scene.hpp"
#include "static_solver.hpp"

using namespace softcontact;

namespace {

constexpr double kE = 1e8, kRho = 1000, kG = 9.81;

Scene bar_scene(const std::string& model, const std::string& size, const std::string& cells, const std::string& fixed,
                const std::string& gravity) {
  return load_scene_from_string("simulation: {dt: 1, steps: 1, gravity: " + gravity +
                                    "}\nmaterials:\n  - {name: m, model: " + model +
                                    ", young: 1e8, poisson: 0, density: 1000}\nobjects:\n  - material: m\n"
                                    "    primitive: {type: box, size: " + size + ", cells: " + cells +
                                    "}\n    fixed: " + fixed + "\n",
                                "test.yaml");
}

/// Mean displacement along axis `d` of the vertices with coordinate `axis` beyond `beyond`.
double mean_displacement(const World& w, const std::vector<double>& x0, int axis, double beyond, int d) {
  double s = 0;
  int n = 0;
  for (std::size_t i = 0; i < w.n_owned; ++i)
    if (beyond > 0 ? x0[3 * i + axis] > beyond : x0[3 * i + axis] < beyond) {
      s += w.x[3 * i + d] - x0[3 * i + d];
      ++n;
    }
  return s / n;
}

/// Tip deflection of the cantilever: box [1, 0.1, 0.1] along x, clamped at x = -0.5,
/// a load P = 1 N in -z spread over the end face x = +0.5 as a uniform traction (each
/// surface triangle there gives a third of its share to each corner).
double cantilever_tip(const std::string& model, int n, std::size_t* tets = nullptr) {
  std::ostringstream cells;
  cells << "[" << 10 * n << ", " << n << ", " << n << "]";
  const Scene s = bar_scene(model, "[1, 0.1, 0.1]", cells.str(), "{min: [-1, -1, -1], max: [-0.499, 1, 1]}", "[0, 0, 0]");
  World w = build_world(s, block_partition(s, 1), 0);
  ElasticForces ef(s, w);
  const double P = 1.0, area = 0.01;
  std::vector<double> fe(w.x.size(), 0.0);
  for (std::size_t t = 0; t < w.triangles.size() / 3; ++t) {
    const index_t* c = &w.triangles[3 * t];
    if (!(w.x[3 * c[0]] > 0.4999 && w.x[3 * c[1]] > 0.4999 && w.x[3 * c[2]] > 0.4999)) continue;
    const double* a = &w.x[3 * c[0]];
    const double* b = &w.x[3 * c[1]];
    const double* cc = &w.x[3 * c[2]];
    const double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, v[3] = {cc[0] - a[0], cc[1] - a[1], cc[2] - a[2]};
    const double tri = 0.5 * std::hypot(u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]);
    for (int k = 0; k < 3; ++k) fe[3 * c[k] + 2] -= P * tri / area / 3;
  }
  const std::vector<double> x0 = w.x;
  EXPECT_GT(test_support::solve_static(ef, w, fe, 1e-15), 0) << model << " n = " << n;
  if (tets) *tets = w.tet_gid.size();
  return -mean_displacement(w, x0, 0, 0.4999, 2);
}

}  // namespace

// A bar of length L = 1 m hanging from its clamped top under its own weight: u(z) solves
// E u'' = -rho g, so the free end moves by delta = rho g L^2 / (2E) = 4.905e-5 m
// (strain 1e-4: small deformation, where all FEM models must agree). Mesh: a 1x1 cell
// cross-section (nu = 0 makes the problem one-dimensional) and n = 2, 4, 8, 16 cells
// along. Measured tip error (linear): 3.8e-4, 2.9e-4, 1.5e-4, 4.5e-5 of delta.
TEST(Statics, BarUnderSelfWeightApproachesTheAnalyticElongation) {
  const double delta = kRho * kG * 1.0 / (2 * kE);
  for (const char* model : {"linear", "corotational", "stvk"}) {
    double prev = HUGE_VAL;
    for (int n : {2, 4, 8, 16}) {
      const Scene s = bar_scene(model, "[0.1, 0.1, 1]", "[1, 1, " + std::to_string(n) + "]",
                                "{min: [-1, -1, 0.49], max: [1, 1, 1]}", "[0, 0, -9.81]");
      World w = build_world(s, block_partition(s, 1), 0);
      ElasticForces ef(s, w);
      std::vector<double> fe(w.x.size(), 0.0);
      for (std::size_t i = 0; i < w.n_owned; ++i) fe[3 * i + 2] = -w.mass[i] * kG;
      const std::vector<double> x0 = w.x;
      ASSERT_GT(test_support::solve_static(ef, w, fe, 1e-16), 0) << model << " n = " << n;
      const double tip = -mean_displacement(w, x0, 2, -0.49, 2);
      const double err = std::abs(tip / delta - 1);
      EXPECT_LT(err, 1e-3) << model << " n = " << n;
      // Linear: refinement reduces the error. StVK adds its geometric non-linearity of
      // relative size ~ strain (1e-4), which limits how close it gets.
      if (std::string(model) == "linear") {
        EXPECT_LT(err, prev) << "n = " << n;
      }
      prev = err;
    }
  }
}

// Cantilever, L = 1 m, square section b = 0.1 m, tip load P = 1 N, E = 1e8 Pa, nu = 0.
// Reference: Timoshenko beam, delta = P L^3 / (3 E I) + P L / (k G A), I = b^4/12,
// G = E/2, A = b^2, k = 5/6: 4.0240e-4 m (Euler-Bernoulli alone 4.0000e-4). delta/L =
// 4e-4: small deflection. Linear tetrahedra are notoriously stiff in bending (shear
// locking), so the error falls slowly: n cells across the section (10 n along) give
// -75.6 %, -45.0 %, -27.2 %, -17.6 % for n = 1..4 (-8.8 % at n = 6, long test). Checked
// here: the error falls at each refinement, from n = 2 on faster than O(h) (approaching
// the asymptotic O(h^2)), the extrapolation of n = 3, 4 to h -> 0 assuming O(h^2) lands
// within 6 %, and the three FEM models agree within 1 % (measured: 2e-6).
TEST(Statics, CantileverTipDeflectionConvergesAndModelsAgree) {
  const double b = 0.1, L = 1, P = 1, I = b * b * b * b / 12;
  const double ref = P * L * L * L / (3 * kE * I) + P * L / (5.0 / 6 * kE / 2 * b * b);
  std::vector<double> tips;
  for (int n : {1, 2, 3, 4}) {
    const double lin = cantilever_tip("linear", n);
    tips.push_back(lin);
    for (const char* model : {"corotational", "stvk"})
      EXPECT_NEAR(cantilever_tip(model, n) / lin, 1.0, 0.01) << model << " n = " << n;
  }
  for (std::size_t k = 1; k < tips.size(); ++k) {
    const double e0 = std::abs(tips[k - 1] / ref - 1), e1 = std::abs(tips[k] / ref - 1);
    EXPECT_LT(e1, e0);
    // h went from 1/k to 1/(k+1): O(h) would give e1/e0 = k/(k+1); from n = 2 to 3 and
    // 3 to 4 the ratios are 0.60 and 0.65 (O(h^2): 0.44, 0.56; n = 1 is not yet in the
    // asymptotic range).
    if (k >= 2) {
      EXPECT_LT(e1 / e0, static_cast<double>(k) / (k + 1)) << "n = " << k + 1;
    }
  }
  EXPECT_LT(std::abs(tips[3] / ref - 1), 0.2);
  const double extrapolated = (16 * tips[3] - 9 * tips[2]) / 7;
  EXPECT_NEAR(extrapolated / ref, 1.0, 0.06);
}
