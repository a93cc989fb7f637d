// The analytic contact response (contact.hpp gives the equations). Work is O(1) per
// collision: one pass for the summed pushes S_v, one (parallel) for the approach and the
// coefficients of the local forces, two folds of the local forces per vertex (all of
// the normal correction and its dynamic part), then friction likewise.
//
// Every per-vertex sum is a fold over the vertex's contributions in the order of their
// collisions' keys (point_gid, triangle_gid), which is the order of the sorted collision
// list. With several ranks a vertex's contributions come from every rank holding a
// collision that touches it: the other ranks send theirs, with the keys, to the owner
// (reduce), which merges them with its own in key order and folds; the owner then sends
// the sums the others need back (reply). The arithmetic is the same on any rank count.
#include "softcontact/contact.hpp"


#include <algorithm>
#include <cmath>

#include "coupled_closure.hpp"

#include "softcontact/error.hpp"
#include "softcontact/exchange.hpp"
#include "softcontact/keyed_sums.hpp"
#include "softcontact/verify.hpp"

namespace softcontact {

namespace {
// Below this many collisions the per-collision loops run on one thread: waking the team
// costs more than the loop saves. tori200 (about 2,070 collisions at rest, 1 rank,
// OMP_WAIT_POLICY=passive): the response took 1.71 to 1.79 ms on 2 threads against 1.01
// to 1.11 ms on 1. Each iteration writes only its own collision, so the thread count
// changes no result.
constexpr std::ptrdiff_t kParallelCollisions = 16384;

inline double norm3(const double* a) { return std::sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]); }

// A vector v acting on a collision's point side: all on i for a vertex collision, split
// by the weights (pw, 1 - pw) over an edge contact's two vertices.
template <int N = 3, class LocalT, class F>
void emit_point_side(const LocalT& L, const double* v, F&& f) {
  if (L.slot2 < 0) {
    f(L.slot[0], v);
    return;
  }
  double a[N], b[N];
  for (int d = 0; d < N; ++d) {
    a[d] = L.pw * v[d];
    b[d] = (1 - L.pw) * v[d];
  }
  f(L.slot[0], a);
  f(L.slot2, b);
}
}  // namespace

ContactResponse::ContactResponse(const Scene& scene, const World& world)
    : friction_(scene.friction), separation_speed_(scene.sim.separation_speed) {
  object_material_.reserve(scene.objects.size());
  for (const SceneObject& o : scene.objects) object_material_.push_back(o.material);
  for (const ObjectLayout& L : world.layout) object_vertex_begin_.push_back(L.vertex_begin);
  slot_of_.assign(world.n_local(), -1);
  force_.assign(3 * world.n_local(), 0.0);
  penetration_.assign(3 * world.n_local(), 0.0);
  anchor_.assign(world.n_owned, StictionAnchor{});
  coupled_ = scene.sim.contact_closure == ContactClosure::coupled;
}

std::int32_t ContactResponse::slot_of_vertex(const World& w, index_t v) {
  const auto i = static_cast<std::size_t>(v);
  if (slot_of_[i] < 0) {
    slot_of_[i] = static_cast<std::int32_t>(vertex_of_.size());
    vertex_of_.push_back(v);
    Slot s{};
    s.mass = w.mass[i];
    s.inv_mass = w.inv_mass[i];
    s.gid = w.vertex_gid[i];
    for (int d = 0; d < 3; ++d) s.dx[d] = s.dx0[d] = w.x[3 * i + d] - w.x_prev[3 * i + d];
    slots_.push_back(s);
  }
  return slot_of_[i];
}

// Which slots are ghosts and who owns them; the neighbours' requests add slots for our
// vertices they touch (KeyedSums::plan, once per step).
void ContactResponse::plan_ghosts(const World& w, NeighbourExchange* exchange) {
  if (!exchange) {
    sums_.plan_local(slots_.size());
    return;
  }
  slot_owner_.resize(slots_.size());
  slot_gid_.resize(slots_.size());
  for (std::size_t k = 0; k < slots_.size(); ++k) {
    const auto v = static_cast<std::size_t>(vertex_of_[k]);
    slot_owner_[k] = v < w.n_owned ? -1 : w.layout[static_cast<std::size_t>(w.vertex_object[v])].rank;
    slot_gid_[k] = slots_[k].gid;
  }
  sums_.plan(exchange, slot_owner_, slot_gid_, [&](gid_t g) {
    const auto o = std::upper_bound(object_vertex_begin_.begin(), object_vertex_begin_.end(), g) -
                   object_vertex_begin_.begin() - 1;
    return slot_of_vertex(w, w.local_vertex(static_cast<int>(o), g));
  });
}

// A per-slot field summed over the collisions in key order (KeyedSums::reduce).
template <std::size_t N, class Emit>
void ContactResponse::sum(const std::vector<Collision>& col, Emit&& emit, double (Slot::*field)[N]) {
  sums_.reduce(
      col.size(), [&](std::size_t q) { return KeyedSums::Key{col[q].point_gid, col[q].triangle_gid}; },
      static_cast<int>(N), emit,
      [&](std::int32_t k) -> double* { return slots_[static_cast<std::size_t>(k)].*field; });
}

// The owners' values of a per-slot field into the ghost slots (KeyedSums::reply).
void ContactResponse::reply(double (Slot::*field)[3]) {
  sums_.reply(3, [&](std::int32_t k) -> double* { return slots_[static_cast<std::size_t>(k)].*field; });
}

// The depth each collision removes in this step, and the step's approach. The part of
// d_i that the pair's approach within the step explains (the gap this step's motion
// opened) is closed with the velocity that goes with it, as in the paper: the relative
// normal velocity is stopped (dynamic_fractions). The rest is an overlap that was there
// before the step (bodies that start overlapping, a gap left by an earlier step); it is
// removed by a position-only correction, which changes no velocity (so it adds no
// kinetic energy), and at most separation_speed * dt of it per step.
void ContactResponse::effective_depths(const std::vector<Collision>& col, double dt) {
  const std::ptrdiff_t nc = static_cast<std::ptrdiff_t>(col.size());
  const double slack = separation_speed_ * dt;
  std::int64_t capped = 0;
#pragma omp parallel for schedule(static) reduction(+ : capped) if (nc >= kParallelCollisions)
  for (std::ptrdiff_t q = 0; q < nc; ++q) {
    const Collision& c = col[static_cast<std::size_t>(q)];
    Local& L = local_[static_cast<std::size_t>(q)];
    const double D = norm3(c.depth.data());
    for (int d = 0; d < 3; ++d) L.d[d] = c.depth[static_cast<std::size_t>(d)];
    L.approach = 0;
    L.dynamic = 1;
    L.closed = 0;
    if (D == 0) continue;
    // Approach of i towards the point of T_i it touches within the step, along -n.
    double approach = 0;
    for (int d = 0; d < 3; ++d) {
      double u = L.pw * slots_[static_cast<std::size_t>(L.slot[0])].dx0[d];
      if (L.slot2 >= 0) u += (1 - L.pw) * slots_[static_cast<std::size_t>(L.slot2)].dx0[d];
      for (int k = 0; k < 3; ++k) u -= c.weight[static_cast<std::size_t>(k)] * slots_[static_cast<std::size_t>(L.slot[1 + k])].dx0[d];
      approach -= u * c.depth[static_cast<std::size_t>(d)] / D;
    }
    L.approach = std::max(approach, 0.0);
    if (D > L.approach + slack) {
      for (int d = 0; d < 3; ++d) L.d[d] *= (L.approach + slack) / D;
      ++capped;
    }
  }
  capped_ = capped;
}

// The dynamic part of each collision's force pair, once the normal correction of every
// vertex is known. What the correction actually closes of collision q's gap along n is
//   A_q = n . (delta_i - sum_j omega_ij delta_j),   delta = corrected x - x~,
// which is |d_q| for an isolated collision but can be less where shares split a vertex.
// The first a_q of it (the step's approach) is stopped with velocity; only what closes
// more is position-only. Measuring against A_q rather than |d_q| matters at rest: with
// a_q / |d_q| a collision closed to a fraction s kept the velocity (1 - s) a_q / dt
// into the contact step after step while a position-only shift held it in place (a
// stored velocity that was not the positions' rate, seen as kinetic energy at rest).
void ContactResponse::dynamic_fractions(const std::vector<Collision>& col) {
  const std::ptrdiff_t nc = static_cast<std::ptrdiff_t>(col.size());
#pragma omp parallel for schedule(static) if (nc >= kParallelCollisions)
  for (std::ptrdiff_t q = 0; q < nc; ++q) {
    const Collision& c = col[static_cast<std::size_t>(q)];
    Local& L = local_[static_cast<std::size_t>(q)];
    const double D = norm3(L.d);
    if (D == 0) continue;
    double closed = 0;
    for (int d = 0; d < 3; ++d) {
      const Slot& si = slots_[static_cast<std::size_t>(L.slot[0])];
      double u = L.pw * (si.dx[d] - si.dx0[d]);
      if (L.slot2 >= 0) {
        const Slot& s2 = slots_[static_cast<std::size_t>(L.slot2)];
        u += (1 - L.pw) * (s2.dx[d] - s2.dx0[d]);
      }
      for (int k = 0; k < 3; ++k) {
        const Slot& sj = slots_[static_cast<std::size_t>(L.slot[1 + k])];
        u -= c.weight[static_cast<std::size_t>(k)] * (sj.dx[d] - sj.dx0[d]);
      }
      closed += u * L.d[d] / D;
    }
    L.closed = closed;
    L.dynamic = closed > L.approach ? L.approach / closed : (L.approach > 0 ? 1.0 : 0.0);
  }
}

// The normal force pair of each collision (contact.hpp gives the rule): f = lambda_q d_i
// on i, -omega_j lambda_q d_i on j in T_i, with lambda_q = 1 / (dt^2 K_q) and the shared
// generalised inverse mass K_q = sum_v beta_v sigma_qv / m_v (beta = 1 for i, omega_j
// for j; kinematic vertices add nothing). sigma_qv is vertex v's share: the part of the
// summed pushes on v (slot.share, sum over its collisions of beta p, p the direction the
// collision pushes v in) that lies along this collision's push, never less than its own
// beta. An isolated collision has sigma = beta and closes exactly; k collisions pushing a
// vertex the same way split it k ways, so no motion is applied twice.
std::int64_t ContactResponse::normal_coefficients(const std::vector<Collision>& col, double dt) {
  const std::ptrdiff_t nc = static_cast<std::ptrdiff_t>(col.size());
  const double inv_dt2 = 1.0 / (dt * dt);
  std::int64_t fixed_pairs = 0;
  // Local forces per collision: each iteration writes only its own record.
#pragma omp parallel for schedule(static) reduction(+ : fixed_pairs) if (nc >= kParallelCollisions)
  for (std::ptrdiff_t q = 0; q < nc; ++q) {
    const Collision& c = col[static_cast<std::size_t>(q)];
    Local& L = local_[static_cast<std::size_t>(q)];
    L.ai = L.aT[0] = L.aT[1] = L.aT[2] = 0;
    L.fa = L.faT[0] = L.faT[1] = L.faT[2] = 0;
    const double D = norm3(c.depth.data());
    if (D == 0) continue;
    const double n[3] = {c.depth[0] / D, c.depth[1] / D, c.depth[2] / D};
    double K = 0;
    const Slot& si = slots_[static_cast<std::size_t>(L.slot[0])];
    if (si.inv_mass > 0)
      K += L.pw * std::max(L.pw, (n[0] * si.share[0] + n[1] * si.share[1] + n[2] * si.share[2]) / D) * si.inv_mass;
    if (L.slot2 >= 0) {  // an edge contact's second point-side vertex
      const Slot& s2 = slots_[static_cast<std::size_t>(L.slot2)];
      const double w2 = 1 - L.pw;
      if (w2 > 0 && s2.inv_mass > 0)
        K += w2 * std::max(w2, (n[0] * s2.share[0] + n[1] * s2.share[1] + n[2] * s2.share[2]) / D) * s2.inv_mass;
    }
    for (int k = 0; k < 3; ++k) {
      const double wk = c.weight[static_cast<std::size_t>(k)];
      const Slot& sj = slots_[static_cast<std::size_t>(L.slot[1 + k])];
      if (wk <= 0 || sj.inv_mass == 0) continue;
      K += wk * std::max(wk, -(n[0] * sj.share[0] + n[1] * sj.share[1] + n[2] * sj.share[2]) / D) * sj.inv_mass;
    }
    if (!(K > 0)) {  // both sides kinematic: nothing can move
      ++fixed_pairs;
      continue;
    }
    const double lambda = inv_dt2 / K;
    L.ai = lambda;
    for (int k = 0; k < 3; ++k) L.aT[k] = -c.weight[static_cast<std::size_t>(k)] * lambda;
    L.fa = L.ai;
    for (int k = 0; k < 3; ++k) L.faT[k] = L.aT[k];
  }
  return fixed_pairs;
}

// simulation.contact_closure: coupled (coupled_closure.hpp): the magnitudes of all
// collisions together, so that every gap closes by its applied depth when all
// corrections act at once. The rows carry global ids and the collisions' keys; with
// several ranks they are gathered to rank 0, merged in key order (the order of the one-
// rank list), solved there and the magnitudes sent back (solve_in_key_order,
// keyed_sums.hpp): the same matrix and the same arithmetic on any rank count. Friction keeps the per-collision coefficients (fa, faT)
// for its stopping forces; Coulomb's cone takes the coupled normal force.
void ContactResponse::coupled_coefficients(const std::vector<Collision>& col, double dt, NeighbourExchange* exchange, ContactStats& stats) {
  const std::size_t nc = col.size();
  std::vector<contact::ClosureRow> rows(nc);
  for (std::size_t q = 0; q < nc; ++q) {
    const Local& L = local_[q];
    contact::ClosureRow& r = rows[q];
    r.key_point = col[q].point_gid;
    r.key_triangle = col[q].triangle_gid;
    const double D = norm3(L.d);
    if (D == 0 || L.ai == 0) continue;
    r.depth = D;
    for (int d = 0; d < 3; ++d) r.n[d] = L.d[d] / D;
    auto add = [&](std::int32_t k, double b) {
      const Slot& s = slots_[static_cast<std::size_t>(k)];
      r.vertex[r.nv] = s.gid;
      r.b[r.nv] = b;
      r.inv_mass[r.nv] = s.inv_mass;
      ++r.nv;
    };
    add(L.slot[0], L.pw);
    for (int k = 0; k < 3; ++k) add(L.slot[1 + k], -col[q].weight[static_cast<std::size_t>(k)]);
    if (L.slot2 >= 0) add(L.slot2, 1 - L.pw);
  }
  contact::ClosureStats cs;
  const std::vector<double> x = solve_in_key_order(
      exchange, rows, [](const contact::ClosureRow& r) { return KeyedSums::Key{r.key_point, r.key_triangle}; },
      [](const std::vector<contact::ClosureRow>& all, contact::ClosureStats& st) {
        return contact::solve_closure(all, kClosureEps, st);
      },
      cs);
  stats.closure_rows = cs.rows;
  stats.closure_dropped = cs.dropped;
  stats.closure_local = cs.local;
  const double inv_dt2 = 1.0 / (dt * dt);
  for (std::size_t q = 0; q < nc; ++q) {
    Local& L = local_[q];
    if (rows[q].depth == 0 || std::isnan(x[q])) continue;  // NaN: the closed form stays
    const double lambda = x[q] / rows[q].depth * inv_dt2;
    L.ai = lambda;
    for (int k = 0; k < 3; ++k) L.aT[k] = -col[q].weight[static_cast<std::size_t>(k)] * lambda;
  }
}

void ContactResponse::friction_coefficients(const std::vector<Collision>& col, ContactStats& stats) {
  // Coulomb friction, decoupled from the normal response (the paper's Sec. 3.4) and
  // computed with the same closed form. After the normal correction, the relative
  // tangential motion of i against the point of T_i it touches within this step is
  //   u_t dt,  u = (x_i - x_i^t - sum_j omega_ij (x_j - x_j^t)) / dt,  tangential to n = d/|d|.
  // Undoing it is a second, tangential "penetration" e_i = -u_t dt, and the local
  // normal force pair with e_i in place of d_i (the same lambda_q) removes it
  // exactly where the normal response removes the penetration exactly: stiction
  // therefore leaves no creep. Because both pairs share their coefficients,
  // |f_t| / |f_n| = |e_i| / |d_i| per collision, which makes Coulomb's law a clamp:
  //   stick  if |e_i| <= mu_s |d_i|,   else slide with e_i scaled to mu_k |d_i|.
  // The pair sums to zero like the normal one.
  //
  // Anchored stiction: when i already sticks to B, u dt is instead the tangential offset
  // of i from its anchor a on B (contact.hpp), both after the normal correction:
  //   u dt = x_i - sum_k b_k x_(a_k),   x = x^t + dx (corrected),
  // which equals the in-step motion when i started the step on its anchor, and otherwise
  // also undoes the slip left over from earlier steps (within the same cone).
  auto corrected = [&](std::int32_t k, index_t v, int d) {
    return x_start_[3 * static_cast<std::size_t>(v) + static_cast<std::size_t>(d)] +
           slots_[static_cast<std::size_t>(k)].dx[d];
  };
  const std::ptrdiff_t nc = static_cast<std::ptrdiff_t>(col.size());
  std::int64_t sticking = 0, sliding = 0;
#pragma omp parallel for schedule(static) reduction(+ : sticking, sliding) if (nc >= kParallelCollisions)
  for (std::ptrdiff_t q = 0; q < nc; ++q) {
    const Collision& c = col[q];
    Local& L = local_[q];
    L.scale = 0;
    L.e[0] = L.e[1] = L.e[2] = 0;
    L.keep_anchor = false;
    L.keep_patch = false;
    L.tangential = L.cone = 0;
    const double dd = norm3(L.d);
    const double dn = dd * L.dynamic;  // the normal force's depth: Coulomb's cone is set by the force, not the shift
    if (dn == 0 || L.fa == 0) continue;
    const Friction& mu = friction_[object_material_[c.object]][object_material_[c.other_object]];
    if (mu.mu_static == 0 && mu.mu_kinetic == 0) continue;
    const double n[3] = {L.d[0] / dd, L.d[1] / dd, L.d[2] / dd};
    double u[3];
    if (L.anchor_slot[0] >= 0) {
      const AnchorEntry& an = *anchor_[static_cast<std::size_t>(c.point)].find(c.other_object);
      for (int d = 0; d < 3; ++d) {
        u[d] = corrected(L.slot[0], c.point, d);
        for (int k = 0; k < 3; ++k)
          u[d] -= an.bary[k] * corrected(L.anchor_slot[k], vertex_of_[static_cast<std::size_t>(L.anchor_slot[k])], d);
      }
    } else {
      for (int d = 0; d < 3; ++d) {
        u[d] = L.pw * slots_[L.slot[0]].dx[d];
        if (L.slot2 >= 0) u[d] += (1 - L.pw) * slots_[L.slot2].dx[d];
        for (int k = 0; k < 3; ++k) u[d] -= c.weight[k] * slots_[L.slot[1 + k]].dx[d];
      }
    }
    const double un = u[0] * n[0] + u[1] * n[1] + u[2] * n[2];
    for (int d = 0; d < 3; ++d) L.e[d] = -(u[d] - un * n[d]);
    const double en = norm3(L.e);
    L.tangential = L.fa * en;
    L.cone = L.ai * mu.mu_static * dn;
    // The normal force relative to the one of the per-collision closed form (1 unless
    // coupled_coefficients replaced it).
    const double ratio = L.ai / L.fa;
    if (en <= mu.mu_static * dn * ratio) {
      L.scale = en == 0 ? 0 : 1;
      L.keep_anchor = L.anchor_slot[0] >= 0;
      ++sticking;
    } else {
      L.scale = mu.mu_kinetic * dn * ratio / en;
      ++sliding;
    }
  }
  // Coulomb per contact patch: the collisions of one body's points against one other
  // body (the records of a body's points are consecutive in the sorted list, and all on
  // its owner's rank). Where the sum of the stopping forces over the patch fits inside
  // the sum of its cones, the patch sticks as a whole: a point that the body's vibration
  // unloads for a step would otherwise slide alone and re-anchor a little further down,
  // and those slips add up to creep (a box on an incline with no damping crept 1 mm/s).
  // Sums in collision order: deterministic.
  std::size_t q0 = 0;
  while (q0 < col.size()) {
    std::size_t q1 = q0;
    while (q1 < col.size() && col[q1].object == col[q0].object) ++q1;
    for (std::size_t q = q0; q < q1; ++q) {
      Local& L = local_[q];
      if (L.scale == 0 || L.cone == 0 || L.keep_patch) continue;
      const std::int32_t other = col[q].other_object;
      double t = 0, n = 0;
      for (std::size_t r = q; r < q1; ++r)
        if (col[r].other_object == other) {
          t += local_[r].tangential;
          n += local_[r].cone;
        }
      const bool stick = t <= n;
      for (std::size_t r = q; r < q1; ++r) {
        if (col[r].other_object != other) continue;
        Local& R = local_[r];
        R.keep_patch = true;
        if (!stick || R.scale == 0 || R.cone == 0 || R.scale == 1) continue;
        R.scale = 1;  // sliding alone, sticking with its patch
        R.keep_anchor = R.anchor_slot[0] >= 0;
        --sliding;
        ++sticking;
      }
    }
    q0 = q1;
  }
  stats.sticking = sticking;
  stats.sliding = sliding;
}

void ContactResponse::respond(World& w, const std::vector<Collision>& col, double dt, ContactStats& stats, NeighbourExchange* exchange) {
  for (index_t v : vertex_of_) slot_of_[static_cast<std::size_t>(v)] = -1;
  vertex_of_.clear();
  slots_.clear();
  materialized_current_ = false;
  stats = ContactStats{};
  stats.collisions = static_cast<std::int64_t>(col.size());
  ++step_;
  if (slot_of_.size() != w.n_local()) {  // the ghost part changed size
    slot_of_.assign(w.n_local(), -1);
    for (index_t& v : materialized_)
      if (static_cast<std::size_t>(v) >= w.n_owned) v = -1;
    materialized_.erase(std::remove(materialized_.begin(), materialized_.end(), -1), materialized_.end());
    force_.resize(3 * w.n_local(), 0.0);
    penetration_.resize(3 * w.n_local(), 0.0);
  }
  if (anchor_.size() != w.n_owned) anchor_.assign(w.n_owned, StictionAnchor{});
  x_start_ = w.x_prev.data();

  // Slots in order of first appearance in the sorted collision list (a fixed order),
  // then the vertices of valid anchors.
  local_.resize(col.size());
  for (std::size_t q = 0; q < col.size(); ++q) {
    Local& L = local_[q];
    L.slot[0] = slot_of_vertex(w, col[q].point);
    for (int k = 0; k < 3; ++k) L.slot[1 + k] = slot_of_vertex(w, col[q].triangle[k]);
    L.slot2 = col[q].point2 >= 0 ? slot_of_vertex(w, col[q].point2) : -1;
    L.pw = col[q].point_weight;
  }
  for (std::size_t q = 0; q < col.size(); ++q) {
    const Collision& c = col[q];
    Local& L = local_[q];
    // Anchors are per (point, other body): edge contacts take none (their friction
    // stops the step's relative motion only).
    const AnchorEntry* an = c.point2 < 0 ? anchor_[static_cast<std::size_t>(c.point)].find(c.other_object) : nullptr;
    const bool anchored = an && an->step >= step_ - kAnchorGrace;
    for (int k = 0; k < 3; ++k) L.anchor_slot[k] = anchored ? slot_of_vertex(w, w.local_vertex(an->object, an->tri[k])) : -1;
  }
  plan_ghosts(w, exchange);  // collective over the neighbours, also without collisions
  // Without neighbours and collisions there is nothing to do; with neighbours every
  // exchange below must take place (they may need our vertices' sums).
  if (sums_.local() && col.empty()) {
    if (coupled_) coupled_coefficients(col, dt, exchange, stats);  // collective: rank 0 gathers every rank's rows
    return;
  }

  // The summed pushes on each vertex (the shares; the paper's column sums s_j of H with
  // a direction), then the coefficients of the local force pairs.
  sum(
      col,
      [&](std::size_t q, auto&& f) {
        const double* p = col[q].depth.data();
        emit_point_side(local_[q], p, f);
        for (int k = 0; k < 3; ++k) {
          const double wk = col[q].weight[static_cast<std::size_t>(k)];
          const double pj[3] = {-wk * p[0], -wk * p[1], -wk * p[2]};
          f(local_[q].slot[1 + k], pj);
        }
      },
      &Slot::share);
  reply(&Slot::share);
  effective_depths(col, dt);
  stats.separating = capped_;
  stats.fixed_pairs = normal_coefficients(col, dt);
  if (coupled_) coupled_coefficients(col, dt, exchange, stats);

  // Normal forces f_i = a_i d_i, f_Ti,j = a_j d_i per vertex; the normal correction
  // (friction sees the corrected motion), x = x~ + dt^2 F / m, of the owned slots; the
  // corrected motions of the ghost slots from their owners.
  sum(
      col,
      [&](std::size_t q, auto&& f) {
        const Local& L = local_[q];
        const double* d = L.d;
        const double fi[3] = {L.ai * d[0], L.ai * d[1], L.ai * d[2]};
        emit_point_side(L, fi, f);
        for (int k = 0; k < 3; ++k) {
          const double fj[3] = {L.aT[k] * d[0], L.aT[k] * d[1], L.aT[k] * d[2]};
          f(L.slot[1 + k], fj);
        }
      },
      &Slot::normal);
  const double dt2 = dt * dt;
  for (std::size_t k = 0; k < slots_.size(); ++k)
    if (sums_.owned(k))
      for (int d = 0; d < 3; ++d) slots_[k].dx[d] += dt2 * slots_[k].inv_mass * slots_[k].normal[d];
  reply(&Slot::dx);
  dynamic_fractions(col);
  for (std::size_t q = 0; q < col.size(); ++q) {
    if (col[q].point2 >= 0) continue;  // the penetration field is per point: vertex collisions
    Slot& si = slots_[static_cast<std::size_t>(local_[q].slot[0])];
    for (int a = 0; a < 3; ++a) si.depth[a] += col[q].depth[static_cast<std::size_t>(a)];
  }
  friction_coefficients(col, stats);
  // What changes velocities, in one sum of six components: the dynamic part of the
  // normal forces (dynamic_fractions) and the friction forces (friction_coefficients
  // reads only the corrected motions dx). A collision without friction adds +0 there,
  // which leaves every sum as it was (a sum that starts at +0 is never -0).
  sum(
      col,
      [&](std::size_t q, auto&& f) {
        const Local& L = local_[q];
        const double* d = L.d;
        const double a = L.ai * L.dynamic;
        const double fs = L.scale == 0 ? 0.0 : L.fa * L.scale;
        const double fi[6] = {a * d[0], a * d[1], a * d[2], fs * L.e[0], fs * L.e[1], fs * L.e[2]};
        emit_point_side<6>(L, fi, f);
        for (int k = 0; k < 3; ++k) {
          const double b = L.aT[k] * L.dynamic;
          const double ft = L.scale == 0 ? 0.0 : L.faT[k] * L.scale;
          const double fj[6] = {b * d[0], b * d[1], b * d[2], ft * L.e[0], ft * L.e[1], ft * L.e[2]};
          f(L.slot[1 + k], fj);
        }
      },
      &Slot::dynamic);

  double sum[3] = {0, 0, 0}, abs_sum = 0;
  for (std::size_t k = 0; k < slots_.size(); ++k) {
    const Slot& s = slots_[k];
    if (!sums_.owned(k)) continue;  // a ghost: its owner applies the sums
    const auto v = static_cast<std::size_t>(vertex_of_[k]);
    // The contact force is the dynamic part (the momentum it transfers, F dt); the
    // position-only part moves x (and x^t with it) but is no force.
    double f[3];
    for (int d = 0; d < 3; ++d) {
      f[d] = s.dynamic[d] + s.dynamic[3 + d];
      sum[d] += f[d];
    }
    abs_sum += norm3(f);
    if (s.inv_mass == 0) continue;
    for (int d = 0; d < 3; ++d) {
      const double shift = dt2 * s.inv_mass * (s.normal[d] - s.dynamic[d]);
      w.x[3 * v + d] += dt2 * s.inv_mass * f[d] + shift;  // (12): x = x~ + dt^2 F / m, and the shift
      w.v[3 * v + d] += dt * s.inv_mass * f[d];
      w.x_prev[3 * v + d] += shift;  // so that position Verlet sees no velocity from the shift
    }
  }
  for (const Collision& c : col) stats.max_depth = std::max(stats.max_depth, norm3(c.depth.data()));
  for (int d = 0; d < 3; ++d) stats.force_sum[d] = sum[d];
  stats.force_abs_sum = abs_sum;
  stats.force_balance = abs_sum > 0 ? norm3(sum) / abs_sum : 0;
  if (!exchange) update_anchors(w, col);
}

// The in-run check's classes (RecordStatus, verify.hpp): capped when the applied
// depth is less than |d_i| (the separation speed), under-closed when the corrections of
// all collisions close less than 90 % of the applied depth, else closed.
void ContactResponse::record_status(const std::vector<Collision>& col, std::size_t n_local,
                                  std::vector<std::int8_t>& status) const {
  status.assign(n_local, kNoRecord);
  std::vector<double> deepest(n_local, -1);
  if (local_.size() < col.size()) return;  // respond() has not seen these collisions
  for (std::size_t q = 0; q < col.size(); ++q) {
    const Collision& c = col[q];
    const auto i = static_cast<std::size_t>(c.point);
    const double D = norm3(c.depth.data());
    if (c.point2 >= 0 || i >= n_local || !(D > deepest[i])) continue;
    deepest[i] = D;
    const Local& L = local_[q];
    const double applied = norm3(L.d);
    if (applied < D * (1 - 1e-12)) status[i] = kCapped;
    else if (L.closed < 0.9 * applied) status[i] = kUnderClosed;
    else status[i] = kClosed;
  }
}

// After the step: points that stuck to a valid anchor keep it; every other colliding
// point takes a new anchor, the foot of its final position on the final plane of T_i
// (barycentric coordinates, not clamped: the foot may lie just outside T_i). One anchor
// per (point, other body), so a point against two bodies keeps both.
// The triangle's final positions: with ghosts, after the halo has refreshed them.
void ContactResponse::update_anchors(const World& w, const std::vector<Collision>& col) {
  if (local_.size() < col.size()) return;  // respond() has not seen these collisions
  for (std::size_t q = 0; q < col.size(); ++q) {
    const Collision& c = col[q];
    if (c.point2 >= 0) continue;  // edge contacts keep no anchor
    AnchorEntry& an = anchor_[static_cast<std::size_t>(c.point)].slot_for(c.other_object);
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
    for (int k = 0; k < 3; ++k) an.tri[k] = w.vertex_gid[static_cast<std::size_t>(c.triangle[k])];
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

void ContactResponse::materialize() {
  if (materialized_current_) return;
  for (index_t v : materialized_)
    for (int d = 0; d < 3; ++d) force_[3 * v + d] = penetration_[3 * v + d] = 0;
  materialized_ = vertex_of_;
  for (std::size_t k = 0; k < slots_.size(); ++k) {
    if (!sums_.owned(k)) continue;  // ghost: partial sums only
    const index_t v = vertex_of_[k];
    for (int d = 0; d < 3; ++d) {
      force_[3 * v + d] = slots_[k].dynamic[d] + slots_[k].dynamic[3 + d];
      penetration_[3 * v + d] = slots_[k].depth[d];
    }
  }
  materialized_current_ = true;
}

const std::vector<double>& ContactResponse::force() {
  materialize();
  return force_;
}

const std::vector<double>& ContactResponse::penetration() {
  materialize();
  return penetration_;
}

}  // namespace softcontact
