#include "softcontact/checkpoint.hpp"

#include <algorithm>
#include <cstdio>
#include <cstring>
#include <filesystem>

#include "h5_util.hpp"
#include "softcontact/error.hpp"
#include "softcontact/fault.hpp"
#include "softcontact/simulator.hpp"

namespace softcontact {

namespace fs = std::filesystem;

namespace {

constexpr std::int64_t kFormat = 2;  // 2: two friction anchors per vertex (one per other body)
constexpr const char* kDir = "checkpoints";
constexpr const char* kPrefix = "checkpoint_";

// FNV-1a, 64 bit, over raw bytes: the scene's data in a fixed order.
class Fingerprint {
public:
  void bytes(const void* p, std::size_t n) {
    const auto* b = static_cast<const unsigned char*>(p);
    for (std::size_t i = 0; i < n; ++i) {
      h_ ^= b[i];
      h_ *= 1099511628211ull;
    }
  }
  template <class T>
  void value(const T& v) { bytes(&v, sizeof v); }
  template <class T>
  void vector(const std::vector<T>& v) {
    value(v.size());
    if (!v.empty()) bytes(v.data(), v.size() * sizeof(T));
  }
  std::uint64_t get() const { return h_; }

private:
  std::uint64_t h_ = 14695981039346656037ull;
};

// The per-vertex state as written: one array per field, packed in owned-run order
// (which is local order: owned vertices are stored by ascending global id per object).
struct Rows {
  std::vector<std::int64_t> anchor_step, anchor_tri;
  std::vector<std::int32_t> anchor_object;
  std::vector<double> anchor_bary;
};

[[noreturn]] void not_a_checkpoint(const std::string& path, const std::string& why) {
  throw InputError(path, 0, "not a readable softcontact checkpoint: " + why);
}

}  // namespace

std::uint64_t scene_fingerprint(const Scene& scene) {
  Fingerprint f;
  const Simulation& s = scene.sim;
  f.value(s.dt);
  f.value(s.gravity);
  f.value(s.integrator);
  f.value(s.self_collisions);
  f.value(scene.materials.size());
  for (const Material& m : scene.materials) {
    f.value(m.model);
    for (double x : {m.young, m.poisson, m.density, m.damping_mass, m.damping_stiffness}) f.value(x);
  }
  f.value(scene.default_friction.mu_static);
  f.value(scene.default_friction.mu_kinetic);
  for (const auto& row : scene.friction)
    for (const Friction& fr : row) {
      f.value(fr.mu_static);
      f.value(fr.mu_kinetic);
    }
  f.value(scene.objects.size());
  for (const SceneObject& o : scene.objects) {
    f.value(o.material);
    f.value(o.kinematic);
    f.value(o.velocity);
    f.vector(o.mesh.points);
    f.vector(o.mesh.tets);
    f.value(o.fixed.size());
    for (const AxisBox& b : o.fixed) {
      f.value(b.min);
      f.value(b.max);
    }
    f.value(o.motion.velocity);
    f.value(o.motion.start);
    f.value(o.motion.stop);
  }
  return f.get();
}

std::string checkpoint_path(const std::string& output_dir, std::int64_t step) {
  char name[64];
  std::snprintf(name, sizeof name, "%s%012lld.h5", kPrefix, static_cast<long long>(step));
  return (fs::path(output_dir) / kDir / name).string();
}

namespace {
// Checkpoints in a folder, by step (ascending).
std::vector<std::pair<std::int64_t, fs::path>> list_checkpoints(const fs::path& dir) {
  std::vector<std::pair<std::int64_t, fs::path>> out;
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(dir, ec)) {
    const std::string name = e.path().filename().string();
    if (name.rfind(kPrefix, 0) != 0 || e.path().extension() != ".h5") continue;
    const std::string digits = e.path().stem().string().substr(std::strlen(kPrefix));
    if (digits.empty() || digits.size() > 18 || digits.find_first_not_of("0123456789") != std::string::npos) continue;
    out.emplace_back(std::stoll(digits), e.path());
  }
  std::sort(out.begin(), out.end());
  return out;
}
}  // namespace

void prune_checkpoints(const std::string& output_dir, std::int64_t keep) {
  const auto all = list_checkpoints(fs::path(output_dir) / kDir);
  std::error_code ec;
  for (std::size_t i = 0; i + static_cast<std::size_t>(std::max<std::int64_t>(keep, 1)) < all.size(); ++i)
    fs::remove(all[i].second, ec);
}

std::string resolve_checkpoint(const std::string& path) {
  std::error_code ec;
  if (!fs::exists(path, ec)) throw InputError(path, 0, "no such checkpoint file or directory");
  if (!fs::is_directory(path, ec)) return path;
  fs::path dir(path);
  if (fs::is_directory(dir / kDir, ec)) dir /= kDir;
  const auto all = list_checkpoints(dir);
  if (all.empty()) throw InputError(path, 0, "no checkpoint (" + std::string(kPrefix) + "*.h5) in this directory");
  return all.back().second.string();
}

void write_checkpoint(MPI_Comm comm, const std::string& path, Simulator& sim, CheckpointInfo info) {
  int rank = 0, size = 1;
  MPI_Comm_rank(comm, &rank);
  MPI_Comm_size(comm, &size);
  const World& w = sim.world();
  info.format = kFormat;
  info.step = sim.step_count();
  info.time = sim.time();
  info.dt = sim.scene().sim.dt;
  info.ranks = size;
  info.anchor_step = sim.anchor_step();
  info.vertices = w.global_vertices;
  info.partition = sim.partition();
  info.boxes = sim.current_boxes();
  if (rank == 0) {
    std::error_code ec;
    fs::create_directories(fs::path(path).parent_path(), ec);
  }
  MPI_Barrier(comm);

  const std::string tmp = path + ".tmp";
  const hid_t file = h5::create_parallel(comm, tmp, "the checkpoint");
  const hid_t state = h5::check_id(H5Gcreate2(file, "/state", H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT), "create /state");
  const std::vector<GidRun> runs = owned_vertex_runs(w);
  const gid_t nv = w.global_vertices;
  h5::write_rows(state, "x", nv, 3, runs, w.x.data());
  if (fault::hit(fault::Point::checkpoint_write, info.step))
    throw RuntimeFailure(fault::io_error(fault::Point::checkpoint_write, tmp));
  h5::write_rows(state, "x_prev", nv, 3, runs, w.x_prev.data());
  h5::write_rows(state, "v", nv, 3, runs, w.v.data());
  const std::vector<StictionAnchor>& anchors = sim.anchors();
  Rows r;
  constexpr int na = StictionAnchor::kPerPoint;
  for (std::size_t i = 0; i < w.n_owned; ++i)
    for (const AnchorEntry& a : anchors[i].entry) {
      r.anchor_step.push_back(a.step);
      r.anchor_object.push_back(a.object);
      for (int c = 0; c < 3; ++c) {
        r.anchor_tri.push_back(a.tri[c]);
        r.anchor_bary.push_back(a.bary[c]);
      }
    }
  h5::write_rows(state, "anchor_step", nv, na, runs, r.anchor_step.data());
  h5::write_rows(state, "anchor_object", nv, na, runs, r.anchor_object.data());
  h5::write_rows(state, "anchor_triangle", nv, 3 * na, runs, r.anchor_tri.data());
  h5::write_rows(state, "anchor_bary", nv, 3 * na, runs, r.anchor_bary.data());
  H5Gclose(state);

  // The run description: written by rank 0 (every rank holds the same), independent I/O.
  const hid_t run = h5::check_id(H5Gcreate2(file, "/run", H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT), "create /run");
  const auto nobj = static_cast<gid_t>(info.partition.size());
  const std::vector<GidRun> mine = rank == 0 ? h5::all_rows(nobj) : std::vector<GidRun>{};
  std::vector<std::int32_t> part(info.partition.begin(), info.partition.end());
  std::vector<double> boxes;
  for (const ObjectBox& b : info.boxes)
    boxes.insert(boxes.end(), {b.lo[0], b.lo[1], b.lo[2], b.hi[0], b.hi[1], b.hi[2]});
  h5::write_rows(run, "partition", nobj, 1, mine, part.data());
  h5::write_rows(run, "boxes", nobj, 6, mine, boxes.data());
  const auto text_size = static_cast<gid_t>(info.scene_text.size());
  h5::write_rows(run, "scene", text_size, 1, rank == 0 ? h5::all_rows(text_size) : std::vector<GidRun>{},
                 info.scene_text.data());
  h5::write_attribute(run, "format", info.format);
  h5::write_attribute(run, "step", info.step);
  h5::write_attribute(run, "time", info.time);
  h5::write_attribute(run, "dt", info.dt);
  h5::write_attribute(run, "steps", info.steps);
  h5::write_attribute(run, "output_every", info.output_every);
  h5::write_attribute(run, "frames", info.frames);
  h5::write_attribute(run, "ranks", info.ranks);
  h5::write_attribute(run, "anchor_step", info.anchor_step);
  h5::write_attribute(run, "vertices", info.vertices);
  h5::write_attribute(run, "fingerprint", static_cast<std::int64_t>(info.fingerprint));
  h5::write_attribute(run, "energy0", info.energy0);
  h5::write_attribute(run, "energy_scale", info.energy_scale);
  h5::write_string_attribute(run, "scene_path", info.scene_path);
  h5::write_string_attribute(run, "output_dir", info.output_dir);
  H5Gclose(run);
  h5::check(H5Fclose(file), "close " + tmp);
  if (fault::hit(fault::Point::checkpoint_rename, info.step))
    throw RuntimeFailure(fault::io_error(fault::Point::checkpoint_rename, path));
  h5::publish(comm, tmp, path, true);
  if (fault::hit(fault::Point::checkpoint_renamed, info.step))
    throw RuntimeFailure(fault::io_error(fault::Point::checkpoint_renamed, path));
}

namespace {

void pack(std::vector<char>& buf, const void* p, std::size_t n) {
  const auto* c = static_cast<const char*>(p);
  buf.insert(buf.end(), c, c + n);
}
template <class T>
void pack(std::vector<char>& buf, const T& v) { pack(buf, &v, sizeof v); }
void pack(std::vector<char>& buf, const std::string& s) {
  pack(buf, s.size());
  pack(buf, s.data(), s.size());
}

class Unpack {
public:
  explicit Unpack(const std::vector<char>& b) : b_(b) {}
  template <class T>
  void get(T& v) {
    std::memcpy(&v, b_.data() + at_, sizeof v);
    at_ += sizeof v;
  }
  void get(std::string& s) {
    std::size_t n = 0;
    get(n);
    s.assign(b_.data() + at_, n);
    at_ += n;
  }

private:
  const std::vector<char>& b_;
  std::size_t at_ = 0;
};

CheckpointInfo read_info_serial(const std::string& path) {
  const h5::QuietErrors quiet;
  const hid_t file = H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  if (file < 0) not_a_checkpoint(path, "HDF5 cannot open it (damaged, truncated, or not HDF5)");
  CheckpointInfo info;
  try {
    const hid_t run = H5Gopen2(file, "/run", H5P_DEFAULT);
    if (run < 0) throw RuntimeFailure(path + ": group /run is missing");
    try {
      info.format = h5::read_attribute<std::int64_t>(run, "format", path);
      if (info.format != kFormat)
        throw RuntimeFailure(path + ": checkpoint format " + std::to_string(info.format) + ", this build reads format " +
                             std::to_string(kFormat));
      info.step = h5::read_attribute<std::int64_t>(run, "step", path);
      info.time = h5::read_attribute<double>(run, "time", path);
      info.dt = h5::read_attribute<double>(run, "dt", path);
      info.steps = h5::read_attribute<std::int64_t>(run, "steps", path);
      info.output_every = h5::read_attribute<std::int64_t>(run, "output_every", path);
      info.frames = h5::read_attribute<std::int64_t>(run, "frames", path);
      info.ranks = h5::read_attribute<std::int64_t>(run, "ranks", path);
      info.anchor_step = h5::read_attribute<std::int64_t>(run, "anchor_step", path);
      info.vertices = h5::read_attribute<std::int64_t>(run, "vertices", path);
      info.fingerprint = static_cast<std::uint64_t>(h5::read_attribute<std::int64_t>(run, "fingerprint", path));
      info.energy0 = h5::read_attribute<double>(run, "energy0", path);
      info.energy_scale = h5::read_attribute<double>(run, "energy_scale", path);
      info.scene_path = h5::read_string_attribute(run, "scene_path", path);
      info.output_dir = h5::read_string_attribute(run, "output_dir", path);
      if (info.step < 0 || info.steps < 1 || info.output_every < 1 || info.frames < 0 || info.vertices < 0 ||
          !(info.dt > 0))
        throw RuntimeFailure(path + ": its run description is out of range");
      const auto n = static_cast<hsize_t>(h5::rows_of(run, "partition"));
      std::vector<std::int32_t> part(n);
      std::vector<double> boxes(6 * n);
      h5::read_rows(run, "partition", static_cast<gid_t>(n), 1, h5::all_rows(static_cast<gid_t>(n)), part.data(), path, false);
      h5::read_rows(run, "boxes", static_cast<gid_t>(n), 6, h5::all_rows(static_cast<gid_t>(n)), boxes.data(), path, false);
      info.partition.assign(part.begin(), part.end());
      for (hsize_t k = 0; k < n; ++k)
        info.boxes.push_back(ObjectBox{{boxes[6 * k], boxes[6 * k + 1], boxes[6 * k + 2]},
                                       {boxes[6 * k + 3], boxes[6 * k + 4], boxes[6 * k + 5]}});
      const auto chars = static_cast<hsize_t>(h5::rows_of(run, "scene"));
      info.scene_text.assign(chars, '\0');
      h5::read_rows(run, "scene", static_cast<gid_t>(chars), 1, h5::all_rows(static_cast<gid_t>(chars)),
                    info.scene_text.data(), path, false);
    } catch (...) {
      H5Gclose(run);
      throw;
    }
    H5Gclose(run);
  } catch (const RuntimeFailure& e) {
    H5Fclose(file);
    std::string why = e.what();
    if (why.rfind(path + ": ", 0) == 0) why = why.substr(path.size() + 2);
    not_a_checkpoint(path, why);
  }
  H5Fclose(file);
  return info;
}

}  // namespace

CheckpointInfo read_checkpoint_info(MPI_Comm comm, const std::string& path) {
  int rank = 0;
  MPI_Comm_rank(comm, &rank);
  std::vector<char> buf;
  std::string error;
  if (rank == 0) {
    try {
      const CheckpointInfo i = read_info_serial(path);
      for (std::int64_t v : {i.format, i.step, i.steps, i.output_every, i.frames, i.ranks, i.anchor_step, i.vertices})
        pack(buf, v);
      pack(buf, i.time);
      pack(buf, i.dt);
      pack(buf, i.energy0);
      pack(buf, i.energy_scale);
      pack(buf, i.fingerprint);
      pack(buf, i.scene_path);
      pack(buf, i.scene_text);
      pack(buf, i.output_dir);
      pack(buf, i.partition.size());
      for (int p : i.partition) pack(buf, p);
      for (const ObjectBox& b : i.boxes) pack(buf, b);
    } catch (const InputError& e) {
      error = e.what();
    }
  }
  // Length < 0: rank 0 failed, and its message follows.
  long long n = error.empty() ? static_cast<long long>(buf.size()) : -static_cast<long long>(error.size());
  MPI_Bcast(&n, 1, MPI_LONG_LONG, 0, comm);
  if (n < 0) {
    error.resize(static_cast<std::size_t>(-n));
    MPI_Bcast(error.data(), static_cast<int>(-n), MPI_CHAR, 0, comm);
    throw InputError(error);
  }
  buf.resize(static_cast<std::size_t>(n));
  MPI_Bcast(buf.data(), static_cast<int>(n), MPI_CHAR, 0, comm);
  CheckpointInfo i;
  Unpack u(buf);
  for (std::int64_t* v : {&i.format, &i.step, &i.steps, &i.output_every, &i.frames, &i.ranks, &i.anchor_step, &i.vertices})
    u.get(*v);
  u.get(i.time);
  u.get(i.dt);
  u.get(i.energy0);
  u.get(i.energy_scale);
  u.get(i.fingerprint);
  u.get(i.scene_path);
  u.get(i.scene_text);
  u.get(i.output_dir);
  std::size_t no = 0;
  u.get(no);
  i.partition.resize(no);
  i.boxes.resize(no);
  for (int& p : i.partition) u.get(p);
  for (ObjectBox& b : i.boxes) u.get(b);
  return i;
}

void read_checkpoint_state(MPI_Comm comm, const std::string& path, const CheckpointInfo& info, Simulator& sim) {
  World& w = sim.world();
  if (info.vertices != w.global_vertices)
    throw InputError(path, 0, "the checkpoint has " + std::to_string(info.vertices) + " vertices, the scene " +
                                  std::to_string(w.global_vertices));
  const hid_t fapl = h5::mpio_access(comm);
  const hid_t file = H5Fopen(path.c_str(), H5F_ACC_RDONLY, fapl);
  H5Pclose(fapl);
  if (file < 0) throw RuntimeFailure("cannot open the checkpoint '" + path + "'");
  const std::vector<GidRun> runs = owned_vertex_runs(w);
  const gid_t nv = w.global_vertices;
  const std::size_t n = w.n_owned;
  Rows r;
  constexpr std::size_t na = StictionAnchor::kPerPoint;
  r.anchor_step.resize(na * n);
  r.anchor_object.resize(na * n);
  r.anchor_tri.resize(3 * na * n);
  r.anchor_bary.resize(3 * na * n);
  try {
    h5::read_rows(file, "/state/x", nv, 3, runs, w.x.data(), path);
    h5::read_rows(file, "/state/x_prev", nv, 3, runs, w.x_prev.data(), path);
    h5::read_rows(file, "/state/v", nv, 3, runs, w.v.data(), path);
    h5::read_rows(file, "/state/anchor_step", nv, na, runs, r.anchor_step.data(), path);
    h5::read_rows(file, "/state/anchor_object", nv, na, runs, r.anchor_object.data(), path);
    h5::read_rows(file, "/state/anchor_triangle", nv, 3 * na, runs, r.anchor_tri.data(), path);
    h5::read_rows(file, "/state/anchor_bary", nv, 3 * na, runs, r.anchor_bary.data(), path);
  } catch (...) {
    H5Fclose(file);
    throw;
  }
  H5Fclose(file);
  const auto nobj = static_cast<std::int32_t>(w.layout.size());
  for (std::size_t i = 0; i < na * n; ++i) {
    bool ok = r.anchor_object[i] >= -1 && r.anchor_object[i] < nobj;
    for (std::size_t c = 0; c < 3; ++c) ok = ok && r.anchor_tri[3 * i + c] >= -1 && r.anchor_tri[3 * i + c] < nv;
    if (!ok)
      throw RuntimeFailure(path + ": the friction anchor of vertex " + std::to_string(w.vertex_gid[i / na]) +
                           " names an object or vertex that does not exist");
  }
  std::vector<StictionAnchor>& anchors = sim.anchors();
  for (std::size_t i = 0; i < na * n; ++i) {
    AnchorEntry& a = anchors[i / na].entry[i % na];
    a.step = r.anchor_step[i];
    a.object = r.anchor_object[i];
    for (std::size_t c = 0; c < 3; ++c) {
      a.tri[c] = r.anchor_tri[3 * i + c];
      a.bary[c] = r.anchor_bary[3 * i + c];
    }
  }
  sim.resume(info.step, info.anchor_step);
}

}  // namespace softcontact
