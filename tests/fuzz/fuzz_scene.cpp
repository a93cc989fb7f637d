// libFuzzer target: the scene parser (YAML text -> validated Scene). Seeds:
// tests/fuzz/corpus/scene (tools/fuzz.sh).
//
// The scene is named as if it lay in tests/data/scenes, so that the seeds' relative mesh
// paths ('../meshes/cube_v41.msh') read the test meshes: the fuzzer then reaches the
// mesh cache, transforms and instancing too. Absolute paths and other relative ones may
// name any file; read_mesh rejects anything without a mesh extension before opening it.
//
// A scene may legitimately ask for millions of tets; the limits here keep each input
// small, so that only sizes the parser fails to bound before building show up as
// findings (timeouts, allocations over -malloc_limit_mb). The stability limit (an
// eigenvalue problem per tet) costs about 0.5 ms per tet in this instrumented -O1 build,
// hence at most 4000 tets: under 2 s, well inside the 5 s timeout.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <string>

#include "fuzz_common.hpp"
#include "mesh_checks.hpp"
#include "softcontact/scene.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string yaml(reinterpret_cast<const char*>(data), size);
  softcontact::SceneLimits limits;
  limits.max_vertices = 4000;
  limits.max_tets = 4000;
  limits.max_objects = 100;
  softcontact::fuzz::expect_accept_or_input_error([&] {
    const softcontact::Scene s = softcontact::load_scene_from_string(yaml, SOFTCONTACT_FUZZ_SCENE_DIR "/fuzz.yaml", limits);
    softcontact::fuzz::require(!s.objects.empty() && !s.materials.empty(), "objects and materials");
    softcontact::fuzz::require(s.num_tets() <= 4000 && s.objects.size() <= 100, "within the limits");
    softcontact::fuzz::require(s.sim.dt > 0 && s.sim.dt < HUGE_VAL, "a positive finite time step");
    softcontact::fuzz::require(softcontact::total_steps(s.sim) >= 1, "at least one step");
    softcontact::fuzz::require(softcontact::steps_between_frames(s.sim) >= 1, "at least one step between frames");
    for (const auto& o : s.objects) {
      softcontact::fuzz::check_mesh(o.mesh);
      softcontact::fuzz::require(o.material >= 0 && static_cast<std::size_t>(o.material) < s.materials.size(),
                                 "material index in range");
    }
  });
  return 0;
}
