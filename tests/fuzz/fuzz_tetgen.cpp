// libFuzzer target: the TetGen reader on an arbitrary pair of files. One input holds
// both: the .node file, then a line "@@ele", then the .ele file (without that line, the
// whole input is the .node file and the .ele file is empty). Seeds:
// tests/fuzz/corpus/tetgen (tools/fuzz.sh).
#include <cstddef>
#include <cstdint>
#include <string_view>

#include "fuzz_common.hpp"
#include "mesh_checks.hpp"
#include "softcontact/mesh_io.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view bytes(reinterpret_cast<const char*>(data), size);
  constexpr std::string_view kSeparator = "\n@@ele\n";
  std::string_view node = bytes, ele;
  if (const std::size_t at = bytes.find(kSeparator); at != std::string_view::npos) {
    node = bytes.substr(0, at + 1);
    ele = bytes.substr(at + kSeparator.size());
  }
  softcontact::fuzz::expect_accept_or_input_error([&] {
    softcontact::MeshReport report;
    const softcontact::TetMesh m = softcontact::read_tetgen_bytes(node, ele, "fuzz.node", "fuzz.ele", &report);
    softcontact::fuzz::check_mesh(m);
  });
  return 0;
}
