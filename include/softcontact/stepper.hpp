#pragma once
// The serial core of a step: the paper's Algorithm 1 on one World, with no MPI
// (docs/architecture.md, "One step"):
//
//   p  <- forces(x^t, v^t)                        UnconstrainedMotion (gravity, internal forces, damping)
//   x~ <- unconstrained motion                    Verlet / symplectic / implicit Euler, prescribed motion
//   C, d <- detection and penetration depth(x~)   CollisionDetector (spatial hashing, consistent depth)
//   F; x, v <- contact response(C, x~, d)         ContactResponse (x = x~ + dt^2 F / m, v += dt F / m)
//
// On one rank step() is the whole step. With several ranks the Simulator (the parallel
// layer) calls the phases one by one and refreshes the ghost rows between them; the
// phases that need the neighbours (the mutual-record keys, the contact response's keyed
// sums) take them as a NeighbourExchange (null: one rank).
#include <cstdint>
#include <memory>
#include <vector>

#include "softcontact/collision.hpp"
#include "softcontact/contact.hpp"
#include "softcontact/scene.hpp"
#include "softcontact/world.hpp"

namespace softcontact {

class NeighbourExchange;
class UnconstrainedMotion;
class SplitForces;

/// Mean and median length over every tet edge of the scene (an edge counts once per
/// tet) [m]; the same on every rank. The mean is mean_of_object_sums of the objects' sums.
void scene_edge_lengths(const Scene& scene, double& mean, double& median);
/// The mean alone, without holding the lengths: bitwise the mean of scene_edge_lengths.
double scene_mean_edge(const Scene& scene);
/// Appends the six edge lengths of every tet of `m`, in tet order [m].
void append_edge_lengths(const TetMesh& m, std::vector<double>& len);
/// The sum of m's edge lengths in tet order [m]; `len` holds them afterwards.
double object_edge_sum(const TetMesh& m, std::vector<double>& len);
/// The mean edge from each object's sum (object_edge_sum, in scene order) and the number
/// of edges: the definition every rank count shares [m].
double mean_of_object_sums(const std::vector<double>& sums, std::int64_t count);
/// The detector's settings for the scene: its self-contact and edge-contact keys, and
/// the mean edge length as the grid's cell size.
CollisionSettings collision_settings_for(const Scene& scene);
/// The same with the scene's mean edge length already known (scene_edge_lengths).
CollisionSettings collision_settings_for(const Scene& scene, double mean_edge);

/// An empty SelfGapCache that knows which objects are copies of one scene entry (placed
/// from one shared mesh: Placement::base), so that their self-contact gap is computed once.
SelfGapCache self_gap_cache_for(const Scene& scene);

class SerialStepper {
public:
  /// The models' rest shapes and the contact response for `world`, whose World::x holds
  /// the scene's initial positions here. The detector comes with make_detector(), once
  /// the World's ghost set is final. `world` must outlive the stepper. `split_owned`: the
  /// owned objects that will be split over ranks (set_split must then name each of them):
  /// no rest data of theirs is built here.
  SerialStepper(const Scene& scene, World& world, const CollisionSettings& settings, std::vector<int> split_owned = {});
  ~SerialStepper();
  SerialStepper(const SerialStepper&) = delete;
  SerialStepper& operator=(const SerialStepper&) = delete;

  /// (Re)builds the collision detector for the World's current objects and ghosts.
  void make_detector();
  /// Objects whose points are queried by the owners of the bodies they enter
  /// (CollisionDetector::delegate; the objects split over ranks), from the next
  /// make_detector() on; detection_and_depth() then sends each record of a ghost point to
  /// the point's owner. Ignored with edge contacts on. Every rank gives the same list.
  void delegate_detection(std::vector<std::int32_t> objects);
  bool has_detector() const { return detector_ != nullptr; }
  /// Sizes the force buffer after the World's ghost part changed.
  void resize();
  /// After the initial state is set: the forces at it and the integrator's start.
  /// `exchange`: as for forces().
  void start(NeighbourExchange* exchange = nullptr);
  /// Objects split over ranks (split_forces.hpp) from now on: ElasticForces skips the
  /// owned ones, `split` adds their forces (null: none).
  void set_split(std::unique_ptr<SplitForces> split);
  const SplitForces* split() const { return split_.get(); }
  SplitForces* split() { return split_.get(); }

  /// One whole step on one rank, from time t: Algorithm 1, one phase per line.
  void step(double t);

  // The phases of step(), for the parallel layer.
  /// p(x^t, v^t): gravity, internal forces, damping. With split objects, collective over
  /// the neighbours of `exchange`.
  void forces(NeighbourExchange* exchange = nullptr);
  /// x~ from p (explicit or implicit), World::x_prev = x^t; prescribed motion over [t, t + dt].
  void unconstrained_motion(double t);
  /// The colliding points at x~ and their consistent penetration vectors; with
  /// scene.sim.mutual_pairs the mutual records settled, their partners' keys exchanged
  /// with the neighbours (collective over them when `exchange` is not null).
  void detection_and_depth(NeighbourExchange* exchange);
  /// Contact forces; x^{t+h} and v^{t+h} of the colliding points (collective over the
  /// neighbours when `exchange` is not null; then call update_anchors() once the ghost
  /// rows hold the final positions).
  void contact_response(NeighbourExchange* exchange);
  /// New static-friction anchors from the final positions (after contact_response()
  /// with an exchange).
  void update_anchors();

  /// Collisions at the initial positions between sides of which at least one moves, and
  /// the deepest of them [m] (this World's; the caller sums over ranks).
  void initial_overlaps(std::int64_t& count, double& depth);

  UnconstrainedMotion& motion() { return *motion_; }
  ContactResponse& response() { return *contact_; }
  const ContactResponse& response() const { return *contact_; }
  /// Collisions of the last step (after detection, before the response), sorted.
  const std::vector<Collision>& collisions() const { return collisions_; }
  const CollisionStats& collision_stats() const { return collision_stats_; }
  const ContactStats& contact_stats() const { return contact_stats_; }
  /// Wall seconds spent in neighbour exchanges of detection_and_depth() so far.
  double exchange_seconds() const { return exchange_seconds_; }
  /// Process CPU seconds spent in them (a wait polls: no work).
  double exchange_cpu_seconds() const { return exchange_cpu_seconds_; }
  /// Records of delegated points this rank made for another rank's points so far (and
  /// received for its own).
  std::int64_t delegated_sent() const { return delegated_sent_; }
  std::int64_t delegated_received() const { return delegated_received_; }

private:
  void settle_mutual_records(NeighbourExchange* exchange);
  void send_delegated_records(NeighbourExchange* exchange);

  const Scene& scene_;
  World& world_;
  CollisionSettings settings_;
  std::unique_ptr<UnconstrainedMotion> motion_;
  std::unique_ptr<SplitForces> split_;
  std::unique_ptr<CollisionDetector> detector_;
  SelfGapCache gaps_;  // self-contact gaps of every object a detector has held (rest shapes only)
  std::unique_ptr<ContactResponse> contact_;
  std::vector<double> f_;
  std::vector<Collision> collisions_;
  std::vector<RecordKey> record_keys_;  // settle_mutual's partners (this rank's and its neighbours')
  CollisionStats collision_stats_;
  ContactStats contact_stats_;
  double exchange_seconds_ = 0, exchange_cpu_seconds_ = 0;
  std::vector<std::int32_t> delegated_;  // objects whose points the bodies' owners query
  std::int64_t delegated_sent_ = 0, delegated_received_ = 0;
  std::vector<std::vector<gid_t>> delegated_points_;  // per neighbour: the delegated points found here
  std::vector<std::vector<char>> delegated_out_;     // per neighbour: the message of send_delegated_records
};

}  // namespace softcontact
