#include "softcontact/simulator.hpp"

#include <petscsys.h>

#include <algorithm>
#include <cmath>

#include "softcontact/forces.hpp"
#include "softcontact/implicit_euler.hpp"
#include "softcontact/integrator.hpp"

namespace softcontact {

namespace {

int rank_of(MPI_Comm c) {
  int r = 0;
  MPI_Comm_rank(c, &r);
  return r;
}
int size_of(MPI_Comm c) {
  int s = 1;
  MPI_Comm_size(c, &s);
  return s;
}

CollisionSettings collision_settings(const Scene& s) {
  CollisionSettings c;
  c.self_collisions = s.sim.self_collisions;
  return c;
}

/// Objects -> ranks for a run with contact. Contacts between objects on different ranks
/// need the halo exchange of the MPI work, which does not exist yet; until then every
/// object stays on rank 0 (correct, not parallel across ranks: use OpenMP threads).
std::vector<int> contact_partition(const Scene& scene, int nranks) {
  (void)nranks;
  return std::vector<int>(scene.objects.size(), 0);
}

double median_edge_length(const World& w) {
  std::vector<double> len;
  len.reserve(6 * (w.tets.size() / 4));
  static constexpr int kEdges[6][2] = {{0, 1}, {0, 2}, {0, 3}, {1, 2}, {1, 3}, {2, 3}};
  for (std::size_t t = 0; t < w.tets.size() / 4; ++t)
    for (const auto& e : kEdges) {
      const double* a = &w.x[3 * w.tets[4 * t + e[0]]];
      const double* b = &w.x[3 * w.tets[4 * t + e[1]]];
      len.push_back(std::hypot(a[0] - b[0], a[1] - b[1], a[2] - b[2]));
    }
  if (len.empty()) return 0;
  std::nth_element(len.begin(), len.begin() + static_cast<std::ptrdiff_t>(len.size() / 2), len.end());
  return len[len.size() / 2];
}

}  // namespace

Simulator::Simulator(MPI_Comm comm, const Scene& scene)
    : comm_(comm),
      scene_(scene),
      world_(build_world(scene, contact_partition(scene, size_of(comm)), rank_of(comm))),
      elastic_(std::make_unique<ElasticForces>(scene, world_)),
      detector_(world_, collision_settings(scene)),
      contact_(scene, world_) {
  if (scene.sim.integrator == IntegratorKind::implicit_euler)
    implicit_ = std::make_unique<ImplicitEuler>(scene, world_, *elastic_);
  median_edge_ = median_edge_length(world_);
  {
    CollisionStats st;
    detector_.detect(world_, nullptr, residual_, st);
    // Overlaps between two fixed sides (walls built flush against a floor) exert no
    // force and move nothing: not worth a warning.
    auto movable = [&](index_t v) { return world_.inv_mass[static_cast<std::size_t>(v)] != 0; };
    for (const Collision& c : residual_) {
      if (!movable(c.point) && !movable(c.triangle[0]) && !movable(c.triangle[1]) && !movable(c.triangle[2])) continue;
      ++initial_overlaps_;
      initial_overlap_depth_ = std::max(initial_overlap_depth_, std::hypot(c.depth[0], c.depth[1], c.depth[2]));
    }
  }
  compute_forces();
  start_integration(world_, scene.sim, f_);
}

Simulator::~Simulator() = default;

namespace {
// The phases of a step as PETSc log events, so that PETSC_OPTIONS=-log_view reports them
// beside PETSc's own (KSPSolve of implicit Euler). Registered once, on first use after
// PetscInitialize; without PETSc (not initialised) nothing is logged.
struct PhaseEvents {
  bool on = false;
  PetscLogEvent forces = 0, integrate = 0, collide = 0, contact = 0;
};

const PhaseEvents& phase_events() {
  static const PhaseEvents ev = [] {
    PhaseEvents e;
    PetscBool init = PETSC_FALSE;
    if (PetscInitialized(&init) != 0 || !init) return e;
    PetscClassId cls = 0;
    e.on = PetscClassIdRegister("softcontact", &cls) == 0 && PetscLogEventRegister("scForces", cls, &e.forces) == 0 &&
           PetscLogEventRegister("scIntegrate", cls, &e.integrate) == 0 &&
           PetscLogEventRegister("scDetectDepth", cls, &e.collide) == 0 &&
           PetscLogEventRegister("scContact", cls, &e.contact) == 0;
    return e;
  }();
  return ev;
}

// Begins a phase's event on construction and ends it on destruction.
class PhaseLog {
public:
  PhaseLog(const PhaseEvents& ev, PetscLogEvent e) : on_(ev.on), e_(e) {
    if (on_) (void)PetscLogEventBegin(e_, nullptr, nullptr, nullptr, nullptr);
  }
  ~PhaseLog() {
    if (on_) (void)PetscLogEventEnd(e_, nullptr, nullptr, nullptr, nullptr);
  }
  PhaseLog(const PhaseLog&) = delete;
  PhaseLog& operator=(const PhaseLog&) = delete;

private:
  bool on_;
  PetscLogEvent e_;
};
}  // namespace

void Simulator::compute_forces() {
  // Step 1: p = gravity + internal forces + Rayleigh damping at (x^t, v^t); implicit
  // Euler treats damping inside its linear system instead.
  gravity_forces(world_, scene_.sim.gravity, f_);
  elastic_->add_forces(world_, f_, !implicit_);
}

void Simulator::step() {
  const Simulation& sim = scene_.sim;
  const PhaseEvents& ev = phase_events();
  double t = MPI_Wtime();
  {
    PhaseLog log(ev, ev.forces);
    compute_forces();
  }
  times_.forces += MPI_Wtime() - t;

  t = MPI_Wtime();
  {
    PhaseLog log(ev, ev.integrate);
    if (implicit_) implicit_->step(world_, sim, f_);
    else unconstrained_step(world_, sim, f_);  // World::x = x~, World::x_prev = x^t
    prescribed_motion(world_, time(), time() + sim.dt);  // moving anchors (scene `motion`)
  }
  times_.integrate += MPI_Wtime() - t;

  {
    PhaseLog log(ev, ev.collide);
    detector_.detect(world_, world_.x_prev.data(), collisions_, collision_stats_);
  }
  times_.detect += collision_stats_.detection_seconds;
  times_.depth += collision_stats_.depth_seconds;

  t = MPI_Wtime();
  {
    PhaseLog log(ev, ev.contact);
    contact_.respond(world_, collisions_, sim.dt, contact_stats_);
  }
  times_.contact += MPI_Wtime() - t;

  ++step_;
  ++timed_steps_;
}

void Simulator::measure(StepDiagnostics& d) {
  d.step = step_;
  d.time = time();
  ElasticMeasures em;
  elastic_->measure(world_, em);
  reduce_mechanics(comm_, scene_, world_, d, &em);
  // Residual penetration: detection again at the corrected positions.
  CollisionStats rs;
  detector_.detect(world_, nullptr, residual_, rs);
  double worst = 0;
  for (const Collision& c : residual_)
    worst = std::max(worst, std::hypot(c.depth[0], c.depth[1], c.depth[2]));
  double local[2] = {worst / (median_edge_ > 0 ? median_edge_ : 1.0), contact_stats_.force_balance};
  double global[2] = {0, 0};
  MPI_Allreduce(local, global, 2, MPI_DOUBLE, MPI_MAX, comm_);
  std::int64_t contacts = collision_stats_.colliding_points, total = 0;
  MPI_Allreduce(&contacts, &total, 1, MPI_INT64_T, MPI_SUM, comm_);
  d.contacts = total;
  d.residual_penetration = global[0];
  d.contact_force_balance = global[1];
}

PhaseTimes Simulator::take_times(std::int64_t& steps) {
  const PhaseTimes t = times_;
  steps = timed_steps_;
  times_ = PhaseTimes{};
  timed_steps_ = 0;
  return t;
}

}  // namespace softcontact
