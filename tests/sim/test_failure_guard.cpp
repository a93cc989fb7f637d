// The numerical-failure guard (docs/reliability.md): each class of failure, on a scene
// built to fail (a soft block on a floor, stepped above its stable time step of 2.807 ms),
// stops the run with a NumericalFailure that says where (step, object, element) and what
// to try, and leaves the last good checkpoint in place. The other checks are switched off
// through simulation.limits so that each case exercises one of them.
#include <gtest/gtest.h>

#include <filesystem>
#include <regex>
#include <sstream>

#include "softcontact/checkpoint.hpp"
#include "softcontact/error.hpp"
#include "softcontact/run.hpp"
#include "softcontact/scene.hpp"

using namespace softcontact;
namespace fs = std::filesystem;

namespace {

Scene block_scene(const std::string& dt, int output_every, const std::string& limits) {
  return load_scene_from_string(R"(
simulation:
  dt: )" + dt + R"(
  steps: 400
  gravity: [0, 0, -9.81]
  output: {every: )" + std::to_string(output_every) + R"(}
  limits: )" + limits + R"(
materials:
  - {name: soft, model: corotational, young: 1.0e5, poisson: 0.3, density: 1000}
  - {name: ground, model: linear, young: 1.0e7, poisson: 0.3, density: 2000}
objects:
  - name: floor
    material: ground
    primitive: {type: plate, size: [1, 1], thickness: 0.1, cells: [4, 4]}
    transform: {translate: [0, 0, -0.05]}
    kinematic: true
  - name: block
    material: soft
    primitive: {type: box, size: [0.2, 0.2, 0.2], cells: [3, 3, 3]}
    transform: {translate: [0, 0, 0.1005]}
)",
                                "guard.yaml");
}

struct Failure {
  std::string message;
  std::int64_t step = -1;
};

// Runs the scene (checkpoints every `ckpt` steps when > 0) and returns the failure.
Failure run_to_failure(Scene scene, const std::string& dir, std::int64_t ckpt = 0) {
  scene.sim.output_dir = dir;
  RunOptions opt;
  opt.quiet = true;
  opt.overwrite = true;
  if (ckpt > 0) opt.checkpoint_every = ckpt;
  std::ostringstream log;
  Failure f;
  try {
    run_scene(MPI_COMM_WORLD, scene, opt, log);
  } catch (const NumericalFailure& e) {
    f.message = e.what();
    std::smatch m;
    if (std::regex_search(f.message, m, std::regex("at step ([0-9]+)"))) f.step = std::stoll(m[1]);
  }
  return f;
}

// Every message says where and what to try.
void expect_where_and_advice(const Failure& f) {
  EXPECT_GT(f.step, 0) << f.message;
  EXPECT_NE(f.message.find("object 'block'"), std::string::npos) << f.message;
  EXPECT_NE(f.message.find("element"), std::string::npos) << f.message;
  EXPECT_NE(f.message.find("Try a smaller dt"), std::string::npos) << f.message;
  EXPECT_NE(f.message.find("stable explicit limit of this scene is 0.002807"), std::string::npos) << f.message;
}

}  // namespace

TEST(FailureGuard, NonFinitePositionsAreCaughtAndLocated) {
  // dt 14x the limit: amplitudes grow ~200x a step until they overflow.
  const Failure f = run_to_failure(block_scene("0.04", 1000, "{max_speed: 1.0e300, max_inverted_fraction: 1}"),
                                   "guard_nonfinite");
  ASSERT_FALSE(f.message.empty()) << "the run finished";
  EXPECT_NE(f.message.find("non-finite position or velocity"), std::string::npos) << f.message;
  expect_where_and_advice(f);
  fs::remove_all("guard_nonfinite");
}

TEST(FailureGuard, RunawaySpeedIsCaughtBeforeItOverflows) {
  // Default limit: 10 x the block's dilatational wave speed (11.6 m/s) = 116 m/s.
  const Failure f = run_to_failure(block_scene("0.004", 1000, "{max_inverted_fraction: 1}"), "guard_speed");
  ASSERT_FALSE(f.message.empty()) << "the run finished";
  EXPECT_NE(f.message.find("above the limit of 116 m/s"), std::string::npos) << f.message;
  expect_where_and_advice(f);
  EXPECT_LT(f.step, 100) << "instability grows by a constant factor per step; it should be caught early";
  fs::remove_all("guard_speed");
}

TEST(FailureGuard, ExplodingEnergyIsCaughtAtAFrame) {
  const Failure f = run_to_failure(block_scene("0.004", 1, "{max_speed: 1.0e300, max_inverted_fraction: 1}"),
                                   "guard_energy");
  ASSERT_FALSE(f.message.empty()) << "the run finished";
  EXPECT_NE(f.message.find("the total energy grew by"), std::string::npos) << f.message;
  expect_where_and_advice(f);
  fs::remove_all("guard_energy");
}

TEST(FailureGuard, InvertedElementsBeyondTheThresholdAreCaughtAndTheLastGoodCheckpointStays) {
  const Failure f = run_to_failure(block_scene("0.004", 1, "{max_speed: 1.0e300}"), "guard_inverted", 5);
  ASSERT_FALSE(f.message.empty()) << "the run finished";
  EXPECT_NE(f.message.find("movable elements inverted"), std::string::npos) << f.message;
  EXPECT_NE(f.message.find("limit 1%"), std::string::npos) << f.message;
  expect_where_and_advice(f);
  // The newest checkpoint predates the failure, is named in the message and is readable.
  const std::string last = resolve_checkpoint("guard_inverted");
  EXPECT_NE(f.message.find("the last good checkpoint is " + fs::absolute(last).lexically_normal().string()),
            std::string::npos)
      << f.message;
  const CheckpointInfo info = read_checkpoint_info(MPI_COMM_WORLD, last);
  EXPECT_LT(info.step, f.step);
  EXPECT_GE(info.step, f.step - 5);
  fs::remove_all("guard_inverted");
}

TEST(FailureGuard, AStableRunOfTheSameSceneIsNotStopped) {
  // dt: auto (half the limit) with the default limits: no false alarm over 400 steps of
  // falling, landing and settling.
  const Failure f = run_to_failure(block_scene("auto", 10, "{}"), "guard_stable");
  EXPECT_TRUE(f.message.empty()) << f.message;
  fs::remove_all("guard_stable");
}
