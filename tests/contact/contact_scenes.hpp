#pragma once
// Helpers for the full-step contact tests: build a Simulator from YAML and measure
// per-object quantities.
#include <mpi.h>

#include <array>
#include <memory>
#include <string>

#include "softcontact/scene.hpp"
#include "softcontact/simulator.hpp"

namespace softcontact::test {

struct Run {
  Scene scene;
  std::unique_ptr<Simulator> sim;
};

inline std::unique_ptr<Run> make_run(const std::string& yaml) {
  auto r = std::make_unique<Run>();
  r->scene = load_scene_from_string(yaml, "test.yaml");
  r->sim = std::make_unique<Simulator>(MPI_COMM_WORLD, r->scene);
  return r;
}

/// Mass-weighted centroid, total mass and momentum of object k (owned vertices).
struct ObjectState {
  std::array<double, 3> centroid{}, momentum{}, contact_force{};
  double mass = 0;
  double min[3] = {1e300, 1e300, 1e300}, max[3] = {-1e300, -1e300, -1e300};
};

inline ObjectState object_state(Simulator& s, int k) {
  ObjectState o;
  World& w = s.world();
  const auto& F = s.contact_force();
  for (std::size_t i = 0; i < w.n_owned; ++i) {
    if (w.vertex_object[i] != k) continue;
    o.mass += w.mass[i];
    for (int d = 0; d < 3; ++d) {
      o.centroid[d] += w.mass[i] * w.x[3 * i + d];
      o.momentum[d] += w.mass[i] * w.v[3 * i + d];
      o.contact_force[d] += F[3 * i + d];
      o.min[d] = std::min(o.min[d], w.x[3 * i + d]);
      o.max[d] = std::max(o.max[d], w.x[3 * i + d]);
    }
  }
  for (int d = 0; d < 3; ++d) o.centroid[d] /= o.mass;
  return o;
}

}  // namespace softcontact::test
