// libFuzzer target: continuing a run's output directory (restart): the frame-resume
// reader frames::resume_frames (src/io/frame_files.hpp), then the index and XDMF
// rewritten from what it kept, as FrameWriter does on rank 0, and diagnostics.csv cut
// back to the checkpoint step (DiagnosticsCsv::resume).
//
// Structure-aware, as fuzz_checkpoint: the input edits a valid output directory of a
// 5-vertex, 2-tet mesh with up to 6 frames (steps 0, 10, 20, ...) written by the rules
// of FrameWriter (h5_model.hpp): mesh.h5 and each frame file are models whose entries
// the input removes, retypes, reshapes and overwrites (step and time attributes NaN,
// negative or out of order, the 'fields' list with other text, datasets of other
// shapes); the input also picks the checkpoint step, leaves frames out, and adds
// stray files to frames/ (temporaries, names of 19 or more digits, files that are not
// HDF5). The directory is built in a private folder under /dev/shm (else /tmp), one per
// input, removed after it. An empty input is a valid directory of 3 frames continued at step 20.
#include <fuzzer/FuzzedDataProvider.h>
#include <hdf5.h>
#include <unistd.h>

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "fuzz_common.hpp"
#include "h5_model.hpp"
#include "io/frame_files.hpp"
#include "io/h5_util.hpp"
#include "softcontact/diagnostics.hpp"
#include "softcontact/error.hpp"

namespace {

namespace fs = std::filesystem;
using namespace softcontact;
using fuzz::H5Kind;

constexpr softcontact::gid_t kVertices = 5, kTets = 2;

fuzz::H5Model mesh_model() {
  fuzz::H5Model m;
  m.push_back(fuzz::dataset("/mesh", "points", H5Kind::f64, {kVertices, 3}, std::vector<double>(3 * kVertices, 0.5)));
  m.push_back(fuzz::dataset("/mesh", "tets", H5Kind::i64, {kTets, 4}, {0, 1, 2, 3, 1, 2, 3, 4}));
  m.push_back(fuzz::dataset("/mesh", "vertex_object", H5Kind::i32, {kVertices}, std::vector<double>(kVertices, 0.0)));
  return m;
}

fuzz::H5Model frame_model(std::int64_t k) {
  fuzz::H5Model m;
  m.push_back(fuzz::scalar_attribute("/", "step", H5Kind::i64, static_cast<double>(10 * k)));
  m.push_back(fuzz::scalar_attribute("/", "time", H5Kind::f64, 0.01 * static_cast<double>(k)));
  m.push_back(fuzz::text_attribute("/", "fields", "velocities:velocity:3\ncontact_forces:contact_force:3\n"));
  m.push_back(fuzz::dataset("/", "positions", H5Kind::f64, {kVertices, 3}, std::vector<double>(3 * kVertices, 0.5)));
  m.push_back(fuzz::dataset("/", "velocities", H5Kind::f64, {kVertices, 3}, std::vector<double>(3 * kVertices, 0.0)));
  m.push_back(fuzz::dataset("/", "contact_forces", H5Kind::f64, {kVertices, 3}, std::vector<double>(3 * kVertices, 0.0)));
  m.push_back(fuzz::dataset("/", "owner_rank", H5Kind::i32, {kVertices}, std::vector<double>(kVertices, 0.0)));
  return m;
}

void write_file(const fs::path& p, const fuzz::H5Model& m) {
  const hid_t f = H5Fcreate(p.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT);
  if (f < 0) std::abort();
  fuzz::write_model(f, m);
  H5Fclose(f);
}

// A fresh private folder per input, removed after it (libFuzzer ends the process without
// running static destructors, so nothing is kept between inputs).
struct WorkDir {
  fs::path path;
  WorkDir() {
    const fs::path base = fs::is_directory("/dev/shm") ? "/dev/shm" : fs::temp_directory_path();
    std::string tmpl = (base / "softcontact_fuzz_frames_XXXXXX").string();
    if (!mkdtemp(tmpl.data())) std::abort();
    path = tmpl;
  }
  ~WorkDir() {
    std::error_code ec;
    fs::remove_all(path, ec);
  }
};

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  FuzzedDataProvider in(data, size);
  const WorkDir work;
  const fs::path dir = work.path / "run";
  fs::create_directories(dir / frames::kFramesDir);

  const int nframes = size == 0 ? 3 : in.ConsumeIntegralInRange<int>(0, 6);
  const std::int64_t last_step = size == 0 ? 20 : in.ConsumeIntegralInRange<std::int64_t>(-1, 70);
  fuzz::H5Model mesh = mesh_model();
  std::vector<fuzz::H5Model> frame(static_cast<std::size_t>(nframes));
  for (int k = 0; k < nframes; ++k) frame[static_cast<std::size_t>(k)] = frame_model(k);
  static const std::vector<std::string> groups = {"/", "/mesh"};
  static const std::vector<std::string> names = {"step", "time", "fields", "positions", "owner_rank", "velocities",
                                                 "points", "tets", "mesh", "extra"};
  std::vector<std::pair<std::string, std::string>> stray;  // (name in frames/, content)
  std::vector<bool> skip(static_cast<std::size_t>(nframes), false);
  bool no_mesh = false;
  for (int e = 0; e < 12 && in.remaining_bytes() > 0; ++e) {
    switch (in.ConsumeIntegralInRange<int>(0, 4)) {
      case 0:
        fuzz::mutate(mesh, in, groups, names);
        break;
      case 1:
        if (nframes > 0) fuzz::mutate(frame[in.ConsumeIntegralInRange<std::size_t>(0, nframes - 1)], in, groups, names);
        break;
      case 2: {  // a stray file: a temporary, a long number, anything
        static const char* const kNames[] = {"000001.h5.tmp", "000009.h5", "99999999999999999999.h5",
                                             "123456789012345678.h5", "notes.txt", "000002"};
        stray.emplace_back(kNames[in.ConsumeIntegralInRange<int>(0, 5)], in.ConsumeRandomLengthString(64));
        break;
      }
      case 3:
        if (nframes > 0) skip[in.ConsumeIntegralInRange<std::size_t>(0, nframes - 1)] = true;
        break;
      default:
        no_mesh = in.ConsumeBool();
        break;
    }
  }

  // diagnostics.csv: the header and a row per step 0..60, then cut or spliced with text
  // from the input (a torn last row, garbage, rows out of order).
  std::string csv = std::string(DiagnosticsCsv::header()) + '\n';
  for (int step = 0; step <= 60; step += 10) csv += std::to_string(step) + ",0.5,1,2,3,0,0,0,4,0,0,0,1e-3\n";
  if (in.remaining_bytes() > 0) {
    const std::size_t at = in.ConsumeIntegralInRange<std::size_t>(0, csv.size());
    if (in.ConsumeBool()) csv.resize(at);
    else csv.insert(at, in.ConsumeRandomLengthString(64));
  }
  std::ofstream(dir / "diagnostics.csv", std::ios::binary) << csv;

  const h5::QuietErrors quiet;
  if (!no_mesh) write_file(dir / frames::kMeshFile, mesh);
  for (int k = 0; k < nframes; ++k)
    if (!skip[static_cast<std::size_t>(k)]) write_file(dir / frames::frame_file(k), frame[static_cast<std::size_t>(k)]);
  for (const auto& [name, content] : stray) std::ofstream(dir / frames::kFramesDir / name, std::ios::binary) << content;

  auto files = [&] {
    std::size_t n = 0;
    for ([[maybe_unused]] const auto& entry : fs::directory_iterator(dir / frames::kFramesDir)) ++n;
    return n;
  };
  const std::size_t before = files();
  softcontact::fuzz::expect_accept_or_input_error([&] {
    std::vector<frames::FrameRecord> kept;
    try {
      kept = frames::resume_frames(dir.string(), kVertices, kTets, last_step);
    } catch (const InputError&) {
      softcontact::fuzz::require(files() == before, "a refused directory is left as it was");
      throw;
    }
    // What FrameWriter relies on: frames in order, none past the checkpoint, names that
    // are safe in the XDMF; the files of the frames kept are there, later ones gone.
    for (std::size_t k = 0; k < kept.size(); ++k) {
      const frames::FrameRecord& f = kept[k];
      softcontact::fuzz::require(f.step >= 0 && f.step <= last_step && std::isfinite(f.time), "frames up to the checkpoint");
      softcontact::fuzz::require(k == 0 || f.step > kept[k - 1].step, "frames in step order");
      softcontact::fuzz::require(f.fields.size() == f.datasets.size(), "a dataset per field");
      for (std::size_t a = 0; a < f.fields.size(); ++a)
        softcontact::fuzz::require(f.datasets[a].find_first_of("<>&\"'/\n") == std::string::npos &&
                                       f.fields[a].first.find_first_of("<>&\"'/\n") == std::string::npos,
                                   "field names safe in the XDMF");
      softcontact::fuzz::require(fs::is_regular_file(dir / frames::frame_file(static_cast<std::int64_t>(k))),
                                 "the file of a frame kept exists");
    }
    for (const auto& entry : fs::directory_iterator(dir / frames::kFramesDir)) {
      const std::string name = entry.path().filename().string();
      softcontact::fuzz::require(entry.path().extension() != ".tmp", "no temporary file left");
      const std::string stem = entry.path().stem().string();
      if (!stem.empty() && stem.find_first_not_of("0123456789") == std::string::npos)
        softcontact::fuzz::require(stem.size() <= 18 && std::stoll(stem) < static_cast<std::int64_t>(kept.size()),
                                   "no numbered file past the frames kept");
    }
    frames::write_index((dir / "frames.h5").string(), static_cast<std::int64_t>(kept.size()));
    frames::write_xdmf((dir / "frames.xdmf").string(), kept, kVertices, kTets);

    // The CSV keeps its header and whole rows of steps up to the checkpoint, a prefix of
    // the rows it had.
    {
      DiagnosticsCsv out;
      out.resume((dir / "diagnostics.csv").string(), last_step);
    }
    std::ifstream back(dir / "diagnostics.csv", std::ios::binary);
    const std::string cut((std::istreambuf_iterator<char>(back)), std::istreambuf_iterator<char>());
    const std::string header = std::string(DiagnosticsCsv::header()) + '\n';
    softcontact::fuzz::require(cut.rfind(header, 0) == 0, "the CSV starts with its header");
    softcontact::fuzz::require(cut.back() == '\n', "the CSV ends with a whole row");
    const std::size_t first_row = csv.find('\n');
    softcontact::fuzz::require(first_row != std::string::npos
                                   ? csv.compare(first_row + 1, cut.size() - header.size(), cut, header.size()) == 0
                                   : cut == header,
                               "the CSV rows kept are the first rows it had");
    for (std::size_t at = header.size(); at < cut.size();) {
      const std::size_t end = cut.find('\n', at);
      softcontact::fuzz::require(std::strtoll(cut.c_str() + at, nullptr, 10) <= last_step, "CSV rows up to the checkpoint");
      at = end + 1;
    }
  });
  return 0;
}
