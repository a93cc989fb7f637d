#include "softcontact/frame_writer.hpp"

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>

#include "softcontact/error.hpp"
#include "softcontact/fault.hpp"
#include "h5_util.hpp"

namespace softcontact {

namespace {

using h5::check;
using h5::check_id;
using h5::write_rows;

constexpr const char* kMeshFile = "mesh.h5";
constexpr const char* kFramesDir = "frames";

std::string frame_group(std::int64_t k) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%06lld", static_cast<long long>(k));
  return buf;
}

// "dataset:xdmf name:components" per line, the fields of a frame in the order written.
std::string encode_fields(const std::vector<std::pair<std::string, int>>& fields, const std::vector<std::string>& datasets) {
  std::string s;
  for (std::size_t a = 0; a < fields.size(); ++a)
    s += datasets[a] + ':' + fields[a].first + ':' + std::to_string(fields[a].second) + '\n';
  return s;
}

bool decode_fields(const std::string& s, std::vector<std::pair<std::string, int>>& fields, std::vector<std::string>& datasets) {
  std::istringstream in(s);
  std::string line;
  while (std::getline(in, line)) {
    const auto a = line.find(':'), b = line.rfind(':');
    if (a == std::string::npos || b == a) return false;
    const std::string comps = line.substr(b + 1);
    if (comps != "1" && comps != "3") return false;
    datasets.push_back(line.substr(0, a));
    fields.emplace_back(line.substr(a + 1, b - a - 1), comps == "3" ? 3 : 1);
  }
  return true;
}

}  // namespace

std::string FrameWriter::frame_file(std::int64_t k) const { return std::string(kFramesDir) + "/" + frame_group(k) + ".h5"; }

FrameWriter::FrameWriter(MPI_Comm comm, const std::string& h5_path, const std::string& xdmf_path, const Scene& scene,
                         const World& w)
    : comm_(comm), h5_path_(h5_path), xdmf_path_(xdmf_path), nv_(w.global_vertices), nt_(w.global_tets) {
  MPI_Comm_rank(comm_, &rank_);
  dir_ = std::filesystem::path(h5_path).parent_path().string();
  if (dir_.empty()) dir_ = ".";
  if (rank_ == 0) {
    std::error_code ec;
    std::filesystem::remove_all(std::filesystem::path(dir_) / kFramesDir, ec);
    std::filesystem::create_directories(std::filesystem::path(dir_) / kFramesDir, ec);
  }
  const std::string mesh_path = (std::filesystem::path(dir_) / kMeshFile).string(), tmp = mesh_path + ".tmp";
  const hid_t file = h5::create_parallel(comm_, tmp, "the output file");
  const hid_t mesh = check_id(H5Gcreate2(file, "/mesh", H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT), "create /mesh");

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
  MPI_Comm_rank(comm_, &rank_);
  dir_ = std::filesystem::path(h5_path).parent_path().string();
  if (dir_.empty()) dir_ = ".";
  std::string failure;
  if (rank_ == 0) {
    namespace fs = std::filesystem;
    const h5::QuietErrors quiet;
    const std::string mesh_path = (fs::path(dir_) / kMeshFile).string();
    const hid_t f = H5Fopen(mesh_path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
    const gid_t rows = f < 0 ? 0 : h5::rows_of(f, "/mesh/points");
    if (f >= 0) H5Fclose(f);
    if (f < 0) failure = "cannot continue the output in '" + dir_ + "': '" + mesh_path + "' is missing or unreadable";
    else if (rows != nv_)
      failure = "cannot continue the output in '" + dir_ + "': its mesh has " + std::to_string(rows) +
                " vertices, the scene " + std::to_string(nv_);
    // Frames 0, 1, ... up to the first missing, damaged or later one; the rest go.
    std::int64_t k = 0;
    for (; failure.empty(); ++k) {
      const fs::path p = fs::path(dir_) / frame_file(k);
      if (!fs::exists(p)) break;
      const hid_t ff = H5Fopen(p.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
      if (ff < 0) break;
      FrameInfo info{-1, 0, {}, {}};
      bool ok = false;
      try {
        info.step = h5::read_attribute<std::int64_t>(ff, "step", p.string());
        info.time = h5::read_attribute<double>(ff, "time", p.string());
        ok = decode_fields(h5::read_string_attribute(ff, "fields", p.string()), info.fields, info.datasets);
      } catch (const RuntimeFailure&) {
        ok = false;
      }
      H5Fclose(ff);
      if (!ok || info.step > last_step) break;
      frames_.push_back(std::move(info));
    }
    std::error_code ec;
    for (const auto& e : fs::directory_iterator(fs::path(dir_) / kFramesDir, ec)) {
      const std::string stem = e.path().stem().string();
      const bool numbered = !stem.empty() && stem.find_first_not_of("0123456789") == std::string::npos;
      if (e.path().extension() == ".tmp" || (numbered && std::stoll(stem) >= k)) fs::remove(e.path(), ec);
    }
    if (failure.empty()) {
      count_ = static_cast<std::int64_t>(frames_.size());
      last_step_ = frames_.empty() ? -1 : frames_.back().step;
      write_index();
      write_xdmf();
    }
  }
  // Length > 0: rank 0 cannot continue, and every rank throws its message.
  long long length = static_cast<long long>(failure.size());
  MPI_Bcast(&length, 1, MPI_LONG_LONG, 0, comm_);
  if (length > 0) {
    failure.resize(static_cast<std::size_t>(length));
    MPI_Bcast(failure.data(), static_cast<int>(length), MPI_CHAR, 0, comm_);
    throw CollectiveFailure(failure);
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

  FrameInfo info{step, time, {}, {}};
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
  h5::write_string_attribute(g, "fields", encode_fields(info.fields, info.datasets));
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
void FrameWriter::write_index() const {
  const std::string tmp = h5_path_ + ".tmp";
  const hid_t f = H5Fcreate(tmp.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT);
  if (f < 0) throw RuntimeFailure("cannot create '" + tmp + "'");
  check(H5Lcreate_external(kMeshFile, "/mesh", f, "mesh", H5P_DEFAULT, H5P_DEFAULT), "link /mesh");
  const hid_t frames = check_id(H5Gcreate2(f, "/frames", H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT), "create /frames");
  for (std::int64_t k = 0; k < count_; ++k)
    check(H5Lcreate_external(frame_file(k).c_str(), "/", frames, frame_group(k).c_str(), H5P_DEFAULT, H5P_DEFAULT),
          "link frame " + frame_group(k));
  H5Gclose(frames);
  check(H5Fclose(f), "close " + tmp);
  std::error_code ec;
  std::filesystem::rename(tmp, h5_path_, ec);
  if (ec) throw RuntimeFailure("cannot rename '" + tmp + "' to '" + h5_path_ + "': " + ec.message());
}

void FrameWriter::write_xdmf() const {
  // ParaView reads this as a temporal collection of unstructured tet grids. Paths inside
  // are relative to the XDMF file, so the output directory can be moved as a whole.
  auto item = [&](const std::string& h5, const std::string& path, gid_t rows, int cols, const char* type, int precision) {
    std::ostringstream s;
    s << "<DataItem Dimensions=\"" << rows;
    if (cols > 1) s << ' ' << cols;
    s << "\" NumberType=\"" << type << "\" Precision=\"" << precision
      << "\" Format=\"HDF\">" << h5 << ':' << path << "</DataItem>";
    return s.str();
  };
  std::ostringstream x;
  x.precision(17);
  x << "<?xml version=\"1.0\" ?>\n<!DOCTYPE Xdmf SYSTEM \"Xdmf.dtd\" []>\n<Xdmf Version=\"3.0\">\n <Domain>\n"
    << "  <Grid Name=\"softcontact\" GridType=\"Collection\" CollectionType=\"Temporal\">\n";
  for (std::size_t k = 0; k < frames_.size(); ++k) {
    const FrameInfo& f = frames_[k];
    const std::string g = frame_file(static_cast<std::int64_t>(k));
    x << "   <Grid Name=\"frame_" << k << "\" GridType=\"Uniform\">\n"
      << "    <Time Value=\"" << f.time << "\"/>\n"
      << "    <Topology TopologyType=\"Tetrahedron\" NumberOfElements=\"" << nt_ << "\">\n     "
      << item(kMeshFile, "/mesh/tets", nt_, 4, "Int", 8) << "\n    </Topology>\n"
      << "    <Geometry GeometryType=\"XYZ\">\n     " << item(g, "/positions", nv_, 3, "Float", 8)
      << "\n    </Geometry>\n";
    for (std::size_t a = 0; a < f.fields.size(); ++a) {
      const auto& [name, comps] = f.fields[a];
      x << "    <Attribute Name=\"" << name << "\" AttributeType=\"" << (comps == 3 ? "Vector" : "Scalar")
        << "\" Center=\"Node\">\n     " << item(g, "/" + f.datasets[a], nv_, comps, "Float", 8) << "\n    </Attribute>\n";
    }
    x << "    <Attribute Name=\"owner_rank\" AttributeType=\"Scalar\" Center=\"Node\">\n     "
      << item(g, "/owner_rank", nv_, 1, "Int", 4) << "\n    </Attribute>\n"
      << "    <Attribute Name=\"object\" AttributeType=\"Scalar\" Center=\"Node\">\n     "
      << item(kMeshFile, "/mesh/vertex_object", nv_, 1, "Int", 4) << "\n    </Attribute>\n"
      << "    <Attribute Name=\"tet_object\" AttributeType=\"Scalar\" Center=\"Cell\">\n     "
      << item(kMeshFile, "/mesh/tet_object", nt_, 1, "Int", 4) << "\n    </Attribute>\n"
      << "   </Grid>\n";
  }
  x << "  </Grid>\n </Domain>\n</Xdmf>\n";
  h5::write_text_atomically(xdmf_path_, x.str());
}

}  // namespace softcontact
