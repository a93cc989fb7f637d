#include "softcontact/checkpoint.hpp"

#include <algorithm>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <limits>

#include "checkpoint_read.hpp"
#include "h5_util.hpp"
#include "softcontact/error.hpp"
#include "softcontact/fault.hpp"
#include "softcontact/mpi_util.hpp"

namespace softcontact {

namespace fs = std::filesystem;

namespace {

using checkpoint::kFormat;
constexpr const char* kDir = "checkpoints";
constexpr const char* kPrefix = "checkpoint_";

// The per-vertex state as written: one array per field, packed in owned-run order
// (which is local order: owned vertices are stored by ascending global id per object).
struct Rows {
  std::vector<std::int64_t> anchor_step, anchor_tri;
  std::vector<std::int32_t> anchor_object;
  std::vector<double> anchor_bary;
};

}  // namespace

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

void write_checkpoint(MPI_Comm comm, const std::string& path, const World& w, const StepState& state,
                      CheckpointInfo info) {
  const int rank = comm_rank(comm), size = comm_size(comm);
  info.format = kFormat;
  info.step = state.step;
  info.ranks = size;
  info.anchor_step = state.anchor_step;
  info.vertices = w.global_vertices;
  if (rank == 0) {
    std::error_code ec;
    fs::create_directories(fs::path(path).parent_path(), ec);
  }
  MPI_Barrier(comm);

  const std::string tmp = path + ".tmp";
  const hid_t file = h5::create_parallel(comm, tmp, "the checkpoint");
  const hid_t group = h5::check_id(H5Gcreate2(file, "/state", H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT), "create /state");
  const std::vector<GidRun> runs = owned_vertex_runs(w);
  const gid_t nv = w.global_vertices;
  h5::write_rows(group, "x", nv, 3, runs, state.x.data());
  if (fault::hit(fault::Point::checkpoint_write, info.step))
    throw RuntimeFailure(fault::io_error(fault::Point::checkpoint_write, tmp));
  h5::write_rows(group, "x_prev", nv, 3, runs, state.x_prev.data());
  h5::write_rows(group, "v", nv, 3, runs, state.v.data());
  const std::vector<StictionAnchor>& anchors = state.anchors;
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
  h5::write_rows(group, "anchor_step", nv, na, runs, r.anchor_step.data());
  h5::write_rows(group, "anchor_object", nv, na, runs, r.anchor_object.data());
  h5::write_rows(group, "anchor_triangle", nv, 3 * na, runs, r.anchor_tri.data());
  h5::write_rows(group, "anchor_bary", nv, 3 * na, runs, r.anchor_bary.data());
  H5Gclose(group);

  // The run description: written by rank 0 (every rank holds the same), independent I/O.
  const hid_t run = h5::check_id(H5Gcreate2(file, "/run", H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT), "create /run");
  const auto nobj = static_cast<gid_t>(info.partition.size());
  const std::vector<GidRun> mine = rank == 0 ? h5::all_rows(nobj) : std::vector<GidRun>{};
  std::vector<std::int32_t> part(info.partition.begin(), info.partition.end());
  std::vector<double> boxes;
  for (const Box& b : info.boxes)
    boxes.insert(boxes.end(), {b.lo[0], b.lo[1], b.lo[2], b.hi[0], b.hi[1], b.hi[2]});
  h5::write_rows(run, "partition", nobj, 1, mine, part.data());
  h5::write_rows(run, "boxes", nobj, 6, mine, boxes.data());
  std::vector<std::int32_t> hosts{static_cast<std::int32_t>(info.split_hosts.size())};
  for (const std::vector<int>& h : info.split_hosts) {
    hosts.push_back(static_cast<std::int32_t>(h.size()));
    hosts.insert(hosts.end(), h.begin(), h.end());
  }
  const auto nhosts = static_cast<gid_t>(hosts.size());
  h5::write_rows(run, "split_hosts", nhosts, 1, rank == 0 ? h5::all_rows(nhosts) : std::vector<GidRun>{},
                 hosts.data());
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

}  // namespace

CheckpointInfo read_checkpoint_info(MPI_Comm comm, const std::string& path) {
  const int rank = comm_rank(comm);
  std::vector<char> buf;
  std::string error;
  if (rank == 0) {
    try {
      const CheckpointInfo i = checkpoint::read_run_file(path);
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
      for (const Box& b : i.boxes) pack(buf, b);
      pack(buf, i.split_hosts.size());
      for (const std::vector<int>& h : i.split_hosts) {
        pack(buf, h.size());
        for (int r : h) pack(buf, r);
      }
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
  for (Box& b : i.boxes) u.get(b);
  std::size_t nsplit = 0;
  u.get(nsplit);
  i.split_hosts.resize(nsplit);
  for (std::vector<int>& h : i.split_hosts) {
    std::size_t parts = 0;
    u.get(parts);
    h.resize(parts);
    for (int& r : h) u.get(r);
  }
  return i;
}

void read_checkpoint_state(MPI_Comm comm, const std::string& path, const CheckpointInfo& info, const World& w,
                           StepState& state) {
  if (info.vertices != w.global_vertices)
    throw InputError(path, 0, "the checkpoint has " + std::to_string(info.vertices) + " vertices, the scene " +
                                  std::to_string(w.global_vertices));
  const hid_t fapl = h5::mpio_access(comm);
  const hid_t file = H5Fopen(path.c_str(), H5F_ACC_RDONLY, fapl);
  H5Pclose(fapl);
  if (file < 0) throw RuntimeFailure("cannot open the checkpoint '" + path + "'");
  const std::size_t n = w.n_owned;
  checkpoint::StateRows r;
  try {
    // Every rank reads the same datasets' shapes: a problem there is everyone's.
    checkpoint::read_state(file, path, w.global_vertices, owned_vertex_runs(w), n, r, true);
  } catch (...) {
    H5Fclose(file);
    throw;
  }
  H5Fclose(file);
  // Values are checked per rank; the first problem by vertex id is everyone's, so every
  // rank throws the same InputError together (none is left waiting in a collective).
  const std::vector<gid_t> gid(w.vertex_gid.begin(), w.vertex_gid.begin() + static_cast<std::ptrdiff_t>(n));
  std::int64_t mine = checkpoint::first_state_problem(r, gid, w.layout);
  if (mine < 0) mine = std::numeric_limits<std::int64_t>::max();
  std::int64_t first = mine;
  MPI_Allreduce(&mine, &first, 1, MPI_INT64_T, MPI_MIN, comm);
  if (first != std::numeric_limits<std::int64_t>::max()) throw InputError(path, 0, checkpoint::state_problem(first));
  state.step = info.step;
  state.anchor_step = info.anchor_step;
  state.x = std::move(r.x);
  state.x_prev = std::move(r.x_prev);
  state.v = std::move(r.v);
  constexpr std::size_t na = StictionAnchor::kPerPoint;
  std::vector<StictionAnchor>& anchors = state.anchors;
  anchors.assign(n, StictionAnchor{});
  for (std::size_t i = 0; i < na * n; ++i) {
    AnchorEntry& a = anchors[i / na].entry[i % na];
    a.step = r.anchor_step[i];
    a.object = r.anchor_object[i];
    for (std::size_t c = 0; c < 3; ++c) {
      a.tri[c] = r.anchor_triangle[3 * i + c];
      a.bary[c] = r.anchor_bary[3 * i + c];
    }
  }
}

}  // namespace softcontact
