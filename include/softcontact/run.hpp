#pragma once
// The run loop: Algorithm 1 of the paper step after step, output frames, diagnostics and
// the progress line.
#include <mpi.h>

#include <cstdint>
#include <iosfwd>
#include <optional>
#include <string>

#include "softcontact/checkpoint.hpp"
#include "softcontact/scene.hpp"

namespace softcontact {

/// Command-line overrides of the scene (batch use).
struct RunOptions {
  std::optional<std::int64_t> steps;
  std::optional<double> end_time;
  std::optional<std::string> output_dir;
  std::optional<std::int64_t> output_every;
  std::optional<std::int64_t> checkpoint_every;   ///< steps between checkpoints
  std::optional<double> checkpoint_minutes;       ///< wall minutes between checkpoints
  std::optional<std::int64_t> verify_every;       ///< steps between in-run checks (verify.hpp)
  bool overwrite = false;
  bool quiet = false;
};

/// Where a restarted run continues: the checkpoint, read and checked against its scene.
struct RestartPoint {
  std::string path;        ///< the checkpoint file
  CheckpointInfo info;
  std::string output_dir;  ///< the run's output directory, which a restart continues
};

/// How `run` and `bench` load a scene on `comm`: copies of multi-copy entries placed,
/// measured and let go (each rank makes again only those it owns or ghosts), the stable
/// step's per-object frequencies shared between the ranks, and each mesh file of
/// multi-copy entries read by one rank and broadcast (docs/architecture.md, "Who holds
/// which mesh", "Who reads which mesh file"). The SceneLimits' other fields keep their
/// defaults.
SceneLimits copies_made_on_demand(MPI_Comm comm);

/// Reads checkpoint `path` (a file, or a directory: its newest checkpoint) and the scene
/// it carries, with the run's settings (steps, frames, output directory) as they were;
/// `opt` then overrides them like a scene. Throws InputError when the checkpoint is not
/// readable or the scene's meshes have changed since. Collective. `limits`: how the
/// scene is loaded (copies_made_on_demand for a run).
Scene load_restart(MPI_Comm comm, const std::string& path, RestartPoint& restart, const SceneLimits& limits = {});

struct RunSummary {
  std::int64_t steps = 0;
  double sim_time = 0;
  double wall_seconds = 0;
  std::int64_t frames = 0;
  std::string h5, xdmf, csv;
  std::int64_t first_step = 0;       ///< step the run started from (a restart's checkpoint step)
  std::string last_checkpoint;       ///< the newest checkpoint written ("" when none)
  std::string stopped_by;            ///< "SIGTERM" / "SIGINT" when a signal ended the run early
  std::string verify_json;           ///< verify_steps.json when --verify-every was given ("" otherwise)
  double peak_rss = 0;               ///< peak resident memory of the largest rank [bytes] (VmHWM)
  /// Ghost-set rebuilds and repartitions (migrations) during the run's steps, the same on
  /// every rank; the set built at the start is not counted. 0 on one rank
  /// (docs/architecture.md, "Ghost set" and "Migration").
  std::int64_t ghost_rebuilds = 0, repartitions = 0;
  /// Objects whose forces were shared over ranks, and over how many.
  int split_objects = 0, split_ranks = 0;
  /// Where the split objects' parts were at the end (Simulator::split_hosts).
  SplitHosts split_hosts;
};

/// Applies the overrides to the scene's simulation settings.
void apply_overrides(Scene& scene, const RunOptions& opt);

/// Names of the files a run writes in its output directory.
inline constexpr const char* kFramesH5 = "frames.h5";
inline constexpr const char* kFramesXdmf = "frames.xdmf";
inline constexpr const char* kDiagnosticsCsv = "diagnostics.csv";

/// Checks (rank 0, result broadcast) that the output directory does not exist, or that
/// `overwrite` is set; throws InputError otherwise. Collective.
void check_output_dir(MPI_Comm comm, const std::string& dir, bool overwrite);

/// Runs the scene, or continues it from `restart`. Collective over `comm`; progress and
/// summary go to `log` on rank 0. SIGTERM and SIGINT end the run after the current step
/// with a checkpoint (RunSummary::stopped_by). Throws NumericalFailure (every rank) when
/// the run becomes unphysical; the last good checkpoint stays.
RunSummary run_scene(MPI_Comm comm, const Scene& scene, const RunOptions& opt, std::ostream& log,
                     const RestartPoint* restart = nullptr);

}  // namespace softcontact
