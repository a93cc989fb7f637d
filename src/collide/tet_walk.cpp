#include "tet_walk.hpp"

#include <algorithm>
#include <cmath>

#include "collision_topology.hpp"
#include "point_in_tet.hpp"

namespace softcontact::collide {

namespace {
// Corners of the face opposite corner j, ordered so that (b - a) x (c - a) points away
// from corner j in a positively oriented tet (the outward faces of surface.hpp).
constexpr int kFace[4][3] = {{1, 2, 3}, {0, 3, 2}, {0, 1, 3}, {0, 2, 1}};
}  // namespace

// Per tet: the outward normals n_j of its faces (flipped for an inverted tet). Along
// the segment, lambda_j is proportional to (a_j - y) . n_j, so the segment leaves through
// face j where (q - p) . n_j > 0, at t_j = ((a_j - p) . n_j) / ((q - p) . n_j): the formula
// of the header without the division by the volume.
TetPlanes prepare_walk(const double* x, const index_t* tets, index_t tet, const V3& p, int skip) {
  TetPlanes s;
  s.tet = tet;
  const index_t* tv = tets + 4 * static_cast<std::size_t>(tet);
  const V3 v[4] = {load(x, tv[0]), load(x, tv[1]), load(x, tv[2]), load(x, tv[3])};
  const V3 e1 = v[1] - v[0], e2 = v[2] - v[0], e3 = v[3] - v[0];
  const double vol6 = dot(e3, cross(e1, e2));
  const double l2 = std::max({norm2(e1), norm2(e2), norm2(e3)});
  // |vol6| > 6 kFlatTet l^3, squared (no square root).
  s.flat = !(vol6 * vol6 > 36 * kFlatTet * kFlatTet * l2 * l2 * l2);
  if (s.flat) return s;
  const double orientation = vol6 > 0 ? 1.0 : -1.0;
  for (int j = 0; j < 4; ++j) {
    if (j == skip) {  // the entry face: a zero normal never counts as a way out
      s.n[j] = {0, 0, 0};
      s.num[j] = 0;
      continue;
    }
    const V3& a = v[kFace[j][0]];
    s.n[j] = orientation * cross(v[kFace[j][1]] - a, v[kFace[j][2]] - a);
    s.num[j] = dot(a - p, s.n[j]);
  }
  return s;
}

WalkResult walk_to_surface(const double* x, const index_t* tets, const index_t* face_neighbour, const index_t* tri,
                           const TetPlanes& start, const V3& p, const V3& q, int max_steps) {
  WalkResult r;
  const V3 dir = q - p;
  index_t cur = start.tet, came_from = -1;
  double t_in = 0;
  TetPlanes next_planes;
  for (int step = 0; step < max_steps; ++step) {
    r.steps = step + 1;
    const index_t* nb = face_neighbour + 4 * static_cast<std::size_t>(cur);
    if (step > 0) {
      int entry = 0;  // the face we came in by
      while (entry < 4 && nb[entry] != came_from) ++entry;
      next_planes = prepare_walk(x, tets, cur, p, entry < 4 ? entry : -1);
    }
    const TetPlanes& planes = step == 0 ? start : next_planes;
    if (planes.flat) return r;  // failed
    int face = -1;
    double t_exit = 0;
    for (int j = 0; j < 4; ++j) {
      const double den = dot(dir, planes.n[j]);
      if (!(den > 0)) continue;  // not moving out through this face
      const double tj = planes.num[j] / den;
      if (face < 0 || tj < t_exit) {
        face = j;
        t_exit = tj;
      }
    }
    if (face < 0 || t_exit > 1) {
      r.status = WalkResult::ended_inside;
      return r;
    }
    t_exit = std::clamp(t_exit, t_in, 1.0);  // rounding must not walk backwards
    const index_t next = nb[face];
    if (next == kOpenFace) return r;  // failed
    if (next >= 0) {
      came_from = cur;
      cur = next;
      t_in = t_exit;
      continue;
    }
    // A surface triangle: barycentric coordinates of the crossing on it, clamped and
    // renormalised against rounding, in the triangle's own vertex order.
    r.status = WalkResult::exited;
    r.t = t_exit;
    r.triangle = -next - 1;
    const index_t* tt = tri + 3 * static_cast<std::size_t>(r.triangle);
    const V3 a = load(x, tt[0]), b = load(x, tt[1]), c = load(x, tt[2]);
    const V3 s = p + t_exit * dir;
    const V3 n = cross(b - a, c - a);
    const double n2 = norm2(n);
    const double inv = n2 > 0 ? 1.0 / n2 : 0.0;  // 0 only for a face of a near-flat tet
    r.bary = {std::max(0.0, dot(n, cross(c - b, s - b)) * inv), std::max(0.0, dot(n, cross(a - c, s - c)) * inv),
              std::max(0.0, dot(n, cross(b - a, s - a)) * inv)};
    const double sum = r.bary[0] + r.bary[1] + r.bary[2];
    if (sum > 0)
      for (double& l : r.bary) l /= sum;
    else
      r.bary = {1.0 / 3, 1.0 / 3, 1.0 / 3};
    return r;
  }
  return r;  // failed: too many steps
}

}  // namespace softcontact::collide
