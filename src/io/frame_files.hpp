#pragma once
// The files of a run's frames beside the writer (internal; layout in
// softcontact/frame_writer.hpp): the index, the XDMF, the field list of a frame, and
// reading back an existing output directory to continue it (restart). Rank-local, no MPI:
// FrameWriter calls these on rank 0, and the fuzz harness (tests/fuzz/fuzz_frames.cpp)
// calls them on directories built from its input.
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "softcontact/frame_writer.hpp"
#include "softcontact/mesh.hpp"

namespace softcontact::frames {

inline constexpr const char* kMeshFile = "mesh.h5";
inline constexpr const char* kFramesDir = "frames";

/// "NNNNNN": the group name of frame k in the index.
std::string frame_group(std::int64_t k);
/// "frames/NNNNNN.h5": frame k's file, relative to the output directory.
std::string frame_file(std::int64_t k);

/// The 'fields' attribute of a frame file: "dataset:xdmf name:components" per line.
std::string encode_fields(const FrameRecord& f);
/// Parses encode_fields' text into f.fields and f.datasets; false when it is not such a
/// text (components other than 1 or 3, names empty or holding characters that XML or
/// HDF5 paths would read otherwise).
bool decode_fields(const std::string& text, FrameRecord& f);

/// Continuing the frames in `dir` (restart at step `last_step`): checks that
/// dir/mesh.h5 holds the mesh of `vertices` vertices and `tets` tets (InputError naming
/// the file otherwise); returns frames 0, 1, ... up to the first that is missing,
/// damaged (an attribute, dataset or shape not as written), not later than the one
/// before it, or past `last_step`, and deletes every later frame file and every
/// temporary file of frames/.
std::vector<FrameRecord> resume_frames(const std::string& dir, gid_t vertices, gid_t tets, std::int64_t last_step);

/// Writes the index `h5_path` (external links to mesh.h5 and frames 0..count-1) through a
/// temporary file and a rename.
void write_index(const std::string& h5_path, std::int64_t count);

/// Writes the XDMF `xdmf_path` for `frames` of a mesh of `vertices` vertices and `tets`
/// tets, through a temporary file and a rename.
void write_xdmf(const std::string& xdmf_path, const std::vector<FrameRecord>& frames, gid_t vertices, gid_t tets);

}  // namespace softcontact::frames
