#pragma once
// Which objects can be in vertex self-contact this step (docs/collision.md,
// "Self-contact"): an exact test that spares the self query of objects that have not
// deformed enough to fold.
//
// At construction, from the reference positions X (the rest positions the detector is
// built from), per object the *gap* g: the smallest distance from a surface vertex i to a
// tet of the same object that shares no vertex with i's star (i and its mesh neighbours),
// capped at half the object's largest tet extent L (the tets are binned by the centres
// of their boxes in cells of edge L, and each vertex visits the 27 cells around it: a tet
// not visited is farther than L / 2).
//
// Per step, per object: the rigid motion x = c + R (X - C) that fits the current
// positions best (c, C the mean positions, R the rotation of the polar decomposition of
// sum (x - c)(X - C)^T), and delta = the largest distance of a vertex from it. If
// 2 delta < g the object cannot be in self-contact: every point of a tet is as close to
// its rigid image as its corners are (an affine map of a convex combination), so a
// vertex i inside a tet T now is within 2 delta of T at rest, and T would have to be a
// tet within the gap, which only tets touching i's star are. An object with a non-finite
// vertex, or no tets, is always tested.
#include <cstdint>
#include <vector>

#include "collision_topology.hpp"
#include "softcontact/collision.hpp"

namespace softcontact::collide {

class SelfCulling {
public:
  /// Gaps from the reference positions `x_ref` (n_local,3); keeps a copy of them. The
  /// objects found in `known` take its gap; a copy of an entry whose gap `known` holds
  /// takes that gap less a rounding margin (SelfGapCache); the others' are computed (one
  /// copy per entry) and added to it.
  void build(const World& w, const CollisionTopology& topo, const double* x_ref, SelfGapCache* known = nullptr);
  /// active[k] = 1 when object slot k can be in self-contact at positions x. `tested`
  /// (per slot; null: all): the slots to look at; the others get active 0 and delta
  /// infinity without a look (a ghost's self-contact is its owner's: on a rank that
  /// ghosts most of its neighbours, most slots).
  void update(const double* x, const CollisionTopology& topo, const std::uint8_t* bad_vertex,
              const std::uint8_t* tested, std::vector<std::uint8_t>& active, std::vector<double>& delta) const;
  double gap(std::size_t slot) const { return gap_[slot]; }

private:
  // The gaps of the slots with have[k] == 0, computed from the reference positions.
  void compute(const World& w, const CollisionTopology& topo, const std::vector<std::uint8_t>& have);

  std::vector<double> gap_;   // per slot [m]
  std::vector<double> ref_;   // (n_local,3) reference positions
};

}  // namespace softcontact::collide
