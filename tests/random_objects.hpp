#pragma once
// The `objects:` part of a random scene shared by the collision and verify tests: `n`
// tori, spheres and boxes of material `m` at random positions in a small region (so
// that many overlap), with random orientations, drawn from `g`.
#include <random>
#include <string>

namespace softcontact::test {

inline std::string random_objects_yaml(std::mt19937_64& g, int n) {
  std::uniform_real_distribution<double> pos(-0.25, 0.25), ang(0, 360);
  std::string yaml;
  for (int k = 0; k < n; ++k) {
    const char* prim[3] = {"{type: torus, major_radius: 0.15, minor_radius: 0.05, resolution: 3, around: 12}",
                           "{type: sphere, radius: 0.12, resolution: 4}",
                           "{type: box, size: [0.3, 0.15, 0.1], cells: [3, 2, 2]}"};
    yaml += "  - material: m\n    primitive: " + std::string(prim[g() % 3]) + "\n    transform: {rotate: [" +
            std::to_string(ang(g)) + ", " + std::to_string(ang(g)) + ", " + std::to_string(ang(g)) +
            "], translate: [" + std::to_string(pos(g)) + ", " + std::to_string(pos(g)) + ", " + std::to_string(pos(g)) +
            "]}\n";
  }
  return yaml;
}

}  // namespace softcontact::test
