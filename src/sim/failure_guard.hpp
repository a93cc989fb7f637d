#pragma once
// The run's numerical-failure guard (docs/reliability.md), the part that watches whole
// frames: the total energy against what the scene can release, the share of inverted
// elements, and the message every rank throws on a failure, which says where the run can
// go on from (the last frame, the last good checkpoint). The cheap per-step checks of
// the vertices and the collective "where is it" searches are the Simulator's
// (health.cpp); run_scene (run.cpp) calls both.
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "softcontact/diagnostics.hpp"
#include "softcontact/scene.hpp"

namespace softcontact {

class FrameWriter;
class Simulator;

/// What the guard compares against, from the scene alone (identical on all ranks).
struct GuardScales {
  double max_speed = 0;      ///< [m/s]
  double release = 0;        ///< energy the scene can release besides its initial energy [J]
  std::int64_t movable_tets = 0;
};
/// The mesh passes (heights along gravity, volumes) of object k by part k % parts, `sum`
/// adding the parts' (SceneLimits::sum; null or one part: all here): the same scales, to
/// the bit, on any number of parts. Collective over the parts.
GuardScales guard_scales(const Scene& scene, int part = 0, int parts = 1,
                         const std::function<void(std::vector<double>&)>& sum = {});

class FailureGuard {
public:
  /// `energy0` and `energy_scale` as a checkpoint saved them (`restart`), else taken from
  /// the first frame.
  /// `scales`: guard_scales(scene), taken before the Simulator drops the meshes a rank does
  /// not need (it would make them again for the pass).
  FailureGuard(const Scene& scene, const GuardScales& scales, const std::string& output_dir, bool restart,
               double energy0, double energy_scale);

  double max_speed() const { return scales_.max_speed; }
  double energy0() const { return energy0_; }
  double energy_scale() const { return release_; }

  /// Where a failure sends the user: the frames written (`frames`' last step) and the
  /// last good checkpoint.
  void watch_frames(const FrameWriter* frames) { frames_ = frames; }
  void checkpoint_written(const std::string& path, std::int64_t step) {
    last_checkpoint_ = path;
    last_checkpoint_step_ = step;
  }
  const std::string& last_checkpoint() const { return last_checkpoint_; }

  /// Throws NumericalFailure with the same message on every rank: `what` at `step`,
  /// then what to try (`solver`: an implicit solve did not converge) and where to go on from.
  [[noreturn]] void fail(std::int64_t step, double time, const std::string& what, bool solver = false) const;

  /// After a frame's reductions at `step` (the frame is written first: it shows the state
  /// that failed): the total energy grown past 10 times what the scene can release, or
  /// more elements inverted than the scene allows (located by the simulator). Collective.
  void check_frame(std::int64_t step, const StepDiagnostics& d, Simulator& sim);

private:
  const Scene& scene_;
  GuardScales scales_;
  std::string dir_;
  double energy0_ = 0, release_ = 0;
  bool have_energy_ = false;
  const FrameWriter* frames_ = nullptr;
  std::string last_checkpoint_;
  std::int64_t last_checkpoint_step_ = -1;
};

}  // namespace softcontact
