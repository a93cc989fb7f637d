#include "failure_guard.hpp"

#include <algorithm>
#include <cmath>
#include <iomanip>
#include <limits>
#include <sstream>

#include "softcontact/error.hpp"
#include "softcontact/forces.hpp"
#include "softcontact/frame_writer.hpp"
#include "softcontact/diagnostics.hpp"
#include "softcontact/simulator.hpp"

namespace softcontact {

namespace {
double norm3(const Vec3& v) { return std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]); }
double total_energy(const StepDiagnostics& d) { return d.kinetic_energy + d.elastic_energy + d.potential_energy; }
}  // namespace

GuardScales guard_scales(const Scene& scene, int part, int parts, const std::function<void(std::vector<double>&)>& sum) {
  if (parts < 1 || !sum) part = 0, parts = 1;
  const double gn = norm3(scene.sim.gravity);
  // The mesh passes, object k on part k % parts: its lowest and highest point along
  // gravity, its volume and tets. Written by one part, zero on the others: the sum over
  // the parts is exact, and what follows is the one-part loop in object order.
  constexpr std::size_t kCols = 4;
  const std::size_t n = scene.objects.size();
  std::vector<double> per(kCols * n, 0.0);
  for (std::size_t k = static_cast<std::size_t>(part); k < n; k += static_cast<std::size_t>(parts)) {
    const Scene::MeshView view = scene.view_mesh(k);  // not kept where this rank dropped it
    const TetMesh& mesh = view.get();
    double lo = std::numeric_limits<double>::infinity(), hi = -lo;
    for (std::size_t i = 0; i < mesh.num_vertices(); ++i) {
      // Height along gravity: how far anything can fall.
      double h = 0;
      for (int d = 0; d < 3; ++d) h += mesh.points[3 * i + static_cast<std::size_t>(d)] * (gn > 0 ? scene.sim.gravity[static_cast<std::size_t>(d)] / gn : 0);
      lo = std::min(lo, h);
      hi = std::max(hi, h);
    }
    per[kCols * k] = lo;
    per[kCols * k + 1] = hi;
    per[kCols * k + 2] = scene.objects[k].kinematic() ? 0.0 : tet_volume_sum(mesh);
    per[kCols * k + 3] = static_cast<double>(mesh.num_tets());
  }
  if (parts > 1) sum(per);
  GuardScales g;
  double c = 0, v = 0, mass = 0, motion_work = 0;
  bool motion = false;
  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  for (std::size_t k = 0; k < n; ++k) {
    const SceneObject& o = scene.objects[k];
    const Material& m = scene.materials[static_cast<std::size_t>(o.material)];
    v = std::max({v, norm3(o.velocity()), norm3(o.motion().velocity)});
    motion = motion || o.motion().moves();
    lo = std::min(lo, per[kCols * k]);
    hi = std::max(hi, per[kCols * k + 1]);
    if (o.kinematic()) continue;
    c = std::max(c, m.wave_speed());
    const double volume = per[kCols * k + 2];
    mass += m.density * volume;
    motion_work += m.young * volume;
    g.movable_tets += static_cast<std::int64_t>(per[kCols * k + 3]);
  }
  const double height = hi > lo ? hi - lo : 0;
  g.max_speed = scene.sim.max_speed > 0 ? scene.sim.max_speed
                                        : 10 * std::max({c, v, std::sqrt(2 * gn * height)});
  // Falling the scene's height, moving at the fastest given speed and, when anchors are
  // driven, the work of straining every movable object fully.
  g.release = mass * gn * height + mass * v * v + (motion ? motion_work : 0);
  return g;
}

FailureGuard::FailureGuard(const Scene& scene, const GuardScales& scales, const std::string& output_dir, bool restart,
                           double energy0, double energy_scale)
    : scene_(scene), scales_(scales), dir_(output_dir), energy0_(energy0), release_(energy_scale),
      have_energy_(restart) {}

void FailureGuard::fail(std::int64_t step, double time, const std::string& what, bool solver) const {
  const Simulation& sim = scene_.sim;
  std::ostringstream m;
  std::ostringstream t;
  t << std::setprecision(6) << time;
  m << "numerical failure at step " << step << " (t = " << t.str() << " s): " << what
    << (solver ? ".\n  Try a smaller dt: now " : ".\n  The run has become unstable. Try a smaller dt: now ") << sim.dt
    << " s";
  const StableStep stable = stable_step(scene_);
  if (std::isfinite(stable.dt)) {
    m << "; the stable explicit limit of this scene is " << stable.dt << " s";
    if (stable.damped())
      m << " (with the Rayleigh damping of object '" << scene_.objects[static_cast<std::size_t>(stable.object)].name
        << "')";
    m << " ('dt: auto' takes " << sim.dt_safety << " of it)";
  }
  if (sim.integrator != IntegratorKind::implicit_euler) m << ", or the implicit_euler integrator";
  if (solver)
    m << "; or give the solver more room: PETSC_OPTIONS=\"-implicit_ksp_max_it N -implicit_ksp_rtol R\" "
         "(defaults 10000 and 1e-10), or another preconditioner (-implicit_pc_type jacobi)";
  m << ".\n  Frames up to step " << (frames_ ? frames_->last_step() : -1) << " are in " << dir_ << "; ";
  if (last_checkpoint_.empty()) m << "no checkpoint was written (simulation.checkpoint, --checkpoint-every).";
  else m << "the last good checkpoint is " << last_checkpoint_ << " (step " << last_checkpoint_step_ << ").";
  throw NumericalFailure(m.str());
}

void FailureGuard::check_frame(std::int64_t step, const StepDiagnostics& d, Simulator& sim) {
  if (!have_energy_) {
    energy0_ = total_energy(d);
    release_ = d.kinetic_energy + d.elastic_energy + scales_.release;
    have_energy_ = true;
  }
  const double grown = total_energy(d) - energy0_;
  if (!std::isfinite(total_energy(d)) || (release_ > 0 && grown > 10 * release_)) {
    std::ostringstream w;
    w << std::setprecision(4) << "the total energy grew by " << grown << " J, more than 10 times the " << release_
      << " J the scene can release; " << sim.locate_energy();
    fail(step, sim.time(), w.str());
  }
  const double allowed = scene_.sim.max_inverted_fraction * static_cast<double>(scales_.movable_tets);
  if (static_cast<double>(d.inverted_elements) > allowed) {
    const std::string where = sim.check_inversions(scene_.sim.max_inverted_fraction);
    if (!where.empty()) fail(step, sim.time(), where);
  }
}

}  // namespace softcontact
