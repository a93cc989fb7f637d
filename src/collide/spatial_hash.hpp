#pragma once
// Uniform-grid spatial hashing (Teschner et al. 2003, "Optimized Spatial Hashing for
// Collision Detection of Deformable Objects") of the query points, in a fixed order.
//
// Grid: cell (cx, cy, cz) = (floor(x / h), floor(y / h), floor(z / h)) for cell size h
// [m]. Teschner hashes the tets' boxes first and then looks each vertex up; here the two
// passes run the other way round, which yields the same (vertex, tet) candidate pairs:
//  1. insert_points: the query points (surface vertices) are sorted by the cell that
//     contains them, and their positions and labels copied in that order;
//  2. for_each_run(range): a tet's bounding box, as a cell range, is answered with the
//     runs of sorted points that lie in those cells.
// Why this order: a tet can then test the points of its cells while its box sits in
// registers, and no tet entries are stored or sorted (a pile of 78K tets makes about
// 260K of them per step). A point inside a closed box always lies in a cell of the box's
// range: floor(x / h) is monotone in x, so lo <= p <= hi gives cell(lo) <= cell(p) <= cell(hi).
//
// Two layouts, chosen per step:
//  - dense (the usual case, contacts cluster): when the cells spanned by the points
//    number at most kDenseCellsPerPoint per point (plus 4096), the points are counting-
//    sorted by dense cell index (z, then y, then x), so the points of cells
//    cx0..cx1 of one (cy, cz) row are one contiguous run: a box costs one run per row
//    (and cells are h / kRowRefine long along x, see there);
//  - hashed (points spread far apart): each point's cell key packs (cx, cy, cz) modulo
//    2^21 into 63 bits; points are radix-sorted by key, and an open-addressing table
//    finds each occupied cell (keys 2^21 cells apart alias, which only adds candidates
//    that the exact tests reject). A box costs one lookup per cell.
// Within a cell the points keep their input (ascending) order: both sorts are stable.
//
// Cost per step: O(points + dense cells) to build, O(rows or cells of the box) per box,
// no allocation once the buffers have grown.
#include <cstdint>
#include <vector>

#include "softcontact/mesh.hpp"
#include "vec3.hpp"

namespace softcontact::collide {

/// The dense layout is used while the points' cell range has at most this many cells
/// per point (plus 4096).
inline constexpr std::int64_t kDenseCellsPerPoint = 32;
/// In the dense layout cells are h / kRowRefine long along x: a box's points come in one
/// run per (y, z) row whatever the number of x cells it spans, so thinner cells along x
/// cost nothing per box and leave fewer points outside the box to test.
inline constexpr double kRowRefine = 4;

/// floor(x * inv_h) clamped to +-2^40 (x finite; the clamp keeps huge coordinates from
/// overflowing and is monotone, so the point-in-box argument above still holds).
inline std::int64_t cell_coord(double x, double inv_h) {
  constexpr double limit = 1099511627776.0;  // 2^40
  double v = x * inv_h;
  if (!(v < limit)) v = limit;
  if (!(v > -limit)) v = -limit;
  // floor without a libm call: truncation rounds towards zero, one too high below 0.
  const auto c = static_cast<std::int64_t>(v);
  return c - (static_cast<double>(c) > v ? 1 : 0);
}

/// Key of cell (cx, cy, cz): each coordinate modulo 2^21, packed into 63 bits.
inline std::uint64_t cell_key(std::int64_t cx, std::int64_t cy, std::int64_t cz) {
  constexpr std::uint64_t m = (std::uint64_t{1} << 21) - 1;
  return ((static_cast<std::uint64_t>(cz) & m) << 42) | ((static_cast<std::uint64_t>(cy) & m) << 21) |
         (static_cast<std::uint64_t>(cx) & m);
}

struct KeyIndex {
  std::uint64_t key;
  std::uint32_t index;
};

/// Stable LSD radix sort of `a` by key (8-bit digits; a digit equal in every key is
/// skipped, so keys that differ only in a few bits take a few passes). `scratch` is a
/// reusable buffer.
void radix_sort(std::vector<KeyIndex>& a, std::vector<KeyIndex>& scratch);

/// Integer cell range of a box, inclusive.
struct CellRange {
  std::int64_t lo[3], hi[3];
  bool empty() const { return lo[0] > hi[0] || lo[1] > hi[1] || lo[2] > hi[2]; }
  double count() const {
    return empty() ? 0.0
                   : static_cast<double>(hi[0] - lo[0] + 1) * static_cast<double>(hi[1] - lo[1] + 1) *
                         static_cast<double>(hi[2] - lo[2] + 1);
  }
};

class SpatialHash {
public:
  void set_cell_size(double h);
  double cell_size() const { return h_; }

  /// Pass 1. `points`: vertex indices in ascending order, finite positions in x (n,3);
  /// `label[v]`: the label (object) of vertex v.
  void insert_points(const double* x, const std::vector<index_t>& points, const std::int32_t* label);

  std::size_t num_points() const { return points_.size(); }
  bool dense() const { return dense_; }

  /// Cells of the box, clipped to the cells that hold points (empty when none can).
  CellRange range_of(const Box& b) const {
    CellRange r;
    for (int d = 0; d < 3; ++d) {
      const std::int64_t lo = cell_coord(b.lo[d], inv_[d]), hi = cell_coord(b.hi[d], inv_[d]);
      r.lo[d] = lo > lo_[d] ? lo : lo_[d];
      r.hi[d] = hi < hi_[d] ? hi : hi_[d];
    }
    return r;
  }

  /// Pass 2: f(k0, k1) for runs [k0, k1) of sorted points that together are exactly the
  /// points in the range's cells (runs may be empty).
  template <class F>
  void for_each_run(const CellRange& r, F&& f) const {
    if (r.empty()) return;
    if (dense_) {
      for (std::int64_t cz = r.lo[2]; cz <= r.hi[2]; ++cz)
        for (std::int64_t cy = r.lo[1]; cy <= r.hi[1]; ++cy) {
          const std::size_t row = static_cast<std::size_t>(((cz - lo_[2]) * dim_[1] + (cy - lo_[1])) * dim_[0] - lo_[0]);
          f(start_[row + static_cast<std::size_t>(r.lo[0])], start_[row + static_cast<std::size_t>(r.hi[0]) + 1]);
        }
      return;
    }
    for (std::int64_t cz = r.lo[2]; cz <= r.hi[2]; ++cz)
      for (std::int64_t cy = r.lo[1]; cy <= r.hi[1]; ++cy)
        for (std::int64_t cx = r.lo[0]; cx <= r.hi[0]; ++cx) {
          const std::int32_t c = find(cell_key(cx, cy, cz));
          if (c >= 0) f(start_[static_cast<std::size_t>(c)], start_[static_cast<std::size_t>(c) + 1]);
        }
  }

  /// Sorted point k: vertex point(k), position sorted_x() + 3k, label sorted_label()[k].
  index_t point(std::size_t k) const { return points_[k]; }
  const index_t* sorted_point() const { return points_.data(); }
  const double* sorted_x() const { return px_.data(); }
  const std::int32_t* sorted_label() const { return pl_.data(); }

private:
  std::int32_t find(std::uint64_t key) const;
  void cell_range(const double* x, const std::vector<index_t>& points, double inv_x);
  double h_ = 1, inv_h_ = 1;
  double inv_[3] = {1, 1, 1};              // per axis, 1 / cell length
  bool dense_ = false;
  std::int64_t lo_[3] = {0, 0, 0}, hi_[3] = {-1, -1, -1}, dim_[3] = {0, 0, 0};
  std::vector<std::int64_t> cell_;         // per input point: dense index, or -1
  std::vector<KeyIndex> pairs_, scratch_;  // hashed layout: (key, input position)
  std::vector<std::size_t> start_;         // dense: (cells + 1) run starts; hashed: (occupied + 1)
  std::vector<std::uint64_t> keys_;        // hashed: occupied cells, ascending key
  std::vector<std::int32_t> table_;        // hashed: open addressing, cell index or -1
  int table_bits_ = 0;
  std::vector<std::uint32_t> order_;       // input position of the k-th sorted point
  std::vector<index_t> points_;            // vertices in cell order
  std::vector<double> px_;                 // their positions, (points, 3)
  std::vector<std::int32_t> pl_;           // their labels
};

}  // namespace softcontact::collide
