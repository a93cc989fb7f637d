#pragma once
// Compares two run output directories (docs/output-format.md) dataset by dataset,
// bitwise: mesh.h5 and every frame file the index frames.h5 links to. owner_rank is the
// one field allowed to differ (it names ranks). Rank-local; for tests.
#include <gtest/gtest.h>
#include <hdf5.h>
#include <mpi.h>
#include <unistd.h>

#include <filesystem>
#include <sstream>
#include <string>
#include <vector>

namespace softcontact::test {

/// A scratch directory under the system's temporary directory, the same on every rank
/// of MPI_COMM_WORLD (named after rank 0's process id).
inline std::filesystem::path scratch_dir(const std::string& name) {
  int rank = 0;
  MPI_Comm_rank(MPI_COMM_WORLD, &rank);
  long tag = rank == 0 ? static_cast<long>(getpid()) : 0;
  MPI_Bcast(&tag, 1, MPI_LONG, 0, MPI_COMM_WORLD);
  return std::filesystem::temp_directory_path() / (name + "_" + std::to_string(tag));
}

inline herr_t collect_datasets(hid_t, const char* name, const H5O_info_t* info, void* data) {
  if (info->type == H5O_TYPE_DATASET) static_cast<std::vector<std::string>*>(data)->push_back(name);
  return 0;
}

// The dataset's bytes in its native type, and "class:size:dims," in `type_desc`.
inline std::vector<char> raw_dataset(hid_t file, const std::string& path, std::string& type_desc) {
  const hid_t d = H5Dopen2(file, path.c_str(), H5P_DEFAULT);
  if (d < 0) return {};
  const hid_t ft = H5Dget_type(d);
  const hid_t t = H5Tget_native_type(ft, H5T_DIR_ASCEND);
  const hid_t s = H5Dget_space(d);
  const auto n = static_cast<std::size_t>(H5Sget_simple_extent_npoints(s));
  std::vector<char> buf(n * H5Tget_size(t));
  H5Dread(d, t, H5S_ALL, H5S_ALL, H5P_DEFAULT, buf.data());
  hsize_t dims[4] = {0, 0, 0, 0};
  const int nd = H5Sget_simple_extent_dims(s, dims, nullptr);
  std::ostringstream o;
  o << H5Tget_class(ft) << ':' << H5Tget_size(ft) << ':';
  for (int i = 0; i < nd; ++i) o << dims[i] << ',';
  type_desc = o.str();
  H5Sclose(s);
  H5Tclose(t);
  H5Tclose(ft);
  H5Dclose(d);
  return buf;
}

// Datasets compared in one pair of files; records failures with `what` in the message.
inline int expect_same_file(const std::string& a_path, const std::string& b_path, const std::string& what) {
  const hid_t a = H5Fopen(a_path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  const hid_t b = H5Fopen(b_path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  EXPECT_GE(a, 0) << a_path;
  EXPECT_GE(b, 0) << b_path;
  if (a < 0 || b < 0) return 0;
  std::vector<std::string> pa, pb;
  H5Ovisit2(a, H5_INDEX_NAME, H5_ITER_INC, collect_datasets, &pa, H5O_INFO_BASIC);
  H5Ovisit2(b, H5_INDEX_NAME, H5_ITER_INC, collect_datasets, &pb, H5O_INFO_BASIC);
  EXPECT_EQ(pa, pb) << a_path << " and " << b_path << " hold different datasets";
  int datasets = 0;
  for (const std::string& p : pa) {
    std::string ta, tb;
    const std::vector<char> da = raw_dataset(a, p, ta), db = raw_dataset(b, p, tb);
    EXPECT_EQ(ta, tb) << a_path << ':' << p;
    ++datasets;
    if (p.size() >= 10 && p.compare(p.size() - 10, 10, "owner_rank") == 0) continue;
    EXPECT_TRUE(da == db) << a_path << ':' << p << " differs " << what;
  }
  for (const char* attr : {"step", "time"}) {
    if (H5Aexists(a, attr) <= 0) continue;
    double va = 0, vb = 1;
    const hid_t x = H5Aopen(a, attr, H5P_DEFAULT), y = H5Aopen(b, attr, H5P_DEFAULT);
    H5Aread(x, H5T_NATIVE_DOUBLE, &va);
    H5Aread(y, H5T_NATIVE_DOUBLE, &vb);
    H5Aclose(x);
    H5Aclose(y);
    EXPECT_EQ(va, vb) << a_path << " attribute " << attr << ' ' << what;
  }
  H5Fclose(a);
  H5Fclose(b);
  return datasets;
}

// Number of frames the index `dir`/frames.h5 links to.
inline int frames_in_index(const std::filesystem::path& dir) {
  const hid_t f = H5Fopen((dir / "frames.h5").c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  if (f < 0) return -1;
  H5G_info_t info{};
  const herr_t s = H5Gget_info_by_name(f, "/frames", &info, H5P_DEFAULT);
  H5Fclose(f);
  return s < 0 ? -1 : static_cast<int>(info.nlinks);
}

/// Every dataset of run directories `a` and `b` identical (bitwise) but owner_rank, and
/// both indexes naming the same number of frames (at least `min_frames`). Returns the
/// datasets compared.
inline int expect_same_output(const std::filesystem::path& a, const std::filesystem::path& b, const std::string& what,
                              int min_frames = 1) {
  const int fa = frames_in_index(a), fb = frames_in_index(b);
  EXPECT_EQ(fa, fb) << "frames in " << a << " and " << b << ' ' << what;
  EXPECT_GE(fa, min_frames) << a;
  int datasets = expect_same_file((a / "mesh.h5").string(), (b / "mesh.h5").string(), what);
  for (int k = 0; k < std::min(fa, fb); ++k) {
    char name[32];
    std::snprintf(name, sizeof name, "frames/%06d.h5", k);
    datasets += expect_same_file((a / name).string(), (b / name).string(), what);
  }
  return datasets;
}

}  // namespace softcontact::test
