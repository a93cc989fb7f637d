#pragma once
// The soft floor scene of the MPI tests (tests/data/scenes/soft_floor.yaml) and its
// variants, shared by the distributed and the restart tests.
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "softcontact/scene.hpp"

namespace softcontact::test {

// soft_floor.yaml with each `from` replaced by `to`, which must occur `count` times.
struct Edit {
  std::string from, to;
  int count;
};
inline Scene soft_floor_edited(const std::vector<Edit>& edits) {
  const std::string path = std::string(SOFTCONTACT_TEST_DATA) + "/scenes/soft_floor.yaml";
  std::ifstream in(path);
  std::stringstream text;
  text << in.rdbuf();
  std::string yaml = text.str();
  for (const Edit& e : edits) {
    int n = 0;
    for (std::size_t at = yaml.find(e.from); at != std::string::npos; at = yaml.find(e.from, at + e.to.size()), ++n)
      yaml.replace(at, e.from.size(), e.to);
    if (n != e.count)
      throw std::runtime_error("soft_floor.yaml: expected '" + e.from + "' " + std::to_string(e.count) + " times");
  }
  return load_scene_from_string(yaml, path);
}

// soft_floor with twelve balls instead of six: the floor holds 35 % of the tets, so it is
// split from 3 ranks on, one part per rank on 3 and three parts (each about half an even
// share, split_part_count) on 4.
inline const Scene& soft_floor_twelve() {
  static const Scene s = soft_floor_edited({{"count: [3, 1, 1], spacing: [0.3, 0, 0]", "count: [6, 1, 1], spacing: [0.18, 0, 0]", 2},
                                            {"translate: [-0.3, ", "translate: [-0.45, ", 2}});
  return s;
}

}  // namespace softcontact::test
