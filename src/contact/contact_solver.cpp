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
    L.ai = L.aT[0] = L.aT[1] = L.aT[2] = 0;
    if (i_fixed && any_kin) {  // two fixed sides: nothing can move
      ++fixed_pairs;
      continue;
    }
    if (any_kin) {
      // alpha = 1 (infinite M_T): i moves the whole way; the kinematic vertices of T_i
      // take the reaction in proportion to c_j omega_ij.
      L.ai = ci * si.mass * inv_dt2;
      for (int k = 0; k < 3; ++k)
        if (c.weight[k] > 0 && slots_[L.slot[1 + k]].inv_mass == 0) L.aT[k] = -cj[k] * c.weight[k] / kin_weight * L.ai;
    } else if (i_fixed) {
      // alpha = 0 (infinite m_i): the triangle moves the whole way; i takes the reaction.
      for (int k = 0; k < 3; ++k) {
        L.aT[k] = -cj[k] * c.weight[k] * slots_[L.slot[1 + k]].mass * inv_dt2;
        L.ai -= L.aT[k];
      }
    } else {
      const double cm = ci * si.mass;
      const double alpha = MT / (cm + MT);  // (5)
      L.ai = cm * alpha * inv_dt2;          // (15)
      for (int k = 0; k < 3; ++k)
        L.aT[k] = -cj[k] * c.weight[k] * slots_[L.slot[1 + k]].mass * (1 - alpha) * inv_dt2;  // (16)
    }
  }
  // Scatter in collision order: every per-vertex sum has a fixed order (eq. 22).
  for (std::size_t q = 0; q < col.size(); ++q) {
    const Local& L = local_[q];
    const double* d = col[q].depth.data();
    Slot& si = slots_[L.slot[0]];
    for (int a = 0; a < 3; ++a) {
      si.normal[a] += L.ai * d[a];
      si.depth[a] += d[a];
    }
    for (int k = 0; k < 3; ++k) {
      Slot& sj = slots_[L.slot[1 + k]];
      for (int a = 0; a < 3; ++a) sj.normal[a] += L.aT[k] * d[a];
    }
  }
  return fixed_pairs;
}

void ContactSolver::friction_forces(const World& w, const std::vector<Collision>& col, double dt, ContactStats& stats) {
  // Coulomb friction, decoupled from the normal response (the paper's Sec. 3.4) and
  // computed with the same closed form. After the normal correction, the relative
  // tangential motion of i against the point of T_i it touches within this step is
  //   u_t dt,  u = (x_i - x_i^t - sum_j omega_ij (x_j - x_j^t)) / dt,  tangential to n = d/|d|.
  // Undoing it is a second, tangential "penetration" e_i = -u_t dt, and the local force
  // pair of eqs (15)-(16) with e_i in place of d_i (same alpha_i, same c_j) removes it
  // exactly where the normal response removes the penetration exactly: stiction
  // therefore leaves no creep. Because both pairs share their coefficients,
  // |f_t| / |f_n| = |e_i| / |d_i| per collision, which makes Coulomb's law a clamp:
  //   stick  if |e_i| <= mu_s |d_i|,   else slide with e_i scaled to mu_k |d_i|.
  // The pair sums to zero like the normal one.
  //
  // Anchored stiction: when i already sticks to B, u dt is instead the tangential offset
  // of i from its anchor a on B (contact.hpp), both after the normal correction:
  //   u dt = x_i - sum_k b_k x_(a_k),
  // which equals the in-step motion when i started the step on its anchor, and otherwise
  // also undoes the slip left over from earlier steps (within the same cone).
  auto corrected = [&](index_t v, int d) {
    const std::int32_t sv = slot_of_[static_cast<std::size_t>(v)];
    return sv >= 0 ? w.x_prev[3 * v + d] + slots_[sv].dx[d] : w.x[3 * v + d];
  };
  const std::ptrdiff_t nc = static_cast<std::ptrdiff_t>(col.size());
  std::int64_t sticking = 0, sliding = 0;
#pragma omp parallel for schedule(static) reduction(+ : sticking, sliding)
  for (std::ptrdiff_t q = 0; q < nc; ++q) {
    const Collision& c = col[q];
    Local& L = local_[q];
    L.scale = 0;
    L.e[0] = L.e[1] = L.e[2] = 0;
    L.keep_anchor = false;
    const double dn = norm3(c.depth.data());
    if (dn == 0 || L.ai == 0) continue;
    const Friction& mu = friction_[object_material_[c.object]][object_material_[c.other_object]];
    if (mu.mu_static == 0 && mu.mu_kinetic == 0) continue;
    const double n[3] = {c.depth[0] / dn, c.depth[1] / dn, c.depth[2] / dn};
    double u[3];
    const Anchor& an = anchor_[static_cast<std::size_t>(c.point)];
    const bool anchored = an.object == c.other_object && an.step >= step_ - kAnchorGrace;
    if (anchored) {
      for (int d = 0; d < 3; ++d) {
        u[d] = corrected(c.point, d);
        for (int k = 0; k < 3; ++k) u[d] -= an.bary[k] * corrected(an.tri[k], d);
      }
    } else {
      for (int d = 0; d < 3; ++d) {
        u[d] = slots_[L.slot[0]].dx[d];
        for (int k = 0; k < 3; ++k) u[d] -= c.weight[k] * slots_[L.slot[1 + k]].dx[d];
      }
    }
    const double un = u[0] * n[0] + u[1] * n[1] + u[2] * n[2];
    for (int d = 0; d < 3; ++d) L.e[d] = -(u[d] - un * n[d]);
    const double en = norm3(L.e);
    if (en <= mu.mu_static * dn) {
      L.scale = en == 0 ? 0 : 1;
      L.keep_anchor = anchored;
      ++sticking;
    } else {
      L.scale = mu.mu_kinetic * dn / en;
      ++sliding;
    }
  }
  stats.sticking = sticking;
  stats.sliding = sliding;
  for (std::size_t q = 0; q < col.size(); ++q) {
    const Local& L = local_[q];
    if (L.scale == 0) continue;
    for (int d = 0; d < 3; ++d) slots_[L.slot[0]].friction[d] += L.ai * L.scale * L.e[d];
    for (int k = 0; k < 3; ++k)
      for (int d = 0; d < 3; ++d) slots_[L.slot[1 + k]].friction[d] += L.aT[k] * L.scale * L.e[d];
  }
}

void ContactSolver::respond(World& w, const std::vector<Collision>& col, double dt, ContactStats& stats) {
  for (index_t v : vertex_of_) slot_of_[v] = -1;
  vertex_of_.clear();
  slots_.clear();
  materialized_current_ = false;
  stats = ContactStats{};
  stats.collisions = static_cast<std::int64_t>(col.size());
  ++step_;
  if (anchor_.size() != w.n_local()) anchor_.assign(w.n_local(), Anchor{});

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
  friction_forces(w, col, dt, stats);

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
  update_anchors(w, col);
}

// After the step: points that stuck to a valid anchor keep it; every other colliding
// point takes a new anchor, the foot of its final position on the final plane of T_i
// (barycentric coordinates, not clamped: the foot may lie just outside T_i). In
// collision order, so a point with records against two bodies ends with the later one.
void ContactSolver::update_anchors(const World& w, const std::vector<Collision>& col) {
  for (std::size_t q = 0; q < col.size(); ++q) {
    const Collision& c = col[q];
    Anchor& an = anchor_[static_cast<std::size_t>(c.point)];
    if (local_[q].keep_anchor) {
      an.step = step_;
      continue;
    }
    const double* a = &w.x[3 * c.triangle[0]];
    const double* b = &w.x[3 * c.triangle[1]];
    const double* e = &w.x[3 * c.triangle[2]];
    const double* p = &w.x[3 * c.point];
    const double ab[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, ae[3] = {e[0] - a[0], e[1] - a[1], e[2] - a[2]},
                 ap[3] = {p[0] - a[0], p[1] - a[1], p[2] - a[2]};
    const double d00 = ab[0] * ab[0] + ab[1] * ab[1] + ab[2] * ab[2], d01 = ab[0] * ae[0] + ab[1] * ae[1] + ab[2] * ae[2],
                 d11 = ae[0] * ae[0] + ae[1] * ae[1] + ae[2] * ae[2], d20 = ap[0] * ab[0] + ap[1] * ab[1] + ap[2] * ab[2],
                 d21 = ap[0] * ae[0] + ap[1] * ae[1] + ap[2] * ae[2];
    const double den = d00 * d11 - d01 * d01;
    an.step = step_;
    an.object = c.other_object;
    for (int k = 0; k < 3; ++k) an.tri[k] = c.triangle[k];
    if (den > 0) {
      const double v = (d11 * d20 - d01 * d21) / den, u = (d00 * d21 - d01 * d20) / den;
      an.bary[0] = 1 - v - u;
      an.bary[1] = v;
      an.bary[2] = u;
    } else {  // a degenerate triangle: the detector's weights
      for (int k = 0; k < 3; ++k) an.bary[k] = c.weight[k];
    }
  }
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
