#pragma once
// A uniform grid of cubic cells for softcontact verify (internal): each item (a tet, a
// surface triangle) is listed in every cell its bounding box touches (CSR). A grid of at
// most 4 cells per entry keeps an offset per cell; a larger one (objects flown apart)
// stores only the occupied cells, as sorted keys, so that it costs memory only where
// items are. Its own code, not the detector's spatial hash (verify.hpp).
#include <array>
#include <cstdint>
#include <span>
#include <vector>

namespace softcontact::verify {

class CellBins {
public:
  using Cell = std::array<std::int64_t, 3>;
  /// Cells per axis; coordinates beyond are clamped into the first or last cell (still
  /// correct, only slower), so keys fit 3 x 21 bits.
  static constexpr std::int64_t kMaxCells = std::int64_t{1} << 21;
  /// Items whose box touches more cells than this are kept apart and offered to every
  /// query (a blown-up tet must not fill memory).
  static constexpr std::int64_t kMaxCellsPerItem = 4096;

  /// Bins `count` items with boxes lo, hi (count,3) in cells of edge `cell` [m]. Items
  /// with a non-finite box are left out. OpenMP; the lists are sorted by item, so the
  /// result does not depend on the thread count.
  void build(double cell, std::size_t count, const double* lo, const double* hi);

  /// The cell of p, clamped; `exact` is false when p lies outside the unclamped grid or is
  /// not finite (then ring searches cannot bound distances by rings).
  Cell cell_of(const double* p, bool* exact = nullptr) const;
  /// Items listed in cell c (empty when none).
  std::span<const std::int32_t> at(const Cell& c) const;
  /// Items too large for the cells: check them in every query.
  const std::vector<std::int32_t>& oversized() const { return oversized_; }
  /// The first cell of item i's box (only for items in the cells).
  const Cell& first_cell(std::size_t i) const { return first_[i]; }
  bool binned(std::size_t i) const { return binned_[i] != 0; }
  double cell_size() const { return h_; }
  /// Distance from p to the nearest face of cell c (0 when p is not inside c): an item
  /// that is not listed in the (2r+1)^3 block of cells around c is farther from p than
  /// r * cell_size() + this.
  double inner_distance(const double* p, const Cell& c) const;
  /// Distance from p to cell c (0 when p is inside c).
  double distance_to_cell(const double* p, const Cell& c) const;
  std::int64_t dim(int axis) const { return dims_[static_cast<std::size_t>(axis)]; }

private:
  static std::uint64_t key(const Cell& c) {
    return (static_cast<std::uint64_t>(c[0]) << 42) | (static_cast<std::uint64_t>(c[1]) << 21) |
           static_cast<std::uint64_t>(c[2]);
  }
  std::int64_t linear(const Cell& c) const { return (c[0] * dims_[1] + c[1]) * dims_[2] + c[2]; }
  double h_ = 1, inv_h_ = 1;
  bool dense_ = false;                 // begin_ has an offset per cell, keys_ is empty
  double origin_[3] = {0, 0, 0};
  std::array<std::int64_t, 3> dims_{1, 1, 1};
  std::vector<std::uint64_t> keys_;    // sparse: occupied cells, ascending
  std::vector<std::int64_t> begin_;    // (cells+1) or (keys+1) offsets into items_
  std::vector<std::int32_t> items_;
  std::vector<std::int32_t> oversized_;
  std::vector<Cell> first_;
  std::vector<char> binned_;
};

}  // namespace softcontact::verify
