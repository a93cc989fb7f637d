#pragma once
// What Simulator::verify keeps between checks (simulator_verify.cpp).
#include <vector>

#include "softcontact/verify.hpp"

namespace softcontact {

// This rank's owned and ghost objects as a VerifyMesh in global order: objects
// ascending, each one's vertices, tets and triangles in their global order. Local ids of
// the mesh are then in the same order as the global ids, so the check breaks ties (the
// lowest id) as the check of the whole scene does.
struct LocalCheck {
  VerifyMesh mesh;
  std::vector<index_t> vertex;     // mesh vertex -> World row
  std::vector<gid_t> vertex_gid;   // mesh vertex -> global id
  std::vector<gid_t> tet_gid;      // mesh tet -> global id
  std::vector<gid_t> triangle_gid; // mesh triangle -> global id
  std::vector<char> counted;       // per object: owned here
};

}  // namespace softcontact
