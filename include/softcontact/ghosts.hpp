#pragma once
// The ghost set of one rank (docs/architecture.md, "Parallel step"): whole objects of
// other ranks within reach of this rank's own, kept in the World's ghost part and
// refreshed through the Halo. A Verlet list of objects, as molecular dynamics keeps
// neighbour lists: built with a skin, and rebuilt only when some owned vertex has moved
// half the skin since. The ghost set changes work, never results.
#include <mpi.h>

#include <cstdint>
#include <memory>
#include <vector>

#include "softcontact/partition.hpp"
#include "softcontact/scene.hpp"
#include "softcontact/surface.hpp"
#include "softcontact/world.hpp"

namespace softcontact {

class Halo;
class NeighbourExchange;

/// Each object's box at its initial positions (Scene::shape).
std::vector<Box> scene_boxes(const Scene& scene);
/// Median over objects of the largest side of their box.
double median_object_size(const std::vector<Box>& box);
/// Every object's box at the current positions, on every rank: the owners' boxes
/// assembled by a min/max reduction (collective over `comm`; 48 bytes per object of the
/// scene: for a repartition, not for the ghost set).
std::vector<Box> object_boxes(MPI_Comm comm, const Scene& scene, const World& w);

/// The other ranks' objects whose box (at the current positions) lies within `skin` of
/// the box of one of this rank's own objects (Box::within: the boxes grown by skin/2
/// overlap), ascending: the set that testing every object's box (object_boxes) against
/// every own box gives, but only boxes near a rank travel to it (each rank's hull of its
/// own boxes all-gathered, then each rank sends every other the own boxes within `skin`
/// of its hull). Per rank: 56 bytes per hull, P integers, 56 bytes per box sent or
/// received (`received`, when given, gets the number of boxes received). Collective.
/// `owners`, when given, gets the rank each ghost's box came from (its owner), in the
/// ghosts' order.
std::vector<int> objects_within_reach(MPI_Comm comm, const World& w, double skin, std::int64_t* received = nullptr,
                                      std::vector<int>* owners = nullptr);

/// Whether object k's mesh is a single-copy entry's that this rank does not hold: a rank
/// that comes to ghost or own it takes it from the rank that holds it
/// (fetch_object_meshes) instead of reading its file again.
bool needs_owner_mesh(const Scene& scene, int k);

/// The meshes of objects `wanted` from the ranks `from` that hold them (their owners),
/// held here afterwards (SceneObject::mesh), each checked against the digest of the mesh
/// the scene first made. Two alltoallv_bytes: the ids out, the meshes back. Returns how
/// many meshes came. Collective: every rank calls it together, with its own (maybe empty)
/// lists.
std::int64_t fetch_object_meshes(MPI_Comm comm, const Scene& scene, const std::vector<int>& wanted,
                                 const std::vector<int>& from);

/// Of `objects` (held by `owners`, one each), the meshes this rank needs_owner_mesh of,
/// fetched from their owners: one MPI_Allreduce says whether any rank needs one, and only
/// then do the ranks call fetch_object_meshes. Returns how many meshes came. Collective.
std::int64_t fetch_meshes_if_needed(MPI_Comm comm, const Scene& scene, const std::vector<int>& objects,
                                    const std::vector<int>& owners);

class GhostSet {
public:
  /// The skin starts at `cell_size` (the detector's cell) and may grow to the median
  /// object size as objects move faster.
  GhostSet(MPI_Comm comm, const Scene& scene, double cell_size);
  ~GhostSet();
  GhostSet(const GhostSet&) = delete;
  GhostSet& operator=(const GhostSet&) = delete;

  /// The ghost set at the current positions: every other rank's object whose box, grown
  /// by skin/2, overlaps the box of one of this rank's objects grown likewise
  /// (objects_within_reach; the owners are the World's), the World's ghost part and the
  /// Halo rebuilt where it changed, the ghost rows of x and x_prev filled from their
  /// owners. Returns true when this rank's ghost objects changed (on
  /// one rank: when `force`), so that the detector must be rebuilt. Collective.
  bool rebuild(World& w, bool force);
  /// Before detection: the ghost rows of x_prev take x^t (the last step's final
  /// positions), those of x take x~ from the owners; the set is rebuilt first when some
  /// owned vertex has moved half the skin. Returns what rebuild() returns, or false.
  /// Collective (nothing on one rank).
  bool refresh_predicted(World& w);
  /// Copies the owners' rows of `xyz` (n_local,3) into the ghost rows (nothing on one
  /// rank). Collective.
  void update(double* xyz);
  /// After the contact response: the ghost rows of x take the owners' final positions.
  /// Since refresh_predicted() the ghosts hold x~, and the response moves only the
  /// vertices it acts on, so only the rows that changed travel (Halo::update_changed);
  /// the same bits as update(w.x). Collective (nothing on one rank).
  void update_final(World& w);
  /// Before the World is replaced (migration): the Halo goes, its traffic is kept in
  /// bytes_received(); the next rebuild(force) makes a new one.
  void drop();

  /// The ghost reach [m]: objects closer than this are ghosted.
  double skin() const { return skin_; }
  /// Whether there are other ranks to exchange with (a Halo exists).
  bool active() const { return halo_ != nullptr; }
  /// The neighbour messages of the contact response (null on one rank).
  NeighbourExchange* exchange();
  /// Ghost-set rebuilds so far.
  std::int64_t rebuilds() const { return rebuilds_; }
  /// The ghost-set tests so far (objects_within_reach: at every rebuild, the set changed
  /// or not), and the object boxes this rank received for them.
  std::int64_t reach_tests() const { return reach_tests_; }
  std::int64_t boxes_received() const { return boxes_received_; }
  /// Single-copy meshes this rank took from their owners for new ghosts so far.
  std::int64_t meshes_fetched() const { return meshes_fetched_; }
  /// Bytes this rank has received through its halos so far.
  std::int64_t bytes_received() const;
  /// Rounds of messages through its halos so far (Halo::rounds).
  std::int64_t rounds() const;

private:
  bool stale(const World& w);

  MPI_Comm comm_;
  int rank_ = 0, nranks_ = 1;
  const Scene& scene_;
  double cell_size_ = 0;
  double skin_ = 0;                  // ghost reach: objects closer than this are ghosted
  double max_skin_ = 0;              // the skin's upper bound: the median object size
  std::int64_t steps_since_ = 0;     // steps since the last rebuild
  std::vector<double> x_at_build_;   // owned positions when the set was built
  std::unique_ptr<Halo> halo_;
  std::int64_t rebuilds_ = 0;
  std::int64_t reach_tests_ = 0, boxes_received_ = 0, meshes_fetched_ = 0;
  std::int64_t bytes_before_ = 0, rounds_before_ = 0;  // of halos since replaced
};

}  // namespace softcontact
