#include "softcontact/bench.hpp"

#include <omp.h>
#include <sys/resource.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <filesystem>
#include <iomanip>
#include <limits>
#include <numeric>
#include <ostream>
#include <sstream>

#include "softcontact/error.hpp"
#include "softcontact/mesh_io.hpp"
#include "softcontact/mpi_util.hpp"
#include "softcontact/simulator.hpp"

namespace softcontact {

namespace {

// The seven phases of PhaseTimes, in table order, with their names in the table and
// the CSV columns.
struct PhaseColumn {
  const char* label;
  const char* column;
  double PhaseTimes::* member;
  Spread BenchResult::* spread;
};

constexpr PhaseColumn kPhases[] = {
    {"forces", "forces", &PhaseTimes::forces, &BenchResult::forces},
    {"integration", "integrate", &PhaseTimes::integrate, &BenchResult::integrate},
    {"detection", "detect", &PhaseTimes::detect, &BenchResult::detect},
    {"penetration depth", "depth", &PhaseTimes::depth, &BenchResult::depth},
    {"contact response", "response", &PhaseTimes::contact, &BenchResult::contact},
    {"communication", "comm", &PhaseTimes::comm, &BenchResult::comm},
    {"output", "output", &PhaseTimes::output, &BenchResult::output},
};
constexpr int kNumPhases = sizeof kPhases / sizeof kPhases[0];

Spread spread_of(const std::vector<double>& v) { return {median_of(v), mean_of(v)}; }

/// Peak resident set size of this process [MiB] (Linux reports ru_maxrss in KiB).
double peak_rss_mib() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return static_cast<double>(u.ru_maxrss) / 1024.0;
}

std::string utc_now() {
  const std::time_t t = std::time(nullptr);
  std::tm tm{};
  gmtime_r(&t, &tm);
  char buf[32];
  std::strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%SZ", &tm);
  return buf;
}

/// A CSV field: quoted when it holds a comma, a quote or a line break.
std::string csv_field(const std::string& s) {
  if (s.find_first_of(",\"\n\r") == std::string::npos) return s;
  std::string q = "\"";
  for (char c : s) q += c == '"' ? std::string("\"\"") : std::string(1, c);
  return q + "\"";
}

std::string num(double x, int digits = 6) {
  std::ostringstream s;
  s << std::setprecision(digits) << x;
  return s.str();
}

std::string fixed(double x, int decimals) {
  std::ostringstream s;
  s << std::fixed << std::setprecision(decimals) << x;
  return s.str();
}

}  // namespace

double median_of(std::vector<double> v) {
  if (v.empty()) return 0;
  const std::size_t h = v.size() / 2;
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(h), v.end());
  const double upper = v[h];
  if (v.size() % 2 == 1) return upper;
  const double lower = *std::max_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(h));
  return 0.5 * (lower + upper);
}

double mean_of(const std::vector<double>& v) {
  if (v.empty()) return 0;
  return std::accumulate(v.begin(), v.end(), 0.0) / static_cast<double>(v.size());
}

void BenchResult::summarise() {
  const std::size_t n = steps.size();
  std::vector<double> c(n), sum(n), wall(n);
  collisions_max = 0;
  for (std::size_t i = 0; i < n; ++i) {
    c[i] = static_cast<double>(steps[i].collisions);
    collisions_max = std::max(collisions_max, steps[i].collisions);
    sum[i] = steps[i].seconds.total();
    wall[i] = steps[i].wall;
  }
  collisions = spread_of(c);
  for (const PhaseColumn& p : kPhases) {
    std::vector<double> v(n);
    for (std::size_t i = 0; i < n; ++i) v[i] = steps[i].seconds.*(p.member);
    this->*(p.spread) = spread_of(v);
  }
  phases = spread_of(sum);
  total = spread_of(wall);
}

BenchResult run_bench(MPI_Comm comm, const Scene& scene, const BenchOptions& opt, std::ostream& log) {
  if (opt.steps < 1) throw InputError("command line: --steps expects a positive integer");
  if (opt.warmup < 0) throw InputError("command line: --warmup expects a non-negative integer");
  const int rank = comm_rank(comm), size = comm_size(comm);

  BenchResult r;
  r.path = scene.path;
  r.scene = std::filesystem::path(scene.path).stem().string();
  r.ranks = size;
  r.threads = omp_get_max_threads();
  r.objects = scene.objects.size();
  r.vertices = scene.num_vertices();
  r.tets = scene.num_tets();
  r.dt = scene.sim.dt;
  r.warmup = opt.warmup;
  const char* policy = std::getenv("OMP_WAIT_POLICY");
  r.omp_wait_policy = policy && *policy ? policy : "default";

  MPI_Barrier(comm);
  double t0 = MPI_Wtime();
  Simulator sim(comm, scene);
  double setup = MPI_Wtime() - t0;

  const std::int64_t n = opt.steps, total_steps = opt.warmup + opt.steps;
  // Per timed step: the seven phases and the wall time (max over ranks), and the
  // colliding points and records (summed over ranks). Reduced once, after the loop, so
  // that the benchmark adds no communication to the steps it times.
  constexpr int kD = kNumPhases + 2;  // the phases, the step's wall time, its "other"
  std::vector<double> secs(static_cast<std::size_t>(kD * n), 0.0);
  std::vector<std::int64_t> counts(static_cast<std::size_t>(2 * n), 0);

  const double start = MPI_Wtime();
  double last_report = start, loop_start = start;
  std::int64_t unused = 0, bytes0 = 0, rounds0 = 0, split0 = 0, rebuilds0 = 0, tests0 = 0, boxes0 = 0, cross = 0, records = 0, edge_searches = 0, edge_pairs = 0;
  double compute = 0, compute_cpu = 0;
  for (std::int64_t k = 1; k <= total_steps; ++k) {
    const bool timed = k > opt.warmup;
    if (k == opt.warmup + 1) {
      MPI_Barrier(comm);
      sim.take_times(unused);  // drop the warm-up's accumulated times
      bytes0 = sim.halo_bytes();
      rounds0 = sim.halo_rounds();
      split0 = sim.split_bytes_sent();
      rebuilds0 = sim.ghost_rebuilds();
      tests0 = sim.ghost_reach_tests();
      boxes0 = sim.ghost_boxes_received();
      loop_start = MPI_Wtime();
    }
    const double s0 = MPI_Wtime();
    sim.step();
    const double wall = MPI_Wtime() - s0;
    const PhaseTimes p = sim.take_times(unused);  // this step alone
    if (timed) {
      const std::size_t i = static_cast<std::size_t>(k - opt.warmup - 1);
      for (int c = 0; c < kNumPhases; ++c) secs[kD * i + c] = p.*(kPhases[c].member);
      secs[kD * i + kNumPhases] = wall;
      secs[kD * i + kNumPhases + 1] = std::max(0.0, wall - p.total());
      counts[2 * i] = sim.collision_stats().colliding_points;
      counts[2 * i + 1] = sim.collision_stats().collisions;
      compute += p.forces + p.integrate + p.detect + p.depth;
      compute_cpu += p.work_cpu;
      cross += sim.cross_rank_collisions();
      records += sim.collision_stats().collisions;
      edge_searches += sim.collision_stats().edge_pair_searches;
      edge_pairs += sim.collision_stats().edge_pairs;
    }
    if (rank == 0 && !opt.quiet) {
      const double now = MPI_Wtime();
      if (now - last_report >= 10.0 || k == total_steps) {
        last_report = now;
        char buf[200];
        std::snprintf(buf, sizeof buf, "bench: step %lld / %lld (%s), t = %.4g s, %.2f steps/s, %lld colliding points",
                      static_cast<long long>(k), static_cast<long long>(total_steps), timed ? "timed" : "warm-up",
                      sim.time(), static_cast<double>(k) / std::max(now - start, 1e-9),
                      static_cast<long long>(sim.collision_stats().colliding_points));
        log << buf << '\n' << std::flush;
      }
    }
  }
  MPI_Barrier(comm);
  r.loop_seconds = MPI_Wtime() - loop_start;
  {
    // A failed implicit solve leaves its object behind without a word (the run loop
    // checks every step; timing here adds no communication to the steps): say so.
    int failed = sim.local_health(std::numeric_limits<double>::infinity()) >= 3 ? 3 : 0;
    MPI_Allreduce(MPI_IN_PLACE, &failed, 1, MPI_INT, MPI_MAX, comm);
    if (failed) throw NumericalFailure("bench: " + sim.diagnose(failed, 0) + "; the timings would be meaningless");
  }
  {
    const double bytes = static_cast<double>(sim.halo_bytes() - bytes0) / static_cast<double>(n);
    double bmax = bytes, bsum = bytes, cmax = compute, csum = compute, umax = compute_cpu, usum = compute_cpu;
    MPI_Allreduce(MPI_IN_PLACE, &bmax, 1, MPI_DOUBLE, MPI_MAX, comm);
    MPI_Allreduce(MPI_IN_PLACE, &bsum, 1, MPI_DOUBLE, MPI_SUM, comm);
    MPI_Allreduce(MPI_IN_PLACE, &cmax, 1, MPI_DOUBLE, MPI_MAX, comm);
    MPI_Allreduce(MPI_IN_PLACE, &csum, 1, MPI_DOUBLE, MPI_SUM, comm);
    MPI_Allreduce(MPI_IN_PLACE, &umax, 1, MPI_DOUBLE, MPI_MAX, comm);
    MPI_Allreduce(MPI_IN_PLACE, &usum, 1, MPI_DOUBLE, MPI_SUM, comm);
    std::int64_t cr[2] = {cross, records};
    MPI_Allreduce(MPI_IN_PLACE, cr, 2, MPI_INT64_T, MPI_SUM, comm);
    double rounds = static_cast<double>(sim.halo_rounds() - rounds0) / static_cast<double>(n);
    MPI_Allreduce(MPI_IN_PLACE, &rounds, 1, MPI_DOUBLE, MPI_MAX, comm);
    r.halo_rounds_max = rounds;
    r.halo_bytes_max = bmax;
    r.halo_bytes_mean = bsum / size;
    r.compute_imbalance = csum > 0 ? cmax / (csum / size) : 1;
    r.cpu_imbalance = usum > 0 ? umax / (usum / size) : 1;
    r.cross_rank_fraction = cr[1] > 0 ? static_cast<double>(cr[0]) / static_cast<double>(cr[1]) : 0;
    const PartitionLoads loads = partition_loads(scene, sim.partition(), sim.split_hosts(), size);
    r.static_work_imbalance = loads.work_imbalance;
    r.static_memory_imbalance = loads.memory_imbalance;
    r.ghost_rebuilds = sim.ghost_rebuilds() - rebuilds0;
    const std::int64_t tests = sim.ghost_reach_tests() - tests0;
    r.ghost_tests = tests;
    double boxes = tests > 0 ? static_cast<double>(sim.ghost_boxes_received() - boxes0) / static_cast<double>(tests) : 0;
    MPI_Allreduce(MPI_IN_PLACE, &boxes, 1, MPI_DOUBLE, MPI_MAX, comm);
    r.ghost_boxes_max = boxes;
    double split[3] = {static_cast<double>(sim.split_bytes_sent() - split0) / static_cast<double>(n),
                       static_cast<double>(sim.split_helped_tets()), static_cast<double>(sim.split_part_bytes_sent())};
    double split_sum[2] = {split[0], split[2]};
    MPI_Allreduce(MPI_IN_PLACE, split, 3, MPI_DOUBLE, MPI_MAX, comm);
    MPI_Allreduce(MPI_IN_PLACE, split_sum, 2, MPI_DOUBLE, MPI_SUM, comm);
    r.split_objects = sim.split_objects();
    r.split_bytes_max = split[0];
    r.split_bytes_sum = split_sum[0];
    r.split_helped_tets_max = static_cast<std::int64_t>(split[1]);
    r.split_part_bytes_max = split[2];
    r.split_part_bytes_sum = split_sum[1];
    int parts[2] = {sim.split_helping_parts(), sim.split_parts_from_ghosts()};
    MPI_Allreduce(MPI_IN_PLACE, parts, 2, MPI_INT, MPI_SUM, comm);
    r.split_helping_parts = parts[0];
    r.split_parts_from_ghosts = parts[1];
    MPI_Allreduce(MPI_IN_PLACE, &edge_pairs, 1, MPI_INT64_T, MPI_SUM, comm);
    r.edge_pair_searches = edge_searches;
    r.edge_pairs_mean = n > 0 ? static_cast<double>(edge_pairs) / static_cast<double>(n) : 0;
  }

  {
    // Each rank's phase totals before the per-step max over ranks below.
    double mine[kNumPhases] = {}, most[kNumPhases] = {}, all[kNumPhases] = {};
    for (std::int64_t i = 0; i < n; ++i)
      for (int c = 0; c < kNumPhases; ++c) mine[c] += secs[static_cast<std::size_t>(kD * i + c)];
    MPI_Allreduce(mine, most, kNumPhases, MPI_DOUBLE, MPI_MAX, comm);
    MPI_Allreduce(mine, all, kNumPhases, MPI_DOUBLE, MPI_SUM, comm);
    for (int c = 0; c < kNumPhases; ++c) {
      r.phase_rank_max.*(kPhases[c].member) = most[c] / static_cast<double>(n);
      r.phase_rank_mean.*(kPhases[c].member) = all[c] / static_cast<double>(n) / size;
    }
  }
  MPI_Allreduce(MPI_IN_PLACE, secs.data(), static_cast<int>(secs.size()), MPI_DOUBLE, MPI_MAX, comm);
  MPI_Allreduce(MPI_IN_PLACE, counts.data(), static_cast<int>(counts.size()), MPI_INT64_T, MPI_SUM, comm);
  double loop = r.loop_seconds;
  MPI_Allreduce(MPI_IN_PLACE, &loop, 1, MPI_DOUBLE, MPI_MAX, comm);
  r.loop_seconds = loop;
  double setup_read[2] = {setup, opt.read_seconds};
  MPI_Allreduce(MPI_IN_PLACE, setup_read, 2, MPI_DOUBLE, MPI_MAX, comm);
  r.setup_seconds = setup_read[0];
  r.read_seconds = setup_read[1];
  std::int64_t files[2] = {static_cast<std::int64_t>(mesh_files_read()), static_cast<std::int64_t>(mesh_files_read())};
  MPI_Allreduce(MPI_IN_PLACE, &files[0], 1, MPI_INT64_T, MPI_MAX, comm);
  MPI_Allreduce(MPI_IN_PLACE, &files[1], 1, MPI_INT64_T, MPI_SUM, comm);
  r.files_read_max = files[0];
  r.files_read_sum = files[1];
  // The same stages on every rank, in the same order: their seconds, then the heap at
  // their ends and before and after the scene was read; max and min over the ranks.
  const std::size_t ns = sim.setup_stages().size();
  std::vector<double> stage_max, stage_min;
  for (const auto& st : sim.setup_stages()) stage_max.push_back(st.second);
  stage_max.insert(stage_max.end(), sim.setup_heap().begin(), sim.setup_heap().end());
  stage_max.push_back(opt.heap_before_read);
  stage_max.push_back(opt.heap_after_read);
  stage_min = stage_max;
  MPI_Allreduce(MPI_IN_PLACE, stage_max.data(), static_cast<int>(stage_max.size()), MPI_DOUBLE, MPI_MAX, comm);
  MPI_Allreduce(MPI_IN_PLACE, stage_min.data(), static_cast<int>(stage_min.size()), MPI_DOUBLE, MPI_MIN, comm);
  for (std::size_t i = 0; i < ns; ++i)
    r.setup_stages.push_back(
        {sim.setup_stages()[i].first, stage_max[i], stage_min[i], stage_max[ns + i], stage_min[ns + i]});
  r.heap_before_read_max = stage_max[2 * ns];
  r.heap_after_read_max = stage_max[2 * ns + 1];
  const double rss = peak_rss_mib();
  double rss_max = rss, rss_sum = rss;
  MPI_Allreduce(MPI_IN_PLACE, &rss_max, 1, MPI_DOUBLE, MPI_MAX, comm);
  MPI_Allreduce(MPI_IN_PLACE, &rss_sum, 1, MPI_DOUBLE, MPI_SUM, comm);
  r.rss_max_mib = rss_max;
  r.rss_mean_mib = rss_sum / size;

  r.steps.resize(static_cast<std::size_t>(n));
  for (std::size_t i = 0; i < r.steps.size(); ++i) {
    BenchStep& s = r.steps[i];
    s.step = opt.warmup + static_cast<std::int64_t>(i) + 1;
    s.time = static_cast<double>(s.step) * scene.sim.dt;
    s.collisions = counts[2 * i];
    s.records = counts[2 * i + 1];
    for (int c = 0; c < kNumPhases; ++c) s.seconds.*(kPhases[c].member) = secs[kD * i + c];
    s.wall = secs[kD * i + kNumPhases];
    s.other = secs[kD * i + kNumPhases + 1];
  }
  r.summarise();
  return r;
}

void print_bench_table(std::ostream& out, const BenchResult& r) {
  const double first_t = r.steps.empty() ? 0 : r.steps.front().time - r.dt;
  const double last_t = r.steps.empty() ? 0 : r.steps.back().time;
  out << "softcontact bench: " << r.scene << " (" << r.path << ")\n"
      << "  " << r.ranks << " rank(s) x " << r.threads << " thread(s); " << r.objects << " objects, " << r.vertices
      << " vertices, " << r.tets << " tets; dt = " << num(r.dt, 4) << " s; OMP_WAIT_POLICY "
      << r.omp_wait_policy << "\n"
      << "  " << r.steps.size() << " timed steps (t = " << num(first_t, 4) << " .. " << num(last_t, 4) << " s) after "
      << r.warmup << " warm-up steps; set-up " << fixed(r.setup_seconds, 2) << " s";
  if (r.read_seconds > 0) out << " after reading the scene in " << fixed(r.read_seconds, 2) << " s";
  out << "; mesh files read: " << r.files_read_sum;
  if (r.ranks > 1) out << " over all ranks, " << r.files_read_max << " by the busiest";
  out << "\n  set-up by stage (ms, max / min over ranks):";
  for (std::size_t i = 0; i < r.setup_stages.size(); ++i) {
    const SetupStage& st = r.setup_stages[i];
    out << (i ? ", " : " ") << st.name << " " << fixed(1e3 * st.max_seconds, 1);
    if (r.ranks > 1) out << " / " << fixed(1e3 * st.min_seconds, 1);
  }
  if (r.heap_setup_max() >= 0) {
    // What each rank's heap holds (max over ranks), not its resident size: the figure to
    // compare between rank counts for what every rank keeps of the whole scene.
    constexpr double kMiB = 1024.0 * 1024.0;
    out << "\n  heap in use (MiB, max over ranks):";
    if (r.heap_after_read_max >= 0)
      out << " before the scene " << fixed(r.heap_before_read_max / kMiB, 2) << ", after reading it "
          << fixed(r.heap_after_read_max / kMiB, 2) << ";";
    out << " after each stage" << (r.ranks > 1 ? " (max / min)" : "");
    for (std::size_t i = 0; i < r.setup_stages.size(); ++i) {
      const SetupStage& st = r.setup_stages[i];
      out << (i ? ", " : " ") << st.name << " " << fixed(st.max_heap_bytes / kMiB, 2);
      if (r.ranks > 1) out << " / " << fixed(st.min_heap_bytes / kMiB, 2);
    }
  }
  out << "\n"
      << "  colliding points per step: median " << num(r.collisions.median, 7) << ", mean "
      << fixed(r.collisions.mean, 1) << ", max " << r.collisions_max << "\n\n";
  constexpr int w = 20;
  out << "  " << std::left << std::setw(w) << "phase" << std::right << std::setw(14) << "median [ms]" << std::setw(12)
      << "mean [ms]" << std::setw(14) << "% of mean" << "\n";
  auto row = [&](const std::string& label, const Spread& s) {
    const double share = r.total.mean > 0 ? 100.0 * s.mean / r.total.mean : 0.0;
    out << "  " << std::left << std::setw(w) << label << std::right << std::setw(14) << fixed(1e3 * s.median, 3)
        << std::setw(12) << fixed(1e3 * s.mean, 3) << std::setw(13) << fixed(share, 1) << "%\n";
  };
  for (const PhaseColumn& p : kPhases) row(p.label, r.*(p.spread));
  // The part of a step outside the timed phases (loops over vertices between them).
  std::vector<double> other(r.steps.size());
  for (std::size_t i = 0; i < r.steps.size(); ++i) other[i] = r.steps[i].other;
  row("other", spread_of(other));
  row("total per step", r.total);
  out << "\n  steps per second: " << fixed(r.steps_per_second(), 2) << " (timed steps / wall time of the loop, "
      << num(r.loop_seconds, 3) << " s)\n"
      << "  peak memory per rank (ru_maxrss): max " << fixed(r.rss_max_mib, 1) << " MiB, mean "
      << fixed(r.rss_mean_mib, 1) << " MiB\n";
  if (r.edge_pairs_mean > 0)
    out << "  edge search: " << fixed(r.edge_pairs_mean, 0) << " candidate pairs per step (mean), found again in "
        << r.edge_pair_searches << " of " << r.steps.size() << " timed steps\n";
  if (r.ranks > 1)
    out << "  halo traffic per step and rank: max " << fixed(r.halo_bytes_max / 1024, 1) << " KiB, mean "
        << fixed(r.halo_bytes_mean / 1024, 1) << " KiB in " << fixed(r.halo_rounds_max, 2)
        << " rounds of neighbour messages (max rank); ghost-set tests " << r.ghost_tests << ", rebuilds "
        << r.ghost_rebuilds << " (object boxes received per test: max " << fixed(r.ghost_boxes_max, 0) << " of "
        << r.objects << " objects)\n";
  if (r.ranks > 1 && r.split_objects > 0)
    out << "  split objects: " << r.split_objects << "; their exchanges " << fixed(r.split_bytes_max / 1024, 1)
        << " KiB sent per step (max rank), " << fixed(r.split_bytes_sum / 1024, 1) << " KiB (all ranks); "
        << r.split_helped_tets_max
        << " tets evaluated for another rank's object (max rank); " << r.split_parts_from_ghosts << " of "
        << r.split_helping_parts << " helping parts take the positions from their ghost rows; their parts sent at set-up "
        << "and migrations " << fixed(r.split_part_bytes_max / 1024, 1) << " KiB (max rank), "
        << fixed(r.split_part_bytes_sum / 1024, 1) << " KiB (all ranks)\n";
  if (r.ranks > 1)
    out << "  load imbalance (compute, max/mean over ranks): wall " << fixed(r.compute_imbalance, 3) << ", CPU "
        << fixed(r.cpu_imbalance, 3) << "; collisions crossing ranks: " << fixed(100 * r.cross_rank_fraction, 1) << "%\n"
        << "  partition by static weights (max/mean over ranks): work " << fixed(r.static_work_imbalance, 3)
        << " (tets; kinematic objects a tenth of their triangles), memory " << fixed(r.static_memory_imbalance, 3)
        << " (the owners' state by the memory model; ghosts not counted)\n";
  if (r.ranks > 1) {
    out << "  per phase, a rank's ms per step (max / mean over ranks):";
    bool first = true;
    for (const PhaseColumn& p : kPhases) {
      const double most = r.phase_rank_max.*(p.member), mean = r.phase_rank_mean.*(p.member);
      if (most <= 0) continue;
      out << (first ? " " : ", ") << p.label << " " << fixed(1e3 * most, 3) << " / " << fixed(1e3 * mean, 3);
      first = false;
    }
    out << "\n";
  }
}

std::string bench_csv_header() {
  std::string h =
      "timestamp,scene,path,ranks,threads,objects,vertices,tets,dt,warmup,steps,collisions_median,collisions_mean,"
      "collisions_max,total_ms_median,total_ms_mean";
  for (const PhaseColumn& p : kPhases) h += std::string(",") + p.column + "_ms_median," + p.column + "_ms_mean";
  h += ",steps_per_second,setup_s,rss_max_mib,rss_mean_mib,omp_wait_policy,halo_bytes_max,halo_bytes_mean,"
       "compute_imbalance,cross_rank_fraction,ghost_rebuilds,cpu_imbalance,read_s,halo_rounds_max,heap_read_mib,"
       "heap_setup_mib,static_work_imbalance,static_memory_imbalance";
  return h;
}

std::string bench_csv_row(const BenchResult& r) {
  std::ostringstream s;
  s << utc_now() << ',' << csv_field(r.scene) << ',' << csv_field(r.path) << ',' << r.ranks << ',' << r.threads << ','
    << r.objects << ',' << r.vertices << ',' << r.tets << ',' << num(r.dt) << ',' << r.warmup << ',' << r.steps.size()
    << ',' << num(r.collisions.median, 10) << ',' << num(r.collisions.mean) << ',' << r.collisions_max << ','
    << num(1e3 * r.total.median) << ',' << num(1e3 * r.total.mean);
  for (const PhaseColumn& p : kPhases) {
    const Spread& v = r.*(p.spread);
    s << ',' << num(1e3 * v.median) << ',' << num(1e3 * v.mean);
  }
  s << ',' << num(r.steps_per_second()) << ',' << num(r.setup_seconds) << ',' << num(r.rss_max_mib) << ','
    << num(r.rss_mean_mib) << ',' << csv_field(r.omp_wait_policy) << ',' << num(r.halo_bytes_max) << ','
    << num(r.halo_bytes_mean) << ',' << num(r.compute_imbalance) << ',' << num(r.cross_rank_fraction) << ','
    << r.ghost_rebuilds << ',' << num(r.cpu_imbalance) << ',' << num(r.read_seconds) << ','
    << num(r.halo_rounds_max);
  // The heap figures are left empty where the C library cannot tell them.
  auto mib = [](double bytes) { return bytes < 0 ? std::string() : num(bytes / (1024.0 * 1024.0)); };
  s << ',' << mib(r.heap_after_read_max) << ',' << mib(r.heap_setup_max()) << ',' << num(r.static_work_imbalance) << ','
    << num(r.static_memory_imbalance);
  return s.str();
}

std::string per_step_csv_header() {
  std::string h = "step,time,collisions,records";
  for (const PhaseColumn& p : kPhases)
    if (p.member != &PhaseTimes::output) h += std::string(",") + p.column + "_ms";
  return h + ",total_ms";
}

void write_per_step_csv(std::ostream& out, const BenchResult& r) {
  out << per_step_csv_header() << '\n';
  for (const BenchStep& s : r.steps) {
    out << s.step << ',' << num(s.time, 10) << ',' << s.collisions << ',' << s.records;
    for (const PhaseColumn& p : kPhases)
      if (p.member != &PhaseTimes::output) out << ',' << num(1e3 * (s.seconds.*(p.member)));
    out << ',' << num(1e3 * s.wall) << '\n';
  }
}

BenchFiles::BenchFiles(MPI_Comm comm, const std::string& csv, const std::string& per_step)
    : csv_path_(csv), per_step_path_(per_step) {
  const int rank = comm_rank(comm);
  std::string problem;
  if (rank == 0) {
    if (!csv.empty()) {
      // Appending: an existing non-empty file must carry our header.
      std::ifstream in(csv);
      std::string first;
      if (in && std::getline(in, first) && !first.empty()) {
        if (first != bench_csv_header())
          problem = "--csv " + csv + ": the file exists with other columns than 'softcontact bench' writes; give a new file";
      } else {
        header_needed_ = true;
      }
      if (problem.empty()) {
        csv_.open(csv, std::ios::app);
        if (!csv_) problem = "--csv " + csv + ": cannot open the file for appending";
      }
    }
    if (problem.empty() && !per_step.empty()) {
      per_step_.open(per_step, std::ios::trunc);
      if (!per_step_) problem = "--per-step " + per_step + ": cannot open the file for writing";
    }
  }
  int len = static_cast<int>(problem.size());
  MPI_Bcast(&len, 1, MPI_INT, 0, comm);
  problem.resize(static_cast<std::size_t>(len));
  MPI_Bcast(problem.data(), len, MPI_CHAR, 0, comm);
  if (!problem.empty()) throw InputError("command line: " + problem);
}

void BenchFiles::write(const BenchResult& r) {
  if (csv_.is_open()) {
    if (header_needed_) csv_ << bench_csv_header() << '\n';
    header_needed_ = false;
    csv_ << bench_csv_row(r) << '\n' << std::flush;
    if (!csv_) throw RuntimeFailure("cannot write " + csv_path_);
  }
  if (per_step_.is_open()) {
    write_per_step_csv(per_step_, r);
    per_step_.flush();
    if (!per_step_) throw RuntimeFailure("cannot write " + per_step_path_);
  }
}

}  // namespace softcontact
