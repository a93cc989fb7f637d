#pragma once
// Bounding-volume hierarchy over one object's surface triangles, for the searches that
// the tet walk cannot do (tet_walk.hpp): all crossings of a segment with the surface,
// and the nearest surface triangle to a point (the deep-intersection fallback).
//
// The tree is built once from the rest positions (median split of the triangle
// centroids along the longest axis, ties by triangle index, up to 4 triangles per leaf,
// nodes in depth-first order so children follow their parent) and refitted to the
// current positions before use: O(s) per refit, O(log s) per query on a mesh that has
// not tangled. Deformation loosens the boxes but never makes a query wrong.
#include <array>
#include <cstdint>
#include <vector>

#include "vec3.hpp"

namespace softcontact::collide {

/// Vertices whose triangles a search skips (self-contact: a vertex and its mesh
/// neighbours, whose own surface is not "the other side"). Empty by default.
struct SkipVertices {
  const index_t* v = nullptr;
  std::size_t n = 0;
  bool touches(const index_t* t) const {
    for (std::size_t k = 0; k < n; ++k)
      if (t[0] == v[k] || t[1] == v[k] || t[2] == v[k]) return true;
    return false;
  }
};

class SurfaceBvh {
public:
  /// `x` (n,3) positions, `tri` (s,3) the World's triangles, `triangles` the rows that
  /// belong to this object.
  void build(const double* x, const index_t* tri, const std::vector<index_t>& triangles);
  /// Boxes at positions x (same triangles as build).
  void refit(const double* x, const index_t* tri);
  bool empty() const { return nodes_.empty(); }
  /// The tree that build() gives for the same object with every triangle row moved by
  /// `by` (a World built again with the object's triangles elsewhere): the split compares
  /// centroids, then rows, and a common shift keeps the rows' order. The boxes are left
  /// as they were; refit() before searching, as always.
  void shift_triangles(index_t by);
  /// The triangle rows in leaf order (the order a search meets them); for tests.
  const std::vector<index_t>& leaf_order() const { return order_; }

  struct Hit {
    double t;                      ///< segment parameter in [0, 1]
    index_t triangle;              ///< row of World::triangles
    std::array<double, 3> bary;    ///< barycentric coordinates of the crossing on it
  };
  /// Appends every crossing of the segment p + t (q - p), t in [0, 1], with the surface
  /// to `hits`, in traversal order (fixed for fixed input). Degenerate triangles met are
  /// skipped and counted in `degenerate`; triangles touching a `skip` vertex are skipped.
  void segment_hits(const double* x, const index_t* tri, const V3& p, const V3& q, std::vector<Hit>& hits,
                    std::int64_t& degenerate, const SkipVertices& skip = {}) const;

  struct Nearest {
    index_t triangle = -1;         ///< -1 only for an empty tree
    V3 point{};                    ///< closest point
    std::array<double, 3> bary{};  ///< its barycentric coordinates on the triangle
    double dist2 = 0;              ///< squared distance [m^2]
  };
  /// The surface triangle nearest to p (ties: lower triangle index), among those not
  /// touching a `skip` vertex.
  Nearest nearest(const double* x, const index_t* tri, const V3& p, std::int64_t& degenerate,
                  const SkipVertices& skip = {}) const;

private:
  struct Node {
    Box box;
    std::int32_t right = -1;  // internal node: left child is this + 1, right child here
    std::int32_t first = 0;   // leaf: order_[first .. first + count)
    std::int32_t count = 0;   // > 0 for a leaf
  };
  struct Item {
    V3 centroid;
    index_t triangle;
  };
  std::int32_t build_node(std::vector<Item>& items, std::size_t begin, std::size_t end, int parent_axis);
  std::vector<Node> nodes_;
  std::vector<index_t> order_;
};

}  // namespace softcontact::collide
