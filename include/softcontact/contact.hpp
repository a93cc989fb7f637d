#pragma once
// The analytic contact response of Spillmann, Becker and Teschner (2007), step 5 of
// Algorithm 1 (method.md, "Contact forces" and "Friction"). No stiffness constant, no
// iteration, no global system: O(1) work per collision. (With the scene key
// simulation.contact_closure: coupled, off by default, the magnitudes lambda_q come from
// one sparse direct solve over all collisions instead: src/contact/coupled_closure.hpp.)
//
// For every collision q = (i, T_i) with penetration vector d_i and weights omega_ij
// (docs/contact.md, "Normal response", derives and tests this):
//
//   f_i     =  lambda_q d_i,   f_Ti,j = -omega_ij lambda_q d_i,   lambda_q = 1 / (dt^2 K_q)
//   K_q     =  sum over v in {i, j, k, l} of beta_v sigma_qv / m_v       (beta_i = 1, beta_j = omega_ij)
//   sigma_qv = max(beta_v, p_q . S_v / |d_i|)                           (the shares; the paper's c-weights)
//
// S_v sums the pushes on v over its collisions (+d for the point, -omega d for a triangle
// vertex), p_q is this collision's push direction. An isolated collision (sigma = beta)
// closes exactly; collisions that push a shared vertex the same way split it. The pair
// sums to zero, so summing the local forces per vertex (eq. 22) conserves momentum.
// Positions are corrected, x = x~ + dt^2 F / m. The part of d_i that the pair's approach
// within the step explains changes the velocity too (v += dt F / m: the relative normal
// velocity is stopped); the rest, an overlap older than the step, is a position-only
// shift (x and x^t move together, v does not change), at most separation_speed * dt per
// step. The reported contact force is the dynamic part.
//
// Kinematic vertices (inverse mass 0) add nothing to K_q; forces on them are recorded
// (the reactions on anchors and walls), never applied. Both sides kinematic: no force.
//
// Friction (Coulomb, decoupled from the normal response as in the paper's Sec. 3.4) is
// applied after the normal correction with the same local force pairs: the relative
// tangential motion e_i of i against T_i within the step replaces d_i, so stiction
// removes it exactly where the normal response removes penetration exactly, and
// friction sums to zero too. Coulomb's cone becomes |e_i| <= mu_s |d_i| (stick), else e_i
// is scaled to mu_k |d_i| (slide), |d_i| the dynamic part; a patch (one body's points
// against one other body) whose summed stopping forces fit in its summed cones sticks as
// a whole. contact_response.cpp derives this.
//
// Static friction is anchored: a sticking point keeps the place on the other body where
// it first stuck (barycentric coordinates in a surface triangle of that body), and e_i
// is measured from that anchor rather than from the start of the step. Small slips that
// the decoupled per-collision forces leave behind (and steps in which a resting point is
// not detected) are thereby pulled back instead of adding up to creep. A point that
// slides, or that has had no contact with that body for more than kAnchorGrace steps,
// takes a new anchor where it ends the step. Anchors are per (point, other body).
#include <cstdint>
#include <vector>

#include "softcontact/collision.hpp"
#include "softcontact/keyed_sums.hpp"
#include "softcontact/scene.hpp"
#include "softcontact/world.hpp"

namespace softcontact {

class NeighbourExchange;

/// Static-friction anchor of a point against one other body: where on that body it
/// sticks (barycentric coordinates in a surface triangle of that body, by global vertex
/// ids, so that it survives ghost rebuilds, migration and restarts).
struct AnchorEntry {
  std::int64_t step = -1;  ///< last step (respond() call) with a contact to this anchor's body
  std::int32_t object = -1;
  gid_t tri[3] = {-1, -1, -1};
  double bary[3] = {0, 0, 0};
};

/// The anchors of one point, one per other body it touches (a point in a corner between
/// a floor and a wall sticks to both), at most kPerPoint; a new body takes the entry
/// unused the longest.
struct StictionAnchor {
  static constexpr int kPerPoint = 2;
  AnchorEntry entry[kPerPoint];
  /// The entry for `object`, or null.
  AnchorEntry* find(std::int32_t object) {
    for (AnchorEntry& e : entry)
      if (e.object == object) return &e;
    return nullptr;
  }
  const AnchorEntry* find(std::int32_t object) const { return const_cast<StictionAnchor*>(this)->find(object); }
  /// The entry for `object`, else the one unused the longest.
  AnchorEntry& slot_for(std::int32_t object) {
    if (AnchorEntry* e = find(object)) return *e;
    AnchorEntry* oldest = &entry[0];
    for (AnchorEntry& e : entry)
      if (e.step < oldest->step) oldest = &e;
    return *oldest;
  }
};

struct ContactStats {
  std::int64_t collisions = 0;      ///< records processed
  std::int64_t fixed_pairs = 0;     ///< collisions between two kinematic sides (no force)
  std::int64_t separating = 0;      ///< collisions deeper than the step's approach allows, resolved at the separation speed
  std::int64_t sticking = 0;        ///< friction: collisions in static friction
  std::int64_t sliding = 0;         ///< friction: collisions in kinetic friction
  double force_balance = 0;         ///< |sum_v F_v| / sum_v |F_v| over this rank's owned vertices (0 without contact)
  double force_sum[3] = {0, 0, 0};  ///< sum_v F_v over owned vertices (reduce over ranks for the balance)
  double force_abs_sum = 0;         ///< sum_v |F_v| over owned vertices
  double max_depth = 0;             ///< largest |d_i| [m]
  std::int64_t closure_rows = 0;    ///< contact_closure coupled: collisions in the system (all ranks)
  std::int64_t closure_dropped = 0; ///< ... of them given no force because they would have pulled
  std::int64_t closure_local = 0;   ///< ... of them left to the per-collision closed form (ill-conditioned)
};

class ContactResponse {
public:
  /// Friction coefficients per pair of objects come from the scene's materials.
  ContactResponse(const Scene& scene, const World& world);

  /// Computes the contact forces of `collisions` at the positions x~ = world.x, corrects
  /// world.x and world.v of movable owned vertices; world.x_prev (x^t) moves with world.x by
  /// the position-only part, so that position Verlet takes no velocity from it.
  /// `collisions` must be sorted by (point_gid, triangle_gid), as CollisionDetector
  /// produces them: every per-vertex sum follows that order, independent of threads and
  /// ranks. With several ranks, `collisions` are this rank's (owned points) and `exchange`
  /// (the parallel layer's Halo, exchange.hpp) carries the column sums, local forces and
  /// corrected motions of ghost vertices to and from their owners (collective over its
  /// neighbours); ghost rows of world.x are not changed (Halo::update refreshes them
  /// afterwards).
  void respond(World& world, const std::vector<Collision>& collisions, double dt, ContactStats& stats,
               NeighbourExchange* exchange = nullptr);

  /// After respond() and after the ghost positions are refreshed: new anchors from the
  /// final positions (respond() calls it itself when there is no exchange).
  void update_anchors(const World& world, const std::vector<Collision>& collisions);

  /// Anchors per owned vertex (n_owned), for migration and checkpoints.
  std::vector<StictionAnchor>& anchors() { return anchor_; }
  /// After respond(): for each local vertex (World index) that is the point of a vertex
  /// collision, the RecordStatus (verify.hpp) of its deepest record; the others keep
  /// kNoRecord. `status` is resized to the World's vertex count.
  void record_status(const std::vector<Collision>& collisions, std::size_t n_local, std::vector<std::int8_t>& status) const;
  std::int64_t anchor_step() const { return step_; }
  void set_anchor_step(std::int64_t s) { step_ = s; }

  /// Steps without contact after which a point forgets its static-friction anchor.
  static constexpr std::int64_t kAnchorGrace = 2;

  /// Total contact force (normal + friction) per local vertex, (n_local,3) [N], of the
  /// last respond(); zero for vertices without contact.
  const std::vector<double>& force();
  /// Sum of the penetration vectors d_i of each colliding point, (n_local,3) [m].
  const std::vector<double>& penetration();

private:
  // The response works on a compact copy of the vertices that take part ("slots", in
  // order of first appearance in the sorted collision list), so that its passes stream
  // through small arrays instead of jumping through the whole World.
  struct Slot {
    double mass, inv_mass;
    double share[3];         // summed pushes: sum over its collisions of beta p (the shares)
    double dx[3];            // x - x^t (x~, then corrected)
    double dx0[3];           // x~ - x^t: the step's unconstrained motion
    double normal[3];        // sum of normal local forces
    double dynamic[6];       // what changes velocities, summed in one exchange: [0, 3) the
                             // normal forces' dynamic part, [3, 6) the friction local forces
    double depth[3];         // sum of d_i as point i
    gid_t gid;
  };
  struct Local {             // per collision
    std::int32_t slot[4];    // i, j, k, l
    std::int32_t slot2;      // edge contacts: the point side's second vertex, else -1
    double pw;               // weight of i on the point side (1 for a vertex collision)
    std::int32_t anchor_slot[3];  // vertices of the anchor triangle when anchored, else -1
    // The local force pair is linear in the penetration vector: f_i = a_i d_i and
    // f_Ti,j = a_j d_i (eqs 15, 16), with a_i + sum_j a_j = 0. Friction reuses the
    // coefficients with a tangential vector in place of d_i.
    double ai;
    double aT[3];
    double fa, faT[3];       // friction's coefficients (ai, aT of the per-collision closed form)
    double d[3];             // the depth removed in this step (d_i, or less for an old overlap)
    double approach;         // how far i moved into T_i along d within the step (>= 0)
    double dynamic;          // the part of the force closed with velocity (the step's approach), in [0, 1]
    double closed;           // A_q: what the normal corrections of all collisions close of its gap along d
    double scale;            // friction: multiple of the tangential vector applied
    double e[3];             // friction: tangential vector
    double tangential;       // friction: |stopping force| of this collision
    double cone;             // friction: mu_s times its normal force
    bool keep_anchor;        // friction: stuck to a valid anchor, which stays
    bool keep_patch;         // friction: its patch (object, other object) has been decided
  };
  std::int32_t slot_of_vertex(const World& w, index_t v);
  void plan_ghosts(const World& w, NeighbourExchange* exchange);
  template <std::size_t N, class Emit>
  void sum(const std::vector<Collision>& col, Emit&& emit, double (Slot::*field)[N]);
  void reply(double (Slot::*field)[3]);
  void effective_depths(const std::vector<Collision>& c, double dt);
  std::int64_t normal_coefficients(const std::vector<Collision>& c, double dt);
  void coupled_coefficients(const std::vector<Collision>& c, double dt, NeighbourExchange* exchange, ContactStats& stats);
  void dynamic_fractions(const std::vector<Collision>& c);
  void friction_coefficients(const std::vector<Collision>& c, ContactStats& stats);
  void materialize();

  std::vector<std::int32_t> object_material_;             // material of each object
  std::vector<std::vector<Friction>> friction_;           // [material][material]
  bool coupled_ = false;                                   // simulation.contact_closure: coupled
  /// Relative regularisation of the coupled closure's diagonal (coupled_closure.hpp).
  static constexpr double kClosureEps = 1e-3;
  double separation_speed_ = 5.0;                          // [m/s] bound for resolving old overlaps
  std::int64_t capped_ = 0;                                // collisions limited by it, last respond()
  std::vector<std::int32_t> slot_of_;                      // n_local, -1 when not taking part
  std::vector<index_t> vertex_of_;                         // per slot
  std::vector<Slot> slots_;
  std::vector<Local> local_;
  std::vector<StictionAnchor> anchor_;                     // n_owned
  std::vector<gid_t> object_vertex_begin_;                 // per object, for gid -> object
  KeyedSums sums_;                                         // the per-vertex sums over ranks (keyed_sums.hpp)
  std::vector<int> slot_owner_;                            // per slot: owner rank of a ghost, -1 owned
  std::vector<gid_t> slot_gid_;                            // per slot: global vertex id
  const double* x_start_ = nullptr;                        // x^t, the step's start, during respond()
  std::int64_t step_ = 0;                                  // respond() calls so far
  std::vector<double> force_, penetration_;                // n_local x 3, filled on demand
  std::vector<index_t> materialized_;                      // entries of force_ that are set
  bool materialized_current_ = true;
};

}  // namespace softcontact
