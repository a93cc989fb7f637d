#pragma once
// Checkpoints (docs/reliability.md): one HDF5 file holding everything a run needs to
// continue bitwise as if it had never stopped, on any number of ranks:
//
//   /state/x, /state/x_prev, /state/v      (N,3) float64, global vertex order
//   /state/anchor_step                     (N,)  int64    stiction anchors (friction),
//   /state/anchor_object                   (N,)  int32    keyed by global ids
//   /state/anchor_triangle                 (N,3) int64
//   /state/anchor_bary                     (N,3) float64
//   /run/scene                             (bytes)        the scene file's text
//   /run/partition                         (objects,) int32, rank of each object
//   /run/boxes                             (objects,6) float64, each object's box
//   /run/split_hosts                       (n,) int32: the split objects' hosts
//                                          (SplitHosts): their count, then per object
//                                          its number of parts and each part's rank;
//                                          absent in checkpoints written before it
//   attributes of /run: format, step, time, dt, steps, output_every, frames, ranks,
//   anchor_step, vertices, fingerprint, energy0, energy_scale, scene_path, output_dir
//
// A checkpoint is written under a temporary name, flushed to disk and renamed, so a kill
// while writing leaves the previous checkpoint as it was.
#include <mpi.h>

#include <cstdint>
#include <string>
#include <vector>

#include "softcontact/partition.hpp"
#include "softcontact/rebalance.hpp"
#include "softcontact/scene.hpp"
#include "softcontact/step_state.hpp"
#include "softcontact/world.hpp"

namespace softcontact {


/// What a checkpoint says about its run (identical on every rank after reading).
struct CheckpointInfo {
  std::int64_t format = 1;
  std::int64_t step = 0;
  double time = 0;
  double dt = 0;
  std::int64_t steps = 0;         ///< steps of the whole run
  std::int64_t output_every = 1;  ///< steps between frames
  std::int64_t frames = 0;        ///< frames written up to this step
  std::int64_t ranks = 1;         ///< ranks of the run that wrote it
  std::int64_t anchor_step = 0;   ///< ContactResponse's step counter
  std::int64_t vertices = 0;      ///< global vertex count
  std::uint64_t fingerprint = 0;  ///< scene_fingerprint() of the scene
  double energy0 = 0;             ///< total energy at the start of the run [J] (failure guard)
  double energy_scale = 0;        ///< energy the scene can release [J] (failure guard)
  std::string scene_path;         ///< the scene file (absolute), which anchors relative mesh paths
  std::string scene_text;         ///< the scene file's text
  std::string output_dir;         ///< the run's output directory (absolute)
  std::vector<int> partition;     ///< object -> rank
  std::vector<Box> boxes;   ///< object boxes at this step
  /// Per split object: the rank of each part (Simulator::split_hosts). A restart on the
  /// same rank count hands them to the Simulator; empty when the checkpoint has none.
  SplitHosts split_hosts;
};

/// A hash of everything in a loaded scene that results depend on: meshes (positions and
/// tets, through each object's mesh_digest), materials, friction, fixed vertices, motions
/// and the simulation settings of the step (dt, gravity, integrator, self-collisions).
/// Restart refuses a scene whose fingerprint differs (a mesh file edited since, for
/// example). This one digests every object's mesh here.
std::uint64_t scene_fingerprint(const Scene& scene);
/// The same from the objects' digests (Scene::object_digests, which ranks can share).
std::uint64_t scene_fingerprint(const Scene& scene, const std::vector<std::uint64_t>& digests);

/// Writes `path` (via path + ".tmp", fsync and rename): the owned rows of `state` (global
/// rows from w's vertex ids) and `info`, whose step, anchor step, rank count and vertex
/// count are taken from `state`, `comm` and `w`; the caller fills the rest (time, dt,
/// partition, boxes, the run's settings). Collective.
void write_checkpoint(MPI_Comm comm, const std::string& path, const World& w, const StepState& state,
                      CheckpointInfo info);

/// Reads the run description of a checkpoint (rank 0 reads, every rank receives it).
/// Throws InputError naming the file when it is not a readable softcontact checkpoint.
/// Collective.
CheckpointInfo read_checkpoint_info(MPI_Comm comm, const std::string& path);

/// Reads the checkpoint's state (positions, previous positions, velocities, anchors,
/// step counters) for the owned vertices of `w`, a World built from the same scene (any
/// partition), into `state` (Simulator::restore installs it). A dataset missing or of
/// another shape, a value that is not finite or an anchor outside its object is an
/// InputError naming the file (and the first such vertex), thrown on every rank together.
/// Collective.
void read_checkpoint_state(MPI_Comm comm, const std::string& path, const CheckpointInfo& info, const World& w,
                           StepState& state);

/// `path` itself when it is a file; for a directory (a run's output directory or its
/// checkpoints/ folder) the checkpoint of the highest step in it. Throws InputError when
/// there is none. Rank-local (file system only).
std::string resolve_checkpoint(const std::string& path);

/// checkpoints/checkpoint_<step, 12 digits>.h5 under `output_dir`.
std::string checkpoint_path(const std::string& output_dir, std::int64_t step);

/// Deletes all but the newest `keep` checkpoints of `output_dir` (rank-local; call on one
/// rank).
void prune_checkpoints(const std::string& output_dir, std::int64_t keep);

}  // namespace softcontact
