#pragma once
// Test support: the energy error trace of position Verlet on a free vibrating cube
// (test_verlet_energy.cpp and the long version).
#include <cmath>
#include <string>
#include <vector>

#include "stepper.hpp"

namespace softcontact::test_support {

struct EnergyTrace {
  double amplitude = 0;  ///< (max - min) of the relative energy error over the run
  double drift = 0;      ///< mean relative error over the last tenth minus over the first tenth
};

/// Runs `steps` steps at dt = dt_scale x (dt: auto) and records E_n / E_1 - 1.
inline EnergyTrace verlet_energy_trace(const std::string& model, double dt_scale, std::int64_t steps) {
  Scene s = load_scene_from_string("simulation: {dt: auto, steps: 1, gravity: [0, 0, 0]}\nmaterials:\n"
                                   "  - {name: m, model: " + model +
                                       ", young: 1e5, poisson: 0.3, density: 1000}\n"
                                       "objects:\n  - material: m\n    primitive: {type: box, size: [1, 1, 1], cells: [2, 2, 2]}\n",
                                   "test.yaml");
  s.sim.dt *= dt_scale;
  Stepper st(std::move(s));
  const double a = 1.5;
  for (std::size_t i = 0; i < st.w.n_owned; ++i) {
    st.w.v[3 * i] = a * st.w.x[3 * i];
    st.w.v[3 * i + 1] = -a * st.w.x[3 * i + 1];
  }
  st.start();
  const double dt = st.scene.sim.dt;
  std::vector<double> xm = st.w.x_prev, x = st.w.x, vc(x.size());  // x^(n-1), x^n
  std::vector<double> err;
  err.reserve(static_cast<std::size_t>(steps));
  double e1 = 0;
  for (std::int64_t n = 0; n < steps; ++n) {
    const double u = st.elastic_energy();  // U(x^n)
    st.step();                              // x^(n+1)
    for (std::size_t k = 0; k < x.size(); ++k) vc[k] = (st.w.x[k] - xm[k]) / (2 * dt);
    const double e = st.kinetic_energy(vc) + u;
    if (n == 0) e1 = e;
    err.push_back(e / e1 - 1);
    xm = x;
    x = st.w.x;
  }
  EnergyTrace t;
  double lo = HUGE_VAL, hi = -HUGE_VAL, first = 0, last = 0;
  const std::size_t tenth = err.size() / 10;
  for (std::size_t k = 0; k < err.size(); ++k) {
    lo = std::min(lo, err[k]);
    hi = std::max(hi, err[k]);
    if (k < tenth) first += err[k] / tenth;
    if (k >= err.size() - tenth) last += err[k] / tenth;
  }
  t.amplitude = hi - lo;
  t.drift = last - first;
  return t;
}

}  // namespace softcontact::test_support
