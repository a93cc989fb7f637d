// Runs under mpiexec with 1, 2 and 3 ranks: every rank writes its owned rows; rank 0
// reads the file back and compares with the serial arrays.
#include <gtest/gtest.h>
#include <hdf5.h>
#include <mpi.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <regex>
#include <sstream>

#include "softcontact/diagnostics.hpp"
#include "softcontact/error.hpp"
#include "softcontact/frame_writer.hpp"
#include "softcontact/mpi_util.hpp"
#include "softcontact/scene.hpp"
#include "softcontact/world.hpp"

using namespace softcontact;

namespace {

Scene five_objects() {
  return load_scene_from_string(R"(
simulation: {dt: 0.001, steps: 10, gravity: [0, 0, -10]}
materials:
  - {name: soft, young: 1e5, poisson: 0.3, density: 1000}
objects:
  - name: floor
    material: soft
    primitive: {type: plate, size: [4, 4], thickness: 0.1, cells: [3, 3]}
    kinematic: true
  - name: cubes
    material: soft
    primitive: {type: box, size: [0.5, 0.5, 0.5], cells: [2, 1, 1]}
    velocity: [1, 0, 0]
    instances: {grid: {count: [2, 2, 1], spacing: [1, 1, 0]}}
)",
                                "scene.yaml");
}

template <class T>
std::vector<T> read_all(hid_t file, const std::string& path, hid_t type, std::vector<hsize_t>* dims_out = nullptr) {
  const hid_t d = H5Dopen2(file, path.c_str(), H5P_DEFAULT);
  EXPECT_GE(d, 0) << path;
  if (d < 0) return {};
  const hid_t s = H5Dget_space(d);
  hsize_t dims[2] = {1, 1};
  const int nd = H5Sget_simple_extent_dims(s, dims, nullptr);
  if (dims_out) dims_out->assign(dims, dims + nd);
  std::vector<T> v(dims[0] * (nd == 2 ? dims[1] : 1));
  H5Dread(d, type, H5S_ALL, H5S_ALL, H5P_DEFAULT, v.data());
  H5Sclose(s);
  H5Dclose(d);
  return v;
}

}  // namespace

TEST(FrameWriter, OwnedRowsLandAtGlobalOffsetsAndXdmfReferencesExistingDatasets) {
  MPI_Comm comm = MPI_COMM_WORLD;
  const int rank = comm_rank(comm), size = comm_size(comm);
  const Scene scene = five_objects();
  World w = build_world(scene, block_partition(scene, size), rank);
  const World serial = build_world(scene, block_partition(scene, 1), 0);

  const std::string dir = "frame_writer_np" + std::to_string(size);
  if (rank == 0) {
    std::filesystem::remove_all(dir);
    std::filesystem::create_directories(dir);
  }
  MPI_Barrier(comm);
  const std::string h5 = dir + "/frames.h5", xdmf = dir + "/frames.xdmf";
  {
    FrameWriter writer(comm, h5, xdmf, scene, w);
    writer.write_frame(0, 0.0, w);
    // Move every owned vertex by its global id so that misplaced rows show.
    for (std::size_t i = 0; i < w.n_owned; ++i) w.x[3 * i + 2] += 1e-3 * static_cast<double>(w.vertex_gid[i]);
    std::vector<double> depth(w.n_owned);
    for (std::size_t i = 0; i < w.n_owned; ++i) depth[i] = static_cast<double>(w.vertex_gid[i]);
    writer.write_frame(7, 0.007, w, {{"depth", "penetration_depth", 1, depth.data()}});
    EXPECT_EQ(writer.frames_written(), 2);
  }
  MPI_Barrier(comm);
  if (rank != 0) return;

  const hid_t f = H5Fopen(h5.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  ASSERT_GE(f, 0);
  std::vector<hsize_t> dims;
  const auto pts = read_all<double>(f, "/mesh/points", H5T_NATIVE_DOUBLE, &dims);
  ASSERT_EQ(dims, (std::vector<hsize_t>{static_cast<hsize_t>(serial.global_vertices), 3}));
  EXPECT_EQ(pts, serial.x);
  const auto tets = read_all<std::int64_t>(f, "/mesh/tets", H5T_NATIVE_INT64, &dims);
  ASSERT_EQ(dims[1], 4u);
  for (std::size_t i = 0; i < tets.size(); ++i) EXPECT_EQ(tets[i], serial.vertex_gid[serial.tets[i]]);
  const auto tris = read_all<std::int64_t>(f, "/mesh/surface_triangles", H5T_NATIVE_INT64);
  ASSERT_EQ(tris.size(), serial.triangles.size());
  for (std::size_t i = 0; i < tris.size(); ++i) EXPECT_EQ(tris[i], serial.triangles[i]);
  const auto mass = read_all<double>(f, "/mesh/vertex_mass", H5T_NATIVE_DOUBLE);
  const auto obj = read_all<std::int32_t>(f, "/mesh/vertex_object", H5T_NATIVE_INT32);
  for (std::size_t i = 0; i < mass.size(); ++i) {
    EXPECT_EQ(obj[i], serial.vertex_object[i]);
    if (obj[i] == 0) EXPECT_TRUE(std::isinf(mass[i]));  // the kinematic floor
    else EXPECT_EQ(mass[i], serial.mass[i]);
  }
  const auto p1 = read_all<double>(f, "/frames/000001/positions", H5T_NATIVE_DOUBLE);
  for (std::size_t i = 0; i < p1.size() / 3; ++i) EXPECT_EQ(p1[3 * i + 2], serial.x[3 * i + 2] + 1e-3 * static_cast<double>(i));
  const auto owner = read_all<std::int32_t>(f, "/frames/000001/owner_rank", H5T_NATIVE_INT32);
  const auto part = block_partition(scene, size);
  for (std::size_t i = 0; i < owner.size(); ++i) EXPECT_EQ(owner[i], part[serial.vertex_object[i]]);
  const auto depth = read_all<double>(f, "/frames/000001/depth", H5T_NATIVE_DOUBLE);
  for (std::size_t i = 0; i < depth.size(); ++i) EXPECT_EQ(depth[i], static_cast<double>(i));
  // time and step attributes
  const hid_t g = H5Gopen2(f, "/frames/000001", H5P_DEFAULT);
  double time = -1;
  std::int64_t step = -1;
  const hid_t at = H5Aopen(g, "time", H5P_DEFAULT), as = H5Aopen(g, "step", H5P_DEFAULT);
  H5Aread(at, H5T_NATIVE_DOUBLE, &time);
  H5Aread(as, H5T_NATIVE_INT64, &step);
  H5Aclose(at);
  H5Aclose(as);
  H5Gclose(g);
  EXPECT_EQ(time, 0.007);
  EXPECT_EQ(step, 7);

  // Every dataset the XDMF names exists, with the dimensions it states.
  std::ifstream in(xdmf);
  std::stringstream ss;
  ss << in.rdbuf();
  const std::string text = ss.str();
  // Items name a file beside the XDMF (never a temporary one) and a dataset in it.
  const std::regex item(R"re(<DataItem Dimensions="([0-9 ]+)"[^>]*>([^:<]+):([^<]+)</DataItem>)re");
  int items = 0;
  for (auto it = std::sregex_iterator(text.begin(), text.end(), item); it != std::sregex_iterator(); ++it) {
    ++items;
    const std::string file = (*it)[2], path = (*it)[3];
    EXPECT_TRUE(file == "mesh.h5" || std::regex_match(file, std::regex("frames/[0-9]{6}\\.h5"))) << file;
    const hid_t ff = H5Fopen((dir + "/" + file).c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
    ASSERT_GE(ff, 0) << file;
    ASSERT_GT(H5Lexists(ff, path.c_str(), H5P_DEFAULT), 0) << file << ':' << path;
    const hid_t d = H5Dopen2(ff, path.c_str(), H5P_DEFAULT);
    const hid_t s = H5Dget_space(d);
    hsize_t dd[2] = {0, 0};
    const int nd = H5Sget_simple_extent_dims(s, dd, nullptr);
    std::ostringstream want;
    want << dd[0];
    if (nd == 2) want << ' ' << dd[1];
    EXPECT_EQ((*it)[1], want.str()) << path;
    H5Sclose(s);
    H5Dclose(d);
    H5Fclose(ff);
  }
  // No temporary file is left behind.
  for (const auto& e : std::filesystem::recursive_directory_iterator(dir))
    EXPECT_NE(e.path().extension(), ".tmp") << e.path();
  EXPECT_EQ(items, 6 + 7);  // tets, positions, velocity, owner_rank, 2 x object; frame 1 adds depth
  EXPECT_NE(text.find("<Time Value=\"0.0070000000000000001\"/>"), std::string::npos);
  EXPECT_NE(text.find("penetration_depth"), std::string::npos);
  H5Fclose(f);
}

// A file no rank can create is a failure of all ranks together (docs/reliability.md, "One
// rank fails, all stop"): every rank throws the same CollectiveFailure, which the program
// prints once, instead of each rank printing its own and calling MPI_Abort. Cases: the
// output directory lies under a regular file; the frames folder is replaced by a regular
// file after the writer started (the output became unwritable in the middle of a run).
TEST(FrameWriter, AFileNoRankCanCreateIsOneCollectiveFailure) {
  MPI_Comm comm = MPI_COMM_WORLD;
  const int rank = comm_rank(comm), size = comm_size(comm);
  const Scene scene = five_objects();
  World w = build_world(scene, block_partition(scene, size), rank);
  const std::string dir = "frame_writer_unwritable_np" + std::to_string(size);
  if (rank == 0) {
    std::filesystem::remove_all(dir);
    std::filesystem::create_directories(dir + "/run");
    std::ofstream(dir + "/a_file") << "not a directory";
  }
  MPI_Barrier(comm);
  // The same message on every rank, and every rank got one (the test would hang if not).
  auto expect_collective = [&](auto&& make, const std::string& message) {
    std::string got;
    try {
      make();
    } catch (const CollectiveFailure& e) {
      got = e.what();
    }
    EXPECT_EQ(got, message);
    int same = got == message ? 1 : 0;
    MPI_Allreduce(MPI_IN_PLACE, &same, 1, MPI_INT, MPI_MIN, comm);
    EXPECT_EQ(same, 1) << "rank " << rank << ": '" << got << "'";
  };
  expect_collective([&] { FrameWriter(comm, dir + "/a_file/out/frames.h5", dir + "/a_file/out/frames.xdmf", scene, w); },
                    "cannot create the output file '" + dir + "/a_file/out/mesh.h5.tmp'");
  {
    FrameWriter writer(comm, dir + "/run/frames.h5", dir + "/run/frames.xdmf", scene, w);
    writer.write_frame(0, 0.0, w);
    MPI_Barrier(comm);
    if (rank == 0) {
      std::filesystem::remove_all(dir + "/run/frames");
      std::ofstream(dir + "/run/frames") << "not a directory";
    }
    MPI_Barrier(comm);
    expect_collective([&] { writer.write_frame(1, 0.001, w); },
                      "cannot create the frame file '" + dir + "/run/frames/000001.h5.tmp'");
    EXPECT_EQ(writer.frames_written(), 1);
  }
  MPI_Barrier(comm);
  if (rank == 0) std::filesystem::remove_all(dir);
}

TEST(Diagnostics, ReductionDoesNotDependOnRankCount) {
  MPI_Comm comm = MPI_COMM_WORLD;
  const Scene scene = five_objects();
  const World w = build_world(scene, block_partition(scene, comm_size(comm)), comm_rank(comm));
  StepDiagnostics d;
  reduce_mechanics(comm, scene, w, d);
  // Reference: serial world, summed per object then over objects, as the contract says.
  const World s = build_world(scene, block_partition(scene, 1), 0);
  double ke[5] = {0, 0, 0, 0, 0}, pe[5] = {0, 0, 0, 0, 0}, px[5] = {0, 0, 0, 0, 0};
  for (std::size_t i = 0; i < s.n_owned; ++i) {
    if (s.inv_mass[i] == 0) continue;
    const int o = s.vertex_object[i];
    ke[o] += 0.5 * s.mass[i] * (s.v[3 * i] * s.v[3 * i] + s.v[3 * i + 1] * s.v[3 * i + 1] + s.v[3 * i + 2] * s.v[3 * i + 2]);
    pe[o] -= s.mass[i] * (-10.0 * s.x[3 * i + 2]);
    px[o] += s.mass[i] * s.v[3 * i];
  }
  double KE = 0, PE = 0, PX = 0;
  for (int o = 0; o < 5; ++o) {
    KE += ke[o];
    PE += pe[o];
    PX += px[o];
  }
  EXPECT_EQ(d.kinetic_energy, KE);  // bitwise
  EXPECT_EQ(d.potential_energy, PE);
  EXPECT_EQ(d.momentum[0], PX);
  // 4 cubes of 0.125 m^3 at 1000 kg/m^3 moving at 1 m/s: KE = 1/2 * 500 * 1 = 250 J.
  EXPECT_NEAR(d.kinetic_energy, 250.0, 1e-9);
  EXPECT_NEAR(d.momentum[0], 500.0, 1e-9);
}
