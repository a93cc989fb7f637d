#include "frame_files.hpp"

#include <hdf5.h>

#include <cctype>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <sstream>

#include "h5_util.hpp"
#include "softcontact/error.hpp"

namespace softcontact::frames {

namespace fs = std::filesystem;

std::string frame_group(std::int64_t k) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%06lld", static_cast<long long>(k));
  return buf;
}

std::string frame_file(std::int64_t k) { return std::string(kFramesDir) + "/" + frame_group(k) + ".h5"; }

std::string encode_fields(const FrameRecord& f) {
  std::string s;
  for (std::size_t a = 0; a < f.fields.size(); ++a)
    s += f.datasets[a] + ':' + f.fields[a].first + ':' + std::to_string(f.fields[a].second) + '\n';
  return s;
}

namespace {
// Names go into the XDMF's XML and into HDF5 paths: letters, digits, '_', '-', '.', ' '.
bool plain_name(const std::string& s) {
  if (s.empty()) return false;
  for (const char c : s)
    if (!(std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == '-' || c == '.' || c == ' ')) return false;
  return true;
}
}  // namespace

bool decode_fields(const std::string& text, FrameRecord& f) {
  std::istringstream in(text);
  std::string line;
  while (std::getline(in, line)) {
    const auto a = line.find(':'), b = line.rfind(':');
    if (a == std::string::npos || b == a) return false;
    const std::string comps = line.substr(b + 1);
    if (comps != "1" && comps != "3") return false;
    std::string dataset = line.substr(0, a), name = line.substr(a + 1, b - a - 1);
    if (!plain_name(dataset) || !plain_name(name)) return false;
    f.datasets.push_back(std::move(dataset));
    f.fields.emplace_back(std::move(name), comps == "3" ? 3 : 1);
  }
  return true;
}

namespace {

// Whether dataset `name` of `file` has `rows` rows of `cols` (1-D when cols == 1).
bool has_shape(hid_t file, const std::string& name, gid_t rows, int cols) {
  const hid_t d = H5Dopen2(file, name.c_str(), H5P_DEFAULT);
  if (d < 0) return false;
  const hid_t sp = H5Dget_space(d);
  hsize_t dims[2] = {0, 0};
  const int nd = sp < 0 ? -1 : H5Sget_simple_extent_ndims(sp);
  const bool ok = nd == (cols == 1 ? 1 : 2) && H5Sget_simple_extent_dims(sp, dims, nullptr) == nd &&
                  dims[0] == static_cast<hsize_t>(rows) && (cols == 1 || dims[1] == static_cast<hsize_t>(cols));
  if (sp >= 0) H5Sclose(sp);
  H5Dclose(d);
  return ok;
}

// Frame file `p` as FrameWriter::write_frame wrote it, or false.
bool read_frame(const fs::path& p, gid_t vertices, FrameRecord& f) {
  const hid_t file = H5Fopen(p.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  if (file < 0) return false;
  bool ok = false;
  try {
    f.step = h5::read_attribute<std::int64_t>(file, "step", p.string());
    f.time = h5::read_attribute<double>(file, "time", p.string());
    ok = f.step >= 0 && std::isfinite(f.time) &&
         decode_fields(h5::read_string_attribute(file, "fields", p.string()), f) &&
         has_shape(file, "positions", vertices, 3) && has_shape(file, "owner_rank", vertices, 1);
    for (std::size_t a = 0; ok && a < f.fields.size(); ++a)
      ok = has_shape(file, f.datasets[a], vertices, f.fields[a].second);
  } catch (const RuntimeFailure&) {
    ok = false;
  }
  H5Fclose(file);
  return ok;
}

}  // namespace

std::vector<FrameRecord> resume_frames(const std::string& dir, gid_t vertices, gid_t tets, std::int64_t last_step) {
  const h5::QuietErrors quiet;
  const std::string mesh_path = (fs::path(dir) / kMeshFile).string();
  const hid_t m = H5Fopen(mesh_path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  if (m < 0)
    throw InputError(mesh_path, 0, "cannot continue the output in '" + dir + "': this file is missing or not HDF5");
  const gid_t rows = h5::rows_of(m, "/mesh/points"), cells = h5::rows_of(m, "/mesh/tets");
  H5Fclose(m);
  if (rows != vertices || cells != tets)
    throw InputError(mesh_path, 0,
                     "cannot continue the output in '" + dir + "': its mesh has " + std::to_string(rows) +
                         " vertices and " + std::to_string(cells) + " tets, the scene " + std::to_string(vertices) +
                         " and " + std::to_string(tets));
  // Frames 0, 1, ... up to the first missing, damaged, out-of-order or later one.
  std::vector<FrameRecord> kept;
  for (std::int64_t k = 0;; ++k) {
    const fs::path p = fs::path(dir) / frame_file(k);
    std::error_code ec;
    FrameRecord f;
    if (!fs::is_regular_file(p, ec) || !read_frame(p, vertices, f) || f.step > last_step ||
        (!kept.empty() && f.step <= kept.back().step))
      break;
    kept.push_back(std::move(f));
  }
  // The rest go, and any temporary file a killed run left.
  const auto count = static_cast<std::int64_t>(kept.size());
  std::error_code ec;
  std::vector<fs::path> doomed;
  for (const auto& e : fs::directory_iterator(fs::path(dir) / kFramesDir, ec)) {
    const std::string stem = e.path().stem().string();
    const bool numbered = !stem.empty() && stem.find_first_not_of("0123456789") == std::string::npos;
    // More digits than an int64 holds is later than any frame kept.
    const bool later = numbered && (stem.size() > 18 || std::stoll(stem) >= count);
    if (e.path().extension() == ".tmp" || later) doomed.push_back(e.path());
  }
  for (const fs::path& p : doomed) fs::remove(p, ec);
  return kept;
}

void write_index(const std::string& h5_path, std::int64_t count) {
  const std::string tmp = h5_path + ".tmp";
  const hid_t f = H5Fcreate(tmp.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT);
  if (f < 0) throw RuntimeFailure("cannot create '" + tmp + "'");
  h5::check(H5Lcreate_external(kMeshFile, "/mesh", f, "mesh", H5P_DEFAULT, H5P_DEFAULT), "link /mesh");
  const hid_t frames = h5::check_id(H5Gcreate2(f, "/frames", H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT), "create /frames");
  for (std::int64_t k = 0; k < count; ++k)
    h5::check(H5Lcreate_external(frame_file(k).c_str(), "/", frames, frame_group(k).c_str(), H5P_DEFAULT, H5P_DEFAULT),
              "link frame " + frame_group(k));
  H5Gclose(frames);
  h5::check(H5Fclose(f), "close " + tmp);
  std::error_code ec;
  fs::rename(tmp, h5_path, ec);
  if (ec) throw RuntimeFailure("cannot rename '" + tmp + "' to '" + h5_path + "': " + ec.message());
}

void write_xdmf(const std::string& xdmf_path, const std::vector<FrameRecord>& frames, gid_t nv, gid_t nt) {
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
  for (std::size_t k = 0; k < frames.size(); ++k) {
    const FrameRecord& f = frames[k];
    const std::string g = frame_file(static_cast<std::int64_t>(k));
    x << "   <Grid Name=\"frame_" << k << "\" GridType=\"Uniform\">\n"
      << "    <Time Value=\"" << f.time << "\"/>\n"
      << "    <Topology TopologyType=\"Tetrahedron\" NumberOfElements=\"" << nt << "\">\n     "
      << item(kMeshFile, "/mesh/tets", nt, 4, "Int", 8) << "\n    </Topology>\n"
      << "    <Geometry GeometryType=\"XYZ\">\n     " << item(g, "/positions", nv, 3, "Float", 8)
      << "\n    </Geometry>\n";
    for (std::size_t a = 0; a < f.fields.size(); ++a) {
      const auto& [name, comps] = f.fields[a];
      x << "    <Attribute Name=\"" << name << "\" AttributeType=\"" << (comps == 3 ? "Vector" : "Scalar")
        << "\" Center=\"Node\">\n     " << item(g, "/" + f.datasets[a], nv, comps, "Float", 8) << "\n    </Attribute>\n";
    }
    x << "    <Attribute Name=\"owner_rank\" AttributeType=\"Scalar\" Center=\"Node\">\n     "
      << item(g, "/owner_rank", nv, 1, "Int", 4) << "\n    </Attribute>\n"
      << "    <Attribute Name=\"object\" AttributeType=\"Scalar\" Center=\"Node\">\n     "
      << item(kMeshFile, "/mesh/vertex_object", nv, 1, "Int", 4) << "\n    </Attribute>\n"
      << "    <Attribute Name=\"tet_object\" AttributeType=\"Scalar\" Center=\"Cell\">\n     "
      << item(kMeshFile, "/mesh/tet_object", nt, 1, "Int", 4) << "\n    </Attribute>\n"
      << "   </Grid>\n";
  }
  x << "  </Grid>\n </Domain>\n</Xdmf>\n";
  h5::write_text_atomically(xdmf_path, x.str());
}

}  // namespace softcontact::frames
