// Long version of the cantilever of test_statics.cpp: finer meshes, n = 4, 6, 8 cells
// across the section (3840, 12960 and 30720 tets), linear model (the corotational and
// StVK models agree with it to 1e-5 at this load, test_statics.cpp). Reference: Timoshenko,
// 4.0240e-4 m. Checked: the error keeps falling, is below 10 % at n = 8, and the
// extrapolation of n = 6, 8 to h -> 0 (assuming O(h^2)) lands within 3 %.
#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "softcontact/scene.hpp"
#include "static_solver.hpp"

using namespace softcontact;

namespace {

double cantilever_tip(int n) {
  const Scene s = load_scene_from_string(
      "simulation: {dt: 1, steps: 1, gravity: [0, 0, 0]}\nmaterials:\n  - {name: m, model: linear, young: 1e8, "
      "poisson: 0, density: 1000}\nobjects:\n  - material: m\n    primitive: {type: box, size: [1, 0.1, 0.1], cells: [" +
          std::to_string(10 * n) + ", " + std::to_string(n) + ", " + std::to_string(n) +
          "]}\n    fixed: {min: [-1, -1, -1], max: [-0.499, 1, 1]}\n",
      "test.yaml");
  World w = build_world(s, block_partition(s, 1), 0);
  ElasticForces ef(s, w);
  std::vector<double> fe(w.x.size(), 0.0);
  for (std::size_t t = 0; t < w.triangles.size() / 3; ++t) {
    const index_t* c = &w.triangles[3 * t];
    if (!(w.x[3 * c[0]] > 0.4999 && w.x[3 * c[1]] > 0.4999 && w.x[3 * c[2]] > 0.4999)) continue;
    const double* a = &w.x[3 * c[0]];
    const double* b = &w.x[3 * c[1]];
    const double* cc = &w.x[3 * c[2]];
    const double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, v[3] = {cc[0] - a[0], cc[1] - a[1], cc[2] - a[2]};
    const double tri = 0.5 * std::hypot(u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]);
    for (int k = 0; k < 3; ++k) fe[3 * c[k] + 2] -= tri / 0.01 / 3;  // P = 1 N over the 0.01 m^2 face
  }
  const std::vector<double> x0 = w.x;
  EXPECT_GT(test_support::solve_static(ef, w, fe, 1e-15), 0);
  double s_tip = 0;
  int cnt = 0;
  for (std::size_t i = 0; i < w.n_owned; ++i)
    if (x0[3 * i] > 0.4999) {
      s_tip += x0[3 * i + 2] - w.x[3 * i + 2];
      ++cnt;
    }
  return s_tip / cnt;
}

}  // namespace

TEST(StaticsLong, CantileverConvergesOnFinerMeshes) {
  const double b = 0.1, E = 1e8, I = b * b * b * b / 12;
  const double ref = 1.0 / (3 * E * I) + 1.0 / (5.0 / 6 * E / 2 * b * b);
  const double t4 = cantilever_tip(4), t6 = cantilever_tip(6), t8 = cantilever_tip(8);
  EXPECT_LT(std::abs(t6 / ref - 1), std::abs(t4 / ref - 1));
  EXPECT_LT(std::abs(t8 / ref - 1), std::abs(t6 / ref - 1));
  EXPECT_LT(std::abs(t8 / ref - 1), 0.10);
  const double extrapolated = (64 * t8 - 36 * t6) / 28;
  EXPECT_NEAR(extrapolated / ref, 1.0, 0.03);
  RecordProperty("error_n4", std::to_string(t4 / ref - 1));
  RecordProperty("error_n6", std::to_string(t6 / ref - 1));
  RecordProperty("error_n8", std::to_string(t8 / ref - 1));
  RecordProperty("error_extrapolated", std::to_string(extrapolated / ref - 1));
}
