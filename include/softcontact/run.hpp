#pragma once
// The run loop: Algorithm 1 of the paper step after step, output frames, diagnostics and
// the progress line.
#include <mpi.h>

#include <cstdint>
#include <iosfwd>
#include <optional>
#include <string>

#include "softcontact/scene.hpp"

namespace softcontact {

/// Command-line overrides of the scene (batch use).
struct RunOptions {
  std::optional<std::int64_t> steps;
  std::optional<double> end_time;
  std::optional<std::string> output_dir;
  std::optional<std::int64_t> output_every;
  bool overwrite = false;
  bool quiet = false;
};

struct RunSummary {
  std::int64_t steps = 0;
  double sim_time = 0;
  double wall_seconds = 0;
  std::int64_t frames = 0;
  std::string h5, xdmf, csv;
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

/// Runs the scene. Collective over `comm`; progress and summary go to `log` on rank 0.
RunSummary run_scene(MPI_Comm comm, const Scene& scene, const RunOptions& opt, std::ostream& log);

}  // namespace softcontact
