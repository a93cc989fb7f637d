#pragma once
// Item 7 of "Penetration vectors" (docs/collision.md): mutual vertex records that
// contradict each other. Where a vertex i of body A is inside body B near B's vertex j
// (T_i weighs at least kMutualWeight on j) and j is inside A near i, the two records
// describe one contact seen from both sides, and their depths must point opposite ways
// (each point leaves the other body towards its own side). The consistent depth,
// propagated over each body's own points, can make them point the same way; the two
// corrections then undo each other on the same two vertices. Such a pair takes one axis
// from the two surfaces' outward normals at i and j and one length, the two vertices'
// overlap along it clamped to [max(|d_i|, |d_j|), |d_i| + |d_j|].
#include <cstdint>
#include <vector>

#include "collision_topology.hpp"
#include "softcontact/collision.hpp"

namespace softcontact::collide {

/// Appends the keys of `records` that can be one half of a mutual pair.
void mutual_record_keys(const World& w, const std::vector<Collision>& records, double min_weight,
                        std::vector<RecordKey>& keys);

/// Settles the contradicting pairs among `records` (CollisionDetector::settle_mutual);
/// sorts `keys`. Returns the number of records changed.
std::int64_t settle_mutual_pairs(const World& w, const CollisionTopology& topo, std::vector<Collision>& records,
                                 std::vector<RecordKey>& keys, double min_weight);

}  // namespace softcontact::collide
