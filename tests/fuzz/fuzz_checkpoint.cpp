// libFuzzer target: the checkpoint reader of --restart (src/io/checkpoint_read.hpp), run
// as load_restart and read_checkpoint_state run it, on one rank: read /run, load the
// stored scene, check the checkpoint against it, read /state and check every row.
//
// Structure-aware: the input does not hold HDF5 bytes but edits of a valid checkpoint
// (h5_model.hpp). Its first byte picks one of two small scenes; the checkpoint of that
// scene (its meshes at rest, anchors unused, format, counts and fingerprint right) is
// built as a model; the rest of the input is a list of edits: entries removed, retyped
// (integer, float, text, variable-length text), reshaped (rank 0 to 3, extents off by
// one or two, a dataset claiming 2^20..2^40 rows it does not hold), values overwritten
// (NaN, infinities, -1, 2^31, +-9.3e18, ...), extra entries, other text for the scene,
// the paths or a char dataset, the fingerprint recomputed for an edited scene, friction
// anchors set on any object and vertex. The model is then written with libhdf5 into
// memory (core driver) and the file image opened again read-only, so that the reader
// decodes the bytes as from disk. An empty input is the valid checkpoint of scene 0.
//
// Raw mode, with SOFTCONTACT_FUZZ_RAW=1 in the environment: an input that begins with
// the HDF5 signature is itself the file image (a real checkpoint, mutated byte by byte).
// libhdf5 1.10 does not survive such bytes: within about a thousand inputs it leaks or
// overflows a heap buffer inside H5Aexists (docs/reliability.md, "Bad input"), which is
// not ours to fix, so tools/fuzz.sh and the corpus use the structured mode only.
#include <fuzzer/FuzzedDataProvider.h>
#include <hdf5.h>

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

#include "fuzz_common.hpp"
#include "h5_model.hpp"
#include "io/checkpoint_read.hpp"
#include "io/h5_util.hpp"
#include "softcontact/contact.hpp"
#include "softcontact/error.hpp"
#include "softcontact/scene.hpp"

namespace {

using namespace softcontact;
using fuzz::H5Kind;

const char* const kScenes[] = {
    // Two objects: a fixed plate and a box.
    "simulation: {dt: 1.0e-3, steps: 10, output: {every: 5}}\n"
    "materials:\n  - {name: soft, model: corotational, young: 1.0e5, poisson: 0.3, density: 1000}\n"
    "objects:\n"
    "  - {name: floor, material: soft, kinematic: true,\n"
    "     primitive: {type: plate, size: [1, 1], thickness: 0.1, cells: [1, 1]}}\n"
    "  - {name: cube, material: soft, primitive: {type: box, size: [0.2, 0.2, 0.2], cells: [1, 1, 1]},\n"
    "     transform: {translate: [0, 0, 0.3]}}\n",
    // Three boxes in a row (grid instances), friction.
    "simulation: {dt: 2.0e-3, steps: 7, output: {every: 1}}\n"
    "materials:\n  - {name: a, model: stvk, young: 2.0e5, poisson: 0.25, density: 500}\n"
    "friction: {default: {static: 0.5, kinetic: 0.4}}\n"
    "objects:\n"
    "  - {name: b, material: a, primitive: {type: box, size: [0.1, 0.1, 0.1], cells: [1, 1, 1]},\n"
    "     instances: {grid: {count: [3, 1, 1], spacing: [0.3, 0, 0]}}}\n",
};
constexpr const char* kPath = "/fuzz/checkpoint_000000000005.h5";
constexpr const char* kScenePath = "/fuzz/scene.yaml";

Scene load(const std::string& text) {
  SceneLimits limits;
  limits.max_vertices = 4000;
  limits.max_tets = 4000;
  limits.max_objects = 100;
  return load_scene_from_string(text, kScenePath, limits);
}

std::vector<ObjectLayout> layout_of(const Scene& s) {
  std::vector<ObjectLayout> out;
  softcontact::gid_t v = 0;
  for (const SceneObject& o : s.objects) {
    ObjectLayout L;
    L.vertex_begin = v;
    L.vertex_count = static_cast<softcontact::gid_t>(o.mesh.num_vertices());
    v += L.vertex_count;
    out.push_back(L);
  }
  return out;
}

// The checkpoint of `scene` at step 5, every vertex at rest where the scene puts it.
fuzz::H5Model valid_checkpoint(const Scene& scene, const std::string& text) {
  std::vector<double> x, part, boxes;
  for (std::size_t k = 0; k < scene.objects.size(); ++k) {
    const TetMesh& m = scene.objects[k].mesh;
    double lo[3] = {HUGE_VAL, HUGE_VAL, HUGE_VAL}, hi[3] = {-HUGE_VAL, -HUGE_VAL, -HUGE_VAL};
    for (std::size_t i = 0; i < m.points.size(); ++i) {
      x.push_back(m.points[i]);
      lo[i % 3] = std::min(lo[i % 3], m.points[i]);
      hi[i % 3] = std::max(hi[i % 3], m.points[i]);
    }
    part.push_back(0);
    boxes.insert(boxes.end(), {lo[0], lo[1], lo[2], hi[0], hi[1], hi[2]});
  }
  const auto nv = static_cast<hsize_t>(x.size() / 3), nobj = static_cast<hsize_t>(scene.objects.size());
  constexpr hsize_t na = StictionAnchor::kPerPoint;
  std::vector<double> chars(text.begin(), text.end());
  fuzz::H5Model m;
  m.push_back(fuzz::dataset("/state", "x", H5Kind::f64, {nv, 3}, x));
  m.push_back(fuzz::dataset("/state", "x_prev", H5Kind::f64, {nv, 3}, x));
  m.push_back(fuzz::dataset("/state", "v", H5Kind::f64, {nv, 3}, std::vector<double>(3 * nv, 0.0)));
  m.push_back(fuzz::dataset("/state", "anchor_step", H5Kind::i64, {nv, na}, std::vector<double>(na * nv, -1.0)));
  m.push_back(fuzz::dataset("/state", "anchor_object", H5Kind::i32, {nv, na}, std::vector<double>(na * nv, -1.0)));
  m.push_back(fuzz::dataset("/state", "anchor_triangle", H5Kind::i64, {nv, 3 * na}, std::vector<double>(3 * na * nv, -1.0)));
  m.push_back(fuzz::dataset("/state", "anchor_bary", H5Kind::f64, {nv, 3 * na}, std::vector<double>(3 * na * nv, 0.0)));
  m.push_back(fuzz::dataset("/run", "partition", H5Kind::i32, {nobj}, part));
  m.push_back(fuzz::dataset("/run", "boxes", H5Kind::f64, {nobj, 6}, boxes));
  m.push_back(fuzz::dataset("/run", "split_hosts", H5Kind::i32, {1}, {0.0}));  // no split object on 1 rank
  fuzz::H5Entry scene_text = fuzz::dataset("/run", "scene", H5Kind::u8, {static_cast<hsize_t>(text.size())}, chars);
  scene_text.text = text;
  m.push_back(scene_text);
  const std::int64_t steps = total_steps(scene.sim), every = steps_between_frames(scene.sim);
  m.push_back(fuzz::scalar_attribute("/run", "format", H5Kind::i64, static_cast<double>(checkpoint::kFormat)));
  m.push_back(fuzz::scalar_attribute("/run", "step", H5Kind::i64, 5));
  m.push_back(fuzz::scalar_attribute("/run", "time", H5Kind::f64, 5 * scene.sim.dt));
  m.push_back(fuzz::scalar_attribute("/run", "dt", H5Kind::f64, scene.sim.dt));
  m.push_back(fuzz::scalar_attribute("/run", "steps", H5Kind::i64, static_cast<double>(steps)));
  m.push_back(fuzz::scalar_attribute("/run", "output_every", H5Kind::i64, static_cast<double>(every)));
  m.push_back(fuzz::scalar_attribute("/run", "frames", H5Kind::i64, 2));
  m.push_back(fuzz::scalar_attribute("/run", "ranks", H5Kind::i64, 1));
  m.push_back(fuzz::scalar_attribute("/run", "anchor_step", H5Kind::i64, 5));
  m.push_back(fuzz::scalar_attribute("/run", "vertices", H5Kind::i64, static_cast<double>(nv)));
  fuzz::H5Entry fp = fuzz::scalar_attribute("/run", "fingerprint", H5Kind::i64, 0);
  fp.ints = {static_cast<std::int64_t>(scene_fingerprint(scene))};
  m.push_back(fp);
  m.push_back(fuzz::scalar_attribute("/run", "energy0", H5Kind::f64, 1.5));
  m.push_back(fuzz::scalar_attribute("/run", "energy_scale", H5Kind::f64, 10));
  m.push_back(fuzz::text_attribute("/run", "scene_path", kScenePath));
  m.push_back(fuzz::text_attribute("/run", "output_dir", "/fuzz/out"));
  return m;
}

fuzz::H5Entry* find(fuzz::H5Model& m, const std::string& group, const std::string& name) {
  for (fuzz::H5Entry& e : m)
    if (e.group == group && e.name == name) return &e;
  return nullptr;
}

// Edits that need to know the checkpoint: anchors, the scene text and its fingerprint.
void edit(fuzz::H5Model& m, FuzzedDataProvider& in, const Scene& scene, const std::vector<ObjectLayout>& layout) {
  switch (in.ConsumeIntegralInRange<int>(0, 3)) {
    case 0: {  // a friction anchor: any object, three vertices of it give or take a few
      fuzz::H5Entry* obj = find(m, "/state", "anchor_object");
      fuzz::H5Entry* tri = find(m, "/state", "anchor_triangle");
      fuzz::H5Entry* bary = find(m, "/state", "anchor_bary");
      if (!obj || !tri || !bary || obj->values.empty()) return;
      const std::size_t e = in.ConsumeIntegralInRange<std::size_t>(0, obj->values.size() - 1);
      const int o = in.ConsumeIntegralInRange<int>(-2, static_cast<int>(layout.size()));
      obj->values[e] = o;
      if (e < obj->ints.size()) obj->ints[e] = o;
      for (std::size_t c = 0; c < 3; ++c) {
        const std::size_t k = 3 * e + c;
        const softcontact::gid_t base = o >= 0 && o < static_cast<int>(layout.size()) ? layout[static_cast<std::size_t>(o)].vertex_begin : 0;
        const softcontact::gid_t count = o >= 0 && o < static_cast<int>(layout.size()) ? layout[static_cast<std::size_t>(o)].vertex_count : 1;
        const softcontact::gid_t t = base + in.ConsumeIntegralInRange<softcontact::gid_t>(-1, count);
        if (k < tri->values.size()) tri->values[k] = static_cast<double>(t);
        if (k < tri->ints.size()) tri->ints[k] = t;
        if (k < bary->values.size()) bary->values[k] = in.ConsumeBool() ? 1.0 / 3 : fuzz::special_value(in);
      }
      break;
    }
    case 1: {  // the other scene's text (the fingerprint no longer matches)
      fuzz::H5Entry* text = find(m, "/run", "scene");
      if (!text) return;
      text->text = kScenes[in.ConsumeIntegralInRange<int>(0, 1)];
      text->dims = {static_cast<hsize_t>(text->text.size())};
      text->values.assign(text->text.size(), 0.0);
      break;
    }
    case 2: {  // the fingerprint of whatever scene text is stored now
      fuzz::H5Entry* text = find(m, "/run", "scene");
      fuzz::H5Entry* fp = find(m, "/run", "fingerprint");
      if (!text || !fp) return;
      try {
        const Scene other = load(text->text);
        fp->ints = {static_cast<std::int64_t>(scene_fingerprint(other))};
        fp->values = {0};
      } catch (const InputError&) {
      }
      break;
    }
    default: {  // the scene text cut short
      fuzz::H5Entry* text = find(m, "/run", "scene");
      if (!text || text->text.empty()) return;
      text->text.resize(in.ConsumeIntegralInRange<std::size_t>(0, text->text.size() - 1));
      break;
    }
  }
  (void)scene;
}

// Opens a file image read-only in memory.
hid_t open_image(const void* data, std::size_t size) {
  const hid_t fapl = H5Pcreate(H5P_FILE_ACCESS);
  H5Pset_fapl_core(fapl, 1 << 16, 0);
  H5Pset_file_image(fapl, const_cast<void*>(data), size);
  const hid_t file = H5Fopen(kPath, H5F_ACC_RDONLY, fapl);
  H5Pclose(fapl);
  return file;
}

// What --restart does with an opened checkpoint, on one rank; throws InputError.
void restart_from(hid_t file) {
  const CheckpointInfo info = checkpoint::read_run(file, kPath);
  const Scene scene = load(info.scene_text);
  checkpoint::check_against_scene(info, scene, kPath, scene.object_digests());
  const std::vector<ObjectLayout> layout = layout_of(scene);
  const auto nv = static_cast<softcontact::gid_t>(info.vertices);
  checkpoint::StateRows rows;
  checkpoint::read_state(file, kPath, nv, h5::all_rows(nv), static_cast<std::size_t>(nv), rows, false);
  std::vector<softcontact::gid_t> gid(static_cast<std::size_t>(nv));
  for (softcontact::gid_t i = 0; i < nv; ++i) gid[static_cast<std::size_t>(i)] = i;
  const std::int64_t problem = checkpoint::first_state_problem(rows, gid, layout);
  if (problem >= 0) throw InputError(kPath, 0, checkpoint::state_problem(problem));

  // Accepted: what the simulator relies on.
  fuzz::require(info.partition.size() == scene.objects.size() && info.boxes.size() == scene.objects.size(),
                "one partition entry and one box per object");
  fuzz::require(info.step >= 0 && info.steps >= 1 && info.output_every >= 1 && info.anchor_step >= 0 &&
                    std::isfinite(info.dt) && info.dt > 0,
                "a run description in range");
  for (const Box& b : info.boxes)
    for (int c = 0; c < 3; ++c) fuzz::require(std::isfinite(b.lo[c]) && std::isfinite(b.hi[c]) && b.lo[c] <= b.hi[c], "finite boxes");
  for (const std::vector<int>& h : info.split_hosts) {
    fuzz::require(!h.empty(), "a split object of at least one part");
    for (int r : h) fuzz::require(r >= 0 && r < info.ranks, "split hosts among the run's ranks");
  }
  for (double v : rows.x) fuzz::require(std::isfinite(v), "finite positions");
  constexpr std::size_t na = StictionAnchor::kPerPoint;
  for (std::size_t e = 0; e < na * static_cast<std::size_t>(nv); ++e) {
    const std::int32_t o = rows.anchor_object[e];
    fuzz::require(o >= -1 && o < static_cast<std::int32_t>(layout.size()), "anchor object in range");
    if (o < 0) continue;
    const ObjectLayout& L = layout[static_cast<std::size_t>(o)];
    for (std::size_t c = 0; c < 3; ++c) {
      const softcontact::gid_t t = rows.anchor_triangle[3 * e + c];
      fuzz::require(t >= L.vertex_begin && t < L.vertex_begin + L.vertex_count, "anchor vertices in their object");
    }
  }
}

void run_image(const void* data, std::size_t size) {
  const h5::QuietErrors quiet;
  const hid_t file = open_image(data, size);
  if (file < 0) return;  // not HDF5 to libhdf5: read_run_file's first refusal, nothing of ours ran
  softcontact::fuzz::expect_accept_or_input_error([&] {
    try {
      restart_from(file);
    } catch (...) {
      H5Fclose(file);
      throw;
    }
  });
  H5Fclose(file);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static const bool raw = std::getenv("SOFTCONTACT_FUZZ_RAW") != nullptr;
  if (raw && size >= 8 && std::memcmp(data, "\x89HDF\r\n\x1a\n", 8) == 0) {
    run_image(data, size);
    return 0;
  }
  FuzzedDataProvider in(data, size);
  const int which = in.ConsumeIntegralInRange<int>(0, 1);
  const std::string text = kScenes[which];
  static const Scene scenes[] = {load(kScenes[0]), load(kScenes[1])};
  const Scene& scene = scenes[which];
  const std::vector<ObjectLayout> layout = layout_of(scene);
  fuzz::H5Model m = valid_checkpoint(scene, text);
  static const std::vector<std::string> groups = {"/", "/run", "/state"};
  static const std::vector<std::string> names = {"format", "step", "x", "partition", "boxes", "scene", "run", "state",
                                                 "fingerprint", "scene_path", "split_hosts", "extra"};
  for (int k = 0; k < 16 && in.remaining_bytes() > 0; ++k) {
    if (in.ConsumeBool()) fuzz::mutate(m, in, groups, names);
    else edit(m, in, scene, layout);
  }

  // Written into memory, then opened again from the image as a file on disk would be.
  const h5::QuietErrors quiet;
  const hid_t fapl = H5Pcreate(H5P_FILE_ACCESS);
  H5Pset_fapl_core(fapl, 1 << 16, 0);
  const hid_t file = H5Fcreate(kPath, H5F_ACC_TRUNC, H5P_DEFAULT, fapl);
  H5Pclose(fapl);
  if (file < 0) std::abort();
  fuzz::write_model(file, m);
  H5Fflush(file, H5F_SCOPE_GLOBAL);
  const ssize_t bytes = H5Fget_file_image(file, nullptr, 0);
  std::vector<char> image(bytes > 0 ? static_cast<std::size_t>(bytes) : 0);
  if (bytes > 0) H5Fget_file_image(file, image.data(), image.size());
  H5Fclose(file);
  if (image.empty()) std::abort();
  run_image(image.data(), image.size());
  return 0;
}
