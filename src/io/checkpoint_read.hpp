#pragma once
// Reading and checking a checkpoint (internal; layout in softcontact/checkpoint.hpp): the
// parts that need no simulator and no MPI, so that the fuzz harness
// (tests/fuzz/fuzz_checkpoint.cpp) runs exactly the code --restart runs. Every problem of
// the file is an InputError naming it (exit status 2); nothing here trusts a count, a
// shape or a value before checking it.
#include <hdf5.h>

#include <cstdint>
#include <string>
#include <vector>

#include "softcontact/checkpoint.hpp"
#include "softcontact/scene.hpp"
#include "softcontact/world.hpp"

namespace softcontact::checkpoint {

/// The checkpoint format this build writes and reads.
inline constexpr std::int64_t kFormat = 2;  // 2: two friction anchors per vertex (one per other body)

/// Reads /run of the open checkpoint `file` and checks it: every attribute present,
/// scalar and in range (format, step >= 0, steps >= 1, dt > 0 and finite, ...), the
/// partition and boxes of one length with finite boxes, no dataset larger than the file.
/// Throws InputError naming `path`.
CheckpointInfo read_run(hid_t file, const std::string& path);

/// Opens `path` (serial HDF5 driver) and read_run()s it.
CheckpointInfo read_run_file(const std::string& path);

/// Checks a checkpoint's run description against the scene loaded from its stored text:
/// the fingerprint (from the objects' `digests`, Scene::object_digests), the number of
/// objects (partition, boxes) and of vertices. Throws InputError naming `path`.
void check_against_scene(const CheckpointInfo& info, const Scene& scene, const std::string& path,
                         const std::vector<std::uint64_t>& digests);

/// The per-vertex state of a checkpoint, rows packed in the order of the runs read
/// (owned-run order on a rank: local order).
struct StateRows {
  std::vector<double> x, x_prev, v;              ///< (n,3)
  std::vector<std::int64_t> anchor_step;         ///< (n,kPerPoint)
  std::vector<std::int32_t> anchor_object;       ///< (n,kPerPoint)
  std::vector<std::int64_t> anchor_triangle;     ///< (n,3 kPerPoint) global vertex ids
  std::vector<double> anchor_bary;               ///< (n,3 kPerPoint)
};

/// Reads the rows `runs` (n rows in all) of every /state dataset of `file`, each checked
/// to have `vertices` rows of the right width. `collective` as for h5::read_rows (true:
/// every rank of the file's communicator calls). Throws InputError naming `path`.
void read_state(hid_t file, const std::string& path, gid_t vertices, const std::vector<GidRun>& runs, std::size_t n,
                StateRows& rows, bool collective);

/// The first problem of the rows, as a key: 8 * (global id of the vertex) + what (an
/// index into the messages of state_problem); -1 when there is none. `gid[i]` is the
/// global id of row i; `layout` the objects' vertex ranges. Values must be finite; an
/// anchor names no object (-1) or an object of the scene and three of its vertices.
/// The key orders problems by vertex, so the smallest over ranks is the same problem
/// whatever the partition.
std::int64_t first_state_problem(const StateRows& rows, const std::vector<gid_t>& gid,
                                 const std::vector<ObjectLayout>& layout);

/// The message for a key of first_state_problem.
std::string state_problem(std::int64_t key);

}  // namespace softcontact::checkpoint
