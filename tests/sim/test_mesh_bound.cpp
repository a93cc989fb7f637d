// The mesh bound of the stable step, `dt_bound: mesh` (docs/models.md, "Stability limit
// and `dt: auto`"; mesh_max_frequency in src/model/stability.cpp): per object, a certified
// upper bound on the highest frequency of its assembled mesh (lumped masses, rest
// stiffness), at most the element bound, computed once per scene entry.
#include <gtest/gtest.h>
#include <omp.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>

#include "softcontact/forces.hpp"
#include "softcontact/scene.hpp"
#include "assembled_modes.hpp"
#include "stepper.hpp"

using namespace softcontact;
using softcontact::test_support::assembled_max_frequency;
using softcontact::test_support::Stepper;
using softcontact::test_support::step_spectral_radius;

namespace {

const std::string kInputs = SOFTCONTACT_INPUTS_DIR;

/// Highest tet frequency of an object (the element bound).
double element_frequency(const SceneObject& o, const Material& m) {
  double w = 0;
  for (std::size_t t = 0; t < o.mesh.num_tets(); ++t) {
    double X[12];
    for (int k = 0; k < 4; ++k)
      for (int d = 0; d < 3; ++d) X[3 * k + d] = o.mesh.points[3 * static_cast<std::size_t>(o.mesh.tets[4 * t + k]) + d];
    w = std::max(w, tet_max_frequency(X, m));
  }
  return w;
}

}  // namespace

// Against the dense eigenvalues of the assembled M^-1/2 K M^-1/2, built from the code's
// own World masses and element stiffnesses (test_support::assembled_max_frequency), on
// five meshes far apart: the Gmsh torus of torus_drop (neo-Hookean), the chess knight of
// chess500 (corotational, the piece that sets its limit), a box and a thin plate of Kuhn
// tets (linear, nu = 0.45 and 0.3) and a mass-spring torus primitive. The bound must be
// >= the exact omega_max (it is guaranteed), within (1 + 2^-10)^(1/2) ~ 1 + 4.9e-4 of it
// (the first candidate, theta (1 + 2^-10), is certified on all five: 60 Lanczos steps
// bring theta that close) and <= the element bound; the Lanczos estimate is <= omega_max.
TEST(MeshBound, CertifiedUpperBoundAgreesWithTheDenseEigenvalue) {
  const std::string yaml = R"(simulation: {dt: auto, dt_bound: mesh, steps: 1, gravity: [0, 0, 0]}
materials:
  - {name: soft, model: neohookean, young: 5.0e4, poisson: 0.35, density: 1000}
  - {name: piece, model: corotational, young: 1.0e4, poisson: 0.3, density: 500}
  - {name: stiff, model: linear, young: 1.0e6, poisson: 0.45, density: 1200}
  - {name: sheet, model: linear, young: 1.0e6, poisson: 0.3, density: 1000}
  - {name: springs, model: mass_spring, young: 3.0e4, poisson: 0.35, density: 1000}
objects:
  - {name: torus, material: soft, mesh: )" + kInputs + R"(/meshes/torus/torus.msh}
  - {name: knight, material: piece, mesh: )" + kInputs + R"(/meshes/chess/knight.msh, transform: {translate: [1, 0, 0]}}
  - name: box
    material: stiff
    primitive: {type: box, size: [0.3, 0.2, 0.1], cells: [3, 2, 2]}
    transform: {translate: [2, 0, 0]}
  - name: plate
    material: sheet
    primitive: {type: plate, size: [0.4, 0.4], thickness: 0.02, cells: [6, 6]}
    transform: {translate: [3, 0, 0]}
  - name: links
    material: springs
    primitive: {type: torus, major_radius: 0.06, minor_radius: 0.015, resolution: 2, around: 12}
    transform: {translate: [4, 0, 0]}
)";
  const Scene s = load_scene_from_string(yaml, "mesh_bound.yaml");
  const Stepper st(load_scene_from_string(yaml, "mesh_bound.yaml"));
  for (std::size_t i = 0; i < s.objects.size(); ++i) {
    const SceneObject& o = s.objects[i];
    const Material& m = s.materials[static_cast<std::size_t>(o.material)];
    const double exact = assembled_max_frequency(st, static_cast<int>(i));
    const double element = element_frequency(o, m);
    const MeshFrequency f = mesh_max_frequency(o.mesh, m, element);
    std::printf("[measured] %s: omega_max %.9g rad/s; mesh bound %.9g (estimate %.9g, residual %.3g 1/s^2, %d "
                "Lanczos steps, %d factorisations), bound / exact - 1 = %.3g; element bound %.6g = %.4f x exact\n",
                o.name.c_str(), exact, f.omega, f.estimate, f.residual, f.steps, f.tries, f.omega / exact - 1, element,
                element / exact);
    EXPECT_TRUE(f.certified) << o.name;
    EXPECT_GE(f.omega, exact) << o.name;
    EXPECT_LE(f.omega, exact * std::sqrt(1 + 0x1.0p-10) * (1 + 1e-9)) << o.name;
    EXPECT_LE(f.estimate, exact * (1 + 1e-12)) << o.name;
    EXPECT_LE(f.omega, element) << o.name;
    EXPECT_EQ(f.element, element) << o.name;
    // From a poor estimate (3 Lanczos steps) the certificate must refuse the candidates
    // below omega_max and still return a bound above it: accepting a candidate unchecked
    // would give theta (1 + 2^-10) < omega_max here.
    const MeshFrequency poor = mesh_max_frequency(o.mesh, m, element, 3);
    std::printf("[measured] %s, 3 Lanczos steps: estimate %.6g = %.4f x omega_max, bound %.6g = %.4f x (%d "
                "factorisations%s)\n", o.name.c_str(), poor.estimate, poor.estimate / exact, poor.omega,
                poor.omega / exact, poor.tries, poor.certified ? "" : ", none certified: the element bound");
    EXPECT_LT(poor.estimate * std::sqrt(1 + 0x1.0p-10), exact) << o.name;
    EXPECT_GT(poor.tries, 1) << o.name;
    EXPECT_GE(poor.omega, exact) << o.name;
    EXPECT_LE(poor.omega, element) << o.name;
  }
  // The scene's step: the mesh bound of the object that sets it, within the element one.
  const StableStep mesh = stable_step(s), element = stable_step(s, DtBound::element);
  EXPECT_EQ(mesh.bound, DtBound::mesh);
  EXPECT_EQ(element.bound, DtBound::element);
  EXPECT_DOUBLE_EQ(s.sim.dt, 0.5 * mesh.dt);
  EXPECT_GE(mesh.dt, element.dt);
  EXPECT_DOUBLE_EQ(mesh.dt, 2 / mesh.omega);
  EXPECT_NE(mesh.explain(s).find("mesh bound, certified"), std::string::npos) << mesh.explain(s);
}

// With damping, on the code's own one-step matrix (as DampedStability.*): a damped linear
// box whose limit stiffness damping sets (damping ratio 0.9 at omega_max). 'dt: auto' with
// the mesh bound and dt_safety 1 is stable for both explicit integrators, within 0.1 % of
// the exact limit h* of the assembled mesh, and 1.05 h* is not stable, so the bound is
// tight. The element bound's step is further below h* (measured in the output).
TEST(MeshBound, DampedAutoStepIsStableAndTight) {
  for (const std::string integrator : {"verlet", "symplectic_euler"}) {
    const std::string yaml = "simulation: {dt: auto, dt_safety: 1, dt_bound: mesh, steps: 1, gravity: [0, 0, 0], "
                             "integrator: " + integrator + R"(}
materials:
  - {name: soft, model: linear, young: 2.5e4, poisson: 0.3, density: 1000, damping: {mass: 1, stiffness: 0.01}}
objects:
  - name: box
    material: soft
    primitive: {type: box, size: [0.3, 0.2, 0.1], cells: [3, 2, 1]}
)";
    const Scene s = load_scene_from_string(yaml, "damped_box.yaml");
    const Material& m = s.materials[0];
    const double w = assembled_max_frequency(Stepper(load_scene_from_string(yaml, "damped_box.yaml")), 0);
    const double exact = damped_stable_step(w, m.damping_mass, m.damping_stiffness);
    const StableStep element = stable_step(s, DtBound::element);
    const double at_auto = step_spectral_radius(s, s.sim.dt);
    const double above = step_spectral_radius(s, 1.05 * exact);
    std::printf("[measured] %s: omega_max %.6g rad/s, xi %.3g; exact limit %.6g s, mesh bound %.6g s (%.6f of it), "
                "element bound %.6g s (%.4f); spectral radius %.12f at dt: auto, %.6f at 1.05 h*\n",
                integrator.c_str(), w, m.damping_mass / (2 * w) + m.damping_stiffness * w / 2, exact, s.sim.dt,
                s.sim.dt / exact, element.dt, element.dt / exact, at_auto, above);
    EXPECT_GT(m.damping_stiffness * w / 2, 0.5) << "the test needs stiffness damping to set the limit";
    EXPECT_LE(s.sim.dt, exact);
    EXPECT_GE(s.sim.dt, 0.999 * exact);
    EXPECT_LE(at_auto, 1 + 1e-9) << integrator;
    EXPECT_GT(above, 1 + 1e-3) << integrator;
  }
}

// Copies of one entry are computed once: rotations and translations leave the eigenvalues
// alone (each copy's own bound agrees with the first's to rounding), but scale does not,
// so entries of the same mesh at different scales keep their own. 'big' (scale 2: half the
// frequencies of linear elasticity) comes first; were the two entries shared, the scene's
// step would be 'big''s, twice too long.
TEST(MeshBound, CopiesOfAnEntryShareTheBoundAndScaleDoesNot) {
  const std::string knight = kInputs + "/meshes/chess/knight.msh";
  const std::string yaml = R"(simulation: {dt: auto, dt_bound: mesh, steps: 1}
materials:
  - {name: piece, model: linear, young: 1.0e4, poisson: 0.3, density: 500}
objects:
  - name: big
    material: piece
    mesh: )" + knight + R"(
    transform: {scale: [2, 2, 2]}
    instances: {random: {count: 3, region: {min: [-2, -2, 0], max: [2, 2, 2]}, seed: 3, rotate: true}}
  - name: small
    material: piece
    mesh: )" + knight + R"(
    instances: {random: {count: 3, region: {min: [3, -2, 0], max: [7, 2, 2]}, seed: 4, rotate: true}}
)";
  const Scene s = load_scene_from_string(yaml, "knights.yaml");
  ASSERT_EQ(s.objects.size(), 6u);
  double w[2] = {0, 0};
  for (std::size_t i = 0; i < s.objects.size(); ++i) {
    const SceneObject& o = s.objects[i];
    EXPECT_EQ(o.entry, static_cast<int>(i / 3)) << o.name;
    const Material& m = s.materials[0];
    const double omega = mesh_max_frequency(o.mesh, m, element_frequency(o, m)).omega;
    if (i % 3 == 0) w[i / 3] = omega;
    EXPECT_NEAR(omega, w[i / 3], 1e-9 * w[i / 3]) << o.name;
  }
  EXPECT_NEAR(w[1] / w[0], 2, 1e-3);
  const StableStep stable = stable_step(s);
  EXPECT_EQ(stable.object, 3);  // small[0]
  EXPECT_NEAR(stable.omega, w[1], 1e-9 * w[1]);
}

// The bound runs on one thread whatever the team: the same dt bitwise on 1 and 2 threads.
TEST(MeshBound, SameStepOnAnyNumberOfThreads) {
  const std::string yaml = R"(simulation: {dt: auto, dt_bound: mesh, steps: 1}
materials:
  - {name: soft, model: neohookean, young: 5.0e4, poisson: 0.35, density: 1000}
objects:
  - {name: torus, material: soft, mesh: )" + kInputs + R"(/meshes/torus/torus.msh}
)";
  const int threads = omp_get_max_threads();
  omp_set_num_threads(1);
  const double one = load_scene_from_string(yaml, "torus.yaml").sim.dt;
  omp_set_num_threads(2);
  const double two = load_scene_from_string(yaml, "torus.yaml").sim.dt;
  omp_set_num_threads(threads);
  EXPECT_EQ(one, two);
}
