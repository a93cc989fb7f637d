#include "surface_bvh.hpp"

#include <algorithm>
#include <numeric>

#include "triangle_queries.hpp"

namespace softcontact::collide {

namespace {
constexpr std::size_t kLeafSize = 4;
constexpr int kMaxDepth = 64;  // stack bound: median splits give depth log2(s / 4) + 1

Box triangle_box(const double* x, const index_t* t) {
  Box b;
  b.reset();
  for (int c = 0; c < 3; ++c) b.add(load(x, t[c]));
  return b;
}

// Does the segment p + t d, t in [0, 1], meet the closed box? Slab test; an axis along
// which the segment does not move is tested directly (no 0 * inf).
bool segment_meets_box(const V3& p, const V3& d, const Box& b) {
  double t0 = 0, t1 = 1;
  for (int k = 0; k < 3; ++k) {
    if (d[k] == 0) {
      if (p[k] < b.lo[k] || p[k] > b.hi[k]) return false;
      continue;
    }
    const double inv = 1.0 / d[k];
    double a = (b.lo[k] - p[k]) * inv, c = (b.hi[k] - p[k]) * inv;
    if (a > c) std::swap(a, c);
    t0 = std::max(t0, a);
    t1 = std::min(t1, c);
    if (t0 > t1) return false;
  }
  return true;
}

double box_dist2(const V3& p, const Box& b) {
  double s = 0;
  for (int k = 0; k < 3; ++k) {
    const double e = p[k] < b.lo[k] ? b.lo[k] - p[k] : (p[k] > b.hi[k] ? p[k] - b.hi[k] : 0);
    s += e * e;
  }
  return s;
}

// Boxes are widened by a relative 1e-9 so that a crossing computed on a triangle's edge
// is not culled by the rounding of the slab test.
void inflate(Box& b) {
  const double pad = 1e-9 * b.max_extent();
  for (int k = 0; k < 3; ++k) {
    b.lo[k] -= pad;
    b.hi[k] += pad;
  }
}
}  // namespace

void SurfaceBvh::build(const double* x, const index_t* tri, const std::vector<index_t>& triangles) {
  nodes_.clear();
  order_ = triangles;
  if (order_.empty()) return;
  std::vector<Item> items(order_.size());
  for (std::size_t k = 0; k < order_.size(); ++k) {
    const index_t* t = tri + 3 * static_cast<std::size_t>(order_[k]);
    items[k] = {(1.0 / 3.0) * (load(x, t[0]) + load(x, t[1]) + load(x, t[2])), order_[k]};
  }
  build_node(items, 0, items.size(), -1);
  for (std::size_t k = 0; k < items.size(); ++k) order_[k] = items[k].triangle;
  refit(x, tri);
}

void SurfaceBvh::shift_triangles(index_t by) {
  for (index_t& r : order_) r += by;
}

namespace {
// Centroid along `axis`, ties by triangle index: a strict total order.
auto along(int axis) {
  return [axis](const auto& a, const auto& b) {
    if (a.centroid[axis] != b.centroid[axis]) return a.centroid[axis] < b.centroid[axis];
    return a.triangle < b.triangle;
  };
}
}  // namespace

// Splits the range at the median of the centroids along the box's longest axis. The
// halves are selected (nth_element), not sorted: a half's set is the same either way, and
// a child that splits again orders its own set; a leaf is sorted along its parent's axis,
// so that every leaf lists its triangles as a full sort at every level would.
std::int32_t SurfaceBvh::build_node(std::vector<Item>& items, std::size_t begin, std::size_t end, int parent_axis) {
  const auto id = static_cast<std::int32_t>(nodes_.size());
  nodes_.emplace_back();
  const auto first = items.begin() + static_cast<std::ptrdiff_t>(begin), last = items.begin() + static_cast<std::ptrdiff_t>(end);
  if (end - begin <= kLeafSize) {
    if (parent_axis >= 0) std::sort(first, last, along(parent_axis));
    nodes_[static_cast<std::size_t>(id)].first = static_cast<std::int32_t>(begin);
    nodes_[static_cast<std::size_t>(id)].count = static_cast<std::int32_t>(end - begin);
    return id;
  }
  Box cb;
  cb.reset();
  for (auto it = first; it != last; ++it) cb.add(it->centroid);
  int axis = 0;
  for (int k = 1; k < 3; ++k)
    if (cb.hi[k] - cb.lo[k] > cb.hi[axis] - cb.lo[axis]) axis = k;
  const std::size_t mid = begin + (end - begin) / 2;
  std::nth_element(first, items.begin() + static_cast<std::ptrdiff_t>(mid), last, along(axis));
  build_node(items, begin, mid, axis);
  const std::int32_t right = build_node(items, mid, end, axis);
  nodes_[static_cast<std::size_t>(id)].right = right;
  return id;
}

void SurfaceBvh::refit(const double* x, const index_t* tri) {
  // Children come after their parent: one backward sweep.
  for (std::size_t i = nodes_.size(); i-- > 0;) {
    Node& n = nodes_[i];
    if (n.count > 0) {
      n.box.reset();
      for (std::int32_t k = 0; k < n.count; ++k)
        n.box.add(triangle_box(x, tri + 3 * static_cast<std::size_t>(order_[static_cast<std::size_t>(n.first + k)])));
      inflate(n.box);
    } else {
      n.box = nodes_[i + 1].box;
      n.box.add(nodes_[static_cast<std::size_t>(n.right)].box);
    }
  }
}

void SurfaceBvh::segment_hits(const double* x, const index_t* tri, const V3& p, const V3& q, std::vector<Hit>& hits,
                              std::int64_t& degenerate, const SkipVertices& skip) const {
  if (nodes_.empty()) return;
  const V3 d = q - p;
  std::int32_t stack[kMaxDepth];
  int top = 0;
  stack[top++] = 0;
  while (top > 0) {
    const Node& n = nodes_[static_cast<std::size_t>(stack[--top])];
    if (!segment_meets_box(p, d, n.box)) continue;
    if (n.count == 0) {
      const auto self = static_cast<std::int32_t>(&n - nodes_.data());
      stack[top++] = n.right;
      stack[top++] = self + 1;
      continue;
    }
    for (std::int32_t k = 0; k < n.count; ++k) {
      const index_t r = order_[static_cast<std::size_t>(n.first + k)];
      const index_t* t = tri + 3 * static_cast<std::size_t>(r);
      if (skip.touches(t)) continue;
      const V3 a = load(x, t[0]), b = load(x, t[1]), c = load(x, t[2]);
      if (triangle_degenerate(a, b, c)) {
        ++degenerate;
        continue;
      }
      Hit h{};
      if (segment_triangle(p, q, a, b, c, h.t, h.bary)) {
        h.triangle = r;
        hits.push_back(h);
      }
    }
  }
}

SurfaceBvh::Nearest SurfaceBvh::nearest(const double* x, const index_t* tri, const V3& p, std::int64_t& degenerate,
                                        const SkipVertices& skip) const {
  Nearest best;
  if (nodes_.empty()) return best;
  best.dist2 = std::numeric_limits<double>::infinity();
  std::int32_t stack[kMaxDepth];
  int top = 0;
  stack[top++] = 0;
  while (top > 0) {
    const Node& n = nodes_[static_cast<std::size_t>(stack[--top])];
    if (box_dist2(p, n.box) > best.dist2) continue;
    if (n.count == 0) {
      // Nearer child last, so that it is searched first and prunes more.
      const auto self = static_cast<std::int32_t>(&n - nodes_.data());
      const double dl = box_dist2(p, nodes_[static_cast<std::size_t>(self + 1)].box);
      const double dr = box_dist2(p, nodes_[static_cast<std::size_t>(n.right)].box);
      if (dl <= dr) {
        stack[top++] = n.right;
        stack[top++] = self + 1;
      } else {
        stack[top++] = self + 1;
        stack[top++] = n.right;
      }
      continue;
    }
    for (std::int32_t k = 0; k < n.count; ++k) {
      const index_t r = order_[static_cast<std::size_t>(n.first + k)];
      const index_t* t = tri + 3 * static_cast<std::size_t>(r);
      if (skip.touches(t)) continue;
      const V3 a = load(x, t[0]), b = load(x, t[1]), c = load(x, t[2]);
      if (triangle_degenerate(a, b, c)) ++degenerate;
      std::array<double, 3> bary{};
      const V3 cp = closest_point_on_triangle(p, a, b, c, bary);
      const double d2 = norm2(p - cp);
      if (d2 < best.dist2 || (d2 == best.dist2 && r < best.triangle)) {
        best.triangle = r;
        best.point = cp;
        best.bary = bary;
        best.dist2 = d2;
      }
    }
  }
  return best;
}

}  // namespace softcontact::collide
