#include "softcontact/integrator.hpp"

#include "softcontact/error.hpp"

namespace softcontact {

namespace {
/// Below this many vertices these loops run on one thread: starting a team would cost
/// more than the loop. (Every vertex is computed alone, so the result never depends on it.)
constexpr std::ptrdiff_t kParallelVertices = 4096;
}  // namespace

void gravity_forces(const World& w, const Vec3& g, std::vector<double>& f) {
  // Each owned row written once (not zeroed first: a step's array keeps its size). The
  // forces have no ghost rows: nothing computes or reads a force on another rank's
  // vertex (a split object's parts send theirs in their own buffers).
  f.resize(3 * w.n_owned);
  const std::ptrdiff_t n = static_cast<std::ptrdiff_t>(w.n_owned);
#pragma omp parallel for schedule(static) if (n >= kParallelVertices)
  for (std::ptrdiff_t i = 0; i < n; ++i) {
    const bool free = w.inv_mass[i] != 0;
    for (int d = 0; d < 3; ++d) f[3 * i + d] = free ? w.mass[i] * g[d] : 0.0;
  }
}

void start_integration(World& w, const Simulation& sim, const std::vector<double>& f) {
  const double dt = sim.dt;
  const std::ptrdiff_t n = static_cast<std::ptrdiff_t>(w.n_owned);
#pragma omp parallel for schedule(static) if (n >= kParallelVertices)
  for (std::ptrdiff_t i = 0; i < n; ++i)
    for (int d = 0; d < 3; ++d)
      w.x_prev[3 * i + d] = w.x[3 * i + d] - dt * w.v[3 * i + d] + 0.5 * dt * dt * w.inv_mass[i] * f[3 * i + d];
}

void unconstrained_step(World& w, const Simulation& sim, const std::vector<double>& f) {
  SC_ASSERT(sim.integrator != IntegratorKind::implicit_euler);
  const double dt = sim.dt;
  const std::ptrdiff_t n = static_cast<std::ptrdiff_t>(w.n_owned);
  if (sim.integrator == IntegratorKind::verlet) {
#pragma omp parallel for schedule(static) if (n >= kParallelVertices)
    for (std::ptrdiff_t i = 0; i < n; ++i)
      for (int d = 0; d < 3; ++d) {
        const std::ptrdiff_t k = 3 * i + d;
        const double xt = w.x[k];
        const double xn = w.inv_mass[i] == 0 ? xt : 2 * xt - w.x_prev[k] + dt * dt * w.inv_mass[i] * f[k];
        w.x_prev[k] = xt;
        w.x[k] = xn;
        w.v[k] = (xn - xt) / dt;
      }
  } else {
#pragma omp parallel for schedule(static) if (n >= kParallelVertices)
    for (std::ptrdiff_t i = 0; i < n; ++i)
      for (int d = 0; d < 3; ++d) {
        const std::ptrdiff_t k = 3 * i + d;
        w.x_prev[k] = w.x[k];
        if (w.inv_mass[i] == 0) continue;
        w.v[k] += dt * w.inv_mass[i] * f[k];
        w.x[k] += dt * w.v[k];
      }
  }
}

void prescribed_motion(World& w, double t0, double t1) {
  // Object by object: owned vertices are stored object by object in owned_objects'
  // order, so only the owned objects are looked at, never the whole scene's.
  SC_ASSERT(w.owned_motion.size() == w.owned_objects.size());
  const double inv_dt = 1.0 / (t1 - t0);
  for (std::size_t j = 0; j < w.owned_objects.size(); ++j) {
    const Motion& m = w.owned_motion[j];
    if (!m.moves()) continue;
    const double s = m.active_time(t0, t1);
    const bool active = s > 0;
    const auto k = static_cast<std::size_t>(w.owned_objects[j]);
    const std::ptrdiff_t b = static_cast<std::ptrdiff_t>(w.vertex_offset[k]);
    const std::ptrdiff_t e = b + static_cast<std::ptrdiff_t>(w.layout[k].vertex_count);
    const double u[3] = {m.velocity[0] * s, m.velocity[1] * s, m.velocity[2] * s};
    // Outside [start, stop] the anchors stand still: velocity 0 (symplectic Euler would
    // otherwise keep the last step's; Verlet has just set 0).
#pragma omp parallel for schedule(static) if (e - b >= kParallelVertices)
    for (std::ptrdiff_t i = b; i < e; ++i) {
      if (w.inv_mass[i] != 0) continue;
      for (int d = 0; d < 3; ++d) {
        if (active) w.x[3 * i + d] += u[d];
        w.v[3 * i + d] = active ? u[d] * inv_dt : 0.0;
      }
    }
  }
}

}  // namespace softcontact
