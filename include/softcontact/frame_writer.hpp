#pragma once
// One HDF5 file (parallel, MPI-IO) and one XDMF file per run: the output contract of
// docs/output-format.md. Every rank writes the rows of the vertices, tets and triangles
// it owns, in one collective call per dataset, at offsets given by global ids; rank 0
// writes the XDMF, which is rewritten (temporary file + rename) after every frame so
// that it only ever references frames that are completely written and flushed.
#include <hdf5.h>
#include <mpi.h>

#include <cstdint>
#include <string>
#include <vector>

#include "softcontact/scene.hpp"
#include "softcontact/world.hpp"

namespace softcontact {

/// A per-vertex field of a frame: `components` values per owned vertex (local order).
struct VertexField {
  std::string name;        ///< dataset name under /frames/NNNNNN/
  std::string xdmf_name;   ///< attribute name shown in ParaView
  int components = 1;      ///< 1 (scalar) or 3 (vector)
  const double* data = nullptr;
};

class FrameWriter {
public:
  /// Creates `h5_path` (collectively) and writes /mesh. `xdmf_path` is written by rank 0.
  FrameWriter(MPI_Comm comm, const std::string& h5_path, const std::string& xdmf_path, const Scene& scene,
              const World& world);
  ~FrameWriter();
  FrameWriter(const FrameWriter&) = delete;
  FrameWriter& operator=(const FrameWriter&) = delete;

  /// Writes /frames/<frame index>/: positions, velocities, owner_rank and `extra` fields,
  /// with attributes 'time' and 'step'; flushes the file, then updates the XDMF.
  void write_frame(std::int64_t step, double time, const World& world, const std::vector<VertexField>& extra = {});

  std::int64_t frames_written() const { return static_cast<std::int64_t>(frames_.size()); }

  /// Closes the file (also done by the destructor). Collective.
  void close();

private:
  struct FrameInfo {
    std::int64_t step;
    double time;
    std::vector<std::pair<std::string, int>> fields;  // (xdmf name / dataset, components)
    std::vector<std::string> datasets;
  };
  void write_xdmf() const;

  MPI_Comm comm_;
  int rank_ = 0;
  hid_t file_ = -1;
  std::string h5_path_, xdmf_path_;
  gid_t nv_ = 0, nt_ = 0;
  std::vector<GidRun> vertex_runs_;
  std::vector<FrameInfo> frames_;
};

}  // namespace softcontact
