#include "softcontact/run.hpp"

#include <signal.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <csignal>
#include <fstream>
#include <functional>
#include <limits>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iomanip>
#include <iostream>
#include <memory>
#include <sstream>

#include "../io/checkpoint_read.hpp"
#include "softcontact/checkpoint.hpp"
#include "softcontact/diagnostics.hpp"
#include "softcontact/error.hpp"
#include "softcontact/fault.hpp"
#include "softcontact/frame_writer.hpp"
#include "softcontact/memory.hpp"
#include "softcontact/mpi_util.hpp"
#include "softcontact/simulator.hpp"
#include "softcontact/stepper.hpp"
#include "softcontact/forces.hpp"
#include "softcontact/surface.hpp"
#include "softcontact/verify.hpp"
#include "softcontact/world.hpp"
#include "failure_guard.hpp"

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
  const int rank = comm_rank(comm);
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

namespace {

// Signals a batch scheduler sends before it kills a job: the run finishes its step,
// writes a checkpoint and ends (docs/reliability.md).
volatile std::sig_atomic_t g_signal = 0;
extern "C" void on_stop_signal(int s) { g_signal = s; }

class StopSignals {
public:
  StopSignals() {
    g_signal = 0;
    struct sigaction sa {};
    sa.sa_handler = on_stop_signal;
    sigemptyset(&sa.sa_mask);
    sa.sa_flags = SA_RESTART;
    sigaction(SIGTERM, &sa, &old_term_);
    sigaction(SIGINT, &sa, &old_int_);
  }
  ~StopSignals() {
    sigaction(SIGTERM, &old_term_, nullptr);
    sigaction(SIGINT, &old_int_, nullptr);
  }
  StopSignals(const StopSignals&) = delete;
  StopSignals& operator=(const StopSignals&) = delete;

private:
  struct sigaction old_term_ {}, old_int_ {};
};

const char* signal_name(int s) { return s == SIGTERM ? "SIGTERM" : s == SIGINT ? "SIGINT" : "a signal"; }

// When checkpoints are due: every `every` steps, every `seconds` of wall time (the
// largest rank clock), at the run's end when either is on, and on a stop signal.
struct CheckpointPolicy {
  std::int64_t every = 0;
  double seconds = 0;
  bool on() const { return every > 0 || seconds > 0; }
  bool due(std::int64_t step, std::int64_t last_step, double since_last, bool stopping) const {
    return (every > 0 && step % every == 0) || (seconds > 0 && since_last >= seconds) || (on() && step == last_step) ||
           stopping;
  }
};

// The output directory: checked, emptied of an earlier run's files (unless a restart
// continues in it), and the scene copied in. Collective: every rank throws if rank 0
// could not make it.
void prepare_output_dir(MPI_Comm comm, int rank, const Scene& scene, const fs::path& dir) {
  int made = 1;
  if (rank == 0) {
    std::error_code ec;
    fs::create_directories(dir, ec);
    for (const char* f : {kFramesH5, kFramesXdmf, kDiagnosticsCsv, "scene.yaml", "mesh.h5"}) fs::remove(dir / f, ec);
    fs::remove_all(dir / "checkpoints", ec);
    made = fs::is_directory(dir) ? 1 : 0;
    if (made) {
      std::ofstream copy(dir / "scene.yaml", std::ios::binary | std::ios::trunc);
      copy << scene.text;
    }
  }
  MPI_Bcast(&made, 1, MPI_INT, 0, comm);
  if (!made) throw CollectiveFailure("cannot create the output directory '" + scene.sim.output_dir + "'");
}

// Rank 0, after a run with --verify-every: the maxima of the in-run checks on the log,
// and verify_steps.json in the output directory.
void report_in_run_checks(const Scene& scene, const VerifyMaxima& verify_max, std::int64_t verify_every,
                          std::int64_t first, std::int64_t last, const fs::path& dir, const std::string& json_path,
                          std::ostream& log) {
  const InsideStats& w = verify_max.deepest.surface;
  auto name = [&](std::int32_t o) { return scene.objects[static_cast<std::size_t>(o)].name; };
  std::ostringstream line;
  line << std::setprecision(4) << "verify (every " << verify_every << " steps, " << verify_max.checks
       << " checks): deepest surface vertex " << verify_max.surface_depth.value << " median edges";
  if (w.vertex >= 0)
    line << " (step " << verify_max.surface_depth.step << ": vertex " << w.vertex << " of " << name(w.object)
         << " in " << name(w.in_object) << ")";
  line << ", at most " << verify_max.surface_count.value << " inside; checks deeper than 0.005 / 0.01 / 0.02: "
       << verify_max.checks_deeper_than(0.005) << " / " << verify_max.checks_deeper_than(0.01) << " / "
       << verify_max.checks_deeper_than(0.02) << " (median " << verify_max.surface_depth_quantile(0.5)
       << "); vertex-checks deeper than 0.005: " << verify_max.deep_by_record[kNoRecord] << " with no record, "
       << verify_max.deep_by_record[kCapped] << " capped by the separation speed, "
       << verify_max.deep_by_record[kUnderClosed] << " closed < 90 %, " << verify_max.deep_by_record[kClosed]
       << " closed along d; interior vertices "
       << verify_max.interior_depth.value << "; in their own body " << verify_max.self_depth.value
       << " (at most " << verify_max.self_count.value << "), edges through their own surface "
       << verify_max.self_crossing_depth.value << "; crossings at most " << verify_max.crossings.value << " ("
       << verify_max.crossings_without_inside_vertex.value << " with no vertex inside), deepest "
       << verify_max.crossing_depth.value << "; inverted tets at most " << verify_max.inverted.value
       << "; speed at most " << verify_max.speed_ratio.value << " x free fall";
  if (verify_max.fastest_vertex >= 0)
    line << " (step " << verify_max.max_speed.step << ": vertex " << verify_max.fastest_vertex << ")";
  line << "\n";
  log << line.str();
  std::ostringstream js;
  js << "{\"every\": " << verify_every << ", \"first_step\": " << first << ", \"last_step\": " << last
     << ", \"maxima\": " << to_json(verify_max) << "}\n";
  std::ofstream json(dir / "verify_steps.json", std::ios::trunc);
  json << js.str();
  if (!json.flush()) throw RuntimeFailure("cannot write '" + json_path + "'");
}

}  // namespace

// `run` and `bench` hold only the meshes of the objects each rank owns or ghosts: copies
// of multi-copy entries are made when needed (docs/architecture.md, "Who holds which mesh").
// The ranks share the stable step's per-object frequencies (SceneLimits::sum).
namespace {
// Adds a vector over the ranks of comm (the `sum` of the passes shared over ranks).
std::function<void(std::vector<double>&)> sum_over(MPI_Comm comm) {
  return [comm](std::vector<double>& v) {
    MPI_Allreduce(MPI_IN_PLACE, v.data(), static_cast<int>(v.size()), MPI_DOUBLE, MPI_SUM, comm);
  };
}
}  // namespace

SceneLimits copies_made_on_demand(MPI_Comm comm) {
  SceneLimits l;
  l.hold_copy_meshes = false;
  l.part = comm_rank(comm);
  l.parts = comm_size(comm);
  l.sum = sum_over(comm);
  l.gather = [comm](const std::vector<double>& mine) { return allgather_doubles(comm, mine); };
  l.broadcast = [comm](std::vector<char>& bytes, int root) { broadcast_bytes(comm, root, bytes); };
  l.scatter = [comm](const std::vector<double>& all, const std::vector<int>& counts, int root) {
    return scatter_doubles(comm, root, all, counts);
  };
  return l;
}

Scene load_restart(MPI_Comm comm, const std::string& path, RestartPoint& restart, const SceneLimits& limits) {
  restart.path = resolve_checkpoint(path);
  restart.info = read_checkpoint_info(comm, restart.path);
  const CheckpointInfo& info = restart.info;
  Scene scene = load_scene_from_string(info.scene_text, info.scene_path, limits);
  checkpoint::check_against_scene(info, scene, restart.path,
                                  scene.object_digests(comm_rank(comm), comm_size(comm), sum_over(comm)));
  Simulation& sim = scene.sim;
  sim.steps = info.steps;
  sim.end_time.reset();
  sim.output_every = info.output_every;
  sim.output_interval = 0;
  // A checkpoint inside a run's output directory continues that directory, wherever it
  // has been moved or copied to since; elsewhere, the directory it was written for.
  const fs::path parent = fs::absolute(restart.path).lexically_normal().parent_path();
  sim.output_dir = parent.filename() == "checkpoints" ? parent.parent_path().string() : info.output_dir;
  restart.output_dir = sim.output_dir;
  return scene;
}

RunSummary run_scene(MPI_Comm comm, const Scene& scene, const RunOptions& opt, std::ostream& log,
                     const RestartPoint* restart) {
  const int rank = comm_rank(comm), nranks = comm_size(comm);
  const Simulation& sim = scene.sim;
  const std::int64_t nsteps = total_steps(sim);
  const std::int64_t every = steps_between_frames(sim);
  const CheckpointPolicy ckpt{opt.checkpoint_every ? *opt.checkpoint_every : sim.checkpoint_every,
                              60 * (opt.checkpoint_minutes ? *opt.checkpoint_minutes : sim.checkpoint_minutes)};
  const std::int64_t first = restart ? restart->info.step : 0;
  if (first > nsteps)
    throw InputError(restart->path, 0,
                     "the checkpoint is at step " + std::to_string(first) + ", past the run's end at step " +
                         std::to_string(nsteps) + ": give --steps or --end-time beyond it");

  // A restart continues in its own output directory unless told to start another one.
  const fs::path dir = fs::absolute(sim.output_dir).lexically_normal();
  const bool continuing = restart && fs::absolute(restart->output_dir).lexically_normal() == dir;
  if (!continuing) check_output_dir(comm, sim.output_dir, opt.overwrite);

  std::vector<int> partition;
  SplitHosts hosts;  // where a new partition put the split objects' parts
  std::optional<EdgeStatistics> edges;  // computed here for a new partition, handed on
  if (restart) {
    const CheckpointInfo& info = restart->info;
    bool same = info.ranks == nranks && info.partition.size() == scene.objects.size();
    for (int r : info.partition) same = same && r >= 0 && r < nranks;
    if (same) {
      partition = info.partition;
    } else {
      // The graph's least reach, as the Simulator's (initial_partition).
      edges = scene_edge_statistics(comm, scene);
      partition =
          partition_at(scene, info.boxes, nranks, {}, comm, &hosts, collision_settings_for(scene, edges->mean).cell_size);
    }
    // The same rank count: the parts where they were. Hosts only place work, never
    // change a result: where they do not fit (a checkpoint without them, or a split
    // turned off since), the Simulator's split_hosts fallback places the parts.
    if (same && split_hosts_fit(scene, partition, nranks, info.split_hosts)) hosts = info.split_hosts;
  }
  // Before the Simulator drops the meshes this rank does not need (whole-scene passes
  // would make them again): the fingerprint checkpoints carry, the failure guard's scales.
  // Each rank digests and measures every nranks-th object (a copy placed for it), one
  // MPI_Allreduce each combines them: no rank makes every mesh.
  const std::uint64_t fingerprint = scene_fingerprint(scene, scene.object_digests(rank, nranks, sum_over(comm)));
  const GuardScales guard_scale = guard_scales(scene, rank, nranks, sum_over(comm));
  Simulator simulator(comm, scene, partition, hosts, edges);
  if (restart) {
    StepState state;
    read_checkpoint_state(comm, restart->path, restart->info, simulator.world(), state);
    simulator.restore(state);
  }
  const std::int64_t rebuilds0 = simulator.ghost_rebuilds(), repartitions0 = simulator.repartitions();
  if (rank == 0 && !restart && simulator.initial_overlaps() > 0)
    std::cerr << scene.path << ": warning: " << simulator.initial_overlaps()
              << " vertices start inside other objects (deepest " << simulator.initial_overlap_depth()
              << " m); the first step pushes them out within one time step, which is violent for deep "
                 "overlaps: move the objects apart\n";

  // Everything is validated: only now touch the file system.
  RunSummary summary;
  summary.first_step = first;
  const fs::path shown(sim.output_dir);  // as the user gave it, for messages
  summary.h5 = (shown / kFramesH5).string();
  summary.xdmf = (shown / kFramesXdmf).string();
  summary.csv = (shown / kDiagnosticsCsv).string();
  if (!continuing) prepare_output_dir(comm, rank, scene, dir);

  World& world = simulator.world();
  std::unique_ptr<FrameWriter> writer =
      continuing ? std::make_unique<FrameWriter>(comm, summary.h5, summary.xdmf, world, first)
                 : std::make_unique<FrameWriter>(comm, summary.h5, summary.xdmf, scene, world);
  DiagnosticsCsv csv;
  if (rank == 0) {
    if (continuing) csv.resume(summary.csv, first);
    else csv.open(summary.csv);
  }

  // A failure: every rank throws the same message, with where to go on from.
  FailureGuard guard(scene, guard_scale, dir.string(), restart != nullptr, restart ? restart->info.energy0 : 0,
                     restart ? restart->info.energy_scale : 0);
  guard.watch_frames(writer.get());
  if (continuing) guard.checkpoint_written(restart->path, first);
  std::int64_t step = first;

  // In-run checks (--verify-every N): the check of softcontact verify after every N-th
  // step, kept as running maxima; a frame at the same step takes its residual from it.
  const std::int64_t verify_every = opt.verify_every ? *opt.verify_every : 0;
  VerifyMaxima verify_max;
  VerifyFrame checked;
  std::int64_t checked_step = -1;
  auto verify_step = [&] {
    checked = simulator.verify(true);
    checked_step = step;
    verify_max.add(checked);
  };

  // A frame, its diagnostics row, and the guard's checks on them.
  auto record = [&] {
    const double t0 = now();
    StepDiagnostics d;
    simulator.measure(d, checked_step == step ? &checked : nullptr);
    writer->write_frame(d.step, d.time, world,
                        {{"contact_forces", "contact_force", 3, simulator.contact_force().data()},
                         {"penetration", "penetration", 3, simulator.penetration().data()}});
    std::int64_t steps = 0;
    PhaseTimes acc = simulator.take_times(steps);
    acc.output += now() - t0;
    d.seconds = steps > 0 ? acc.scaled(1.0 / static_cast<double>(steps)) : acc;
    if (rank == 0) csv.write(d);
    guard.check_frame(step, d, simulator);
  };

  auto write_ckpt = [&] {
    // Never checkpoint a state the guard would reject.
    const std::string bad = simulator.check_inversions(sim.max_inverted_fraction);
    if (!bad.empty()) guard.fail(step, simulator.time(), bad);
    const double t0 = now();
    CheckpointInfo info;
    info.time = simulator.time();
    info.dt = sim.dt;
    info.partition = simulator.partition();
    info.boxes = simulator.current_boxes();  // collective
    info.split_hosts = simulator.split_hosts();
    info.steps = nsteps;
    info.output_every = every;
    info.frames = writer->frames_written();
    info.fingerprint = fingerprint;
    info.energy0 = guard.energy0();
    info.energy_scale = guard.energy_scale();
    info.scene_path = fs::absolute(scene.path).lexically_normal().string();
    info.scene_text = scene.text;
    info.output_dir = dir.string();
    const std::string path = checkpoint_path(dir.string(), step);
    write_checkpoint(comm, path, simulator.world(), simulator.snapshot(), info);
    if (rank == 0) prune_checkpoints(dir.string(), sim.checkpoint_keep);
    guard.checkpoint_written(path, step);
    if (rank == 0 && !opt.quiet)
      log << "checkpoint: " << path << " (step " << step << ", " << std::setprecision(3) << now() - t0 << " s)\n"
          << std::flush;
  };

  if (!continuing) {
    if (verify_every > 0) verify_step();
    record();
  }

  const StopSignals signals;
  Progress progress(log, rank == 0 && !opt.quiet, nsteps, sim.dt);
  const double wall0 = now();
  double since_checkpoint = now();
  int stop_signal = 0;
  while (step < nsteps) {
    simulator.step();
    ++step;
    if (fault::hit(fault::Point::step, step) && world.n_owned > 0)  // a numerical failure on this rank
      world.x[0] = std::numeric_limits<double>::quiet_NaN();
    if (verify_every > 0 && step % verify_every == 0) verify_step();
    if (step % every == 0 || step == nsteps) record();
    // One reduction a step: a stop signal on any rank, the health of every rank's
    // vertices and implicit solves, and the wall time since the last checkpoint (rank clocks differ).
    double flags[3] = {static_cast<double>(g_signal), static_cast<double>(simulator.local_health(guard.max_speed())),
                       now() - since_checkpoint};
    MPI_Allreduce(MPI_IN_PLACE, flags, 3, MPI_DOUBLE, MPI_MAX, comm);
    if (flags[1] > 0)
      guard.fail(step, simulator.time(), simulator.diagnose(static_cast<int>(flags[1]), guard.max_speed()), flags[1] >= 3);
    stop_signal = static_cast<int>(flags[0]);
    if (ckpt.due(step, nsteps, flags[2], stop_signal != 0)) {
      write_ckpt();
      since_checkpoint = now();
    }
    if (stop_signal != 0) break;
    progress.update(step);
  }
  writer->close();
  if (verify_every > 0 && rank == 0) {
    summary.verify_json = (shown / "verify_steps.json").string();
    report_in_run_checks(scene, verify_max, verify_every, first, step, dir, summary.verify_json, log);
  }
  summary.peak_rss = peak_rss_bytes();
  MPI_Allreduce(MPI_IN_PLACE, &summary.peak_rss, 1, MPI_DOUBLE, MPI_MAX, comm);
  summary.steps = step - first;
  summary.sim_time = simulator.time();
  summary.wall_seconds = now() - wall0;
  summary.frames = writer->frames_written();
  summary.last_checkpoint = guard.last_checkpoint();
  summary.ghost_rebuilds = simulator.ghost_rebuilds() - rebuilds0;
  summary.repartitions = simulator.repartitions() - repartitions0;
  summary.split_objects = simulator.split_objects();
  summary.split_ranks = simulator.split_ranks();
  summary.split_hosts = simulator.split_hosts();
  if (stop_signal != 0) summary.stopped_by = signal_name(stop_signal);
  return summary;
}

}  // namespace softcontact
