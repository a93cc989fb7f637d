#include "checkpoint_read.hpp"

#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>

#include "h5_util.hpp"
#include "softcontact/contact.hpp"
#include "softcontact/error.hpp"

namespace softcontact {

namespace {
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

/// scene_fingerprint with the time step `dt` in place of the scene's.
std::uint64_t fingerprint_with_dt(const Scene& scene, double dt, const std::vector<std::uint64_t>& digests) {
  Fingerprint f;
  const Simulation& s = scene.sim;
  f.value(dt);
  f.value(s.gravity);
  f.value(s.integrator);
  f.value(s.self_collisions);
  f.value(s.edge_contacts);
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
  if (digests.size() != scene.objects.size())
    throw std::logic_error("scene_fingerprint: " + std::to_string(digests.size()) + " digests for " +
                           std::to_string(scene.objects.size()) + " objects");
  for (std::size_t k = 0; k < scene.objects.size(); ++k) {
    const SceneObject& o = scene.objects[k];
    f.value(o.material);
    f.value(o.kinematic());
    f.value(o.velocity());
    f.value(digests[k]);  // the mesh: its points and tets (mesh_digest)
    f.value(o.fixed().size());
    for (const Box& b : o.fixed()) {
      f.value(b.lo);
      f.value(b.hi);
    }
    f.value(o.motion().velocity);
    f.value(o.motion().start);
    f.value(o.motion().stop);
  }
  return f.get();
}

}  // namespace

std::uint64_t scene_fingerprint(const Scene& scene, const std::vector<std::uint64_t>& digests) {
  return fingerprint_with_dt(scene, scene.sim.dt, digests);
}

std::uint64_t scene_fingerprint(const Scene& scene) { return scene_fingerprint(scene, scene.object_digests()); }

namespace checkpoint {

namespace {

[[noreturn]] void not_a_checkpoint(const std::string& path, const std::string& why) {
  throw InputError(path, 0, "not a readable softcontact checkpoint: " + why);
}

// The rows of dataset `name` in `run`, refused when the dataset would hold more bytes
// than the whole file: a damaged extent must not make us allocate what the file cannot
// hold (our checkpoints are never compressed).
gid_t rows_within_file(hid_t run, const char* name, std::size_t bytes_per_row, hsize_t file_bytes) {
  const gid_t rows = h5::rows_of(run, name);
  if (static_cast<hsize_t>(rows) > file_bytes / bytes_per_row)
    throw RuntimeFailure(std::string("dataset '") + name + "' claims " + std::to_string(rows) + " rows, more than the " +
                         std::to_string(file_bytes) + "-byte file holds");
  return rows;
}

CheckpointInfo read_run_checked(hid_t file, const std::string& path) {
  CheckpointInfo info;
  hsize_t file_bytes = 0;
  if (H5Fget_filesize(file, &file_bytes) < 0) throw RuntimeFailure("HDF5 cannot tell its size");
  const hid_t run = H5Gopen2(file, "/run", H5P_DEFAULT);
  if (run < 0) throw RuntimeFailure("group /run is missing");
  try {
    info.format = h5::read_attribute<std::int64_t>(run, "format", path);
    if (info.format != kFormat)
      throw RuntimeFailure("checkpoint format " + std::to_string(info.format) + ", this build reads format " +
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
    // anchor_step >= 0: the contact response subtracts a grace period from it.
    if (info.step < 0 || info.steps < 1 || info.output_every < 1 || info.frames < 0 || info.ranks < 1 ||
        info.anchor_step < 0 || info.vertices < 0 || !(info.dt > 0) || !std::isfinite(info.dt) ||
        !std::isfinite(info.time) || !std::isfinite(info.energy0) || !std::isfinite(info.energy_scale) ||
        info.scene_path.empty() || info.output_dir.empty())
      throw RuntimeFailure("its run description is out of range");
    const gid_t n = rows_within_file(run, "partition", sizeof(std::int32_t), file_bytes);
    std::vector<std::int32_t> part(static_cast<std::size_t>(n));
    std::vector<double> boxes(6 * static_cast<std::size_t>(n));
    h5::read_rows(run, "partition", n, 1, h5::all_rows(n), part.data(), path, false);
    h5::read_rows(run, "boxes", n, 6, h5::all_rows(n), boxes.data(), path, false);
    info.partition.assign(part.begin(), part.end());
    for (gid_t k = 0; k < n; ++k) {
      const double* b = &boxes[6 * static_cast<std::size_t>(k)];
      for (int c = 0; c < 3; ++c)
        if (!std::isfinite(b[c]) || !std::isfinite(b[3 + c]) || b[c] > b[3 + c])
          throw RuntimeFailure("the box of object " + std::to_string(k) + " in /run/boxes is not finite or inside out");
      info.boxes.push_back(Box{{b[0], b[1], b[2]}, {b[3], b[4], b[5]}});
    }
    // Optional (checkpoints from before 2026-11-29 have none): count, then per split
    // object its parts and their ranks, each a rank of the run that wrote it.
    const gid_t nh = rows_within_file(run, "split_hosts", sizeof(std::int32_t), file_bytes);
    if (nh > 0) {
      std::vector<std::int32_t> h(static_cast<std::size_t>(nh));
      h5::read_rows(run, "split_hosts", nh, 1, h5::all_rows(nh), h.data(), path, false);
      std::size_t at = 1;
      auto bad = [&](const std::string& why) { throw RuntimeFailure("/run/split_hosts " + why); };
      if (h[0] < 0 || static_cast<gid_t>(h[0]) >= nh) bad("names " + std::to_string(h[0]) + " split objects");
      info.split_hosts.resize(static_cast<std::size_t>(h[0]));
      for (std::vector<int>& list : info.split_hosts) {
        if (at >= h.size() || h[at] < 1 || static_cast<std::size_t>(h[at]) > h.size() - at - 1)
          bad("is cut short or names a split object of no parts");
        list.assign(h.begin() + static_cast<std::ptrdiff_t>(at) + 1, h.begin() + static_cast<std::ptrdiff_t>(at) + 1 + h[at]);
        at += 1 + static_cast<std::size_t>(h[at]);
        for (int r : list)
          if (r < 0 || r >= info.ranks) bad("names rank " + std::to_string(r) + " of a run on " + std::to_string(info.ranks));
      }
      if (at != h.size()) bad("holds " + std::to_string(h.size() - at) + " values past its last split object");
    }
    const gid_t chars = rows_within_file(run, "scene", 1, file_bytes);
    info.scene_text.assign(static_cast<std::size_t>(chars), '\0');
    h5::read_rows(run, "scene", chars, 1, h5::all_rows(chars), info.scene_text.data(), path, false);
  } catch (...) {
    H5Gclose(run);
    throw;
  }
  H5Gclose(run);
  return info;
}

}  // namespace

CheckpointInfo read_run(hid_t file, const std::string& path) {
  const h5::QuietErrors quiet;
  try {
    return read_run_checked(file, path);
  } catch (const RuntimeFailure& e) {
    // The h5 helpers name the file: say it once.
    std::string why = e.what();
    if (why.rfind(path + ": ", 0) == 0) why = why.substr(path.size() + 2);
    not_a_checkpoint(path, why);
  }
}

CheckpointInfo read_run_file(const std::string& path) {
  const h5::QuietErrors quiet;
  const hid_t file = H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  if (file < 0) not_a_checkpoint(path, "HDF5 cannot open it (damaged, truncated, or not HDF5)");
  try {
    CheckpointInfo info = read_run(file, path);
    H5Fclose(file);
    return info;
  } catch (...) {
    H5Fclose(file);
    throw;
  }
}

void check_against_scene(const CheckpointInfo& info, const Scene& scene, const std::string& path,
                         const std::vector<std::uint64_t>& digests) {
  if (scene_fingerprint(scene, digests) != info.fingerprint) {
    // Everything but the step the same: the stable step of 'dt: auto' is computed
    // differently by this build than by the one that wrote the checkpoint.
    if (info.dt != scene.sim.dt && fingerprint_with_dt(scene, info.dt, digests) == info.fingerprint) {
      std::ostringstream s;
      s.precision(17);
      s << "the scene it continues ('" << info.scene_path << "') is unchanged, but its time step now comes out as dt = "
        << scene.sim.dt << " s against dt = " << info.dt
        << " s when the checkpoint was written (a softcontact version that computes the stable step of 'dt: auto' "
           "differently), so the run cannot continue bitwise; run the scene again from its start";
      throw InputError(path, 0, s.str());
    }
    throw InputError(path, 0,
                     "the scene it continues ('" + info.scene_path +
                         "', as stored in the checkpoint) now reads differently: a mesh file it uses has changed or "
                         "moved since the checkpoint was written (or the checkpoint was written by a softcontact "
                         "from before 2026-11-28, whose fingerprint hashed the meshes differently), so the run "
                         "cannot continue bitwise");
  }
  // The fingerprint covers both counts; a damaged file may still disagree with itself.
  const auto objects = scene.objects.size();
  std::int64_t vertices = 0;
  vertices = static_cast<std::int64_t>(scene.num_vertices());
  if (info.partition.size() != objects || info.boxes.size() != objects)
    throw InputError(path, 0,
                     "not a readable softcontact checkpoint: /run/partition has " + std::to_string(info.partition.size()) +
                         " rows, the scene " + std::to_string(objects) + " objects");
  if (info.vertices != vertices)
    throw InputError(path, 0,
                     "not a readable softcontact checkpoint: it has " + std::to_string(info.vertices) +
                         " vertices, the scene it stores " + std::to_string(vertices));
}

void read_state(hid_t file, const std::string& path, gid_t vertices, const std::vector<GidRun>& runs, std::size_t n,
                StateRows& r, bool collective) {
  constexpr std::size_t na = StictionAnchor::kPerPoint;
  r.x.resize(3 * n);
  r.x_prev.resize(3 * n);
  r.v.resize(3 * n);
  r.anchor_step.resize(na * n);
  r.anchor_object.resize(na * n);
  r.anchor_triangle.resize(3 * na * n);
  r.anchor_bary.resize(3 * na * n);
  const h5::QuietErrors quiet;
  try {
    h5::read_rows(file, "/state/x", vertices, 3, runs, r.x.data(), path, collective);
    h5::read_rows(file, "/state/x_prev", vertices, 3, runs, r.x_prev.data(), path, collective);
    h5::read_rows(file, "/state/v", vertices, 3, runs, r.v.data(), path, collective);
    h5::read_rows(file, "/state/anchor_step", vertices, na, runs, r.anchor_step.data(), path, collective);
    h5::read_rows(file, "/state/anchor_object", vertices, na, runs, r.anchor_object.data(), path, collective);
    h5::read_rows(file, "/state/anchor_triangle", vertices, 3 * na, runs, r.anchor_triangle.data(), path, collective);
    h5::read_rows(file, "/state/anchor_bary", vertices, 3 * na, runs, r.anchor_bary.data(), path, collective);
  } catch (const RuntimeFailure& e) {
    std::string why = e.what();
    if (why.rfind(path + ": ", 0) == 0) why = why.substr(path.size() + 2);
    not_a_checkpoint(path, why);
  }
}

namespace {
const char* const kProblems[] = {
    "a position (/state/x) that is not finite",
    "a previous position (/state/x_prev) that is not finite",
    "a velocity (/state/v) that is not finite",
    "a friction anchor naming an object that does not exist (/state/anchor_object)",
    "a friction anchor on vertices outside the object it names (/state/anchor_triangle)",
    "a friction anchor with weights that are not finite (/state/anchor_bary)",
};
constexpr std::int64_t kKinds = 8;
}  // namespace

std::int64_t first_state_problem(const StateRows& r, const std::vector<gid_t>& gid, const std::vector<ObjectLayout>& layout) {
  constexpr std::size_t na = StictionAnchor::kPerPoint;
  const auto finite3 = [](const std::vector<double>& a, std::size_t i) {
    return std::isfinite(a[3 * i]) && std::isfinite(a[3 * i + 1]) && std::isfinite(a[3 * i + 2]);
  };
  const auto nobj = static_cast<std::int64_t>(layout.size());
  std::int64_t first = -1;
  for (std::size_t i = 0; i < gid.size(); ++i) {
    int what = -1;
    if (!finite3(r.x, i)) what = 0;
    else if (!finite3(r.x_prev, i)) what = 1;
    else if (!finite3(r.v, i)) what = 2;
    for (std::size_t e = na * i; what < 0 && e < na * (i + 1); ++e) {
      const std::int32_t o = r.anchor_object[e];
      if (o < -1 || o >= nobj) {
        what = 3;
        break;
      }
      if (o == -1) continue;  // an unused entry: its other fields are never read
      const ObjectLayout& L = layout[static_cast<std::size_t>(o)];
      for (std::size_t c = 0; c < 3; ++c) {
        const gid_t t = r.anchor_triangle[3 * e + c];
        if (t < L.vertex_begin || t - L.vertex_begin >= L.vertex_count) what = 4;
        else if (!std::isfinite(r.anchor_bary[3 * e + c])) what = 5;
        if (what >= 0) break;
      }
    }
    if (what >= 0) {
      const std::int64_t key = kKinds * gid[i] + what;
      if (first < 0 || key < first) first = key;
    }
  }
  return first;
}

std::string state_problem(std::int64_t key) {
  return "not a readable softcontact checkpoint: vertex " + std::to_string(key / kKinds) + " has " +
         kProblems[key % kKinds];
}

}  // namespace checkpoint
}  // namespace softcontact
