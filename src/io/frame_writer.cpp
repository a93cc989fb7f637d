#include "softcontact/frame_writer.hpp"

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>

#include "frame_files.hpp"
#include "h5_util.hpp"
#include "softcontact/error.hpp"
#include "softcontact/fault.hpp"
#include "softcontact/mpi_util.hpp"

namespace softcontact {

namespace {

using h5::check;
using h5::check_id;
using h5::write_rows;

using frames::frame_file;
using frames::kFramesDir;
using frames::kMeshFile;

}  // namespace

FrameWriter::FrameWriter(MPI_Comm comm, const std::string& h5_path, const std::string& xdmf_path, const Scene& scene,
                         const World& w)
    : comm_(comm), h5_path_(h5_path), xdmf_path_(xdmf_path), nv_(w.global_vertices), nt_(w.global_tets) {
  rank_ = comm_rank(comm_);
  dir_ = std::filesystem::path(h5_path).parent_path().string();
  if (dir_.empty()) dir_ = ".";
  if (rank_ == 0) {
    std::error_code ec;
    std::filesystem::remove_all(std::filesystem::path(dir_) / kFramesDir, ec);
    std::filesystem::create_directories(std::filesystem::path(dir_) / kFramesDir, ec);
  }
  const std::string mesh_path = (std::filesystem::path(dir_) / kMeshFile).string(), tmp = mesh_path + ".tmp";
  const hid_t file = h5::create_parallel(comm_, tmp, "the output file", true);
  // The object table below is one text attribute of about 20 bytes per object: past 64
  // KiB (some 3,000 objects) HDF5 cannot keep it in the group's header (compact storage),
  // and creating it failed. Dense attribute storage (format of HDF5 1.8 and later, asked
  // for when the file is created) has no such limit.
  const hid_t gcpl = check_id(H5Pcreate(H5P_GROUP_CREATE), "create a group creation property list");
  check(H5Pset_attr_phase_change(gcpl, 0, 0), "ask for dense attribute storage");
  const hid_t mesh = H5Gcreate2(file, "/mesh", H5P_DEFAULT, gcpl, H5P_DEFAULT);
  H5Pclose(gcpl);
  check_id(mesh, "create /mesh");

  // Owned rows in global order; connectivity in global vertex ids.
  vertex_runs_ = owned_vertex_runs(w);
  const std::size_t n = w.n_owned;
  std::vector<std::int32_t> obj(w.vertex_object.begin(), w.vertex_object.begin() + static_cast<std::ptrdiff_t>(n));
  std::vector<double> mass(n);
  for (std::size_t i = 0; i < n; ++i)
    mass[i] = w.inv_mass[i] == 0 ? std::numeric_limits<double>::infinity() : w.mass[i];
  std::vector<std::int64_t> tets(4 * w.m_owned), tris(3 * w.s_owned);  // ghosts are not written
  for (std::size_t i = 0; i < tets.size(); ++i) tets[i] = w.vertex_gid[w.tets[i]];
  for (std::size_t i = 0; i < tris.size(); ++i) tris[i] = w.vertex_gid[w.triangles[i]];
  std::vector<std::int32_t> tet_obj(w.tet_object.begin(), w.tet_object.begin() + static_cast<std::ptrdiff_t>(w.m_owned));

  write_rows(mesh, "points", nv_, 3, vertex_runs_, w.x.data());
  write_rows(mesh, "tets", nt_, 4, owned_tet_runs(w), tets.data());
  write_rows(mesh, "tet_object", nt_, 1, owned_tet_runs(w), tet_obj.data());
  write_rows(mesh, "surface_triangles", w.global_triangles, 3, owned_triangle_runs(w), tris.data());
  write_rows(mesh, "vertex_object", nv_, 1, vertex_runs_, obj.data());
  write_rows(mesh, "vertex_mass", nv_, 1, vertex_runs_, mass.data());

  // Object table (names, materials) as attributes of /mesh, for post-processing.
  std::ostringstream names;
  for (std::size_t k = 0; k < scene.objects.size(); ++k)
    names << scene.objects[k].name << '\t' << scene.materials[scene.objects[k].material].name << '\n';
  h5::write_string_attribute(mesh, "objects", names.str());
  const std::int64_t nobj = static_cast<std::int64_t>(scene.objects.size());
  h5::write_attribute(mesh, "num_objects", nobj);
  H5Gclose(mesh);
  check(H5Fclose(file), "close " + tmp);
  h5::publish(comm_, tmp, mesh_path, false);
  if (rank_ == 0) {
    write_index();
    write_xdmf();
  }
}

FrameWriter::FrameWriter(MPI_Comm comm, const std::string& h5_path, const std::string& xdmf_path, const World& w,
                         std::int64_t last_step)
    : comm_(comm), h5_path_(h5_path), xdmf_path_(xdmf_path), nv_(w.global_vertices), nt_(w.global_tets) {
  rank_ = comm_rank(comm_);
  dir_ = std::filesystem::path(h5_path).parent_path().string();
  if (dir_.empty()) dir_.assign(1, '.');  // not = ".": GCC 12 warns falsely (-Wrestrict) here
  // Rank 0 reads the directory; an InputError there (mesh.h5 missing or another mesh)
  // becomes everyone's, a file-system failure (RuntimeFailure) ends the job.
  std::string failure;
  if (rank_ == 0) {
    try {
      frames_ = frames::resume_frames(dir_, nv_, nt_, last_step);
      count_ = static_cast<std::int64_t>(frames_.size());
      last_step_ = frames_.empty() ? -1 : frames_.back().step;
      write_index();
      write_xdmf();
    } catch (const InputError& e) {
      failure = e.what();
    }
  }
  // Length > 0: rank 0 cannot continue, and every rank throws its message.
  long long length = static_cast<long long>(failure.size());
  MPI_Bcast(&length, 1, MPI_LONG_LONG, 0, comm_);
  if (length > 0) {
    failure.resize(static_cast<std::size_t>(length));
    MPI_Bcast(failure.data(), static_cast<int>(length), MPI_CHAR, 0, comm_);
    throw InputError(failure);
  }
  std::int64_t state[2] = {count_, last_step_};
  MPI_Bcast(state, 2, MPI_INT64_T, 0, comm_);
  count_ = state[0];
  last_step_ = state[1];
}

void FrameWriter::write_frame(std::int64_t step, double time, const World& w, const std::vector<VertexField>& extra) {
  const std::int64_t k = frames_written();
  const std::string path = (std::filesystem::path(dir_) / frame_file(k)).string(), tmp = path + ".tmp";
  const hid_t g = h5::create_parallel(comm_, tmp, "the frame file");
  h5::write_attribute(g, "time", time);
  h5::write_attribute(g, "step", step);

  frames::FrameRecord info{step, time, {}, {}};
  vertex_runs_ = owned_vertex_runs(w);  // objects may have migrated since the last frame
  write_rows(g, "positions", nv_, 3, vertex_runs_, w.x.data());
  if (fault::hit(fault::Point::frame_write, step)) throw RuntimeFailure(fault::io_error(fault::Point::frame_write, tmp));
  write_rows(g, "velocities", nv_, 3, vertex_runs_, w.v.data());
  info.fields.emplace_back("velocity", 3);
  info.datasets.push_back("velocities");
  std::vector<std::int32_t> owner(w.n_owned, rank_);
  write_rows(g, "owner_rank", nv_, 1, vertex_runs_, owner.data());
  for (const VertexField& f : extra) {
    write_rows(g, f.name, nv_, f.components, vertex_runs_, f.data);
    info.fields.emplace_back(f.xdmf_name, f.components);
    info.datasets.push_back(f.name);
  }
  h5::write_string_attribute(g, "fields", frames::encode_fields(info));
  check(H5Fclose(g), "close " + tmp);
  if (fault::hit(fault::Point::frame_rename, step)) throw RuntimeFailure(fault::io_error(fault::Point::frame_rename, path));
  h5::publish(comm_, tmp, path, false);
  if (fault::hit(fault::Point::frame_renamed, step))
    throw RuntimeFailure(fault::io_error(fault::Point::frame_renamed, h5_path_));
  ++count_;
  last_step_ = step;
  if (rank_ == 0) {
    frames_.push_back(std::move(info));
    write_index();
    write_xdmf();
  }
}

// The index: external links only, so it is small and rewritten whole after every frame.
void FrameWriter::write_index() const { frames::write_index(h5_path_, count_); }

void FrameWriter::write_xdmf() const { frames::write_xdmf(xdmf_path_, frames_, nv_, nt_); }

}  // namespace softcontact
