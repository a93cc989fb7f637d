// The material laws of src/model (material_law.hpp interface), tested on the
// deformation gradient alone: rest state, rigid motions, the stress as the gradient of
// the energy and the tangent as the derivative of the stress (central finite
// differences, on random, near-flat and inverted F), the linearisation at rest, the
// damping stresses, and the polar decomposition.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>
#include <string>

#include "model/corotational.hpp"
#include "model/linear.hpp"
#include "model/mass_spring.hpp"
#include "model/neohookean.hpp"
#include "model/polar_decomposition.hpp"
#include "model/stvk.hpp"

using namespace softcontact::model;

namespace {

/// Scientific notation for RecordProperty (std::to_string rounds small numbers to 0).
std::string sci(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.2e", v);
  return buf;
}

// E = 1e5 Pa, nu = 0.3
const Lame kLame{1e5 * 0.3 / (1.3 * 0.4), 1e5 / 2.6};
constexpr double kYoung = 1e5;

/// Rotation exp([a]x) by Rodrigues' formula.
Mat3 rotation(const double a[3]) {
  const double th = std::sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]);
  const double k[3] = {a[0] / th, a[1] / th, a[2] / th};
  const Mat3 K = {0, -k[2], k[1], k[2], 0, -k[0], -k[1], k[0], 0};
  Mat3 R = kIdentity3;
  const Mat3 K2 = mul(K, K);
  for (int i = 0; i < 9; ++i) R[i] += std::sin(th) * K[i] + (1 - std::cos(th)) * K2[i];
  return R;
}

struct Rng {
  std::mt19937_64 gen{12345};
  double uniform(double a, double b) { return std::uniform_real_distribution<double>(a, b)(gen); }
  Mat3 rotation() {
    const double a[3] = {uniform(-2, 2), uniform(-2, 2), uniform(-2, 2)};
    return ::rotation(a);
  }
  /// I + noise of size s.
  Mat3 near_identity(double s) {
    Mat3 F = kIdentity3;
    for (double& v : F) v += uniform(-s, s);
    return F;
  }
};

/// The configurations the derivative tests run on: moderate strains (rotated), a nearly
/// flat element (one singular value 1e-3) and an inverted one (det F < 0).
std::vector<std::pair<std::string, Mat3>> test_gradients() {
  Rng rng;
  std::vector<std::pair<std::string, Mat3>> out;
  for (int k = 0; k < 4; ++k) out.emplace_back("random" + std::to_string(k), mul(rng.rotation(), rng.near_identity(0.3)));
  const Mat3 flat = {1, 0.1, 0, 0.05, 1, 0.02, 0, 0, 1e-3};
  out.emplace_back("near-flat", mul(rng.rotation(), mul(flat, rng.rotation())));
  const Mat3 inv = {1.1, 0.1, 0, 0.05, 0.9, 0.02, 0, 0.03, -0.4};
  out.emplace_back("inverted", mul(rng.rotation(), mul(inv, rng.rotation())));
  return out;
}

double max_abs(const Mat3& a) {
  double m = 0;
  for (double v : a) m = std::max(m, std::abs(v));
  return m;
}

/// dPsi/dF by central differences (step h relative to F's smallest singular value).
template <class Law>
void expect_stress_is_energy_gradient(const Law& law, const std::string& name) {
  double worst = 0;  // largest |P - FD| / (max |P| + mu)
  for (const auto& [what, F] : test_gradients()) {
    if (name == "linear" && what == "inverted") continue;  // linear: any F, nothing special
    const double h = what == "near-flat" ? 1e-8 : 1e-6;
    const Mat3 P = law.stress(F);
    Mat3 fd;
    for (int k = 0; k < 9; ++k) {
      Mat3 a = F, b = F;
      a[k] += h;
      b[k] -= h;
      fd[k] = (law.energy(a) - law.energy(b)) / (2 * h);
    }
    const double scale = max_abs(P) + kLame.mu;
    for (int k = 0; k < 9; ++k) {
      EXPECT_NEAR(P[k], fd[k], 1e-6 * scale) << name << ", " << what << ", entry " << k;
      worst = std::max(worst, std::abs(P[k] - fd[k]) / scale);
    }
  }
  ::testing::Test::RecordProperty("worst_" + name, sci(worst));
}

/// dP/dF against central differences of the stress.
template <class Law>
void expect_tangent_is_stress_derivative(const Law& law, const std::string& name) {
  double worst = 0;  // largest |dP/dF - FD| / max(|dP/dF|, mu)
  for (const auto& [what, F] : test_gradients()) {
    const double h = what == "near-flat" ? 1e-8 : 1e-6;
    const Mat9 D = law.stress_derivative(F);
    double scale = kLame.mu;
    for (double v : D) scale = std::max(scale, std::abs(v));
    for (int kl = 0; kl < 9; ++kl) {
      Mat3 a = F, b = F;
      a[kl] += h;
      b[kl] -= h;
      const Mat3 pa = law.stress(a), pb = law.stress(b);
      for (int ij = 0; ij < 9; ++ij) {
        const double fd = (pa[ij] - pb[ij]) / (2 * h);
        EXPECT_NEAR(D[9 * ij + kl], fd, 1e-6 * scale) << name << ", " << what << ", dP" << ij << "/dF" << kl;
        worst = std::max(worst, std::abs(D[9 * ij + kl] - fd) / scale);
      }
    }
  }
  ::testing::Test::RecordProperty("worst_" + name, sci(worst));
}

MassSpringLaw spring_law(double beta = 0) {
  // An irregular tet; its unit edge directions are the law's parameters.
  const double X[12] = {0, 0, 0, 1, 0.1, 0, 0.2, 0.9, 0.1, 0.3, 0.2, 1.1};
  return MassSpringLaw::from_rest(kYoung, beta, X);
}

}  // namespace

TEST(MaterialLaws, RestStateHasNoEnergyAndNoStress) {
  auto check = [](const auto& law, const char* name) {
    EXPECT_NEAR(law.energy(kIdentity3), 0.0, 1e-10 * kLame.mu) << name;
    EXPECT_LE(max_abs(law.stress(kIdentity3)), 1e-10 * kLame.mu) << name;
  };
  check(LinearLaw{kLame, 0}, "linear");
  check(CorotationalLaw{kLame, 0}, "corotational");
  check(StvkLaw{kLame, 0}, "stvk");
  check(NeoHookeanLaw(kLame, 0), "neohookean");
  check(spring_law(), "mass_spring");
}

// Rotation invariance: every model but the linear one feels no stress under any rotation,
// however large; the linear one only under infinitesimal rotations F = I + W, W skew.
TEST(MaterialLaws, RigidRotationsGiveZeroStress) {
  Rng rng;
  for (int k = 0; k < 20; ++k) {
    const Mat3 R = rng.rotation();
    auto check = [&](const auto& law, const char* name) {
      EXPECT_LE(max_abs(law.stress(R)), 1e-9 * kLame.mu) << name << ", rotation " << k;
      EXPECT_NEAR(law.energy(R), 0.0, 1e-9 * kLame.mu) << name;
    };
    check(CorotationalLaw{kLame, 0}, "corotational");
    check(StvkLaw{kLame, 0}, "stvk");
    check(NeoHookeanLaw(kLame, 0), "neohookean");
    check(spring_law(), "mass_spring");
    const double w[3] = {rng.uniform(-1e-3, 1e-3), rng.uniform(-1e-3, 1e-3), rng.uniform(-1e-3, 1e-3)};
    const Mat3 F = {1, -w[2], w[1], w[2], 1, -w[0], -w[1], w[0], 1};
    EXPECT_EQ(max_abs(LinearLaw{kLame, 0}.stress(F)), 0.0);
  }
  // ... and the linear model's known artefact: a finite rotation strains it.
  const double a[3] = {0, 0, M_PI / 2};
  EXPECT_GT(max_abs(LinearLaw{kLame, 0}.stress(rotation(a))), kLame.mu);
}

TEST(MaterialLaws, StressIsTheGradientOfTheEnergy) {
  expect_stress_is_energy_gradient(LinearLaw{kLame, 0}, "linear");
  expect_stress_is_energy_gradient(CorotationalLaw{kLame, 0}, "corotational");
  expect_stress_is_energy_gradient(StvkLaw{kLame, 0}, "stvk");
  expect_stress_is_energy_gradient(NeoHookeanLaw(kLame, 0), "neohookean");
  expect_stress_is_energy_gradient(spring_law(), "mass_spring");
}

TEST(MaterialLaws, TangentIsTheDerivativeOfTheStress) {
  expect_tangent_is_stress_derivative(LinearLaw{kLame, 0}, "linear");
  expect_tangent_is_stress_derivative(CorotationalLaw{kLame, 0}, "corotational");
  expect_tangent_is_stress_derivative(StvkLaw{kLame, 0}, "stvk");
  expect_tangent_is_stress_derivative(NeoHookeanLaw(kLame, 0), "neohookean");
  expect_tangent_is_stress_derivative(spring_law(), "mass_spring");
}

// Every FEM model is Hooke's law with the material's Lame parameters for small strains.
TEST(MaterialLaws, FemModelsLineariseToHookesLaw) {
  const Mat9 ref = LinearLaw{kLame, 0}.stress_derivative(kIdentity3);
  auto check = [&](const Mat9& D, const char* name) {
    for (int k = 0; k < 81; ++k) EXPECT_NEAR(D[k], ref[k], 1e-9 * kLame.mu) << name << " entry " << k;
  };
  check(CorotationalLaw{kLame, 0}.stress_derivative(kIdentity3), "corotational");
  check(StvkLaw{kLame, 0}.stress_derivative(kIdentity3), "stvk");
  check(NeoHookeanLaw(kLame, 0).stress_derivative(kIdentity3), "neohookean");
  // The stiffness warping of the corotational model equals its exact tangent at any
  // rotated rest state.
  Rng rng;
  const Mat3 R = rng.rotation();
  const CorotationalLaw co{kLame, 0};
  const Mat9 exact = co.stress_derivative(R), warped = co.warped_stress_derivative(R);
  for (int k = 0; k < 81; ++k) EXPECT_NEAR(warped[k], exact[k], 1e-9 * kLame.mu) << "entry " << k;
}

// The derivation of k_e = E V / L_e^2 (mass_spring.hpp, docs/models.md): the springs of
// any tet give an elasticity tensor whose isotropic part (its average over orientations)
// is Hooke's law with lambda = mu = 2E/5, i.e. Young's modulus E and Poisson ratio 1/4.
// The isotropic part of a tensor with the symmetries of C is fixed by the two
// contractions C_iijj = 9 lambda + 6 mu and C_ijij = 3 lambda + 12 mu. The six Kuhn tets
// of a cube (the box primitive) give cubic symmetry with C11 = 13/9 E, C12 = C44 = 5/18 E,
// i.e. a modulus of 756/558 E = 1.355 E along a cell axis.
TEST(MaterialLaws, MassSpringStiffnessReproducesYoungsModulus) {
  Rng rng;
  for (int k = 0; k < 10; ++k) {
    double X[12];
    for (double& v : X) v = rng.uniform(-1, 1);
    const double* p = X;
    const Mat3 dm = {p[3] - p[0], p[6] - p[0], p[9] - p[0], p[4] - p[1], p[7] - p[1],
                     p[10] - p[1], p[5] - p[2], p[8] - p[2], p[11] - p[2]};
    if (std::abs(det(dm)) < 0.05) continue;  // keep away from flat tets
    const Mat9 D = MassSpringLaw::from_rest(kYoung, 0, X).stress_derivative(kIdentity3);
    double iijj = 0, ijij = 0;
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) {
        iijj += D[9 * (4 * i) + 4 * j];
        ijij += D[9 * (3 * i + j) + 3 * i + j];
      }
    const double lambda = 0.4 * kYoung, mu = 0.4 * kYoung;
    EXPECT_NEAR(iijj, 9 * lambda + 6 * mu, 1e-9 * kYoung) << "tet " << k;
    EXPECT_NEAR(ijij, 3 * lambda + 12 * mu, 1e-9 * kYoung) << "tet " << k;
  }
  // Kuhn split of the unit cube: the path 0 -> e_a -> e_a + e_b -> (1,1,1) for each
  // permutation (a, b, c).
  const int perms[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};
  Mat9 avg{};
  for (const auto& p : perms) {
    double X[12] = {0};
    for (int d = 0; d < 3; ++d) {
      X[3 + d] = d == p[0];
      X[6 + d] = d == p[0] || d == p[1];
      X[9 + d] = 1;
    }
    const Mat9 Dk = MassSpringLaw::from_rest(kYoung, 0, X).stress_derivative(kIdentity3);
    for (int k = 0; k < 81; ++k) avg[k] += Dk[k] / 6;
  }
  EXPECT_NEAR(avg[9 * 0 + 0], 13.0 / 9 * kYoung, 1e-9 * kYoung);  // C11 = dP_xx/dF_xx
  EXPECT_NEAR(avg[9 * 0 + 4], 5.0 / 18 * kYoung, 1e-9 * kYoung);  // C12 = dP_xx/dF_yy
  EXPECT_NEAR(avg[9 * 1 + 1], 5.0 / 18 * kYoung, 1e-9 * kYoung);  // C44 = dP_xy/dF_xy
}

TEST(MaterialLaws, DampingVanishesForRigidMotionAndDissipates) {
  constexpr double beta = 0.01;
  Rng rng;
  const LinearLaw lin{kLame, beta};
  const CorotationalLaw co{kLame, beta};
  const StvkLaw sv{kLame, beta};
  const NeoHookeanLaw nh(kLame, beta);
  const MassSpringLaw ms = spring_law(beta);
  for (int k = 0; k < 10; ++k) {
    const double w[3] = {rng.uniform(-3, 3), rng.uniform(-3, 3), rng.uniform(-3, 3)};
    const Mat3 W = {0, -w[2], w[1], w[2], 0, -w[0], -w[1], w[0], 0};
    const Mat3 F = mul(rng.rotation(), rng.near_identity(0.2));
    const Mat3 R = rng.rotation();
    // A spin dF/dt = W F of any deformed state: the Green strain rate and the springs'
    // stretch rates are zero; the corotational damping only for a rotated rest state.
    EXPECT_LE(max_abs(sv.damping_stress(F, mul(W, F))), 1e-9 * beta * kLame.mu) << "stvk";
    EXPECT_LE(max_abs(nh.damping_stress(F, mul(W, F))), 1e-9 * beta * kLame.mu) << "neohookean";
    EXPECT_LE(max_abs(ms.damping_stress(F, mul(W, F))), 1e-9 * beta * kYoung) << "mass_spring";
    EXPECT_LE(max_abs(co.damping_stress(R, mul(W, R))), 1e-9 * beta * kLame.mu) << "corotational";
    EXPECT_LE(max_abs(lin.damping_stress(kIdentity3, W)), 1e-12 * beta * kLame.mu) << "linear";
    // Power P_d : dF/dt >= 0 for any rate.
    const Mat3 Fd = rng.near_identity(1.0);
    EXPECT_GE(ddot(lin.damping_stress(F, Fd), Fd), 0.0);
    EXPECT_GE(ddot(co.damping_stress(F, Fd), Fd), 0.0);
    EXPECT_GE(ddot(sv.damping_stress(F, Fd), Fd), 0.0);
    EXPECT_GE(ddot(nh.damping_stress(F, Fd), Fd), 0.0);
    EXPECT_GE(ddot(ms.damping_stress(F, Fd), Fd), 0.0);
  }
  // At rest, every FEM damping stress is beta times Hooke's law of the rate (-beta K v).
  const Mat3 Fd = rng.near_identity(1.0);
  const Mat3 ref = scaled(LinearLaw::hooke(kLame, Fd), beta);
  for (const Mat3& p : {co.damping_stress(kIdentity3, Fd), sv.damping_stress(kIdentity3, Fd),
                        nh.damping_stress(kIdentity3, Fd)})
    for (int k = 0; k < 9; ++k) EXPECT_NEAR(p[k], ref[k], 1e-12 * max_abs(ref));
}

TEST(PolarDecomposition, NewtonAgreesWithSvdAndInvertedElementsGetARotation) {
  Rng rng;
  for (int k = 0; k < 50; ++k) {
    const Mat3 F = mul(rng.rotation(), rng.near_identity(k < 25 ? 0.05 : 0.4));
    Mat3 Rn;
    ASSERT_GT(det(F), 0);
    ASSERT_TRUE(polar_newton(F, Rn)) << k;
    const Mat3 Rs = rotation_from_svd(F);
    for (int i = 0; i < 9; ++i) EXPECT_NEAR(Rn[i], Rs[i], 1e-13) << k;
  }
  // Inverted: R is a proper rotation and S = R^T F symmetric with one negative eigenvalue
  // (det S = det F < 0).
  for (const auto& [what, F] : test_gradients()) {
    const Mat3 R = rotation_part(F);
    EXPECT_NEAR(det(R), 1.0, 1e-12) << what;
    const Mat3 RtR = mul_tn(R, R);
    for (int i = 0; i < 9; ++i) EXPECT_NEAR(RtR[i], kIdentity3[i], 1e-12) << what;
    const Mat3 S = mul_tn(R, F);
    EXPECT_NEAR(S[1], S[3], 1e-12) << what;
    EXPECT_NEAR(S[2], S[6], 1e-12) << what;
    EXPECT_NEAR(S[5], S[7], 1e-12) << what;
  }
  // The corotational force pushes an inverted element back: the energy decreases along
  // -P (towards un-inversion), and P is finite.
  const Mat3 F = {1, 0, 0, 0, 1, 0, 0, 0, -0.2};
  const CorotationalLaw co{kLame, 0};
  const Mat3 P = co.stress(F);
  EXPECT_LT(P[8], 0.0);  // dPsi/dF_zz < 0: growing F_zz (towards +1) lowers the energy
}
