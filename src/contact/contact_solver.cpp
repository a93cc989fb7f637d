// The analytic contact response (contact.hpp gives the equations). Work is O(1) per
// collision: one pass for the column sums s_j, one (parallel) for alpha_i and the local
// forces, one scatter of the local forces in collision order, then friction likewise.
#include "softcontact/contact.hpp"

#include <cmath>

namespace softcontact {

namespace {
inline double norm3(const double* a) { return std::sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]); }
}  // namespace

ContactSolver::ContactSolver(const Scene& scene, const World& world) : friction_(scene.friction) {
  object_material_.reserve(scene.objects.size());
  for (const SceneObject& o : scene.objects) object_material_.push_back(o.material);
  slot_of_.assign(world.n_local(), -1);
  force_.assign(3 * world.n_local(), 0.0);
  penetration_.assign(3 * world.n_local(), 0.0);
}

std::int64_t ContactSolver::normal_forces(const std::vector<Collision>& col, double dt) {
  // Column sums s_j of H and collision counts, in collision order.
  for (std::size_t q = 0; q < col.size(); ++q) {
    const Collision& c = col[q];
    const Local& L = local_[q];
    for (int k = 0; k < 3; ++k) slots_[L.slot[1 + k]].column_sum += c.weight[k];
    slots_[L.slot[0]].count += 1;
  }
  const std::ptrdiff_t nc = static_cast<std::ptrdiff_t>(col.size());
  const double inv_dt2 = 1.0 / (dt * dt);
  std::int64_t fixed_pairs = 0;
  // Local forces per collision: each iteration writes only its own record.
#pragma omp parallel for schedule(static) reduction(+ : fixed_pairs)
  for (std::ptrdiff_t q = 0; q < nc; ++q) {
    const Collision& c = col[q];
    Local& L = local_[q];
    const Slot& si = slots_[L.slot[0]];
    const bool i_fixed = si.inv_mass == 0;
    const double ci = 1.0 / (1.0 + si.column_sum);  // (6)
    double cj[3], kin_weight = 0, MT = 0;
    bool any_kin = false;
    for (int k = 0; k < 3; ++k) {
      const Slot& sj = slots_[L.slot[1 + k]];
      cj[k] = 1.0 / (1.0 + sj.column_sum);
      if (c.weight[k] <= 0) continue;
      if (sj.inv_mass == 0) {
        any_kin = true;
        kin_weight += cj[k] * c.weight[k];
      } else {
        MT += cj[k] * c.weight[k] * sj.mass;
      }
    }
    for (int d = 0; d < 3; ++d) L.fi[d] = L.fT[0][d] = L.fT[1][d] = L.fT[2][d] = 0;
    L.fn = 0;
    if (i_fixed && any_kin) {  // two fixed sides: nothing can move
      ++fixed_pairs;
      continue;
    }
    if (any_kin) {
      // alpha = 1 (infinite M_T): i moves the whole way; the kinematic vertices of T_i
      // take the reaction in proportion to c_j omega_ij.
      for (int d = 0; d < 3; ++d) L.fi[d] = ci * si.mass * c.depth[d] * inv_dt2;
      for (int k = 0; k < 3; ++k) {
        if (c.weight[k] <= 0 || slots_[L.slot[1 + k]].inv_mass != 0) continue;
        const double share = cj[k] * c.weight[k] / kin_weight;
        for (int d = 0; d < 3; ++d) L.fT[k][d] = -share * L.fi[d];
      }
    } else if (i_fixed) {
      // alpha = 0 (infinite m_i): the triangle moves the whole way; i takes the reaction.
      for (int k = 0; k < 3; ++k) {
        const double a = -cj[k] * c.weight[k] * slots_[L.slot[1 + k]].mass * inv_dt2;
        for (int d = 0; d < 3; ++d) {
          L.fT[k][d] = a * c.depth[d];
          L.fi[d] -= L.fT[k][d];
        }
      }
    } else {
      const double cm = ci * si.mass;
      const double alpha = MT / (cm + MT);                                  // (5)
      for (int d = 0; d < 3; ++d) L.fi[d] = cm * alpha * c.depth[d] * inv_dt2;  // (15)
      for (int k = 0; k < 3; ++k) {
        const double a = -cj[k] * c.weight[k] * slots_[L.slot[1 + k]].mass * (1 - alpha) * inv_dt2;  // (16)
        for (int d = 0; d < 3; ++d) L.fT[k][d] = a * c.depth[d];
      }
    }
    L.fn = norm3(L.fi);
  }
  // Scatter in collision order: every per-vertex sum has a fixed order (eq. 22).
  for (std::size_t q = 0; q < col.size(); ++q) {
    const Local& L = local_[q];
    Slot& si = slots_[L.slot[0]];
    for (int d = 0; d < 3; ++d) {
      si.normal[d] += L.fi[d];
      si.depth[d] += col[q].depth[d];
    }
    for (int k = 0; k < 3; ++k) {
      Slot& sj = slots_[L.slot[1 + k]];
      for (int d = 0; d < 3; ++d) sj.normal[d] += L.fT[k][d];
    }
  }
  return fixed_pairs;
}

void ContactSolver::friction_forces(const std::vector<Collision>& col, double dt, ContactStats& stats) {
  // Method.md, "Friction": velocities implied by the corrected positions; relative
  // tangential velocity u_t of i against the point of T_i it touches; the force that
  // stops it within the step, f_t = -m_eff u_t / dt, limited by Coulomb's cone. A point
  // that several constraints act on must not be stopped several times over: the
  // stopping force is shared with the factor c_i / (collisions at i), the weights c that
  // share the normal response (c_i = 1 against a fixed obstacle, 1/2 where two matching
  // surfaces press into each other).
  const std::ptrdiff_t nc = static_cast<std::ptrdiff_t>(col.size());
  const double inv_dt = 1.0 / dt;
  std::int64_t sticking = 0, sliding = 0;
#pragma omp parallel for schedule(static) reduction(+ : sticking, sliding)
  for (std::ptrdiff_t q = 0; q < nc; ++q) {
    const Collision& c = col[q];
    Local& L = local_[q];
    double* ft = L.fi;  // reused: the normal forces are already scattered
    ft[0] = ft[1] = ft[2] = 0;
    const double dn = norm3(c.depth.data());
    if (dn == 0 || L.fn == 0) continue;
    const Friction& mu = friction_[object_material_[c.object]][object_material_[c.other_object]];
    if (mu.mu_static == 0 && mu.mu_kinetic == 0) continue;
    const double n[3] = {c.depth[0] / dn, c.depth[1] / dn, c.depth[2] / dn};
    const Slot& si = slots_[L.slot[0]];
    double u[3];
    for (int d = 0; d < 3; ++d) {
      u[d] = si.dx[d];
      for (int k = 0; k < 3; ++k) u[d] -= c.weight[k] * slots_[L.slot[1 + k]].dx[d];
      u[d] *= inv_dt;
    }
    const double un = u[0] * n[0] + u[1] * n[1] + u[2] * n[2];
    const double ut[3] = {u[0] - un * n[0], u[1] - un * n[1], u[2] - un * n[2]};
    const double ut_len = norm3(ut);
    if (ut_len == 0) continue;
    double inv_meff = si.inv_mass;
    for (int k = 0; k < 3; ++k) inv_meff += c.weight[k] * c.weight[k] * slots_[L.slot[1 + k]].inv_mass;
    if (inv_meff == 0) continue;  // both sides fixed
    const double share = 1.0 / ((1.0 + si.column_sum) * si.count);
    const double stop = share * ut_len * inv_dt / inv_meff;  // |f_t| that stops the sliding
    double mag;
    if (stop <= mu.mu_static * L.fn) {
      mag = stop;
      ++sticking;
    } else {
      mag = mu.mu_kinetic * L.fn;
      ++sliding;
    }
    for (int d = 0; d < 3; ++d) ft[d] = -mag * ut[d] / ut_len;
  }
  stats.sticking = sticking;
  stats.sliding = sliding;
  for (std::size_t q = 0; q < col.size(); ++q) {
    const Local& L = local_[q];
    const Collision& c = col[q];
    for (int d = 0; d < 3; ++d) slots_[L.slot[0]].friction[d] += L.fi[d];
    for (int k = 0; k < 3; ++k)
      for (int d = 0; d < 3; ++d) slots_[L.slot[1 + k]].friction[d] -= c.weight[k] * L.fi[d];
  }
}

void ContactSolver::respond(World& w, const std::vector<Collision>& col, double dt, ContactStats& stats) {
  for (index_t v : vertex_of_) slot_of_[v] = -1;
  vertex_of_.clear();
  slots_.clear();
  materialized_current_ = false;
  stats = ContactStats{};
  stats.collisions = static_cast<std::int64_t>(col.size());

  // Slots in order of first appearance in the sorted collision list: a fixed order.
  local_.resize(col.size());
  auto slot = [&](index_t v) {
    if (slot_of_[v] < 0) {
      slot_of_[v] = static_cast<std::int32_t>(vertex_of_.size());
      vertex_of_.push_back(v);
      Slot s{};
      s.mass = w.mass[v];
      s.inv_mass = static_cast<std::size_t>(v) < w.n_owned ? w.inv_mass[v] : 0.0;
      for (int d = 0; d < 3; ++d) s.dx[d] = w.x[3 * v + d] - w.x_prev[3 * v + d];
      slots_.push_back(s);
    }
    return slot_of_[v];
  };
  for (std::size_t q = 0; q < col.size(); ++q) {
    local_[q].slot[0] = slot(col[q].point);
    for (int k = 0; k < 3; ++k) local_[q].slot[1 + k] = slot(col[q].triangle[k]);
  }
  if (col.empty()) return;

  stats.fixed_pairs = normal_forces(col, dt);
  // Normal correction first (friction sees the corrected velocities), x = x~ + dt^2 F/m.
  const double dt2 = dt * dt;
  for (Slot& s : slots_)
    for (int d = 0; d < 3; ++d) s.dx[d] += dt2 * s.inv_mass * s.normal[d];
  friction_forces(col, dt, stats);

  double sum[3] = {0, 0, 0}, abs_sum = 0;
  for (std::size_t k = 0; k < slots_.size(); ++k) {
    const Slot& s = slots_[k];
    const index_t v = vertex_of_[k];
    double f[3];
    for (int d = 0; d < 3; ++d) {
      f[d] = s.normal[d] + s.friction[d];
      sum[d] += f[d];
    }
    abs_sum += norm3(f);
    if (s.inv_mass == 0) continue;
    for (int d = 0; d < 3; ++d) {
      w.x[3 * v + d] += dt2 * s.inv_mass * f[d];  // (12): x = x~ + dt^2 F / m
      w.v[3 * v + d] += dt * s.inv_mass * f[d];
    }
  }
  for (const Collision& c : col) stats.max_depth = std::max(stats.max_depth, norm3(c.depth.data()));
  stats.force_balance = abs_sum > 0 ? norm3(sum) / abs_sum : 0;
}

void ContactSolver::materialize() {
  if (materialized_current_) return;
  for (index_t v : materialized_)
    for (int d = 0; d < 3; ++d) force_[3 * v + d] = penetration_[3 * v + d] = 0;
  materialized_ = vertex_of_;
  for (std::size_t k = 0; k < slots_.size(); ++k) {
    const index_t v = vertex_of_[k];
    for (int d = 0; d < 3; ++d) {
      force_[3 * v + d] = slots_[k].normal[d] + slots_[k].friction[d];
      penetration_[3 * v + d] = slots_[k].depth[d];
    }
  }
  materialized_current_ = true;
}

const std::vector<double>& ContactSolver::force() {
  materialize();
  return force_;
}

const std::vector<double>& ContactSolver::penetration() {
  materialize();
  return penetration_;
}

}  // namespace softcontact
