#pragma once
// The analytic contact response of Spillmann, Becker and Teschner (2007), step 5 of
// Algorithm 1 (method.md, "Contact forces" and "Friction"). No stiffness constant, no
// iteration, no global system: O(1) work per collision.
//
// For every collision (i, T_i) with penetration vector d_i and weights omega_ij:
//
//   s_j     = sum over collisions with j in T of omega_j          (column sums of H)
//   c_j     = 1 / (1 + s_j)                                        (6)
//   M_T     = sum_{j in T_i} c_j omega_ij m_j
//   alpha_i = M_T / (c_i m_i + M_T)                                (5)
//   f_i     =  c_i m_i alpha_i d_i / dt^2                          (15)  on point i
//   f_Ti,j  = -c_j omega_ij m_j (1 - alpha_i) d_i / dt^2           (16)  on j in T_i
//
// f_i + sum_j f_Ti,j = 0 by the choice of alpha_i, so summing the local forces per
// vertex (eq. 22) conserves momentum to rounding and gives the reaction on triangle
// vertices that do not collide themselves. Positions are then corrected,
// x = x~ + dt^2 F / m, and velocities take the same correction, v += dt F / m.
//
// Kinematic vertices (inverse mass 0) have infinite mass: if a vertex of T_i with
// omega > 0 is kinematic, alpha_i = 1 and the reaction -f_i goes to the kinematic
// vertices of T_i in proportion to c_j omega_ij; if i is kinematic, alpha_i = 0 and i
// takes the reaction. Forces on kinematic vertices are recorded, never applied.
//
// Friction (Coulomb, decoupled from the normal response as in the paper's Sec. 3.4) is
// applied after the normal correction with the same local force pairs: the relative
// tangential motion e_i of i against T_i within the step replaces d_i in (15)-(16), so
// stiction removes it exactly where the normal response removes penetration exactly,
// and friction sums to zero too. Coulomb's cone becomes |e_i| <= mu_s |d_i| (stick),
// else e_i is scaled to mu_k |d_i| (slide); contact_solver.cpp derives this.
//
// Static friction is anchored: a sticking point keeps the place on the other body where
// it first stuck (barycentric coordinates in a surface triangle of that body), and e_i
// is measured from that anchor rather than from the start of the step. Small slips that
// the decoupled per-collision forces leave behind (and steps in which a resting point is
// not detected) are thereby pulled back instead of adding up to creep. A point that
// slides, or that has had no contact with that body for more than kAnchorGrace steps,
// takes a new anchor where it ends the step.
#include <cstdint>
#include <vector>

#include "softcontact/collision.hpp"
#include "softcontact/scene.hpp"
#include "softcontact/world.hpp"

namespace softcontact {

struct ContactStats {
  std::int64_t collisions = 0;      ///< records processed
  std::int64_t fixed_pairs = 0;     ///< collisions between two kinematic sides (no force)
  std::int64_t sticking = 0;        ///< friction: collisions in static friction
  std::int64_t sliding = 0;         ///< friction: collisions in kinetic friction
  double force_balance = 0;         ///< |sum_v F_v| / sum_v |F_v| over all vertices (0 without contact)
  double max_depth = 0;             ///< largest |d_i| [m]
};

class ContactSolver {
public:
  /// Friction coefficients per pair of objects come from the scene's materials.
  ContactSolver(const Scene& scene, const World& world);

  /// Computes the contact forces of `collisions` at the positions x~ = world.x, corrects
  /// world.x and world.v of movable owned vertices (x_prev, holding x^t, is unchanged).
  /// `collisions` must be sorted by (point_gid, triangle_gid), as CollisionDetector
  /// produces them: every per-vertex sum follows that order, independent of threads and
  /// ranks.
  void respond(World& world, const std::vector<Collision>& collisions, double dt, ContactStats& stats);

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
    double column_sum;       // s_j
    double count;            // collisions with this vertex as the point i
    double dx[3];            // x - x^t (x~, then corrected)
    double normal[3];        // sum of normal local forces
    double friction[3];      // sum of friction local forces
    double depth[3];         // sum of d_i as point i
  };
  struct Local {             // per collision
    std::int32_t slot[4];    // i, j, k, l
    // The local force pair is linear in the penetration vector: f_i = a_i d_i and
    // f_Ti,j = a_j d_i (eqs 15, 16), with a_i + sum_j a_j = 0. Friction reuses the
    // coefficients with a tangential vector in place of d_i.
    double ai;
    double aT[3];
    double scale;            // friction: multiple of the tangential vector applied
    double e[3];             // friction: tangential vector
    bool keep_anchor;        // friction: stuck to a valid anchor, which stays
  };
  // Static-friction anchor of a point (per local vertex): where on the other body it
  // sticks. Local vertex indices (the World does not renumber during a run).
  struct Anchor {
    std::int64_t step = -1;  // last step with a contact to this anchor's body
    std::int32_t object = -1;
    index_t tri[3] = {-1, -1, -1};
    double bary[3] = {0, 0, 0};
  };
  std::int64_t normal_forces(const std::vector<Collision>& c, double dt);
  void friction_forces(const World& w, const std::vector<Collision>& c, double dt, ContactStats& stats);
  void update_anchors(const World& w, const std::vector<Collision>& c);
  void materialize();

  std::vector<std::int32_t> object_material_;             // material of each object
  std::vector<std::vector<Friction>> friction_;           // [material][material]
  std::vector<std::int32_t> slot_of_;                      // n_local, -1 when not taking part
  std::vector<index_t> vertex_of_;                         // per slot
  std::vector<Slot> slots_;
  std::vector<Local> local_;
  std::vector<Anchor> anchor_;                             // n_local
  std::int64_t step_ = 0;                                  // respond() calls so far
  std::vector<double> force_, penetration_;                // n_local x 3, filled on demand
  std::vector<index_t> materialized_;                      // entries of force_ that are set
  bool materialized_current_ = true;
};

}  // namespace softcontact
