// Every shipped scene (inputs/*.yaml, found at run time, so that a scene added later is
// covered without touching this file) loads, starts free of overlaps and runs a short
// stretch of its own simulation with the contact response behaving: contacts appear
// (after an unmeasured fall for scenes that start in the air), no point stays inside another body by more
// than a small fraction of an edge, the contact forces sum to zero, and every position
// stays finite. The full runs and their figures are in docs/validation.md ("Shipped
// scenes"); this is the short guard that the default suite can afford. One test per
// scene (ShippedScene.ShortRunResolvesContactsAndStaysFinite/NAME), the scenes listed when
// the executable starts; tests/CMakeLists.txt makes this file depend on inputs/*.yaml, so
// that adding or changing a scene rebuilds it and ctest's list (fixed when the executable
// is built) follows. One test per scene lets ctest and the sanitizer run's GoogleTest
// shards spread them over the cores: as one test they were one 200-second item under ASan.
#include <gtest/gtest.h>
#include <mpi.h>

#include <algorithm>
#include <cctype>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "softcontact/collision.hpp"
#include "softcontact/scene.hpp"
#include "softcontact/diagnostics.hpp"
#include "softcontact/simulator.hpp"

using namespace softcontact;

namespace {

/// Scenes whose objects start apart and fall for longer than the short run: they first
/// fall for this much simulated time [s] unmeasured (to just before their first contact),
/// then run the measured short run like every other scene, which must then see contacts
/// too. In seconds, not steps, so that it does not depend on dt (dt: auto follows the
/// materials and their damping). A new scene that falls first belongs here, with the
/// reason.
const std::map<std::string, std::pair<double, std::string>> kFallsFirst = {
    {"default", {0.2425, "the balls start 0.28 m above the floor: first contact at about 0.244 s"}},
    {"soft_floor", {0.035, "the lower balls' lowest vertices start about 7 mm above the floor: first contact at about 0.037 s (step 125)"}},
    {"tori200", {0.090, "the chains start 15 mm above the membrane, which sags with them: first contact at about 0.1 s"}},
    {"torus_drop", {0.030, "the lowest tori start 5 mm above the floor: first contact at about 0.032 s"}},
};

/// Steps of the short run. chess500's lowest pieces touch the floor at step 31; the
/// scenes of kFallsFirst fall first (default touches at step 4,983, tori200 at 385,
/// torus_drop at about 336). The
/// whole test took 7 s on one idle core in a Release build with 1,870 steps in all; since
/// dt: auto includes the damping (docs/models.md) default's heavy stiffness damping
/// (beta = 1e-3 s) cuts its dt 4.6-fold, and the test takes 5,665 steps (32 s on the
/// shared, loaded 2-core machine, default's 5,016 steps 8 s of it).
constexpr int kSteps = 60;

/// Residual penetration after the contact response, over the median edge length
/// (Simulator::measure). The response
/// closes each contact it finds in the step (docs/contact.md); the residual is
/// softcontact verify's deepest surface vertex inside another body, measured
/// independently of the detector. In these short runs (the first contacts only) the worst
/// measured is 3.3e-4 (bars_squeezed); the tolerance is the goal of the issue "Contact
/// resolved in every step", 0.5 % of the median edge. Whole runs and piles are checked by
/// the 'scenes' label (tests/app/scene_verify_test.sh), which most piles do not pass at
/// this goal yet (docs/validation.md, "Contact response in piles").
constexpr double kResidualTolerance = 0.005;

/// |sum F| / sum |F| over all contact forces, the reactions recorded on kinematic
/// vertices included (contact.md: forces on kinematic vertices are recorded, never
/// applied). Each collision's local forces sum to zero in closed form (eqs. 15, 16), so
/// the balance is rounding: measured at most 1.9e-16 here, 1e-15 over the full runs of
/// chess500 and tori200. Tolerance 1e-10.
constexpr double kBalanceTolerance = 1e-10;

/// The repository's inputs/ (tests/data/../../inputs).
std::filesystem::path inputs_dir() {
  return (std::filesystem::path(SOFTCONTACT_TEST_DATA) / ".." / ".." / "inputs").lexically_normal();
}

std::vector<std::string> shipped_scenes() {
  std::vector<std::string> scenes;
  for (const auto& e : std::filesystem::directory_iterator(inputs_dir()))
    if (e.is_regular_file() && e.path().extension() == ".yaml") scenes.push_back(e.path().string());
  std::sort(scenes.begin(), scenes.end());
  return scenes;
}

// GoogleTest's name for a scene's test: letters, digits and underscores only.
std::string test_name(const std::string& path) {
  std::string name = std::filesystem::path(path).stem().string();
  for (char& c : name)
    if (!std::isalnum(static_cast<unsigned char>(c))) c = '_';
  return name;
}

class ShippedScene : public ::testing::TestWithParam<std::string> {};  // the scene file's path

}  // namespace

TEST(ShippedScenes, InputsHoldScenes) { EXPECT_FALSE(shipped_scenes().empty()) << "no scenes in " << inputs_dir(); }

TEST_P(ShippedScene, ShortRunResolvesContactsAndStaysFinite) {
  const std::filesystem::path path = GetParam();
  const std::string name = path.stem().string();
  const auto t0 = std::chrono::steady_clock::now();
  Scene scene;
  ASSERT_NO_THROW(scene = load_scene(path.string())) << "inputs/" << name << ".yaml does not load";
  Simulator sim(MPI_COMM_WORLD, scene);
  // Shipped scenes start free of overlaps: a deep initial overlap is thrown apart at
  // depth / dt (contact.md, "Limits"). Bodies built touching (the archway's stones)
  // start "inside" by rounding only (measured 2e-17 m); the tolerance is 1e-6 of the
  // median edge.
  EXPECT_LE(sim.initial_overlap_depth(), 1e-6 * sim.median_edge())
      << sim.initial_overlaps() << " points start inside other bodies";

  if (const auto it = kFallsFirst.find(name); it != kFallsFirst.end())
    for (std::int64_t k = 0, n = static_cast<std::int64_t>(it->second.first / scene.sim.dt); k < n; ++k) sim.step();

  std::int64_t most_movable = 0, first_contact_step = -1;
  double worst_residual = 0, worst_balance = 0;
  bool finite = true;
  for (int k = 0; k < kSteps && finite; ++k) {
    sim.step();
    StepDiagnostics d;
    sim.measure(d);
    // Collisions with a movable side: touching kinematic parts (chess500's flush walls)
    // give records with no force (contact.md, "Kinematic vertices"), which do not count.
    const World& w = sim.world();
    std::int64_t movable = 0;
    for (const Collision& c : sim.collisions()) {
      bool m = w.inv_mass[c.point] > 0;
      for (index_t j : c.triangle) m = m || w.inv_mass[j] > 0;
      movable += m ? 1 : 0;
    }
    if (movable > 0 && first_contact_step < 0) first_contact_step = sim.step_count();
    most_movable = std::max(most_movable, movable);
    worst_residual = std::max(worst_residual, d.residual_penetration);
    worst_balance = std::max(worst_balance, d.contact_force_balance);
    for (std::size_t i = 0; i < 3 * w.n_owned; ++i) finite = finite && std::isfinite(w.x[i]);
    EXPECT_TRUE(finite) << "non-finite position after step " << sim.step_count();
  }
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  std::printf("[measured] %-22s %7zu tets  %lld steps in %5.1f s: first contact at step %lld, most movable collisions %lld, "
              "worst residual %.3g median edges, worst balance %.2g\n",
              name.c_str(), scene.num_tets(), static_cast<long long>(sim.step_count()), seconds, static_cast<long long>(first_contact_step),
              static_cast<long long>(most_movable), worst_residual, worst_balance);

  EXPECT_GT(most_movable, 0) << "no contact in " << kSteps << " measured steps; if the scene falls first, list it in "
                                "kFallsFirst with the steps to skip and the reason";
  EXPECT_LE(worst_residual, kResidualTolerance);
  EXPECT_LE(worst_balance, kBalanceTolerance);
}

INSTANTIATE_TEST_SUITE_P(Inputs, ShippedScene, ::testing::ValuesIn(shipped_scenes()),
                         [](const ::testing::TestParamInfo<std::string>& info) { return test_name(info.param); });
