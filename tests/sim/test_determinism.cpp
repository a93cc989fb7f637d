// The same scene run with 1 and 2 OpenMP threads gives bitwise identical positions:
// per-tet kernels that depend on their tet alone, per-vertex gathers in tet-id order,
// per-object solves (docs/architecture.md, "Determinism").
#include <gtest/gtest.h>
#include <omp.h>

#include <string>
#include <vector>

#include "stepper.hpp"

using namespace softcontact;
using softcontact::test_support::Stepper;

namespace {

/// One object per model (each a sphere of 6^3-ish cells, > 1 block of tets, > 4096
/// vertices in all so that every parallel loop really runs in parallel), with Rayleigh
/// damping, gravity, a fixed box and an initial spin.
std::string scene_yaml(const std::string& integrator, const std::vector<std::string>& models) {
  std::string y = "simulation: {dt: auto, steps: 1, gravity: [0, 0, -9.81], integrator: " + integrator +
                  "}\nmaterials:\n";
  for (const auto& m : models)
    y += "  - {name: " + m + ", model: " + m +
         ", young: 1e5, poisson: 0.3, density: 1000, damping: {mass: 0.5, stiffness: 1e-3}}\n";
  y += "objects:\n";
  for (std::size_t k = 0; k < models.size(); ++k)
    y += "  - material: " + models[k] + "\n    primitive: {type: sphere, radius: 0.5, resolution: 12}\n" +
         "    transform: {translate: [" + std::to_string(2.0 * k) + ", 0, 0]}\n    velocity: [0, 0, -1]\n" +
         "    fixed: {min: [" + std::to_string(2.0 * k - 1) + ", -1, 0.45], max: [" + std::to_string(2.0 * k + 1) +
         ", 1, 1]}\n";
  return y;
}

std::vector<double> run(const std::string& yaml, int threads, int steps) {
  omp_set_num_threads(threads);
  Stepper st = Stepper::from_yaml(yaml);
  for (std::size_t i = 0; i < st.w.n_owned; ++i)  // a spin about z on top of the fall
    if (st.w.inv_mass[i] != 0) {
      st.w.v[3 * i] += -3 * st.w.x[3 * i + 1];
      st.w.v[3 * i + 1] += 3 * (st.w.x[3 * i] - 2.0 * st.w.vertex_object[i]);
    }
  st.start();
  for (int k = 0; k < steps; ++k) st.step();
  return st.w.x;
}

void expect_thread_independent(const std::string& yaml, int steps) {
  const int before = omp_get_max_threads();
  const std::vector<double> one = run(yaml, 1, steps);
  for (int threads : {2}) {
    const std::vector<double> many = run(yaml, threads, steps);
    ASSERT_EQ(many.size(), one.size());
    std::size_t differ = 0;
    for (std::size_t k = 0; k < one.size(); ++k) differ += many[k] != one[k];
    EXPECT_EQ(differ, 0u) << threads << " threads";
  }
  omp_set_num_threads(before);
}

}  // namespace

TEST(Determinism, ExplicitRunsAreBitwiseIdenticalForAnyThreadCount) {
  const std::vector<std::string> models = {"linear", "corotational", "stvk", "neohookean", "mass_spring"};
  expect_thread_independent(scene_yaml("verlet", models), 20);
  expect_thread_independent(scene_yaml("symplectic_euler", models), 10);
}

TEST(Determinism, ImplicitRunsAreBitwiseIdenticalForAnyThreadCount) {
  expect_thread_independent(scene_yaml("implicit_euler", {"linear", "corotational"}), 5);
}
