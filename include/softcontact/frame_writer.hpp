#pragma once
// The frames of a run (docs/output-format.md), written so that a kill at any moment
// (kill -9 included) leaves every frame written before it readable:
//
//   mesh.h5             /mesh: the mesh, written once
//   frames/NNNNNN.h5    one file per frame: positions, velocities, owner_rank, ... with
//                       attributes 'time' and 'step' on its root group
//   frames.h5           the index: /mesh and /frames/NNNNNN are external links to the
//                       above, so h5py and HDF5 read one file as the contract describes
//   frames.xdmf         for ParaView, referencing the files above directly
//
// Every file is written (collectively, MPI-IO: each rank its owned rows at offsets given
// by global ids) under a temporary name and renamed when complete; the index and the
// XDMF are rewritten after every frame and only ever name complete files. An HDF5 file
// that is open when the process dies can be damaged; no file that is referenced is ever
// open for writing.
#include <hdf5.h>
#include <mpi.h>

#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "softcontact/scene.hpp"
#include "softcontact/world.hpp"

namespace softcontact {

namespace frames {
/// What the index and the XDMF say about one frame file (src/io/frame_files.hpp).
struct FrameRecord {
  std::int64_t step = -1;
  double time = 0;
  std::vector<std::pair<std::string, int>> fields;  ///< (xdmf name, components), besides positions
  std::vector<std::string> datasets;                 ///< the dataset of each field
};
}  // namespace frames

/// A per-vertex field of a frame: `components` values per owned vertex (local order).
struct VertexField {
  std::string name;        ///< dataset name under /frames/NNNNNN/
  std::string xdmf_name;   ///< attribute name shown in ParaView
  int components = 1;      ///< 1 (scalar) or 3 (vector)
  const double* data = nullptr;
};

class FrameWriter {
public:
  /// Writes mesh.h5 and an empty index `h5_path` beside it (collectively); `xdmf_path` is
  /// written by rank 0.
  FrameWriter(MPI_Comm comm, const std::string& h5_path, const std::string& xdmf_path, const Scene& scene,
              const World& world);

  /// Continues the frames of an earlier run in the same place (restart): keeps the frames
  /// up to step `last_step` and deletes later or damaged ones (frames::resume_frames).
  /// Throws InputError when mesh.h5 is missing or does not match the world. Collective.
  FrameWriter(MPI_Comm comm, const std::string& h5_path, const std::string& xdmf_path, const World& world,
              std::int64_t last_step);
  FrameWriter(const FrameWriter&) = delete;
  FrameWriter& operator=(const FrameWriter&) = delete;

  /// Writes frames/<frame index>.h5: positions, velocities, owner_rank and `extra` fields,
  /// with attributes 'time' and 'step'; then links it into the index and the XDMF.
  void write_frame(std::int64_t step, double time, const World& world, const std::vector<VertexField>& extra = {});

  std::int64_t frames_written() const { return count_; }
  /// Step of the last frame written (-1 before the first).
  std::int64_t last_step() const { return last_step_; }

  /// Nothing stays open between frames; kept for callers that mark the end of output.
  void close() {}

private:
  void write_index() const;
  void write_xdmf() const;

  MPI_Comm comm_;
  int rank_ = 0;
  std::string dir_, h5_path_, xdmf_path_;
  std::int64_t count_ = 0, last_step_ = -1;
  gid_t nv_ = 0, nt_ = 0;
  std::vector<GidRun> vertex_runs_;
  std::vector<frames::FrameRecord> frames_;  // rank 0
};

}  // namespace softcontact
