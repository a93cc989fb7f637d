#pragma once
// HDF5 helpers shared by the frame writer and the checkpoints (internal): datasets whose
// rows are spread over the ranks by global id, written and read with one collective call
// each; scalar attributes; files written under a temporary name and renamed when whole.
#include <hdf5.h>
#include <mpi.h>

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "softcontact/world.hpp"

namespace softcontact::h5 {

/// Throws RuntimeFailure("HDF5 failed to <what>") when status < 0.
void check(herr_t status, const std::string& what);
hid_t check_id(hid_t id, const std::string& what);

template <class T>
hid_t type_of();
template <>
inline hid_t type_of<double>() { return H5T_NATIVE_DOUBLE; }
template <>
inline hid_t type_of<std::int64_t>() { return H5T_NATIVE_INT64; }
template <>
inline hid_t type_of<std::int32_t>() { return H5T_NATIVE_INT32; }
template <>
inline hid_t type_of<char>() { return H5T_NATIVE_CHAR; }

/// Creates dataset `name` (rows x cols; 1-D when cols == 1) in `loc` and writes this
/// rank's rows: `runs` are the global row ranges it owns, `data` the rows packed in that
/// order. One collective H5Dwrite (independent when `collective` is false, for files
/// only one rank has open); a rank with no rows takes part with an empty selection.
template <class T>
void write_rows(hid_t loc, const std::string& name, gid_t rows, int cols, const std::vector<GidRun>& runs,
                const T* data, bool collective = true);

/// Reads the rows `runs` of dataset `name` into `data` (packed in run order). Checks the
/// dataset's shape against (rows, cols); throws RuntimeFailure naming `file` otherwise.
/// `collective` as for write_rows.
template <class T>
void read_rows(hid_t loc, const std::string& name, gid_t rows, int cols, const std::vector<GidRun>& runs, T* data,
               const std::string& file, bool collective = true);

/// The number of rows (first dimension) of dataset `name` in `loc`; 0 when it is missing
/// or has no dimensions.
gid_t rows_of(hid_t loc, const std::string& name);

/// All rows of a dataset: one run [0, rows).
inline std::vector<GidRun> all_rows(gid_t rows) { return rows > 0 ? std::vector<GidRun>{{0, rows}} : std::vector<GidRun>{}; }

template <class T>
void write_attribute(hid_t loc, const char* name, const T& value);
void write_string_attribute(hid_t loc, const char* name, const std::string& value);
/// Reads a scalar attribute (one value, converted to T); throws RuntimeFailure naming
/// `file` when it is missing, holds more or fewer values or does not convert.
template <class T>
T read_attribute(hid_t loc, const char* name, const std::string& file);
/// The longest text attribute read_string_attribute accepts [bytes].
inline constexpr std::size_t kMaxTextAttribute = std::size_t{1} << 24;
/// Reads a scalar fixed-length text attribute (write_string_attribute), up to its first
/// NUL; throws RuntimeFailure as read_attribute, and for any other type or a longer one.
std::string read_string_attribute(hid_t loc, const char* name, const std::string& file);

/// File access with the MPI-IO driver on `comm`.
hid_t mpio_access(MPI_Comm comm);

/// Creates (truncates) `path` for parallel writing on every rank of `comm`. When every
/// rank fails, every rank throws the same CollectiveFailure "cannot create WHAT 'path'";
/// when some do, those throw it as a RuntimeFailure of their own. Collective.
/// `large_attributes`: the file format of HDF5 1.8 and later, whose object headers can
/// keep attributes past 64 KiB in dense storage (a group created with attribute phase
/// change 0, 0).
hid_t create_parallel(MPI_Comm comm, const std::string& path, const std::string& what, bool large_attributes = false);

/// Switches HDF5's automatic error printing off for the life of the object (files that
/// may be damaged are probed; their failures are ours to report).
class QuietErrors {
public:
  QuietErrors();
  ~QuietErrors();
  QuietErrors(const QuietErrors&) = delete;
  QuietErrors& operator=(const QuietErrors&) = delete;

private:
  H5E_auto2_t func_ = nullptr;
  void* data_ = nullptr;
};

/// Makes `tmp` the file `path` (rank 0 of `comm` renames after every rank is done with
/// it; with `sync`, its data reach the disk first). Collective; throws on failure.
void publish(MPI_Comm comm, const std::string& tmp, const std::string& path, bool sync);

/// Writes `text` to `path` through a temporary file and a rename (one process).
void write_text_atomically(const std::string& path, const std::string& text);

}  // namespace softcontact::h5
