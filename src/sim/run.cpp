#include "softcontact/run.hpp"

#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iomanip>
#include <iostream>
#include <memory>
#include <sstream>

#include "softcontact/diagnostics.hpp"
#include "softcontact/error.hpp"
#include "softcontact/frame_writer.hpp"
#include "softcontact/simulator.hpp"
#include "softcontact/world.hpp"

namespace softcontact {

namespace fs = std::filesystem;

namespace {

double now() { return MPI_Wtime(); }

std::string format_seconds(double s) {
  char buf[64];
  if (!std::isfinite(s)) return "?";
  if (s < 60) std::snprintf(buf, sizeof buf, "%.1f s", s);
  else if (s < 3600) std::snprintf(buf, sizeof buf, "%d min %02d s", static_cast<int>(s / 60), static_cast<int>(s) % 60);
  else std::snprintf(buf, sizeof buf, "%d h %02d min", static_cast<int>(s / 3600), static_cast<int>(s / 60) % 60);
  return buf;
}

/// The progress line on rank 0: simulated time, steps per second, ETA; at most once a
/// second, rewritten in place on a terminal and one line each in a batch log.
class Progress {
public:
  Progress(std::ostream& out, bool enabled, std::int64_t total, double dt)
      : out_(out), enabled_(enabled), tty_(isatty(STDOUT_FILENO) && &out == &std::cout), total_(total), dt_(dt),
        start_(now()), last_(start_) {}

  void update(std::int64_t step) {
    if (!enabled_) return;
    const double t = now();
    if (t - last_ < (tty_ ? 0.5 : 10.0) && step != total_) return;
    last_ = t;
    const double rate = step / std::max(t - start_, 1e-9);
    char buf[256];
    std::snprintf(buf, sizeof buf, "t = %.4g / %.4g s   step %lld / %lld   %.1f steps/s   ETA %s", step * dt_,
                  total_ * dt_, static_cast<long long>(step), static_cast<long long>(total_), rate,
                  format_seconds((total_ - step) / rate).c_str());
    // Padding instead of a terminal escape: Open MPI hands rank 0 a pseudo-terminal even
    // when mpirun's own output goes to a file.
    if (tty_) out_ << '\r' << std::left << std::setw(96) << buf << (step == total_ ? "\n" : "") << std::flush;
    else out_ << buf << '\n' << std::flush;
  }

private:
  std::ostream& out_;
  bool enabled_, tty_;
  std::int64_t total_;
  double dt_, start_, last_;
};

}  // namespace

void apply_overrides(Scene& scene, const RunOptions& opt) {
  Simulation& sim = scene.sim;
  if (opt.steps && opt.end_time) throw InputError("command line: give either --steps or --end-time, not both");
  if (opt.steps) {
    sim.steps = *opt.steps;
    sim.end_time.reset();
  }
  if (opt.end_time) {
    sim.end_time = *opt.end_time;
    sim.steps.reset();
  }
  if (opt.output_dir) sim.output_dir = *opt.output_dir;
  if (opt.output_every) {
    sim.output_every = *opt.output_every;
    sim.output_interval = 0;
  }
}

void check_output_dir(MPI_Comm comm, const std::string& dir, bool overwrite) {
  int rank = 0;
  MPI_Comm_rank(comm, &rank);
  int status = 0;  // 0 ok, 1 exists, 2 not a directory
  if (rank == 0) {
    std::error_code ec;
    if (fs::exists(dir, ec)) status = !fs::is_directory(dir, ec) ? 2 : (overwrite ? 0 : 1);
  }
  MPI_Bcast(&status, 1, MPI_INT, 0, comm);
  if (status == 1)
    throw InputError("output directory '" + dir +
                     "' already exists; pass --overwrite to replace its results, or --output DIR for another directory");
  if (status == 2) throw InputError("output path '" + dir + "' exists and is not a directory");
}

RunSummary run_scene(MPI_Comm comm, const Scene& scene, const RunOptions& opt, std::ostream& log) {
  int rank = 0;
  MPI_Comm_rank(comm, &rank);
  const Simulation& sim = scene.sim;
  const std::int64_t nsteps = total_steps(sim);
  const std::int64_t every = steps_between_frames(sim);

  check_output_dir(comm, sim.output_dir, opt.overwrite);

  // The models' rest state is the world as built (before any step).
  Simulator simulator(comm, scene);
  if (rank == 0 && simulator.initial_overlaps() > 0)
    std::cerr << scene.path << ": warning: " << simulator.initial_overlaps()
              << " vertices start inside other objects (deepest " << simulator.initial_overlap_depth()
              << " m); the first step pushes them out within one time step, which is violent for deep "
                 "overlaps: move the objects apart\n";

  // Everything is validated: only now touch the file system.
  RunSummary summary;
  const fs::path dir(sim.output_dir);
  summary.h5 = (dir / kFramesH5).string();
  summary.xdmf = (dir / kFramesXdmf).string();
  summary.csv = (dir / kDiagnosticsCsv).string();
  int made = 1;
  if (rank == 0) {
    std::error_code ec;
    fs::create_directories(dir, ec);
    for (const char* f : {kFramesH5, kFramesXdmf, kDiagnosticsCsv, "scene.yaml"}) fs::remove(dir / f, ec);
    fs::copy_file(scene.path, dir / "scene.yaml", fs::copy_options::overwrite_existing, ec);
    made = fs::is_directory(dir) ? 1 : 0;
  }
  MPI_Bcast(&made, 1, MPI_INT, 0, comm);
  if (!made) throw RuntimeFailure("cannot create the output directory '" + sim.output_dir + "'");

  World& world = simulator.world();
  FrameWriter writer(comm, summary.h5, summary.xdmf, scene, world);
  DiagnosticsCsv csv;
  if (rank == 0) csv.open(summary.csv);

  auto record = [&] {
    const double t0 = now();
    StepDiagnostics d;
    simulator.measure(d);
    writer.write_frame(d.step, d.time, world,
                       {{"contact_forces", "contact_force", 3, simulator.contact_force().data()},
                        {"penetration", "penetration", 3, simulator.penetration().data()}});
    std::int64_t steps = 0;
    PhaseTimes acc = simulator.take_times(steps);
    acc.output += now() - t0;
    d.seconds = steps > 0 ? acc.scaled(1.0 / static_cast<double>(steps)) : acc;
    if (rank == 0) csv.write(d);
  };
  record();

  Progress progress(log, rank == 0 && !opt.quiet, nsteps, sim.dt);
  const double wall0 = now();
  for (std::int64_t step = 1; step <= nsteps; ++step) {
    simulator.step();
    if (step % every == 0 || step == nsteps) record();
    progress.update(step);
  }
  writer.close();
  summary.steps = nsteps;
  summary.sim_time = static_cast<double>(nsteps) * sim.dt;
  summary.wall_seconds = now() - wall0;
  summary.frames = writer.frames_written();
  return summary;
}

}  // namespace softcontact
