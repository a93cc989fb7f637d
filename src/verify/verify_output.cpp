// softcontact verify OUTPUT_DIR: reads a run's output (docs/output-format.md) with the
// HDF5 C API and checks every selected frame (verify.hpp): in one process, or with the
// frames shared by several (VerifyFrameShare; the command line gives one over MPI).
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <limits>
#include <sstream>
#include <type_traits>

#include "../io/h5_util.hpp"
#include "softcontact/error.hpp"
#include "softcontact/verify.hpp"

namespace softcontact {

namespace {

namespace fs = std::filesystem;

// An HDF5 file opened read-only (serial driver), closed on scope exit. Failures to
// open or read are bad input here: InputError naming the file.
class H5File {
public:
  explicit H5File(const std::string& path) : path_(path) {
    const h5::QuietErrors quiet;
    if (!fs::exists(path)) throw InputError(path, 0, "file does not exist");
    id_ = H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
    if (id_ < 0) throw InputError(path, 0, "not a readable HDF5 file (damaged, or not written by softcontact)");
  }
  ~H5File() {
    if (id_ >= 0) H5Fclose(id_);
  }
  H5File(const H5File&) = delete;
  H5File& operator=(const H5File&) = delete;

  /// All rows of dataset `name`, which must have `cols` columns (and `rows` rows unless < 0).
  template <class T>
  std::vector<T> read(const std::string& name, int cols, gid_t rows = -1) const {
    const h5::QuietErrors quiet;
    const gid_t n = rows >= 0 ? rows : h5::rows_of(id_, name);
    std::vector<T> data(static_cast<std::size_t>(n) * static_cast<std::size_t>(cols));
    try {
      h5::read_rows(id_, name, n, cols, h5::all_rows(n), data.data(), path_, false);
    } catch (const RuntimeFailure& e) {
      throw InputError(e.what());
    }
    return data;
  }
  template <class T>
  T attribute(const char* name) const {
    const h5::QuietErrors quiet;
    try {
      return h5::read_attribute<T>(id_, name, path_);
    } catch (const RuntimeFailure& e) {
      throw InputError(e.what());
    }
  }
  std::string text_attribute(const char* name) const {
    const h5::QuietErrors quiet;
    try {
      return h5::read_string_attribute(id_, name, path_);
    } catch (const RuntimeFailure& e) {
      return "";
    }
  }
  hid_t id() const { return id_; }

private:
  std::string path_;
  hid_t id_ = -1;
};

struct FrameFile {
  std::int64_t number;
  std::string path;
};

// frames/NNNNNN.h5, in frame order (*.tmp and other names are left alone).
std::vector<FrameFile> list_frames(const fs::path& dir) {
  std::vector<FrameFile> frames;
  std::error_code ec;
  const fs::path fdir = dir / "frames";
  if (!fs::is_directory(fdir, ec)) throw InputError(fdir.string(), 0, "no frames directory (not a softcontact output)");
  for (const auto& e : fs::directory_iterator(fdir, ec)) {
    const std::string stem = e.path().stem().string();
    if (e.path().extension() != ".h5" || stem.empty() || stem.size() > 12 ||
        stem.find_first_not_of("0123456789") != std::string::npos)
      continue;
    frames.push_back({std::stoll(stem), e.path().string()});
  }
  std::sort(frames.begin(), frames.end(), [](const FrameFile& a, const FrameFile& b) { return a.number < b.number; });
  if (frames.empty()) throw InputError(fdir.string(), 0, "no frame files (frames/NNNNNN.h5)");
  return frames;
}

// The indices into `frames` that `spec` selects: all, first, last, or a comma list of
// frame numbers and ranges A:B[:STEP] (B included); negative numbers count from the end.
std::vector<std::size_t> select_frames(const std::string& spec, const std::vector<FrameFile>& frames) {
  const auto count = static_cast<std::int64_t>(frames.size());
  const std::int64_t top = frames.back().number;
  std::vector<std::size_t> pick;
  if (spec == "all") {
    for (std::size_t i = 0; i < frames.size(); ++i) pick.push_back(i);
    return pick;
  }
  if (spec == "last") return {frames.size() - 1};
  if (spec == "first") return {0};
  auto bad = [&](const std::string& why) -> InputError {
    return InputError("command line: --frames '" + spec + "': " + why + " (see 'softcontact verify --help')");
  };
  auto number = [&](const std::string& s) {
    std::size_t pos = 0;
    long long v = 0;
    try {
      v = std::stoll(s, &pos);
    } catch (const std::exception&) {
      pos = 0;
    }
    if (s.empty() || pos != s.size()) throw bad("'" + s + "' is not a frame number");
    return v < 0 ? top + 1 + v : static_cast<std::int64_t>(v);
  };
  std::vector<std::int64_t> wanted;
  std::stringstream in(spec);
  std::string item;
  while (std::getline(in, item, ',')) {
    std::vector<std::string> parts;
    std::stringstream ps(item);
    std::string p;
    while (std::getline(ps, p, ':')) parts.push_back(p);
    if (parts.empty() || parts.size() > 3) throw bad("'" + item + "' is not N or A:B[:STEP]");
    const std::int64_t a = number(parts[0]);
    const std::int64_t b = parts.size() > 1 ? number(parts[1]) : a;
    const std::int64_t step = parts.size() > 2 ? number(parts[2]) : 1;
    if (step < 1) throw bad("a range's step must be positive");
    for (std::int64_t k = a; k <= b; k += step) wanted.push_back(k);
  }
  for (std::int64_t k : wanted) {
    const auto it = std::find_if(frames.begin(), frames.end(), [&](const FrameFile& f) { return f.number == k; });
    if (it == frames.end())
      throw bad("there is no frame " + std::to_string(k) + " (frames 0 to " + std::to_string(top) + ", " +
                std::to_string(count) + " files)");
    pick.push_back(static_cast<std::size_t>(it - frames.begin()));
  }
  std::sort(pick.begin(), pick.end());
  pick.erase(std::unique(pick.begin(), pick.end()), pick.end());
  return pick;
}

// Gravity and the largest initial or prescribed speed from the scene copy, read as plain
// YAML: its mesh paths are relative to where the scene was, so the scene parser cannot
// load it from the output directory. Defaults as in the scene format.
void scene_motion(const fs::path& path, Vec3& gravity, double& v0, std::ostream& err) {
  gravity = Simulation{}.gravity;
  v0 = 0;
  if (!fs::exists(path)) {
    err << "softcontact verify: warning: " << path.string() << " is missing: gravity taken as [0, 0, -9.81]\n";
    return;
  }
  auto vec = [](const YAML::Node& n, Vec3& out) {
    if (!n || !n.IsSequence() || n.size() != 3) return false;
    for (std::size_t d = 0; d < 3; ++d) out[d] = n[d].as<double>();
    return true;
  };
  try {
    const YAML::Node root = YAML::LoadFile(path.string());
    if (root["simulation"] && root["simulation"]["gravity"] && !vec(root["simulation"]["gravity"], gravity))
      throw InputError(path.string(), 0, "simulation.gravity is not a list of 3 numbers");
    if (root["objects"] && root["objects"].IsSequence())
      for (const YAML::Node& o : root["objects"]) {
        Vec3 v{};
        if (vec(o["velocity"], v)) v0 = std::max(v0, std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]));
        if (o["motion"] && vec(o["motion"]["velocity"], v))
          v0 = std::max(v0, std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]));
      }
  } catch (const YAML::Exception& e) {
    throw InputError(path.string(), e.mark.line >= 0 ? e.mark.line + 1 : 0, "cannot read the scene copy: " + e.msg);
  }
}

struct MeshData {
  VerifyMesh mesh;
  std::vector<double> rest;
  std::vector<std::string> names;
};

MeshData read_mesh(const fs::path& path) {
  MeshData d;
  const H5File f(path.string());
  d.rest = f.read<double>("/mesh/points", 3);
  const gid_t n = static_cast<gid_t>(d.rest.size() / 3);
  if (n == 0) throw InputError(path.string(), 0, "the mesh has no vertices");
  VerifyMesh& m = d.mesh;
  m.tets = f.read<gid_t>("/mesh/tets", 4);
  if (m.tets.empty()) throw InputError(path.string(), 0, "the mesh has no tets");
  m.tet_object = f.read<std::int32_t>("/mesh/tet_object", 1, static_cast<gid_t>(m.tets.size() / 4));
  m.triangles = f.read<gid_t>("/mesh/surface_triangles", 3);
  m.vertex_object = f.read<std::int32_t>("/mesh/vertex_object", 1, n);
  const std::vector<double> mass = f.read<double>("/mesh/vertex_mass", 1, n);
  std::int64_t objects = 0;
  for (std::int32_t o : m.vertex_object) objects = std::max<std::int64_t>(objects, std::int64_t{o} + 1);
  if (H5Aexists_by_name(f.id(), "/mesh", "num_objects", H5P_DEFAULT) > 0) {
    const hid_t g = H5Gopen2(f.id(), "/mesh", H5P_DEFAULT);
    if (g >= 0) {
      const h5::QuietErrors quiet;
      try {
        objects = h5::read_attribute<std::int64_t>(g, "num_objects", path.string());
      } catch (const RuntimeFailure&) {
      }
      std::istringstream names;
      try {
        names.str(h5::read_string_attribute(g, "objects", path.string()));
      } catch (const RuntimeFailure&) {
      }
      std::string line;
      while (std::getline(names, line)) d.names.push_back(line.substr(0, line.find('\t')));
      H5Gclose(g);
    }
  }
  if (objects < 1 || objects > std::numeric_limits<std::int32_t>::max())
    throw InputError(path.string(), 0, "num_objects = " + std::to_string(objects) + " is out of range");
  // A body is kinematic when every one of its vertices has infinite mass.
  m.object_fixed.assign(static_cast<std::size_t>(objects), 1);
  std::vector<char> seen(static_cast<std::size_t>(objects), 0);
  for (std::size_t i = 0; i < static_cast<std::size_t>(n); ++i) {
    const std::int32_t o = m.vertex_object[i];
    if (o < 0 || o >= objects) continue;  // prepare_verify_mesh reports it
    seen[static_cast<std::size_t>(o)] = 1;
    if (!std::isinf(mass[i])) m.object_fixed[static_cast<std::size_t>(o)] = 0;
  }
  for (std::size_t k = 0; k < seen.size(); ++k)
    if (!seen[k]) m.object_fixed[k] = 0;
  prepare_verify_mesh(m, d.rest.data(), path.string());
  return d;
}

std::string object_name(const MeshData& d, std::int32_t o) {
  if (o < 0) return "-";
  const auto k = static_cast<std::size_t>(o);
  return k < d.names.size() && !d.names[k].empty() ? d.names[k] : "object " + std::to_string(o);
}

bool limited(double limit) { return limit >= 0 && std::isfinite(limit); }

std::string fmt(const char* f, double x) {
  char buf[64];
  std::snprintf(buf, sizeof buf, f, x);
  return buf;
}

std::string limit_json(double limit) { return limited(limit) ? fmt("%.9g", limit) : "null"; }

std::string json_string(const std::string& text) {
  std::string s = "\"";
  for (char c : text) {
    if (c == '"' || c == '\\') s += '\\';
    if (static_cast<unsigned char>(c) < 0x20) s += ' ';
    else s += c;
  }
  return s + '"';
}

// One selected frame's check, as process 0 reports it (trivially copyable: gathered as
// bytes from the processes sharing the frames).
struct CheckedFrame {
  std::int64_t pick = 0;  // index into the selected frames
  double time = 0;        // the frame's time [s]
  int checked = 0;        // 0: before --skip-frames-before
  VerifyFrame result;
};
static_assert(std::is_trivially_copyable_v<CheckedFrame>, "CheckedFrame is gathered as bytes");

}  // namespace

int verify_output(const std::string& dir_arg, const VerifyOutputOptions& opt, std::ostream& out, std::ostream& err) {
  const int rank = opt.share ? opt.share->rank() : 0, size = opt.share ? opt.share->size() : 1;
  const fs::path dir(dir_arg);
  const auto t0 = std::chrono::steady_clock::now();
  MeshData md;
  std::vector<FrameFile> frames;
  std::vector<std::size_t> pick;
  Vec3 gravity{};
  double v0 = 0;
  VerifyOptions vo;
  auto set_up = [&] {
    std::error_code ec;
    if (!fs::exists(dir, ec)) throw InputError(dir_arg, 0, "output directory does not exist");
    if (!fs::is_directory(dir, ec)) throw InputError(dir_arg, 0, "is not a directory");
    md = read_mesh(dir / "mesh.h5");
    frames = list_frames(dir);
    pick = select_frames(opt.frames, frames);
    std::ostringstream quiet;  // the warnings once, from process 0
    scene_motion(dir / "scene.yaml", gravity, v0, rank == 0 ? err : quiet);
    // The first frame's velocities are the initial ones.
    const gid_t n = static_cast<gid_t>(md.mesh.num_vertices());
    const H5File f0(frames.front().path);
    const std::vector<double> v = f0.read<double>("velocities", 3, n);
    for (std::size_t i = 0; i < static_cast<std::size_t>(n); ++i) {
      const double s = std::sqrt(v[3 * i] * v[3 * i] + v[3 * i + 1] * v[3 * i + 1] + v[3 * i + 2] * v[3 * i + 2]);
      if (std::isfinite(s)) v0 = std::max(v0, s);
    }
    vo.free_fall_speed = free_fall_speed(md.rest.data(), static_cast<std::size_t>(n), gravity, v0);
  };
  // The check of selected frame j.
  auto check = [&](std::size_t j) {
    CheckedFrame c;
    c.pick = static_cast<std::int64_t>(j);
    const H5File f(frames[pick[j]].path);
    c.time = f.attribute<double>("time");
    if (opt.skip && c.time < opt.skip_before) return c;
    const gid_t n = static_cast<gid_t>(md.mesh.num_vertices());
    const std::vector<double> x = f.read<double>("positions", 3, n);
    const std::vector<double> v = f.read<double>("velocities", 3, n);
    c.result = verify_frame(md.mesh, x.data(), v.data(), vo);
    c.result.step = f.attribute<std::int64_t>("step");
    c.result.time = c.time;
    c.checked = 1;
    return c;
  };

  // Several processes: each sets up and checks its frames; an input error anywhere stops
  // every process with the lowest one's message; process 0 gathers the checks.
  std::vector<CheckedFrame> gathered;
  if (size > 1) {
    std::vector<CheckedFrame> mine;
    std::string error;
    try {
      set_up();
      for (std::size_t j = static_cast<std::size_t>(rank); j < pick.size(); j += static_cast<std::size_t>(size))
        mine.push_back(check(j));
    } catch (const InputError& e) {
      error = e.what();
    }
    error = opt.share->first_error(error);
    if (!error.empty()) throw InputError(error);
    std::vector<char> bytes(mine.size() * sizeof(CheckedFrame));
    if (!mine.empty()) std::memcpy(bytes.data(), mine.data(), bytes.size());
    bytes = opt.share->gather(bytes);
    if (rank != 0) return 0;
    gathered.resize(bytes.size() / sizeof(CheckedFrame));
    if (!gathered.empty()) std::memcpy(gathered.data(), bytes.data(), gathered.size() * sizeof(CheckedFrame));
    std::sort(gathered.begin(), gathered.end(),
              [](const CheckedFrame& x, const CheckedFrame& y) { return x.pick < y.pick; });
  } else {
    set_up();
  }
  const VerifyMesh& mesh = md.mesh;
  const gid_t n = static_cast<gid_t>(mesh.num_vertices());
  const VerifyThresholds& lim = opt.thresholds;
  const double h = mesh.median_edge;

  out << "verify " << dir_arg << ": " << mesh.num_objects() << " objects, " << n << " vertices, " << mesh.num_tets()
      << " tets, " << mesh.num_triangles() << " surface triangles; median edge h = " << fmt("%.4g", h)
      << " m; free-fall speed v_ff = " << fmt("%.4g", vo.free_fall_speed) << " m/s\n";
  out << " frame      step    time [s]  surf.in  depth/h    p99/h  int.in  depth/h   cross  no-vtx  depth/h  inverted"
         "  v/v_ff  self.in   self/h  self.x  depth/h\n";

  VerifyMaxima worst;
  std::vector<std::string> rows, violations;
  VerifyFrame last;
  std::int64_t last_frame = -1;
  double latest = 0;  // time of the last selected frame
  for (std::size_t j = 0; j < pick.size(); ++j) {
    // One process: each frame checked here and its line printed as it is done.
    const CheckedFrame c = size > 1 ? gathered.at(j) : check(j);
    const FrameFile& ff = frames[pick[j]];
    latest = c.time;
    if (!c.checked) continue;
    const VerifyFrame& r = c.result;
    worst.add(r);
    char line[300];
    std::snprintf(line, sizeof line, "%6lld %9lld %11.5g %8lld %8.4f %8.4f %7lld %8.4f %7lld %7lld %8.4f %9lld %7.3f %8lld %8.4f %7lld %8.4f\n",
                  static_cast<long long>(ff.number), static_cast<long long>(r.step), r.time,
                  static_cast<long long>(r.surface.count), r.surface_depth(), r.surface.p99_depth / h,
                  static_cast<long long>(r.interior.count), r.interior_depth(),
                  static_cast<long long>(r.crossings.count), static_cast<long long>(r.crossings.without_inside_vertex),
                  r.crossing_depth(), static_cast<long long>(r.inverted), r.speed_ratio,
                  static_cast<long long>(r.self.count), r.self_depth(),
                  static_cast<long long>(r.self_crossings.count), r.self_crossing_depth());
    out << line << std::flush;
    const std::string at = "frame " + std::to_string(ff.number) + " (t = " + fmt("%.6g", r.time) + " s)";
    if (limited(lim.max_depth) && r.surface_depth() > lim.max_depth)
      violations.push_back(at + ": surface vertex " + std::to_string(r.surface.vertex) + " of " +
                           object_name(md, r.surface.object) + " is " + fmt("%.4g", r.surface_depth()) + " h deep in " +
                           object_name(md, r.surface.in_object) + " (limit " + fmt("%.4g", lim.max_depth) + ")");
    if (limited(lim.max_interior_depth) && r.interior_depth() > lim.max_interior_depth)
      violations.push_back(at + ": interior vertex " + std::to_string(r.interior.vertex) + " of " +
                           object_name(md, r.interior.object) + " is " + fmt("%.4g", r.interior_depth()) +
                           " h deep in " + object_name(md, r.interior.in_object) + " (limit " +
                           fmt("%.4g", lim.max_interior_depth) + ")");
    if (limited(lim.max_self_depth) && r.self_depth() > lim.max_self_depth)
      violations.push_back(at + ": surface vertex " + std::to_string(r.self.vertex) + " of " +
                           object_name(md, r.self.object) + " is " + fmt("%.4g", r.self_depth()) +
                           " h deep in its own body (self-contact; limit " + fmt("%.4g", lim.max_self_depth) + ")");
    if (lim.max_crossings >= 0 && r.crossings.count > lim.max_crossings)
      violations.push_back(at + ": " + std::to_string(r.crossings.count) + " surface crossings (limit " +
                           std::to_string(lim.max_crossings) + ")");
    if (limited(lim.max_speed_ratio) && r.speed_ratio > lim.max_speed_ratio)
      violations.push_back(at + ": vertex " + std::to_string(r.fastest) + " moves at " + fmt("%.4g", r.max_speed) +
                           " m/s, " + fmt("%.3g", r.speed_ratio) + " x the free-fall speed (limit " +
                           fmt("%.3g", lim.max_speed_ratio) + ")");
    if (r.nonfinite > 0)
      violations.push_back(at + ": " + std::to_string(r.nonfinite) + " vertices with a non-finite position or velocity");
    std::ostringstream row;
    row << "{\"frame\": " << ff.number << ", \"check\": " << to_json(r) << "}";
    rows.push_back(row.str());
    last = r;
    last_frame = ff.number;
  }
  if (last_frame < 0)
    throw InputError("command line: --skip-frames-before " + fmt("%.6g", opt.skip_before) +
                     " leaves none of the selected frames to check (the last is at t = " +
                     fmt("%.6g", latest) + " s)");
  if (lim.max_inverted >= 0 && last.inverted > lim.max_inverted)
    violations.push_back("last frame " + std::to_string(last_frame) + ": " + std::to_string(last.inverted) +
                         " inverted tets, the first tet " + std::to_string(last.first_inverted) + " (limit " +
                         std::to_string(lim.max_inverted) + ")");

  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const bool pass = violations.empty();
  out << "summary: " << worst.checks << " frame(s) checked in " << fmt("%.3g", seconds) << " s";
  if (size > 1) out << " by " << size << " processes";
  out << "\n";
  if (worst.checks > 0) {
    const VerifyFrame& d = worst.deepest;
    out << "  deepest surface vertex: " << fmt("%.4g", worst.surface_depth.value) << " h";
    if (d.surface.vertex >= 0)
      out << " = " << fmt("%.4g", d.surface.max_depth) << " m (vertex " << d.surface.vertex << " of "
          << object_name(md, d.surface.object) << " in " << object_name(md, d.surface.in_object) << ", t = "
          << fmt("%.6g", d.time) << " s)";
    out << "; at most " << static_cast<long long>(worst.surface_count.value) << " surface vertices inside\n"
        << "  deepest interior vertex: " << fmt("%.4g", worst.interior_depth.value) << " h; at most "
        << static_cast<long long>(worst.interior_count.value) << " inside\n"
        << "  deepest surface vertex in its own body: " << fmt("%.4g", worst.self_depth.value) << " h; at most "
        << static_cast<long long>(worst.self_count.value) << " inside; its surface edges through its own surface: at most "
        << static_cast<long long>(worst.self_crossings.value) << ", deepest " << fmt("%.4g", worst.self_crossing_depth.value)
        << " h\n"
        << "  surface crossings: at most " << static_cast<long long>(worst.crossings.value) << " ("
        << static_cast<long long>(worst.crossings_without_inside_vertex.value)
        << " with no vertex inside), deepest " << fmt("%.4g", worst.crossing_depth.value) << " h\n"
        << "  inverted tets: at most " << static_cast<long long>(worst.inverted.value) << ", " << last.inverted
        << " at the last frame\n"
        << "  fastest vertex: " << fmt("%.4g", worst.max_speed.value) << " m/s, "
        << fmt("%.3g", worst.speed_ratio.value) << " x v_ff (vertex " << worst.fastest_vertex << ", t = "
        << fmt("%.6g", worst.max_speed.time) << " s)\n";
  }
  for (const std::string& v : violations) out << "  exceeded: " << v << "\n";
  out << (pass ? "PASS" : "FAIL") << ": limits surface depth "
      << (limited(lim.max_depth) ? fmt("%.4g", lim.max_depth) + " h" : "none") << ", interior depth "
      << (limited(lim.max_interior_depth) ? fmt("%.4g", lim.max_interior_depth) + " h" : "none") << ", self depth "
      << (limited(lim.max_self_depth) ? fmt("%.4g", lim.max_self_depth) + " h" : "none") << ", crossings "
      << (lim.max_crossings >= 0 ? std::to_string(lim.max_crossings) : "none") << ", inverted at the last frame "
      << (lim.max_inverted >= 0 ? std::to_string(lim.max_inverted) : "none") << ", speed "
      << (limited(lim.max_speed_ratio) ? fmt("%.3g", lim.max_speed_ratio) + " x v_ff" : "none") << "\n";

  std::ostringstream js;
  js << "{\n  \"directory\": " << json_string(dir_arg) << ",\n  \"pass\": " << (pass ? "true" : "false")
     << ",\n  \"median_edge\": " << fmt("%.9g", h) << ",\n  \"free_fall_speed\": " << fmt("%.9g", vo.free_fall_speed)
     << ",\n  \"initial_speed\": " << fmt("%.9g", v0) << ",\n  \"gravity\": [" << fmt("%.9g", gravity[0]) << ", "
     << fmt("%.9g", gravity[1]) << ", " << fmt("%.9g", gravity[2]) << "]"
     << ",\n  \"thresholds\": {\"max_depth_edges\": " << limit_json(lim.max_depth)
     << ", \"max_interior_depth_edges\": " << limit_json(lim.max_interior_depth)
     << ", \"max_self_depth_edges\": " << limit_json(lim.max_self_depth)
     << ", \"max_crossings\": " << (lim.max_crossings >= 0 ? std::to_string(lim.max_crossings) : "null")
     << ", \"max_inverted_last_frame\": " << (lim.max_inverted >= 0 ? std::to_string(lim.max_inverted) : "null")
     << ", \"max_speed_ratio\": " << limit_json(lim.max_speed_ratio) << "}"
     << ",\n  \"violations\": [";
  for (std::size_t i = 0; i < violations.size(); ++i) js << (i ? ", " : "") << json_string(violations[i]);
  js << "],\n  \"maxima\": " << to_json(worst) << ",\n  \"frames\": [\n";
  for (std::size_t i = 0; i < rows.size(); ++i) js << "    " << rows[i] << (i + 1 < rows.size() ? ",\n" : "\n");
  js << "  ]\n}\n";
  const std::string json = opt.json.empty() ? (dir / "verify.json").string() : opt.json;
  {
    std::ofstream o(json, std::ios::trunc);
    o << js.str();
    o.flush();
    if (!o) throw InputError(json, 0, "cannot write the JSON summary");
  }
  out << "json: " << json << "\n";
  return pass ? 0 : 1;
}

}  // namespace softcontact
