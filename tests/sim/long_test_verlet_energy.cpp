// Long version of test_verlet_energy.cpp: 10^6 steps (about 620 periods of the lowest
// mode) at dt = dt: auto and 2 x 10^6 at dt/2, for the corotational and neo-Hookean
// models. Same criteria: the relative energy error stays bounded (amplitude below 5 %),
// does not drift (last tenth vs first tenth: below 5 % of the amplitude), and its
// amplitude falls about fourfold (3 to 5) when dt is halved.
#include <gtest/gtest.h>
#include <omp.h>

#include <cmath>
#include <string>

#include "verlet_energy.hpp"

using namespace softcontact;
using namespace softcontact::test_support;

TEST(VerletEnergyLong, BoundedWithoutDriftOverAMillionSteps) {
  const int before = omp_get_max_threads();
  omp_set_num_threads(1);
  for (const char* model : {"corotational", "neohookean"}) {
    const EnergyTrace a = verlet_energy_trace(model, 1.0, 1000000);
    const EnergyTrace b = verlet_energy_trace(model, 0.5, 2000000);
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
