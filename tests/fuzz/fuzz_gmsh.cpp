// libFuzzer target: the Gmsh reader (MSH 2.2 and 4.1, ASCII and binary) on arbitrary
// bytes. Seeds: tests/fuzz/corpus/gmsh (tools/fuzz.sh).
#include <cstddef>
#include <cstdint>
#include <string_view>

#include "fuzz_common.hpp"
#include "mesh_checks.hpp"
#include "softcontact/mesh_io.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view bytes(reinterpret_cast<const char*>(data), size);
  softcontact::fuzz::expect_accept_or_input_error([&] {
    softcontact::MeshReport report;
    const softcontact::TetMesh m = softcontact::read_gmsh_bytes(bytes, "fuzz.msh", &report);
    softcontact::fuzz::check_mesh(m);
  });
  return 0;
}
