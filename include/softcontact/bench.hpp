#pragma once
// The scene benchmark (`softcontact bench`): a scene run for a fixed number of steps with
// no frame output, timed per step and per phase of Algorithm 1 (PhaseTimes), with the
// colliding points of every step. Summaries are medians and means over the timed steps
// (the machines it runs on are shared and noisy: medians are the figures to quote).
//
// Timings are wall-clock seconds, the largest over the ranks for each step and phase (a
// step is as slow as its slowest rank); collision counts are summed over the ranks.
// Nothing here changes the simulation: it is Simulator::step() in a loop.
#include <mpi.h>

#include <cstdint>
#include <fstream>
#include <iosfwd>
#include <string>
#include <vector>

#include "softcontact/diagnostics.hpp"
#include "softcontact/scene.hpp"

namespace softcontact {

struct BenchOptions {
  std::int64_t steps = 100;  ///< timed steps (> 0)
  std::int64_t warmup = 0;   ///< untimed steps before them (>= 0)
  bool quiet = false;        ///< no progress lines
  /// Wall seconds this rank spent reading the scene (load_scene) before run_bench, from a
  /// barrier: reported as the max over ranks (0: not measured).
  double read_seconds = 0;
  /// The C heap in use on this rank before and after reading the scene [bytes]
  /// (heap_in_use_bytes; -1: not measured), reported as the max over ranks.
  double heap_before_read = -1, heap_after_read = -1;
};

/// One timed step.
struct BenchStep {
  std::int64_t step = 0;         ///< 1-based index of the step since t = 0 (warm-up included)
  double time = 0;               ///< simulated time after the step [s]
  std::int64_t collisions = 0;   ///< colliding points (CollisionStats::colliding_points), all ranks
  std::int64_t records = 0;      ///< collision records (a point inside two bodies counts twice)
  PhaseTimes seconds;            ///< per phase [s], max over ranks
  double wall = 0;               ///< the whole Simulator::step() [s], max over ranks
  /// What no phase holds (rebalance checks, migration, bookkeeping): wall minus the phases
  /// on each rank, then the max over ranks [s] (never negative, unlike the difference of
  /// the maxima).
  double other = 0;
};

/// One stage of the Simulator's construction: its wall seconds, max and min over the
/// ranks (a wait at a collective inside the stage counts: a large max with a small min is
/// ranks waiting for the slowest).
struct SetupStage {
  std::string name;
  double max_seconds = 0, min_seconds = 0;
  double max_heap_bytes = -1, min_heap_bytes = -1;  ///< the C heap in use at its end, max and min over ranks (-1: unknown)
};

/// Median and mean over the timed steps of one quantity.
struct Spread {
  double median = 0, mean = 0;
};

struct BenchResult {
  std::string scene;   ///< the scene file's stem ("tori200")
  std::string path;    ///< the scene file
  int ranks = 1, threads = 1;
  std::size_t objects = 0, vertices = 0, tets = 0;
  double dt = 0;
  std::int64_t warmup = 0;
  std::vector<BenchStep> steps;  ///< the timed steps, identical on every rank
  double setup_seconds = 0;      ///< building the Simulator (max over ranks)
  double read_seconds = 0;       ///< reading the scene before it (max over ranks; 0: not measured)
  std::int64_t files_read_max = 0;  ///< mesh files read by a rank from its start to the bench's end (max over ranks)
  std::int64_t files_read_sum = 0;  ///< the same over all ranks
  /// The Simulator's construction by stage (Simulator::setup_stages), max and min over ranks.
  std::vector<SetupStage> setup_stages;
  double loop_seconds = 0;       ///< wall time of the timed steps, barrier to barrier
  double rss_max_mib = 0, rss_mean_mib = 0;  ///< peak resident memory per rank (ru_maxrss)
  /// The C heap in use (heap_in_use_bytes) before and after reading the scene, max over
  /// ranks [bytes] (-1: not measured); after each set-up stage: setup_stages.
  double heap_before_read_max = -1, heap_after_read_max = -1;
  /// The heap in use when the set-up ended (its last stage's, max over ranks) [bytes].
  double heap_setup_max() const { return setup_stages.empty() ? -1 : setup_stages.back().max_heap_bytes; }
  std::string omp_wait_policy;   ///< the OMP_WAIT_POLICY environment variable, or "default"
  /// Halo traffic: bytes received per timed step by one rank (max and mean over ranks).
  double halo_bytes_max = 0, halo_bytes_mean = 0;
  double halo_rounds_max = 0;  // rounds of neighbour messages per step (Halo::rounds), max rank
  /// Load imbalance: max over ranks / mean of the compute seconds (forces, integration,
  /// detection, depth: the phases without communication) of the timed steps.
  double compute_imbalance = 1;
  /// The same from process CPU seconds of forces, detection and depth (PhaseTimes::work_cpu,
  /// what the rebalance weighs): meaningful also when ranks share cores.
  double cpu_imbalance = 1;
  /// Per phase, a rank's own seconds per timed step (its phase times summed over the
  /// timed steps / steps), the largest and the mean over ranks: which phase one rank
  /// holds the others up in (a phase's time includes that rank's waits inside it). The
  /// max is at most the mean over steps of `seconds` (each step's max over ranks).
  PhaseTimes phase_rank_max, phase_rank_mean;
  /// Collision records whose triangle lies on another rank's object / all records.
  double cross_rank_fraction = 0;
  /// The partition at the end of the timed steps by the static weights the initial
  /// partition balances (partition_loads, rebalance.hpp): max / mean over ranks of the
  /// work (tets) and of the memory the owners hold (the memory model's owned state).
  double static_work_imbalance = 1, static_memory_imbalance = 1;
  /// Objects split for their forces (at the end), and their exchanges: bytes sent per
  /// timed step by one rank (max over ranks), tets a rank evaluates for another rank's
  /// object (max over ranks).
  int split_objects = 0;
  double split_bytes_max = 0;
  double split_bytes_sum = 0;  ///< the same, summed over the ranks
  std::int64_t split_helped_tets_max = 0;
  /// The split objects' part meshes (and parts handed to a new owner) sent since the
  /// Simulator was made: at set-up and after each migration, not per step (Simulator::
  /// split_part_bytes_sent); max over ranks and sum.
  double split_part_bytes_max = 0, split_part_bytes_sum = 0;
  /// At the end, over all ranks: parts of split objects evaluated off their owner, and of
  /// those the ones reading the positions from ghost rows (split_forces.hpp).
  int split_helping_parts = 0, split_parts_from_ghosts = 0;
  std::int64_t ghost_rebuilds = 0;  ///< ghost-set rebuilds during the timed steps (rank 0)
  /// Object boxes received per ghost-set test during the timed steps (max over ranks; 0
  /// without a test): what the test costs a rank, against every object of the scene
  /// before it exchanged boxes between neighbours only.
  double ghost_boxes_max = 0;
  std::int64_t ghost_tests = 0;     ///< ghost-set tests during the timed steps (rank 0; the same on every rank)
  /// With edge contacts: timed steps in which the edge search found its candidate pairs
  /// again (the skin used up; rank 0), and the pairs held per step (mean over steps, sum
  /// over ranks).
  std::int64_t edge_pair_searches = 0;
  double edge_pairs_mean = 0;

  // Summaries of `steps` (filled by run_bench; summarise() recomputes them).
  Spread collisions;
  std::int64_t collisions_max = 0;
  Spread forces, integrate, detect, depth, contact, comm, output, phases, total;

  double steps_per_second() const {
    return loop_seconds > 0 ? static_cast<double>(steps.size()) / loop_seconds : 0.0;
  }
  void summarise();
};

/// Median of `v` (the mean of the two middle values for an even count; 0 when empty).
double median_of(std::vector<double> v);
/// Arithmetic mean of `v` (0 when empty).
double mean_of(const std::vector<double>& v);

/// Builds a Simulator for `scene` and runs opt.warmup + opt.steps steps. Collective over
/// `comm`; progress lines (at most one per 10 s) go to `log` on rank 0 unless opt.quiet.
BenchResult run_bench(MPI_Comm comm, const Scene& scene, const BenchOptions& opt, std::ostream& log);

/// The human-readable table.
void print_bench_table(std::ostream& out, const BenchResult& r);

/// One row per run; bench_csv_header() is its first line (docs/benchmarks.md lists the
/// columns).
std::string bench_csv_header();
std::string bench_csv_row(const BenchResult& r);

/// One row per timed step: step,time,collisions,records, the phases in ms, total_ms.
std::string per_step_csv_header();
void write_per_step_csv(std::ostream& out, const BenchResult& r);

/// The files of --csv (appended to; its header is written when the file is new or empty)
/// and --per-step (replaced), either may be empty. Opened by rank 0 in the constructor,
/// before the run, so that a bad path or a CSV with other columns is bad input (InputError,
/// on every rank) rather than a failure after minutes of stepping. Collective.
class BenchFiles {
public:
  BenchFiles(MPI_Comm comm, const std::string& csv, const std::string& per_step);
  /// Writes the row and the per-step rows (rank 0; a no-op elsewhere). Throws
  /// RuntimeFailure when a write fails.
  void write(const BenchResult& r);

private:
  std::string csv_path_, per_step_path_;
  std::ofstream csv_, per_step_;
  bool header_needed_ = false;
};

}  // namespace softcontact
