#include "softcontact/cli.hpp"

#include <H5public.h>
#include <metis.h>
#include <omp.h>
#include <petscsys.h>
#include <yaml-cpp/yaml.h>

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <iomanip>
#include <iostream>
#include <limits>
#include <map>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include "softcontact/bench.hpp"
#include "softcontact/split_forces.hpp"
#include "softcontact/config.hpp"
#include "softcontact/error.hpp"
#include "softcontact/fault.hpp"
#include "softcontact/memory.hpp"
#include "softcontact/mpi_util.hpp"
#include "softcontact/rebalance.hpp"
#include "softcontact/simulator.hpp"
#include "softcontact/stepper.hpp"
#include "softcontact/run.hpp"
#include "softcontact/scene.hpp"
#include "softcontact/surface.hpp"
#include "softcontact/verify.hpp"

namespace softcontact {

namespace detail {
std::string nearest(const std::string& word, const std::vector<std::string>& candidates);
}

namespace {


// The run's memory estimate [bytes per rank], for the message when memory runs out.
double g_memory_estimate = 0;

const char* kMainHelp =
    "softcontact " SOFTCONTACT_VERSION
    " - colliding deformable bodies with analytic, non-iterative contact forces\n"
    "(Spillmann, Becker, Teschner 2007)\n"
    "\n"
    "usage: mpirun -n RANKS softcontact COMMAND [options]\n"
    "\n"
    "commands:\n"
    "  run SCENE.yaml     run a scene, write HDF5/XDMF frames and a diagnostics CSV\n"
    "  check SCENE.yaml   validate a scene and print a summary without running\n"
    "  bench SCENE.yaml   time a scene per step and phase, without output (docs/benchmarks.md)\n"
    "  verify OUTPUT_DIR  check a run's frames independently: penetrations, crossings, inverted tets,\n"
    "                     speeds (docs/validation.md, \"softcontact verify\")\n"
    "  info               version and the libraries this build uses\n"
    "\n"
    "options:\n"
    "  -h, --help         this help; 'softcontact COMMAND --help' for a command's options\n"
    "  --version          print the version\n"
    "\n"
    "exit status: 0 success (also a run stopped by SIGTERM/SIGINT after writing a checkpoint),\n"
    "1 the run failed (out of memory, an I/O error; verify: a limit exceeded), 2 bad input\n"
    "(scene, mesh, command line, checkpoint, output directory, a run whose memory estimate\n"
    "cannot fit), 3 numerical failure (also an implicit solve that does not converge)\n"
    "PETSc options (e.g. -log_view) are read from the PETSC_OPTIONS environment variable.\n";

const char* kRunHelp =
    "usage: mpirun -n RANKS softcontact run SCENE.yaml [options]\n"
    "       mpirun -n RANKS softcontact run --restart CHECKPOINT [options]\n"
    "\n"
    "Runs the scene and writes, in the output directory (scene 'simulation.output.directory',\n"
    "default output/<scene name>): frames.h5 and frames.xdmf (open the .xdmf in ParaView),\n"
    "diagnostics.csv and a copy of the scene. Options override the scene:\n"
    "\n"
    "  --steps N          number of time steps (replaces the scene's end_time or steps)\n"
    "  --end-time T       simulated seconds to run (replaces end_time or steps)\n"
    "  --output DIR       output directory\n"
    "  --output-every K   steps between output frames (replaces output every/interval)\n"
    "  --overwrite        replace the results in an existing output directory\n"
    "  --checkpoint-every N    write a checkpoint every N steps (scene 'simulation.checkpoint.every')\n"
    "  --checkpoint-minutes T  ... and/or every T minutes of wall time ('checkpoint.minutes')\n"
    "  --restart FILE|DIR continue a run from a checkpoint (or the newest one in a run's output\n"
    "                     directory), on any number of ranks, bitwise as if it had not stopped;\n"
    "                     frames continue in the same directory unless --output names another\n"
    "  --verify-every N   after every N-th step, the check of 'softcontact verify' on all positions\n"
    "                     (each rank its own objects); the maxima are printed at the end and written to\n"
    "                     OUTPUT_DIR/verify_steps.json, with the vertices left inside counted by\n"
    "                     what the contact response did about them (docs/validation.md)\n"
    "  --quiet            no progress line (for batch logs); the final summary is kept\n"
    "  -h, --help         this help\n"
    "\n"
    "The first line estimates the peak memory per rank; a run that cannot fit the address-space\n"
    "limit (ulimit -v) or its share of the node's memory is refused before building (exit 2).\n"
    "SIGTERM or SIGINT (what batch schedulers send before a kill) ends the run after the\n"
    "current step with a checkpoint; the run stops with exit status 3 and a message saying\n"
    "where, when it becomes numerically unstable (docs/reliability.md).\n";

const char* kCheckHelp =
    "usage: softcontact check SCENE.yaml [--ranks N]\n"
    "\n"
    "Reads and validates the scene and every mesh it uses, then prints a summary: objects,\n"
    "vertices, tets, mass, stable time step, steps and frames, and the estimated peak memory\n"
    "per rank. Nothing is written.\n"
    "\n"
    "  --ranks N          estimate the memory for a run on N ranks (default: this command's ranks)\n"
    "  -h, --help         this help\n"
    "\n"
    "Exit status 2 with a message naming the file and line when something is wrong, or when\n"
    "the estimate does not fit this process's address-space limit (ulimit -v) or its share\n"
    "of this node's available memory.\n";

const char* kBenchHelp =
    "usage: mpirun -n RANKS softcontact bench SCENE.yaml [options]\n"
    "\n"
    "Runs the scene for a fixed number of steps without writing frames and prints, per\n"
    "phase of the step, the median and mean wall time per step, the colliding points per\n"
    "step, steps per second and the peak memory per rank. The scene's end_time or steps\n"
    "are ignored. OMP_NUM_THREADS sets the threads; on a shared machine also set\n"
    "OMP_WAIT_POLICY=passive (docs/benchmarks.md, \"Scenes\").\n"
    "\n"
    "  --steps N          timed steps (default 100)\n"
    "  --warmup K         untimed steps before them (default 0)\n"
    "  --csv FILE         append one row for this run to FILE (header when FILE is new)\n"
    "  --per-step FILE    write one row per timed step: colliding points and phase times\n"
    "  --quiet            no progress lines\n"
    "  -h, --help         this help\n";

const char* kVerifyHelp =
    "usage: softcontact verify OUTPUT_DIR [options]\n"
    "\n"
    "Checks the frames a run wrote, independently of the collision detector: surface and\n"
    "interior vertices inside other bodies and how deep (distance to that body's surface),\n"
    "surface edges through other bodies' surface triangles, surface vertices inside their own\n"
    "body away from their neighbours (self-contact), inverted tets, and the fastest\n"
    "vertex against the free-fall speed v_ff = sqrt(v0^2 + 2 |g| H) of the scene. Depths are\n"
    "in median tet edge lengths h. One line per frame, a summary, and a JSON file.\n"
    "Under mpirun the ranks share the frames (each reads the mesh and checks every N-th\n"
    "frame; rank 0 reports): the same report as one process, in less time.\n"
    "\n"
    "  --frames SPEC            all (default), first, last, or a comma list of frame numbers\n"
    "                           and ranges A:B[:STEP] (B included; negative: from the end)\n"
    "  --skip-frames-before T   do not check frames before simulated time T [s]\n"
    "  --max-depth F            largest surface-vertex depth, in h (default 0.005)\n"
    "  --max-interior-depth F   largest interior-vertex depth, in h (default: none)\n"
    "  --max-self-depth F       largest depth of a surface vertex in its own body, in h\n"
    "                           (default: none)\n"
    "  --max-crossings N        most surface crossings in a frame (default: none)\n"
    "  --max-inverted N         most inverted tets at the last checked frame (default 0)\n"
    "  --max-speed-ratio R      largest speed / v_ff (default 3)\n"
    "  --json FILE              the JSON summary (default OUTPUT_DIR/verify.json)\n"
    "  -h, --help               this help\n"
    "\n"
    "exit status: 0 within the limits, 1 a limit exceeded (or a non-finite vertex), 2 bad\n"
    "input (missing directory or file, unreadable HDF5, bad option).\n";

const char* kInfoHelp = "usage: softcontact info\n\nPrints the version and the libraries of this build.\n";

[[noreturn]] void usage_error(const std::string& msg, const char* command) {
  std::string m = "command line: " + msg;
  if (command) m += std::string(" (see 'softcontact ") + command + " --help')";
  else m += " (see 'softcontact --help')";
  throw InputError(m);
}

/// Parsed arguments of one command: positional words and --options with values.
struct Args {
  std::vector<std::string> positional;
  std::map<std::string, std::string> values;
  std::vector<std::string> flags;
  bool help = false;
};

Args parse_args(int argc, const char* const* argv, int first, const char* command,
                const std::vector<std::string>& valued, const std::vector<std::string>& flags) {
  Args a;
  for (int i = first; i < argc; ++i) {
    const std::string s = argv[i];
    if (s == "-h" || s == "--help") {
      a.help = true;
      continue;
    }
    if (s.rfind("--", 0) == 0) {
      std::string key = s, value;
      const auto eq = s.find('=');
      if (eq != std::string::npos) {
        key = s.substr(0, eq);
        value = s.substr(eq + 1);
      }
      if (std::find(valued.begin(), valued.end(), key) != valued.end()) {
        if (eq == std::string::npos) {
          if (i + 1 >= argc) usage_error("option " + key + " needs a value", command);
          value = argv[++i];
        }
        a.values[key] = value;
      } else if (std::find(flags.begin(), flags.end(), key) != flags.end()) {
        if (eq != std::string::npos) usage_error("option " + key + " takes no value", command);
        a.flags.push_back(key);
      } else {
        std::vector<std::string> all = valued;
        all.insert(all.end(), flags.begin(), flags.end());
        all.push_back("--help");
        std::string msg = "unknown option '" + key + "'";
        const std::string guess = detail::nearest(key, all);
        if (!guess.empty()) msg += " (did you mean '" + guess + "'?)";
        usage_error(msg, command);
      }
    } else if (s.size() > 1 && s[0] == '-') {
      usage_error("unknown option '" + s + "' (options start with '--'; PETSc options go in PETSC_OPTIONS)", command);
    } else {
      a.positional.push_back(s);
    }
  }
  return a;
}

bool has(const Args& a, const std::string& flag) {
  return std::find(a.flags.begin(), a.flags.end(), flag) != a.flags.end();
}

std::int64_t parse_count(const std::string& opt, const std::string& v, const char* command) {
  std::size_t pos = 0;
  long long n = 0;
  try {
    n = std::stoll(v, &pos);
  } catch (const std::exception&) {
    pos = 0;
  }
  if (pos != v.size() || v.empty() || n < 1) usage_error(opt + " expects a positive integer, got '" + v + "'", command);
  return n;
}

std::int64_t parse_nonnegative(const std::string& opt, const std::string& v, const char* command) {
  std::size_t pos = 0;
  long long n = -1;
  try {
    n = std::stoll(v, &pos);
  } catch (const std::exception&) {
    pos = 0;
  }
  if (pos != v.size() || v.empty() || n < 0) usage_error(opt + " expects a non-negative integer, got '" + v + "'", command);
  return n;
}

// A number option: the whole value must parse and satisfy `ok`, else a usage error
// "OPT expects EXPECTED, got 'V'".
double parse_number(const std::string& opt, const std::string& v, const char* command, bool (*ok)(double),
                    const char* expected) {
  std::size_t pos = 0;
  double x = 0;
  try {
    x = std::stod(v, &pos);
  } catch (const std::exception&) {
    pos = 0;
  }
  if (pos != v.size() || v.empty() || !ok(x)) usage_error(opt + " expects " + expected + ", got '" + v + "'", command);
  return x;
}

double parse_seconds(const std::string& opt, const std::string& v, const char* command) {
  return parse_number(opt, v, command, [](double x) { return x > 0 && std::isfinite(x); },
                      "a positive number of seconds");
}

std::string scene_argument(const Args& a, const char* command) {
  if (a.positional.empty()) usage_error(std::string("'") + command + "' needs a scene file", command);
  if (a.positional.size() > 1) usage_error("unexpected argument '" + a.positional[1] + "'", command);
  return a.positional[0];
}

void print_warnings(const Scene& s, std::ostream& err) {
  for (const auto& w : s.warnings) err << w << '\n';
}

std::string human(double x, const char* unit) {
  std::ostringstream s;
  s << std::setprecision(4) << x << ' ' << unit;
  return s.str();
}

void print_summary(const Scene& s, std::ostream& out) {
  const Simulation& sim = s.sim;
  out << "scene " << s.path << "\n";
  out << "  objects " << s.objects.size() << ", materials " << s.materials.size() << "\n";
  double total_mass = 0;
  std::size_t tris = 0;
  out << "  " << std::left << std::setw(24) << "object" << std::setw(14) << "material" << std::setw(14) << "model"
      << std::right << std::setw(10) << "vertices" << std::setw(10) << "tets" << std::setw(14) << "mass [kg]"
      << "  fixed vertices\n";
  constexpr std::size_t kShown = 20;
  for (std::size_t k = 0; k < s.objects.size(); ++k) {
    const SceneObject& o = s.objects[k];
    const Scene::MeshView view = s.view_mesh(k);
    const TetMesh& mesh = view.get();
    const Material& m = s.materials[o.material];
    const double mass = m.density * tet_volume_sum(mesh);
    total_mass += mass;
    tris += s.shape(k).triangles;
    std::size_t fixed = 0;
    for (std::size_t i = 0; i < mesh.num_vertices(); ++i) {
      bool f = o.kinematic();
      for (const Box& b : o.fixed()) f = f || b.contains(&mesh.points[3 * i]);
      fixed += f;
    }
    if (k < kShown)
      out << "  " << std::left << std::setw(24) << o.name << std::setw(14) << m.name << std::setw(14)
          << to_string(m.model) << std::right << std::setw(10) << mesh.num_vertices() << std::setw(10)
          << mesh.num_tets() << std::setw(14) << std::setprecision(5) << mass << "  "
          << (o.kinematic() ? "all (kinematic)" : std::to_string(fixed)) << "\n";
  }
  if (s.objects.size() > kShown) out << "  ... and " << s.objects.size() - kShown << " more objects\n";
  out << "  total: " << s.num_vertices() << " vertices, " << s.num_tets() << " tets, " << tris
      << " surface triangles, mass " << human(total_mass, "kg") << "\n";
  const StableStep stable = stable_step(s);
  out << "  stable explicit time step " << human(stable.dt, "s") << " (" << stable.explain(s) << ")\n";
  if (sim.dt_bound == DtBound::mesh) {
    const StableStep element = stable_step(s, DtBound::element);
    out << "  element bound " << human(element.dt, "s") << " (the mesh bound is " << std::setprecision(4)
        << stable.dt / element.dt << " times it)\n";
  }
  out << "  time step " << human(sim.dt, "s") << (sim.dt_auto ? " (auto, safety " : " (given") ;
  if (sim.dt_auto) out << sim.dt_safety;
  out << "), integrator " << to_string(sim.integrator) << "\n";
  const std::int64_t n = total_steps(sim);
  out << "  " << n << " steps to t = " << human(static_cast<double>(n) * sim.dt, "s") << ", a frame every "
      << steps_between_frames(sim) << " steps, output to " << sim.output_dir << "\n";
}

// Which objects a run on `ranks` ranks splits for their forces (split_forces.hpp), or
// from how many ranks on the largest one would be.
void print_split_objects(const Scene& s, int ranks, std::ostream& out) {
  out << "  objects split for their forces (docs/architecture.md): ";
  if (!s.sim.split_objects) {
    out << "none (simulation.split_objects: false)\n";
    return;
  }
  if (s.sim.integrator == IntegratorKind::implicit_euler) {
    out << "none (implicit Euler objects are not split)\n";
    return;
  }
  const double total = static_cast<double>(s.num_tets());
  const std::vector<char> mask = split_mask(s, ranks);
  std::size_t largest = s.objects.size();
  std::vector<std::size_t> split;
  for (std::size_t k = 0; k < s.objects.size(); ++k) {
    if (mask[k]) split.push_back(k);
    if (!s.objects[k].kinematic() && (largest == s.objects.size() || s.shape(k).tets > s.shape(largest).tets)) largest = k;
  }
  auto share = [&](std::size_t k) {
    std::ostringstream p;
    p << std::fixed << std::setprecision(1) << 100.0 * static_cast<double>(s.shape(k).tets) / total << " %";
    return p.str();
  };
  for (std::size_t i = 0; i < split.size(); ++i)
    out << (i ? ", " : "") << "'" << s.objects[split[i]].name << "' (" << s.shape(split[i]).tets << " tets, "
        << share(split[i]) << " of the scene)";
  if (!split.empty()) {
    out << " on " << ranks << " ranks";
    // An object cut into fewer parts than ranks (split_part_count): how many.
    const char* sep = "; ";
    for (std::size_t k : split) {
      const int parts = split_part_count(static_cast<std::int64_t>(s.shape(k).tets), static_cast<std::int64_t>(s.num_tets()), ranks);
      if (parts >= ranks) continue;
      out << sep << "'" << s.objects[k].name << "' in " << parts << " parts";
      sep = ", ";
    }
    out << "\n";
    return;
  }
  out << "none on " << ranks << " rank(s)";
  if (largest < s.objects.size() && s.shape(largest).tets > 0) {
    // The fewest ranks with tets x ranks > all tets.
    const auto from = static_cast<std::int64_t>(std::floor(total / static_cast<double>(s.shape(largest).tets))) + 1;
    out << "; the largest deformable object, '" << s.objects[largest].name << "' (" << share(largest)
        << " of the tets), would be from " << std::max<std::int64_t>(from, 2) << " ranks on";
  }
  out << "\n";
}

// The initial partition a run on `ranks` ranks would make (computed here on one process:
// the same answer), and what it gives each rank by its static weights. Collective over
// `comm` (the edge statistics); printed by rank 0.
void print_partition_loads(MPI_Comm comm, const Scene& s, int ranks, std::ostream& out) {
  if (ranks <= 1) return;
  const double mean_edge = scene_edge_statistics(comm, s).mean;
  if (comm_rank(comm) != 0) return;
  SplitHosts hosts;
  const std::vector<int> part =
      initial_partition(s, ranks, MPI_COMM_NULL, &hosts, collision_settings_for(s, mean_edge).cell_size);
  const PartitionLoads l = partition_loads(s, part, hosts, ranks);
  out << "  partition on " << ranks << " ranks (max / mean over ranks of the static weights, docs/architecture.md, "
      << "\"Partition\"): work imbalance " << std::fixed << std::setprecision(3) << l.work_imbalance
      << ", memory imbalance " << l.memory_imbalance << std::defaultfloat << "\n";
}

int cmd_check(const Args& a, MPI_Comm comm, std::ostream& out, std::ostream& err) {
  const Scene s = load_scene(scene_argument(a, "check"));
  const int rank = comm_rank(comm), size = comm_size(comm);
  const int ranks = a.values.count("--ranks") ? static_cast<int>(parse_count("--ranks", a.values.at("--ranks"), "check")) : size;
  const MemoryEstimate mem = estimate_memory(s, ranks);
  if (rank == 0) {
    print_warnings(s, err);
    print_summary(s, out);
    out << "  memory: about " << format_bytes(mem.per_rank) << " peak per rank on " << ranks
        << " rank(s); address space (ulimit -v) about " << format_bytes(address_space_needed(mem))
        << " (docs/reliability.md, \"Memory\")\n";
    print_split_objects(s, ranks, out);
  }
  print_partition_loads(comm, s, ranks, out);
  // The limits are this process's: they say something for a run on this node.
  check_memory_fits(comm, mem, s.path);
  if (rank == 0) out << "scene is valid\n";
  return 0;
}

int cmd_run(const Args& a, MPI_Comm comm, std::ostream& out, std::ostream& err) {
  {
    const int world_rank = comm_rank(MPI_COMM_WORLD), world_size = comm_size(MPI_COMM_WORLD);
    fault::configure(world_rank, world_size);  // the testing hook SOFTCONTACT_FAULT (docs/reliability.md)
  }
  RunOptions opt;
  if (a.values.count("--steps")) opt.steps = parse_count("--steps", a.values.at("--steps"), "run");
  if (a.values.count("--end-time")) opt.end_time = parse_seconds("--end-time", a.values.at("--end-time"), "run");
  if (a.values.count("--output")) {
    opt.output_dir = a.values.at("--output");
    if (opt.output_dir->empty()) usage_error("--output expects a directory", "run");
  }
  if (a.values.count("--output-every"))
    opt.output_every = parse_count("--output-every", a.values.at("--output-every"), "run");
  if (a.values.count("--checkpoint-every"))
    opt.checkpoint_every = parse_count("--checkpoint-every", a.values.at("--checkpoint-every"), "run");
  if (a.values.count("--checkpoint-minutes"))
    opt.checkpoint_minutes = parse_seconds("--checkpoint-minutes", a.values.at("--checkpoint-minutes"), "run");
  if (a.values.count("--verify-every"))
    opt.verify_every = parse_count("--verify-every", a.values.at("--verify-every"), "run");
  opt.overwrite = has(a, "--overwrite");
  opt.quiet = has(a, "--quiet");
  RestartPoint restart;
  const bool restarting = a.values.count("--restart") > 0;
  if (restarting) {
    if (!a.positional.empty())
      usage_error("give either a scene or --restart (the checkpoint carries its scene), not both", "run");
    if (a.values.at("--restart").empty()) usage_error("--restart expects a checkpoint file or directory", "run");
  }
  Scene s = restarting ? load_restart(comm, a.values.at("--restart"), restart, copies_made_on_demand(comm))
                           : load_scene(scene_argument(a, "run"), copies_made_on_demand(comm));
  apply_overrides(s, opt);
  const int rank = comm_rank(comm), size = comm_size(comm);
  const MemoryEstimate mem = estimate_memory(s, size);
  g_memory_estimate = mem.per_rank;
  if (rank == 0) {
    print_warnings(s, err);
    out << "softcontact " << SOFTCONTACT_VERSION << ": " << s.path << ": " << s.objects.size() << " objects, "
        << s.num_vertices() << " vertices, " << s.num_tets() << " tets on " << size << " rank(s) x "
        << omp_get_max_threads() << " thread(s); dt = " << s.sim.dt << " s, " << total_steps(s.sim)
        << " steps; memory about " << format_bytes(mem.per_rank) << " per rank\n";
    if (restarting)
      out << "restart: from " << restart.path << " (step " << restart.info.step << ", written on " << restart.info.ranks
          << " rank(s))\n";
    out << std::flush;
  }
  // Objects are the unit of distribution: ranks beyond the object count stay idle.
  if (rank == 0 && static_cast<std::size_t>(size) > s.objects.size())
    err << "softcontact: warning: " << size << " ranks for " << s.objects.size()
        << " objects: objects are never split, so " << size - static_cast<int>(s.objects.size())
        << " rank(s) will own nothing\n";
  // Before anything is built: a run that cannot fit is refused now, not after an hour.
  check_memory_fits(comm, mem, s.path);
  const RunSummary r = run_scene(comm, s, opt, out, restarting ? &restart : nullptr);
  if (rank == 0 && !r.stopped_by.empty()) {
    out << "\nstopped by " << r.stopped_by << " at step " << r.first_step + r.steps << " (t = " << r.sim_time
        << " s); checkpoint " << r.last_checkpoint << "\n"
        << "continue with: softcontact run --restart " << r.last_checkpoint << "\n";
    return 0;
  }
  if (rank == 0) {
    out << "done: " << r.steps << " steps to t = " << r.sim_time << " s in " << std::setprecision(3) << r.wall_seconds
        << " s (" << std::setprecision(4) << (r.wall_seconds > 0 ? r.steps / r.wall_seconds : 0.0) << " steps/s), "
        << r.frames << " frames, peak memory " << format_bytes(r.peak_rss) << " per rank (largest; estimated "
        << format_bytes(mem.per_rank) << ")\n"
        << "output:      " << r.xdmf << "  (open in ParaView: paraview " << r.xdmf << ")\n"
        << "             " << r.h5 << "  (HDF5, layout in docs/output-format.md)\n"
        << "diagnostics: " << r.csv << "\n";
    if (size > 1)
    {
      out << "ranks:       " << r.ghost_rebuilds << " ghost-set rebuilds, " << r.repartitions << " repartitions";
      if (r.split_objects > 0)
        out << ", " << r.split_objects << " object(s) split for their forces over " << r.split_ranks
            << (r.split_ranks < size ? " of " + std::to_string(size) : std::string()) << " ranks";
      out << "\n";
    }
    if (!r.verify_json.empty()) out << "verify:      " << r.verify_json << "\n";
  }
  return 0;
}

int cmd_bench(const Args& a, MPI_Comm comm, std::ostream& out, std::ostream& err) {
  BenchOptions opt;
  if (a.values.count("--steps")) opt.steps = parse_count("--steps", a.values.at("--steps"), "bench");
  if (a.values.count("--warmup")) opt.warmup = parse_nonnegative("--warmup", a.values.at("--warmup"), "bench");
  opt.quiet = has(a, "--quiet");
  const std::string csv = a.values.count("--csv") ? a.values.at("--csv") : "";
  const std::string per_step = a.values.count("--per-step") ? a.values.at("--per-step") : "";
  if (a.values.count("--csv") && csv.empty()) usage_error("--csv expects a file name", "bench");
  if (a.values.count("--per-step") && per_step.empty()) usage_error("--per-step expects a file name", "bench");
  MPI_Barrier(comm);
  const double t0 = MPI_Wtime();
  opt.heap_before_read = heap_in_use_bytes();
  const Scene s = load_scene(scene_argument(a, "bench"), copies_made_on_demand(comm));
  opt.read_seconds = MPI_Wtime() - t0;
  opt.heap_after_read = heap_in_use_bytes();
  const int rank = comm_rank(comm);
  if (rank == 0) print_warnings(s, err);
  BenchFiles files(comm, csv, per_step);
  const BenchResult r = run_bench(comm, s, opt, err);
  if (rank == 0) {
    print_bench_table(out, r);
    files.write(r);
  }
  return 0;
}

double parse_limit(const std::string& opt, const std::string& v) {
  return parse_number(opt, v, "verify", [](double x) { return x >= 0; }, "a non-negative number");
}

// The frames of verify_output shared by the ranks of `comm` (VerifyFrameShare).
class MpiFrameShare final : public VerifyFrameShare {
public:
  explicit MpiFrameShare(MPI_Comm comm) : comm_(comm) {}
  int rank() const override { return comm_rank(comm_); }
  int size() const override { return comm_size(comm_); }
  std::vector<char> gather(const std::vector<char>& mine) const override {
    if (mine.size() > static_cast<std::size_t>(std::numeric_limits<int>::max()))
      throw RuntimeFailure("verify: a rank's frame checks exceed 2 GiB");
    const int count = static_cast<int>(mine.size()), ranks = size();
    std::vector<int> counts(rank() == 0 ? static_cast<std::size_t>(ranks) : 0), offsets(counts.size());
    MPI_Gather(&count, 1, MPI_INT, counts.data(), 1, MPI_INT, 0, comm_);
    std::size_t total = 0;
    for (std::size_t p = 0; p < counts.size(); ++p) {
      if (total > static_cast<std::size_t>(std::numeric_limits<int>::max()))
        throw RuntimeFailure("verify: the frame checks exceed 2 GiB");
      offsets[p] = static_cast<int>(total);
      total += static_cast<std::size_t>(counts[p]);
    }
    std::vector<char> all(total);
    MPI_Gatherv(mine.data(), count, MPI_BYTE, all.data(), counts.data(), offsets.data(), MPI_BYTE, 0, comm_);
    return all;
  }
  std::string first_error(const std::string& mine) const override {
    const int ranks = size();
    int me = mine.empty() ? ranks : rank(), first = ranks;
    MPI_Allreduce(&me, &first, 1, MPI_INT, MPI_MIN, comm_);
    if (first == ranks) return {};
    std::string message = rank() == first ? mine : std::string();
    int length = static_cast<int>(message.size());
    MPI_Bcast(&length, 1, MPI_INT, first, comm_);
    message.resize(static_cast<std::size_t>(length));
    MPI_Bcast(message.data(), length, MPI_CHAR, first, comm_);
    return message;
  }

private:
  MPI_Comm comm_;
};

// Every rank checks its share of the frames (VerifyFrameShare), rank 0 reports; rank 0's
// exit status (or the input error) goes to every rank.
int cmd_verify(const Args& a, MPI_Comm comm, std::ostream& out, std::ostream& err) {
  if (a.positional.empty()) usage_error("'verify' needs an output directory", "verify");
  if (a.positional.size() > 1) usage_error("unexpected argument '" + a.positional[1] + "'", "verify");
  VerifyOutputOptions opt;
  auto value = [&](const char* key) { return a.values.count(key) ? &a.values.at(key) : nullptr; };
  if (auto v = value("--frames")) {
    if (v->empty()) usage_error("--frames expects all, first, last or a list of frames", "verify");
    opt.frames = *v;
  }
  if (auto v = value("--max-depth")) opt.thresholds.max_depth = parse_limit("--max-depth", *v);
  if (auto v = value("--max-interior-depth")) opt.thresholds.max_interior_depth = parse_limit("--max-interior-depth", *v);
  if (auto v = value("--max-self-depth")) opt.thresholds.max_self_depth = parse_limit("--max-self-depth", *v);
  if (auto v = value("--max-crossings")) opt.thresholds.max_crossings = parse_nonnegative("--max-crossings", *v, "verify");
  if (auto v = value("--max-inverted")) opt.thresholds.max_inverted = parse_nonnegative("--max-inverted", *v, "verify");
  if (auto v = value("--max-speed-ratio")) opt.thresholds.max_speed_ratio = parse_limit("--max-speed-ratio", *v);
  if (auto v = value("--skip-frames-before")) {
    opt.skip_before = parse_limit("--skip-frames-before", *v);
    opt.skip = true;
  }
  if (auto v = value("--json")) {
    if (v->empty()) usage_error("--json expects a file name", "verify");
    opt.json = *v;
  }
  const MpiFrameShare share(comm);
  opt.share = &share;
  int code = 0;
  std::string message;
  try {
    code = verify_output(a.positional[0], opt, out, err);
  } catch (const InputError& e) {
    message = e.what();
    code = kExitInputError;
  }
  MPI_Bcast(&code, 1, MPI_INT, 0, comm);
  int length = static_cast<int>(message.size());
  MPI_Bcast(&length, 1, MPI_INT, 0, comm);
  message.resize(static_cast<std::size_t>(length));
  MPI_Bcast(message.data(), length, MPI_CHAR, 0, comm);
  if (code == kExitInputError) throw InputError(message);
  return code;
}

int cmd_info(std::ostream& out) {
  int mpi_len = 0;
  char mpi_version[MPI_MAX_LIBRARY_VERSION_STRING];
  MPI_Get_library_version(mpi_version, &mpi_len);
  std::string mpi(mpi_version, static_cast<std::size_t>(mpi_len));
  mpi = mpi.substr(0, mpi.find_first_of(",\n"));
  char petsc[256];
  PetscGetVersion(petsc, sizeof petsc);
  unsigned h5maj = 0, h5min = 0, h5rel = 0;
  H5get_libversion(&h5maj, &h5min, &h5rel);
  out << "softcontact " << SOFTCONTACT_VERSION << "\n"
      << "  MPI:      " << mpi << "\n"
      << "  PETSc:    " << petsc << "\n"
      << "  HDF5:     " << h5maj << '.' << h5min << '.' << h5rel << " (parallel)\n"
      << "  METIS:    " << METIS_VER_MAJOR << '.' << METIS_VER_MINOR << '.' << METIS_VER_SUBMINOR << "\n"
      << "  Eigen:    " << EIGEN_WORLD_VERSION << '.' << EIGEN_MAJOR_VERSION << '.' << EIGEN_MINOR_VERSION << "\n"
      << "  OpenMP:   " << _OPENMP << ", " << omp_get_max_threads() << " threads\n";
  return 0;
}

int dispatch(int argc, const char* const* argv, MPI_Comm comm, std::ostream& out, std::ostream& err) {
  const int rank = comm_rank(comm);
  auto say = [&](const char* text) {
    if (rank == 0) out << text;
    return 0;
  };
  if (argc < 2) {
    if (rank == 0) err << kMainHelp;
    usage_error("no command given", nullptr);
  }
  const std::string cmd = argv[1];
  if (cmd == "-h" || cmd == "--help" || cmd == "help") return say(kMainHelp);
  if (cmd == "--version") return say("softcontact " SOFTCONTACT_VERSION "\n");
  if (cmd == "run") {
    const Args a = parse_args(argc, argv, 2, "run",
                              {"--steps", "--end-time", "--output", "--output-every", "--restart", "--checkpoint-every",
                               "--checkpoint-minutes", "--verify-every"},
                              {"--overwrite", "--quiet"});
    return a.help ? say(kRunHelp) : cmd_run(a, comm, out, err);
  }
  if (cmd == "check") {
    const Args a = parse_args(argc, argv, 2, "check", {"--ranks"}, {});
    return a.help ? say(kCheckHelp) : cmd_check(a, comm, out, err);
  }
  if (cmd == "bench") {
    const Args a = parse_args(argc, argv, 2, "bench", {"--steps", "--warmup", "--csv", "--per-step"}, {"--quiet"});
    return a.help ? say(kBenchHelp) : cmd_bench(a, comm, out, err);
  }
  if (cmd == "verify") {
    const Args a = parse_args(argc, argv, 2, "verify",
                              {"--frames", "--max-depth", "--max-interior-depth", "--max-self-depth", "--max-crossings", "--max-inverted",
                               "--max-speed-ratio", "--json", "--skip-frames-before"},
                              {});
    return a.help ? say(kVerifyHelp) : cmd_verify(a, comm, out, err);
  }
  if (cmd == "info") {
    const Args a = parse_args(argc, argv, 2, "info", {}, {});
    return a.help ? say(kInfoHelp) : (rank == 0 ? cmd_info(out) : 0);
  }
  std::string msg = "unknown command '" + cmd + "'";
  const std::string guess = detail::nearest(cmd, {"run", "check", "bench", "verify", "info", "help"});
  if (!guess.empty()) msg += " (did you mean '" + guess + "'?)";
  usage_error(msg, nullptr);
}

}  // namespace

int run_cli(int argc, const char* const* argv, MPI_Comm comm, std::ostream& out, std::ostream& err) {
  const int rank = comm_rank(comm), size = comm_size(comm);
  int code = 0;
  bool input_error = false;
  std::string message;
  try {
    code = dispatch(argc, argv, comm, out, err);
  } catch (const InputError& e) {
    // Input is read identically on every rank, so every rank gets here together;
    // the lowest rank that failed speaks.
    code = kExitInputError;
    input_error = true;
    message = e.what();
  } catch (const NumericalFailure& e) {
    // Detected collectively: every rank is here with the same message.
    if (rank == 0) err << "softcontact: error: " << e.what() << std::endl;
    return kExitNumericalFailure;
  } catch (const CollectiveFailure& e) {
    // Detected by every rank together, with the same message.
    if (rank == 0) err << "softcontact: error: " << e.what() << std::endl;
    return 1;
  } catch (const std::bad_alloc&) {
    // Out of memory on this rank: what it had, what was expected, what to try. The
    // others may be waiting in a collective call, so end the whole job.
    err << "softcontact: error";
    if (size > 1) err << " on rank " << rank;
    err << ": out of memory (std::bad_alloc) with " << format_bytes(peak_rss_bytes()) << " resident at the peak";
    if (g_memory_estimate > 0) err << ", estimated " << format_bytes(g_memory_estimate) << " per rank";
    const MemoryLimits lim = memory_limits(MPI_COMM_SELF);
    if (lim.address_space > 0) err << ", address-space limit " << format_bytes(lim.address_space) << " (ulimit -v)";
    err << ". Try more ranks on more nodes, fewer ranks per node, a higher limit, or coarser meshes "
           "(docs/reliability.md, \"Memory\")" << std::endl;
    if (size > 1) MPI_Abort(comm, 1);
    return 1;
  } catch (const std::exception& e) {
    // A failure of this rank alone (I/O, numerical): the others may be waiting in a
    // collective call, so end the whole job.
    err << "softcontact: error";
    if (size > 1) err << " on rank " << rank;
    err << ": " << e.what() << std::endl;
    if (size > 1) MPI_Abort(comm, 1);
    return 1;
  }
  // A command may also return a status of its own on every rank (verify: 1, a limit exceeded).
  int failed_rank = input_error ? rank : size;
  int first = size;
  MPI_Allreduce(&failed_rank, &first, 1, MPI_INT, MPI_MIN, comm);
  if (first < size) {
    if (rank == first) err << "softcontact: error: " << message << std::endl;
    return kExitInputError;
  }
  return code;
}

}  // namespace softcontact
