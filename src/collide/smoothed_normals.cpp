#include "smoothed_normals.hpp"

namespace softcontact::collide {

V3 vertex_normal(const double* x, const index_t* tri, const CollisionTopology& topo, index_t v) {
  V3 sum{0, 0, 0};
  for (std::size_t k = topo.tri_begin[static_cast<std::size_t>(v)]; k < topo.tri_begin[static_cast<std::size_t>(v) + 1]; ++k) {
    const index_t* t = tri + 3 * static_cast<std::size_t>(topo.tri_of[k]);
    const V3 a = load(x, t[0]);
    sum = sum + cross(load(x, t[1]) - a, load(x, t[2]) - a);
  }
  return normalized(sum);
}

void smoothed_vertex_normals(const double* x, const index_t* tri, const CollisionTopology& topo,
                             const ObjectInfo& object, double* face, double* normals, std::int64_t& degenerate) {
  // Each triangle's cross product once (vertex_normal computes it once per corner: the
  // same operands in the same order, so the same bits), then the per-vertex sums.
  for (index_t t : object.triangles) {
    const index_t* tv = tri + 3 * static_cast<std::size_t>(t);
    const V3 a = load(x, tv[0]);
    const V3 n = cross(load(x, tv[1]) - a, load(x, tv[2]) - a);
    for (int d = 0; d < 3; ++d) face[3 * static_cast<std::size_t>(t) + d] = n[d];
  }
  std::int64_t bad = 0;
  for (index_t v : object.surface_vertices) {
    V3 sum{0, 0, 0};
    for (std::size_t k = topo.tri_begin[static_cast<std::size_t>(v)]; k < topo.tri_begin[static_cast<std::size_t>(v) + 1]; ++k)
      sum = sum + load(face, topo.tri_of[k]);
    const V3 n = normalized(sum);
    if (n[0] == 0 && n[1] == 0 && n[2] == 0) ++bad;
    for (int d = 0; d < 3; ++d) normals[3 * static_cast<std::size_t>(v) + d] = n[d];
  }
  degenerate += bad;
}

V3 interpolated_normal(const double* x, const index_t* tri, const double* normals, index_t t,
                       const std::array<double, 3>& bary) {
  const index_t* v = tri + 3 * static_cast<std::size_t>(t);
  const V3 a = load(x, v[0]);
  const V3 face = normalized(cross(load(x, v[1]) - a, load(x, v[2]) - a));
  // Crease rule: a vertex normal more than kCreaseDegrees away from this triangle's own
  // normal belongs to a sharp feature (a box's edge or corner averages faces 90 degrees
  // apart); across the triangle it would tilt every penetration vector towards the
  // edge, pushing bodies sideways and overestimating depths. Such a corner uses the
  // face normal instead, so flat faces keep their exact normal up to their rim while
  // smooth surfaces (neighbouring faces a few tens of degrees apart) stay smooth.
  V3 n{0, 0, 0};
  for (int c = 0; c < 3; ++c) {
    const V3 nv = load(normals, v[c]);
    const bool sharp = nv[0] * face[0] + nv[1] * face[1] + nv[2] * face[2] < kCreaseCosine;
    n = n + bary[c] * (sharp ? face : nv);
  }
  n = normalized(n);
  if (n[0] != 0 || n[1] != 0 || n[2] != 0) return n;
  return face;
}

}  // namespace softcontact::collide
