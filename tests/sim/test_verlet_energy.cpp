// Energy behaviour of position Verlet on a free vibrating body (docs/validation.md,
// "Deformation models"): the energy error stays bounded with no drift, and is O(dt^2).
#include <gtest/gtest.h>
#include <omp.h>

#include <cmath>
#include <string>
#include <vector>

#include "stepper.hpp"
#include "verlet_energy.hpp"

using namespace softcontact;
using namespace softcontact::test_support;

// A free cube (1 m, 2x2x2 cells, E = 1e5 Pa, nu = 0.3, rho = 1000: c = 11.6 m/s), no
// gravity, started with the velocity field v = a (x, -y, 0) (strain amplitude ~5 %, a
// non-linear regime for the corotational and neo-Hookean models). Energy E_n = 1/2 m v_n^2
// + U(x_n) with the central velocity v_n = (x_(n+1) - x_(n-1)) / (2 dt), which is the
// O(dt^2) accurate one (World::v is Verlet's backward difference, O(dt)).
// 10^5 steps at dt = dt: auto (0.5 x the guaranteed limit, ~62 periods of the lowest
// mode), then 2 x 10^5 steps at dt/2 over the same time.
// Measured (corotational): relative amplitude 1.70e-2 at dt, ratio to dt/2 4.07; drift
// over the run (mean energy error of the last tenth minus that of the first) 0.16 % of
// the amplitude. Tolerances: amplitude below 5 %, ratio in [3, 5], drift below 5 % of the
// amplitude. The neo-Hookean model and 10^6 steps: long_test_verlet_energy.cpp.
TEST(VerletEnergy, BoundedWithoutDriftAndQuadraticInDt) {
  const int before = omp_get_max_threads();
  omp_set_num_threads(1);  // 27 vertices: threads would only add overhead
  for (const char* model : {"corotational"}) {
    const EnergyTrace a = verlet_energy_trace(model, 1.0, 100000);
    const EnergyTrace b = verlet_energy_trace(model, 0.5, 200000);
    EXPECT_LT(a.amplitude, 0.05) << model;
    EXPECT_LT(std::abs(a.drift), 0.05 * a.amplitude) << model;
    EXPECT_LT(std::abs(b.drift), 0.05 * b.amplitude) << model;
    const double ratio = a.amplitude / b.amplitude;
    EXPECT_GT(ratio, 3.0) << model;
    EXPECT_LT(ratio, 5.0) << model;
    RecordProperty(std::string("amplitude_") + model, std::to_string(a.amplitude));
    RecordProperty(std::string("ratio_") + model, std::to_string(ratio));
    RecordProperty(std::string("drift_") + model, std::to_string(a.drift / a.amplitude));
  }
  omp_set_num_threads(before);
}
