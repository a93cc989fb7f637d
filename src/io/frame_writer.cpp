#include "softcontact/frame_writer.hpp"

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>

#include "softcontact/error.hpp"

namespace softcontact {

namespace {

void check(herr_t status, const std::string& what) {
  if (status < 0) throw RuntimeFailure("HDF5 failed to " + what);
}
hid_t check_id(hid_t id, const std::string& what) {
  if (id < 0) throw RuntimeFailure("HDF5 failed to " + what);
  return id;
}

template <class T>
hid_t h5type();
template <>
hid_t h5type<double>() { return H5T_NATIVE_DOUBLE; }
template <>
hid_t h5type<std::int64_t>() { return H5T_NATIVE_INT64; }
template <>
hid_t h5type<std::int32_t>() { return H5T_NATIVE_INT32; }

/// Creates dataset `name` (rows x cols) in `loc` and writes this rank's rows: `runs` are
/// the global row ranges it owns, `data` the rows packed in the same order. One
/// collective H5Dwrite; a rank with no rows takes part with an empty selection.
template <class T>
void write_rows(hid_t loc, const std::string& name, gid_t rows, int cols, const std::vector<GidRun>& runs,
                const T* data) {
  const hsize_t dims[2] = {static_cast<hsize_t>(rows), static_cast<hsize_t>(cols)};
  const int rank = cols == 1 ? 1 : 2;
  const hid_t fspace = check_id(H5Screate_simple(rank, dims, nullptr), "create a dataspace for " + name);
  const hid_t dset = check_id(H5Dcreate2(loc, name.c_str(), h5type<T>(), fspace, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT),
                              "create dataset " + name);
  hsize_t local = 0;
  if (runs.empty()) {
    check(H5Sselect_none(fspace), "select rows");
  } else {
    bool first = true;
    for (const GidRun& r : runs) {
      const hsize_t start[2] = {static_cast<hsize_t>(r.begin), 0};
      const hsize_t count[2] = {static_cast<hsize_t>(r.count), static_cast<hsize_t>(cols)};
      check(H5Sselect_hyperslab(fspace, first ? H5S_SELECT_SET : H5S_SELECT_OR, start, nullptr, count, nullptr),
            "select rows of " + name);
      first = false;
      local += static_cast<hsize_t>(r.count);
    }
  }
  const hsize_t mdims[1] = {local * static_cast<hsize_t>(cols)};
  const hid_t mspace = check_id(H5Screate_simple(1, mdims, nullptr), "create a memory dataspace");
  if (local == 0) check(H5Sselect_none(mspace), "select nothing");
  const hid_t dxpl = H5Pcreate(H5P_DATASET_XFER);
  check(H5Pset_dxpl_mpio(dxpl, H5FD_MPIO_COLLECTIVE), "set collective transfer");
  check(H5Dwrite(dset, h5type<T>(), mspace, fspace, dxpl, data), "write dataset " + name);
  H5Pclose(dxpl);
  H5Sclose(mspace);
  H5Dclose(dset);
  H5Sclose(fspace);
}

void write_attribute(hid_t loc, const char* name, hid_t type, const void* value) {
  const hid_t space = H5Screate(H5S_SCALAR);
  const hid_t attr = check_id(H5Acreate2(loc, name, type, space, H5P_DEFAULT, H5P_DEFAULT), std::string("create attribute ") + name);
  check(H5Awrite(attr, type, value), std::string("write attribute ") + name);
  H5Aclose(attr);
  H5Sclose(space);
}

std::string frame_group(std::int64_t k) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "/frames/%06lld", static_cast<long long>(k));
  return buf;
}

}  // namespace

FrameWriter::FrameWriter(MPI_Comm comm, const std::string& h5_path, const std::string& xdmf_path, const Scene& scene,
                         const World& w)
    : comm_(comm), h5_path_(h5_path), xdmf_path_(xdmf_path), nv_(w.global_vertices), nt_(w.global_tets) {
  MPI_Comm_rank(comm_, &rank_);
  vertex_runs_ = owned_vertex_runs(w);
  const hid_t fapl = H5Pcreate(H5P_FILE_ACCESS);
  check(H5Pset_fapl_mpio(fapl, comm_, MPI_INFO_NULL), "set the MPI-IO driver");
  file_ = H5Fcreate(h5_path.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, fapl);
  H5Pclose(fapl);
  if (file_ < 0) throw RuntimeFailure("cannot create the output file '" + h5_path + "'");

  const hid_t mesh = check_id(H5Gcreate2(file_, "/mesh", H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT), "create /mesh");
  H5Gclose(check_id(H5Gcreate2(file_, "/frames", H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT), "create /frames"));

  // Owned rows in global order; connectivity in global vertex ids.
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

  // Object table (names, materials) as attributes of /mesh/objects, for post-processing.
  std::ostringstream names;
  for (std::size_t k = 0; k < scene.objects.size(); ++k)
    names << scene.objects[k].name << '\t' << scene.materials[scene.objects[k].material].name << '\n';
  const std::string table = names.str();
  const hid_t str = H5Tcopy(H5T_C_S1);
  H5Tset_size(str, table.size() + 1);
  write_attribute(mesh, "objects", str, table.c_str());
  H5Tclose(str);
  const std::int64_t nobj = static_cast<std::int64_t>(scene.objects.size());
  write_attribute(mesh, "num_objects", H5T_NATIVE_INT64, &nobj);
  H5Gclose(mesh);
  check(H5Fflush(file_, H5F_SCOPE_GLOBAL), "flush " + h5_path_);
}

FrameWriter::~FrameWriter() {
  try {
    close();
  } catch (...) {
    // Destructors must not throw; close() already reported nothing we can act on here.
  }
}

void FrameWriter::close() {
  if (file_ >= 0) {
    H5Fclose(file_);
    file_ = -1;
  }
}

void FrameWriter::write_frame(std::int64_t step, double time, const World& w, const std::vector<VertexField>& extra) {
  const std::int64_t k = frames_written();
  const std::string gname = frame_group(k);
  const hid_t g = check_id(H5Gcreate2(file_, gname.c_str(), H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT), "create " + gname);
  write_attribute(g, "time", H5T_NATIVE_DOUBLE, &time);
  write_attribute(g, "step", H5T_NATIVE_INT64, &step);

  FrameInfo info{step, time, {}, {}};
  vertex_runs_ = owned_vertex_runs(w);  // objects may have migrated since the last frame
  write_rows(g, "positions", nv_, 3, vertex_runs_, w.x.data());
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
  H5Gclose(g);
  check(H5Fflush(file_, H5F_SCOPE_GLOBAL), "flush " + h5_path_);
  frames_.push_back(std::move(info));
  if (rank_ == 0) write_xdmf();
}

void FrameWriter::write_xdmf() const {
  // ParaView reads this as a temporal collection of unstructured tet grids. Paths inside
  // are relative to the XDMF file, so the output directory can be moved as a whole.
  const std::string h5 = std::filesystem::path(h5_path_).filename().string();
  auto item = [&](const std::string& path, gid_t rows, int cols, const char* type, int precision) {
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
    const std::string g = frame_group(static_cast<std::int64_t>(k));
    x << "   <Grid Name=\"frame_" << k << "\" GridType=\"Uniform\">\n"
      << "    <Time Value=\"" << f.time << "\"/>\n"
      << "    <Topology TopologyType=\"Tetrahedron\" NumberOfElements=\"" << nt_ << "\">\n     "
      << item("/mesh/tets", nt_, 4, "Int", 8) << "\n    </Topology>\n"
      << "    <Geometry GeometryType=\"XYZ\">\n     " << item(g + "/positions", nv_, 3, "Float", 8)
      << "\n    </Geometry>\n";
    for (std::size_t a = 0; a < f.fields.size(); ++a) {
      const auto& [name, comps] = f.fields[a];
      x << "    <Attribute Name=\"" << name << "\" AttributeType=\"" << (comps == 3 ? "Vector" : "Scalar")
        << "\" Center=\"Node\">\n     " << item(g + "/" + f.datasets[a], nv_, comps, "Float", 8) << "\n    </Attribute>\n";
    }
    x << "    <Attribute Name=\"owner_rank\" AttributeType=\"Scalar\" Center=\"Node\">\n     "
      << item(g + "/owner_rank", nv_, 1, "Int", 4) << "\n    </Attribute>\n"
      << "    <Attribute Name=\"object\" AttributeType=\"Scalar\" Center=\"Node\">\n     "
      << item("/mesh/vertex_object", nv_, 1, "Int", 4) << "\n    </Attribute>\n"
      << "    <Attribute Name=\"tet_object\" AttributeType=\"Scalar\" Center=\"Cell\">\n     "
      << item("/mesh/tet_object", nt_, 1, "Int", 4) << "\n    </Attribute>\n"
      << "   </Grid>\n";
  }
  x << "  </Grid>\n </Domain>\n</Xdmf>\n";
  const std::string tmp = xdmf_path_ + ".tmp";
  {
    std::ofstream out(tmp, std::ios::trunc);
    out << x.str();
    out.flush();
    if (!out) throw RuntimeFailure("cannot write '" + tmp + "'");
  }
  std::error_code ec;
  std::filesystem::rename(tmp, xdmf_path_, ec);
  if (ec) throw RuntimeFailure("cannot rename '" + tmp + "' to '" + xdmf_path_ + "': " + ec.message());
}

}  // namespace softcontact
