#include "h5_util.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>

#include "softcontact/error.hpp"
#include "softcontact/mpi_util.hpp"

namespace softcontact::h5 {

void check(herr_t status, const std::string& what) {
  if (status < 0) throw RuntimeFailure("HDF5 failed to " + what);
}

hid_t check_id(hid_t id, const std::string& what) {
  if (id < 0) throw RuntimeFailure("HDF5 failed to " + what);
  return id;
}

namespace {

// Selects `runs` (rows) of a (rows, cols) file space; returns the rows selected.
hsize_t select_runs(hid_t fspace, int cols, const std::vector<GidRun>& runs, const std::string& name) {
  hsize_t local = 0;
  if (runs.empty()) {
    check(H5Sselect_none(fspace), "select rows");
    return 0;
  }
  bool first = true;
  for (const GidRun& r : runs) {
    const hsize_t start[2] = {static_cast<hsize_t>(r.begin), 0};
    const hsize_t count[2] = {static_cast<hsize_t>(r.count), static_cast<hsize_t>(cols)};
    check(H5Sselect_hyperslab(fspace, first ? H5S_SELECT_SET : H5S_SELECT_OR, start, nullptr, count, nullptr),
          "select rows of " + name);
    first = false;
    local += static_cast<hsize_t>(r.count);
  }
  return local;
}

hid_t memory_space(hsize_t values) {
  const hsize_t mdims[1] = {values};
  const hid_t mspace = check_id(H5Screate_simple(1, mdims, nullptr), "create a memory dataspace");
  if (values == 0) check(H5Sselect_none(mspace), "select nothing");
  return mspace;
}

hid_t transfer(bool collective) {
  const hid_t dxpl = check_id(H5Pcreate(H5P_DATASET_XFER), "create a transfer property list");
  if (collective) check(H5Pset_dxpl_mpio(dxpl, H5FD_MPIO_COLLECTIVE), "set collective transfer");
  return dxpl;
}

}  // namespace

template <class T>
void write_rows(hid_t loc, const std::string& name, gid_t rows, int cols, const std::vector<GidRun>& runs,
                const T* data, bool collective) {
  const hsize_t dims[2] = {static_cast<hsize_t>(rows), static_cast<hsize_t>(cols)};
  const hid_t fspace = check_id(H5Screate_simple(cols == 1 ? 1 : 2, dims, nullptr), "create a dataspace for " + name);
  const hid_t dset = check_id(H5Dcreate2(loc, name.c_str(), type_of<T>(), fspace, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT),
                              "create dataset " + name);
  const hsize_t local = select_runs(fspace, cols, runs, name);
  const hid_t mspace = memory_space(local * static_cast<hsize_t>(cols));
  const hid_t dxpl = transfer(collective);
  const herr_t status = H5Dwrite(dset, type_of<T>(), mspace, fspace, dxpl, data);
  H5Pclose(dxpl);
  H5Sclose(mspace);
  H5Dclose(dset);
  H5Sclose(fspace);
  check(status, "write dataset " + name);
}

template <class T>
void read_rows(hid_t loc, const std::string& name, gid_t rows, int cols, const std::vector<GidRun>& runs, T* data,
               const std::string& file, bool collective) {
  const hid_t dset = H5Dopen2(loc, name.c_str(), H5P_DEFAULT);
  if (dset < 0) throw RuntimeFailure(file + ": dataset '" + name + "' is missing");
  const hid_t fspace = H5Dget_space(dset);
  hsize_t dims[2] = {0, 0};
  const int nd = H5Sget_simple_extent_ndims(fspace);
  const bool shape_ok = nd == (cols == 1 ? 1 : 2) && H5Sget_simple_extent_dims(fspace, dims, nullptr) == nd &&
                        dims[0] == static_cast<hsize_t>(rows) && (cols == 1 || dims[1] == static_cast<hsize_t>(cols));
  if (!shape_ok) {
    H5Sclose(fspace);
    H5Dclose(dset);
    throw RuntimeFailure(file + ": dataset '" + name + "' should have " + std::to_string(rows) + " rows of " +
                         std::to_string(cols));
  }
  const hsize_t local = select_runs(fspace, cols, runs, name);
  const hid_t mspace = memory_space(local * static_cast<hsize_t>(cols));
  const hid_t dxpl = transfer(collective);
  const herr_t status = H5Dread(dset, type_of<T>(), mspace, fspace, dxpl, data);
  H5Pclose(dxpl);
  H5Sclose(mspace);
  H5Sclose(fspace);
  H5Dclose(dset);
  if (status < 0) throw RuntimeFailure(file + ": cannot read dataset '" + name + "'");
}

template void write_rows<double>(hid_t, const std::string&, gid_t, int, const std::vector<GidRun>&, const double*, bool);
template void write_rows<std::int64_t>(hid_t, const std::string&, gid_t, int, const std::vector<GidRun>&,
                                       const std::int64_t*, bool);
template void write_rows<std::int32_t>(hid_t, const std::string&, gid_t, int, const std::vector<GidRun>&,
                                       const std::int32_t*, bool);
template void write_rows<char>(hid_t, const std::string&, gid_t, int, const std::vector<GidRun>&, const char*, bool);
gid_t rows_of(hid_t loc, const std::string& name) {
  const hid_t d = H5Dopen2(loc, name.c_str(), H5P_DEFAULT);
  const hid_t sp = d < 0 ? -1 : H5Dget_space(d);
  hsize_t dims[2] = {0, 0};
  const int nd = sp < 0 ? -1 : H5Sget_simple_extent_ndims(sp);
  if (nd < 1 || nd > 2 || H5Sget_simple_extent_dims(sp, dims, nullptr) != nd) dims[0] = 0;
  if (sp >= 0) H5Sclose(sp);
  if (d >= 0) H5Dclose(d);
  return static_cast<gid_t>(dims[0]);
}

template void read_rows<double>(hid_t, const std::string&, gid_t, int, const std::vector<GidRun>&, double*,
                                const std::string&, bool);
template void read_rows<std::int64_t>(hid_t, const std::string&, gid_t, int, const std::vector<GidRun>&, std::int64_t*,
                                      const std::string&, bool);
template void read_rows<std::int32_t>(hid_t, const std::string&, gid_t, int, const std::vector<GidRun>&, std::int32_t*,
                                      const std::string&, bool);
template void read_rows<char>(hid_t, const std::string&, gid_t, int, const std::vector<GidRun>&, char*,
                              const std::string&, bool);

template <class T>
void write_attribute(hid_t loc, const char* name, const T& value) {
  const hid_t space = H5Screate(H5S_SCALAR);
  const hid_t attr = check_id(H5Acreate2(loc, name, type_of<T>(), space, H5P_DEFAULT, H5P_DEFAULT),
                              std::string("create attribute ") + name);
  const herr_t status = H5Awrite(attr, type_of<T>(), &value);
  H5Aclose(attr);
  H5Sclose(space);
  check(status, std::string("write attribute ") + name);
}

template void write_attribute<double>(hid_t, const char*, const double&);
template void write_attribute<std::int64_t>(hid_t, const char*, const std::int64_t&);
template void write_attribute<std::int32_t>(hid_t, const char*, const std::int32_t&);

void write_string_attribute(hid_t loc, const char* name, const std::string& value) {
  const hid_t str = H5Tcopy(H5T_C_S1);
  H5Tset_size(str, value.size() + 1);
  const hid_t space = H5Screate(H5S_SCALAR);
  const hid_t attr = check_id(H5Acreate2(loc, name, str, space, H5P_DEFAULT, H5P_DEFAULT), std::string("create attribute ") + name);
  const herr_t status = H5Awrite(attr, str, value.c_str());
  H5Aclose(attr);
  H5Sclose(space);
  H5Tclose(str);
  check(status, std::string("write attribute ") + name);
}

namespace {
// One value: H5Aread fills as many as the attribute's dataspace holds.
bool holds_one_value(hid_t attr) {
  const hid_t space = H5Aget_space(attr);
  if (space < 0) return false;
  const bool one = H5Sget_simple_extent_npoints(space) == 1;
  H5Sclose(space);
  return one;
}
}  // namespace

template <class T>
T read_attribute(hid_t loc, const char* name, const std::string& file) {
  T value{};
  if (H5Aexists(loc, name) <= 0) throw RuntimeFailure(file + ": attribute '" + name + "' is missing");
  const hid_t attr = H5Aopen(loc, name, H5P_DEFAULT);
  const herr_t status = attr < 0 || !holds_one_value(attr) ? -1 : H5Aread(attr, type_of<T>(), &value);
  if (attr >= 0) H5Aclose(attr);
  if (status < 0) throw RuntimeFailure(file + ": cannot read attribute '" + name + "'");
  return value;
}

template double read_attribute<double>(hid_t, const char*, const std::string&);
template std::int64_t read_attribute<std::int64_t>(hid_t, const char*, const std::string&);
template std::int32_t read_attribute<std::int32_t>(hid_t, const char*, const std::string&);

std::string read_string_attribute(hid_t loc, const char* name, const std::string& file) {
  if (H5Aexists(loc, name) <= 0) throw RuntimeFailure(file + ": attribute '" + name + "' is missing");
  const hid_t attr = H5Aopen(loc, name, H5P_DEFAULT);
  const hid_t type = attr < 0 ? -1 : H5Aget_type(attr);
  std::string value;
  herr_t status = -1;
  if (type >= 0 && H5Tget_class(type) == H5T_STRING && H5Tis_variable_str(type) == 0 && holds_one_value(attr) &&
      H5Tget_size(type) <= kMaxTextAttribute) {
    value.assign(H5Tget_size(type), '\0');
    status = H5Aread(attr, type, value.data());
    value.resize(value.find('\0') == std::string::npos ? value.size() : value.find('\0'));
  }
  if (type >= 0) H5Tclose(type);
  if (attr >= 0) H5Aclose(attr);
  if (status < 0) throw RuntimeFailure(file + ": cannot read the text attribute '" + name + "'");
  return value;
}

hid_t mpio_access(MPI_Comm comm) {
  const hid_t fapl = check_id(H5Pcreate(H5P_FILE_ACCESS), "create a file access property list");
  check(H5Pset_fapl_mpio(fapl, comm, MPI_INFO_NULL), "set the MPI-IO driver");
  return fapl;
}

hid_t create_parallel(MPI_Comm comm, const std::string& path, const std::string& what, bool large_attributes) {
  hid_t file = -1;
  {
    const QuietErrors quiet;
    const hid_t fapl = mpio_access(comm);
    // Object headers of format 2 (HDF5 1.8), which can keep attributes densely.
    if (large_attributes) H5Pset_libver_bounds(fapl, H5F_LIBVER_V18, H5F_LIBVER_LATEST);
    file = H5Fcreate(path.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, fapl);
    H5Pclose(fapl);
  }
  int created = file >= 0 ? 1 : 0;
  MPI_Allreduce(MPI_IN_PLACE, &created, 1, MPI_INT, MPI_MAX, comm);
  const std::string message = "cannot create " + what + " '" + path + "'";
  if (!created) throw CollectiveFailure(message);
  // Some ranks only: a failure of those ranks alone (they end the job with MPI_Abort; the
  // others wait in the next collective call, since closing the file would be one too).
  if (file < 0) throw RuntimeFailure(message);
  return file;
}

QuietErrors::QuietErrors() {
  H5Eget_auto2(H5E_DEFAULT, &func_, &data_);
  H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
}

QuietErrors::~QuietErrors() { H5Eset_auto2(H5E_DEFAULT, func_, data_); }

namespace {
bool sync_file(const std::string& path) {
  const int fd = ::open(path.c_str(), O_RDONLY);
  if (fd < 0) return false;
  const bool ok = ::fsync(fd) == 0;
  ::close(fd);
  return ok;
}
}  // namespace

void publish(MPI_Comm comm, const std::string& tmp, const std::string& path, bool sync) {
  const int rank = comm_rank(comm);
  MPI_Barrier(comm);  // every rank has closed the file
  int ok = 1;
  std::string why;
  if (rank == 0) {
    std::error_code ec;
    if (sync && !sync_file(tmp)) {
      ok = 0;
      why = "cannot flush '" + tmp + "' to disk";
    } else {
      std::filesystem::rename(tmp, path, ec);
      if (ec) {
        ok = 0;
        why = "cannot rename '" + tmp + "' to '" + path + "': " + ec.message();
      } else if (sync) {
        sync_file(std::filesystem::path(path).parent_path().empty() ? "." : std::filesystem::path(path).parent_path().string());
      }
    }
  }
  MPI_Bcast(&ok, 1, MPI_INT, 0, comm);
  if (!ok) {
    // The same message on every rank: one of them prints it.
    long long n = static_cast<long long>(why.size());
    MPI_Bcast(&n, 1, MPI_LONG_LONG, 0, comm);
    why.resize(static_cast<std::size_t>(n));
    MPI_Bcast(why.data(), static_cast<int>(n), MPI_CHAR, 0, comm);
    throw CollectiveFailure(why);
  }
}

void write_text_atomically(const std::string& path, const std::string& text) {
  const std::string tmp = path + ".tmp";
  {
    std::ofstream out(tmp, std::ios::trunc | std::ios::binary);
    out << text;
    out.flush();
    if (!out) throw RuntimeFailure("cannot write '" + tmp + "'");
  }
  std::error_code ec;
  std::filesystem::rename(tmp, path, ec);
  if (ec) throw RuntimeFailure("cannot rename '" + tmp + "' to '" + path + "': " + ec.message());
}

}  // namespace softcontact::h5
