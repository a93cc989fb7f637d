#pragma once
// Invariants of a mesh that a reader accepted (validate_mesh promises them).
#include <cmath>
#include <cstddef>

#include "fuzz_common.hpp"
#include "softcontact/mesh.hpp"

namespace softcontact::fuzz {

inline void check_mesh(const TetMesh& m) {
  require(m.points.size() % 3 == 0 && m.tets.size() % 4 == 0, "array sizes are multiples of 3 and 4");
  require(m.num_tets() > 0, "at least one tet");
  for (double x : m.points) require(std::isfinite(x), "finite coordinates");
  for (index_t v : m.tets) require(v >= 0 && static_cast<std::size_t>(v) < m.num_vertices(), "tet vertex in range");
}

}  // namespace softcontact::fuzz
