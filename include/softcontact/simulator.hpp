#pragma once
// One simulation in memory: the paper's Algorithm 1 step after step (method.md),
//
//   p  <- internal forces(x^t) + gravity + damping        ElasticForces
//   x~ <- unconstrained motion                             Verlet / symplectic / implicit Euler
//   C  <- detect collisions(x~)                            CollisionDetector (spatial hashing)
//   d  <- penetration vectors(C, x~)                       CollisionDetector (consistent depth)
//   F  <- contact forces(C, x~, d); x = x~ + dt^2 F / m    ContactSolver
//
// without any file output, so that tests and benchmarks drive it directly; run_scene()
// adds frames, diagnostics and the progress line around it.
#include <mpi.h>

#include <cstdint>
#include <memory>
#include <vector>

#include "softcontact/collision.hpp"
#include "softcontact/contact.hpp"
#include "softcontact/diagnostics.hpp"
#include "softcontact/scene.hpp"
#include "softcontact/world.hpp"

namespace softcontact {

class ElasticForces;
class ImplicitEuler;

class Simulator {
public:
  /// Builds this rank's World (objects partitioned over the ranks of `comm`) and every
  /// phase's precomputed data. Collective.
  Simulator(MPI_Comm comm, const Scene& scene);
  ~Simulator();
  Simulator(const Simulator&) = delete;
  Simulator& operator=(const Simulator&) = delete;

  /// One time step. Collective.
  void step();

  std::int64_t step_count() const { return step_; }
  double time() const { return static_cast<double>(step_) * scene_.sim.dt; }
  World& world() { return world_; }
  const World& world() const { return world_; }
  const Scene& scene() const { return scene_; }

  /// Collisions of the last step (after detection, before the response), sorted.
  const std::vector<Collision>& collisions() const { return collisions_; }
  const CollisionStats& collision_stats() const { return collision_stats_; }
  const ContactStats& contact_stats() const { return contact_stats_; }
  /// Contact force per local vertex of the last step, (n_local,3) [N].
  const std::vector<double>& contact_force() { return contact_.force(); }
  /// Sum of penetration vectors per colliding vertex of the last step, (n_local,3) [m].
  const std::vector<double>& penetration() { return contact_.penetration(); }

  /// Energies, momentum, contact counts, force balance and the residual penetration (a
  /// second detection pass at the corrected positions: the largest remaining depth over
  /// the median edge length). Collective; costs one detection, so call it per frame.
  void measure(StepDiagnostics& d);

  /// Wall time per phase accumulated since the last call, and the steps it covers.
  PhaseTimes take_times(std::int64_t& steps);

  /// Collisions already present at the initial positions (objects that start
  /// overlapping): the first step pushes them apart at (depth / dt).
  std::int64_t initial_overlaps() const { return initial_overlaps_; }
  double initial_overlap_depth() const { return initial_overlap_depth_; }

  /// Median edge length of all tets of this rank [m].
  double median_edge() const { return median_edge_; }

private:
  void compute_forces();

  MPI_Comm comm_;
  const Scene& scene_;
  World world_;
  std::unique_ptr<ElasticForces> elastic_;
  std::unique_ptr<ImplicitEuler> implicit_;
  CollisionDetector detector_;
  ContactSolver contact_;
  std::vector<double> f_;
  std::vector<Collision> collisions_, residual_;
  CollisionStats collision_stats_;
  ContactStats contact_stats_;
  PhaseTimes times_;
  std::int64_t timed_steps_ = 0;
  std::int64_t step_ = 0;
  double median_edge_ = 0;
  std::int64_t initial_overlaps_ = 0;
  double initial_overlap_depth_ = 0;
};

}  // namespace softcontact
