// Scene entries -> placed objects: transforms, grid copies and seeded random placement.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <memory>
#include <random>
#include <sstream>
#include <unordered_map>
#include <vector>

#include "scene_internal.hpp"
#include "softcontact/error.hpp"

namespace softcontact {

namespace {

Mat3 mul(const Mat3& a, const Mat3& b) {
  Mat3 c{};
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      for (int k = 0; k < 3; ++k) c[3 * i + j] += a[3 * i + k] * b[3 * k + j];
  return c;
}

/// A double in [0, 1) from 53 random bits: unlike std::uniform_real_distribution, whose
/// algorithm is implementation-defined, this gives the same placement on every platform.
double unit(std::mt19937_64& g) { return static_cast<double>(g() >> 11) * 0x1.0p-53; }

/// Uniformly distributed rotation (Shoemake's method: a uniform unit quaternion).
Mat3 random_rotation(std::mt19937_64& g) {
  const double u1 = unit(g), u2 = 2 * M_PI * unit(g), u3 = 2 * M_PI * unit(g);
  const double a = std::sqrt(1 - u1), b = std::sqrt(u1);
  const double w = a * std::sin(u2), x = a * std::cos(u2), y = b * std::sin(u3), z = b * std::cos(u3);
  return {1 - 2 * (y * y + z * z), 2 * (x * y - z * w),     2 * (x * z + y * w),
          2 * (x * y + z * w),     1 - 2 * (x * x + z * z), 2 * (y * z - x * w),
          2 * (x * z - y * w),     2 * (y * z + x * w),     1 - 2 * (x * x + y * y)};
}

TetMesh transformed(const TetMesh& m, const Vec3& scale, const Mat3& R, const Vec3& t) {
  TetMesh out = m;
  for (std::size_t i = 0; i < m.num_vertices(); ++i) {
    const double s[3] = {m.points[3 * i] * scale[0], m.points[3 * i + 1] * scale[1], m.points[3 * i + 2] * scale[2]};
    for (int r = 0; r < 3; ++r) out.points[3 * i + r] = R[3 * r] * s[0] + R[3 * r + 1] * s[1] + R[3 * r + 2] * s[2] + t[r];
  }
  // A reflection (never produced here: scales are positive) would invert every tet.
  return out;
}

struct Sphere {
  Vec3 c;
  double r;
};

Sphere bounding_sphere(const TetMesh& m) {
  Vec3 lo{HUGE_VAL, HUGE_VAL, HUGE_VAL}, hi{-HUGE_VAL, -HUGE_VAL, -HUGE_VAL};
  for (std::size_t i = 0; i < m.num_vertices(); ++i)
    for (int d = 0; d < 3; ++d) {
      lo[d] = std::min(lo[d], m.points[3 * i + d]);
      hi[d] = std::max(hi[d], m.points[3 * i + d]);
    }
  Sphere s{{(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, (lo[2] + hi[2]) / 2}, 0};
  for (std::size_t i = 0; i < m.num_vertices(); ++i)
    s.r = std::max(s.r, std::hypot(m.points[3 * i] - s.c[0], m.points[3 * i + 1] - s.c[1], m.points[3 * i + 2] - s.c[2]));
  return s;
}

Box bounding_box(const TetMesh& m) {
  Box b = Box::none();
  for (std::size_t i = 0; i < m.num_vertices(); ++i) b.add(&m.points[3 * i]);
  return b;
}

/// The boxes of the objects placed so far, asked whether a sphere reaches into any of
/// them. Testing every box made random placement of n copies O(n^2) box tests (hours for
/// the allowed 10^6 copies); here boxes sit in a uniform grid of cells one sphere
/// diameter wide, so a query looks at the 8 cells around the sphere. Boxes that span many
/// cells (a floor plate) or lie too far out for the integer cell numbers are kept in a
/// list tested one by one. The answer is the same as testing every box.
class BoxIndex {
public:
  BoxIndex(const Vec3& origin, double cell) : origin_(origin), cell_(cell) {}

  void add(const Box& b) {
    const std::size_t id = boxes_.size();
    boxes_.push_back(b);
    std::array<std::int64_t, 3> lo{}, hi{};
    if (!cells_of(b.lo, b.hi, lo, hi) || span(lo, hi) > kMaxCellsPerBox) {
      big_.push_back(id);
      return;
    }
    for (std::int64_t i = lo[0]; i <= hi[0]; ++i)
      for (std::int64_t j = lo[1]; j <= hi[1]; ++j)
        for (std::int64_t k = lo[2]; k <= hi[2]; ++k) grid_[{i, j, k}].push_back(id);
  }

  /// Whether the ball of radius r about c reaches into (strictly overlaps) a box.
  bool reaches(const Vec3& c, double r) const {
    const auto hits = [&](std::size_t id) {
      const Box& b = boxes_[id];
      double d2 = 0;  // squared distance from c to the box
      for (int k = 0; k < 3; ++k) {
        const double e = std::max({b.lo[k] - c[k], 0.0, c[k] - b.hi[k]});
        d2 += e * e;
      }
      return d2 < r * r;
    };
    if (std::any_of(big_.begin(), big_.end(), hits)) return true;
    std::array<std::int64_t, 3> lo{}, hi{};
    if (!cells_of({c[0] - r, c[1] - r, c[2] - r}, {c[0] + r, c[1] + r, c[2] + r}, lo, hi) ||
        span(lo, hi) > kMaxCellsPerBox) {
      // Off the grid: every box (as before the index; only for degenerate regions).
      for (std::size_t id = 0; id < boxes_.size(); ++id)
        if (hits(id)) return true;
      return false;
    }
    for (std::int64_t i = lo[0]; i <= hi[0]; ++i)
      for (std::int64_t j = lo[1]; j <= hi[1]; ++j)
        for (std::int64_t k = lo[2]; k <= hi[2]; ++k)
          if (const auto it = grid_.find({i, j, k}); it != grid_.end() && std::any_of(it->second.begin(), it->second.end(), hits))
            return true;
    return false;
  }

private:
  static constexpr std::int64_t kMaxCellsPerBox = 64;
  using Cell = std::array<std::int64_t, 3>;
  struct CellHash {
    std::size_t operator()(const Cell& c) const {
      std::uint64_t h = 0x9E3779B97F4A7C15ull;
      for (std::int64_t v : c) h = (h ^ static_cast<std::uint64_t>(v)) * 0x100000001B3ull;
      return static_cast<std::size_t>(h ^ (h >> 29));
    }
  };

  static std::int64_t span(const Cell& lo, const Cell& hi) {
    return (hi[0] - lo[0] + 1) * (hi[1] - lo[1] + 1) * (hi[2] - lo[2] + 1);
  }
  /// Cell numbers of the box [a, b]; false when they do not fit a 64-bit integer safely.
  bool cells_of(const Vec3& a, const Vec3& b, Cell& lo, Cell& hi) const {
    constexpr double kLimit = 0x1.0p52;
    if (!(cell_ > 0 && std::isfinite(cell_))) return false;
    for (int d = 0; d < 3; ++d) {
      const double l = std::floor((a[d] - origin_[d]) / cell_), h = std::floor((b[d] - origin_[d]) / cell_);
      if (!(std::abs(l) < kLimit && std::abs(h) < kLimit) || h - l > kMaxCellsPerBox) return false;
      lo[d] = static_cast<std::int64_t>(l);
      hi[d] = static_cast<std::int64_t>(h);
    }
    return true;
  }

  Vec3 origin_;
  double cell_;
  std::vector<Box> boxes_;
  std::vector<std::size_t> big_;
  std::unordered_map<Cell, std::vector<std::size_t>, CellHash> grid_;
};

/// What the entry's objects share (one instance for all its copies).
std::shared_ptr<const ObjectTraits> traits_of(const EntrySpec& spec) {
  ObjectTraits t;
  t.source = spec.source;
  t.velocity = spec.velocity;
  t.kinematic = spec.kinematic;
  t.fixed = spec.fixed;
  t.motion = spec.motion;
  return std::make_shared<const ObjectTraits>(std::move(t));
}

/// An object of the entry; a copy without its mesh gets its shape from the caller.
SceneObject make_object(const EntrySpec& spec, const std::shared_ptr<const ObjectTraits>& traits, TetMesh mesh,
                        const std::string& name, Placement placement = {}) {
  SceneObject o;
  o.name = name;
  o.material = spec.material;
  o.mesh = std::move(mesh);
  o.placement = std::move(placement);
  o.traits = traits;
  o.entry = spec.index;
  return o;
}

}  // namespace

Mat3 rotation_xyz_degrees(const Vec3& e) {
  const double k = M_PI / 180;
  const double cx = std::cos(e[0] * k), sx = std::sin(e[0] * k);
  const double cy = std::cos(e[1] * k), sy = std::sin(e[1] * k);
  const double cz = std::cos(e[2] * k), sz = std::sin(e[2] * k);
  const Mat3 rx{1, 0, 0, 0, cx, -sx, 0, sx, cx};
  const Mat3 ry{cy, 0, sy, 0, 1, 0, -sy, 0, cy};
  const Mat3 rz{cz, -sz, 0, sz, cz, 0, 0, 0, 1};
  return mul(rz, mul(ry, rx));
}

Mat3 rotation_axis_angle(const Vec3& axis, double deg) {
  const double len = std::hypot(axis[0], axis[1], axis[2]);
  const double x = axis[0] / len, y = axis[1] / len, z = axis[2] / len;
  const double a = deg * M_PI / 180, c = std::cos(a), s = std::sin(a), C = 1 - c;
  return {c + x * x * C,     x * y * C - z * s, x * z * C + y * s,
          y * x * C + z * s, c + y * y * C,     y * z * C - x * s,
          z * x * C - y * s, z * y * C + x * s, c + z * z * C};
}

namespace {
/// How to make the entry's mesh again as its transform places it (none without a remake).
std::function<TetMesh()> placed_remake(const EntrySpec& spec) {
  if (!spec.remake) return {};
  return [make = spec.remake, scale = spec.scale, rotation = spec.rotation, translate = spec.translate] {
    return transformed(make(), scale, rotation, translate);
  };
}
std::string entry_source(const EntrySpec& spec) { return "object '" + spec.name + "' (" + spec.source + ")"; }
}  // namespace

SceneObject single_made_elsewhere(const EntrySpec& spec, std::uint64_t digest, const ObjectShape& shape) {
  Placement p;
  p.kind = Placement::Kind::entry;
  p.base = EntryMesh::made_elsewhere(entry_source(spec), digest, placed_remake(spec));
  SceneObject o = make_object(spec, traits_of(spec), TetMesh(), spec.name, std::move(p));
  o.shape = shape;
  return o;
}

void instantiate(const EntrySpec& spec, std::vector<SceneObject>& objects, bool hold_meshes,
                 std::vector<PendingRandom>* pending) {
  // The entry's mesh as its transform places it, and how to make it again.
  std::function<TetMesh()> remake = placed_remake(spec);
  const std::string source = entry_source(spec);
  const std::shared_ptr<const ObjectTraits> traits = traits_of(spec);
  TetMesh placed = transformed(spec.mesh, spec.scale, spec.rotation, spec.translate);
  if (spec.instancing == EntrySpec::Instancing::single) {
    // The object is the entry: its mesh is held by the object, and the entry keeps only
    // how to make it again (Placement::Kind::entry), when it can.
    Placement p;
    if (remake) {
      p.kind = Placement::Kind::entry;
      p.base = EntryMesh::recipe(source, placed, std::move(remake));
    }
    objects.push_back(make_object(spec, traits, std::move(placed), spec.name, std::move(p)));
    return;
  }
  // Copies keep the entry's mesh once, shared, and how each is placed from it, so that a
  // rank can drop the copies it does not need and make them again bitwise the same
  // (Placement::place, which places them here too).
  const auto shared = EntryMesh::held(source, std::move(placed), std::move(remake));
  const TetMesh& base = shared->get();
  ObjectShape copy_shape;  // counts shared by all copies (the boundary is a matter of topology)
  copy_shape.vertices = base.num_vertices();
  copy_shape.tets = base.num_tets();
  copy_shape.triangles = hold_meshes ? 0 : extract_surface(base).num_triangles();
  switch (spec.instancing) {
    case EntrySpec::Instancing::single:
      return;
    case EntrySpec::Instancing::grid: {
      // Without its mesh a grid copy needs only its box, and that is the entry's box
      // moved by the offset, to the bit: Placement::place adds the offset to each
      // coordinate once (x = q + o; the products with 0 and 1 change no value), and
      // rounding is monotonic, so the smallest of the fl(q + o) is fl(min q + o), the
      // largest likewise. So no copy is placed here (only the sign of a zero bound can
      // differ, and -0 == +0 in every comparison of boxes).
      Box base_box = Box::none();
      for (std::size_t i = 0; i < base.num_vertices(); ++i) add_point(base_box, &base.points[3 * i]);
      int k = 0;
      for (int iz = 0; iz < spec.grid_count[2]; ++iz)
        for (int iy = 0; iy < spec.grid_count[1]; ++iy)
          for (int ix = 0; ix < spec.grid_count[0]; ++ix) {
            Placement p;
            p.kind = Placement::Kind::offset;
            p.base = shared;
            p.offset = {ix * spec.grid_spacing[0], iy * spec.grid_spacing[1], iz * spec.grid_spacing[2]};
            const std::string name = spec.name + "[" + std::to_string(k++) + "]";
            if (hold_meshes) {
              TetMesh m = p.place();
              objects.push_back(make_object(spec, traits, std::move(m), name, std::move(p)));
              continue;
            }
            ObjectShape s = copy_shape;
            for (int d = 0; d < 3; ++d) {
              s.box.lo[d] = base_box.lo[d] + p.offset[d];
              s.box.hi[d] = base_box.hi[d] + p.offset[d];
            }
            SceneObject o = make_object(spec, traits, TetMesh(), name, std::move(p));
            o.shape = s;
            objects.push_back(std::move(o));
          }
      return;
    }
    case EntrySpec::Instancing::random: {
      // The copies take their slots now and are placed by place_random: at once here, or
      // after every entry is read when the caller shares the placement over ranks.
      const Sphere own = bounding_sphere(base);
      for (int d = 0; d < 3; ++d)
        if (spec.region.hi[d] - spec.region.lo[d] < 2 * own.r) {
          std::ostringstream s;
          s << "the 'random.region' is narrower than one copy (bounding diameter " << 2 * own.r
            << " m) along axis " << "xyz"[d];
          throw InputError(s.str());
        }
      PendingRandom entry;
      entry.spec = spec;
      entry.spec.mesh = TetMesh();
      entry.radius = own.r;
      entry.first = objects.size();
      for (int k = 0; k < spec.random_count; ++k) {
        Placement p;
        p.kind = Placement::Kind::about_centre;
        p.base = shared;
        p.centre = own.c;
        // a slot: counts and an empty box until placed (the box of a mesh-holding copy
        // is dropped again when it is placed)
        SceneObject o = make_object(spec, traits, TetMesh(), spec.name + "[" + std::to_string(k) + "]", std::move(p));
        o.shape = copy_shape;
        o.shape->box = Box::none();
        objects.push_back(std::move(o));
      }
      if (pending) {
        pending->push_back(std::move(entry));
        return;
      }
      std::vector<PendingRandom> one{std::move(entry)};
      if (const auto failed = place_random(one, objects, hold_meshes, SceneLimits{})) throw InputError(failed->detail);
      return;
    }
  }
}

namespace {

/// Doubles per placed copy in the records that place_random shares: rotation (9), offset
/// (3), box (6). Each entry's record starts with kEntryHeader doubles: its position in
/// `pending`, copies placed, failed (0 or 1), attempts in all and for the copy that failed.
constexpr std::size_t kCopyDoubles = 18, kEntryHeader = 5;

/// Rejection sampling of one pending entry's centres (and rotations), deterministic for
/// its seed: a copy's bounding sphere must not reach into the axis-aligned box of
/// anything placed before it (boxes rather than spheres for those: the bounding sphere of
/// a wide floor plate would cover the whole region above it). Appends the entry's record
/// to `out` and fills its slots' boxes (the later entries of its group index them).
/// Returns false when the region is full.
bool place_entry(std::size_t position, const PendingRandom& e, bool hold_meshes, std::vector<SceneObject>& objects,
                 std::vector<double>& out) {
  const EntrySpec& spec = e.spec;
  const double r = e.radius;
  BoxIndex placed(spec.region.lo, 2 * r);
  // A copy's ball lies in the region (its centre keeps r from every side), so a box
  // farther than r from the region cannot be reached by one (it is more than 2r from
  // every centre, far beyond rounding): only the others before the entry are indexed.
  // The answers are those of indexing every earlier object; slots not placed yet hold
  // an empty box, and by place_random's grouping none of them can come near.
  Box near = spec.region;
  for (int d = 0; d < 3; ++d) {
    near.lo[d] -= r;
    near.hi[d] += r;
  }
  for (std::size_t i = 0; i < e.first; ++i) {
    const SceneObject& o = objects[i];
    const Box b = o.shape ? o.shape->box : bounding_box(o.mesh);
    if (b.overlaps(near)) placed.add(b);
  }
  const std::size_t header = out.size();
  out.insert(out.end(), {static_cast<double>(position), 0, 0, 0, 0});
  const Mat3 identity{1, 0, 0, 0, 1, 0, 0, 0, 1};
  std::mt19937_64 gen(spec.seed);
  // At most 1000 attempts per copy on average, and 100000 for one copy: a region that
  // is full ends the placement at once instead of after up to 10^9 attempts.
  const std::int64_t max_attempts = 1000 + 1000 * static_cast<std::int64_t>(spec.random_count);
  constexpr std::int64_t kMaxAttemptsPerCopy = 100000;
  std::int64_t attempts = 0;
  for (int k = 0; k < spec.random_count; ++k) {
    for (std::int64_t tries = 1;; ++tries) {
      if (++attempts > max_attempts || tries > kMaxAttemptsPerCopy) {
        out[header + 1] = k;
        out[header + 2] = 1;
        out[header + 3] = static_cast<double>(attempts - 1);
        out[header + 4] = static_cast<double>(tries - 1);
        return false;
      }
      Vec3 c;
      for (int d = 0; d < 3; ++d) c[d] = spec.region.lo[d] + r + unit(gen) * (spec.region.hi[d] - spec.region.lo[d] - 2 * r);
      const Mat3 R = spec.random_rotate ? random_rotation(gen) : identity;
      if (placed.reaches(c, r)) continue;
      // rotate about the copy's own centre, then move the centre to c
      SceneObject& o = objects[e.first + static_cast<std::size_t>(k)];
      o.placement.rotation = R;
      o.placement.offset = c;
      TetMesh m = o.placement.place();
      placed.add(bounding_box(m));
      Box shape_box = Box::none();  // as make_object measures a copy's shape
      for (std::size_t i = 0; i < m.num_vertices(); ++i) add_point(shape_box, &m.points[3 * i]);
      o.shape->box = shape_box;
      if (hold_meshes) o.mesh = std::move(m);  // kept, not placed again from the records
      out.insert(out.end(), R.begin(), R.end());
      out.insert(out.end(), c.begin(), c.end());
      out.insert(out.end(), shape_box.lo.begin(), shape_box.lo.end());
      out.insert(out.end(), shape_box.hi.begin(), shape_box.hi.end());
      break;
    }
  }
  out[header + 1] = spec.random_count;
  return true;
}

std::size_t find_root(std::vector<std::size_t>& parent, std::size_t i) {
  while (parent[i] != i) i = parent[i] = parent[parent[i]];
  return i;
}

}  // namespace

std::optional<PlacementFailure> place_random(std::vector<PendingRandom>& pending, std::vector<SceneObject>& objects,
                                             bool hold_meshes, const SceneLimits& limits) {
  const std::size_t n = pending.size();
  if (n == 0) return std::nullopt;
  // Groups: entries whose regions, each widened by its copy radius, overlap (a sweep
  // along x over the widened regions, then union-find). A copy's box lies in its ball,
  // which lies in its region to rounding, so no box of one group comes within a copy
  // radius of another group's region.
  std::vector<Box> reach(n);
  for (std::size_t i = 0; i < n; ++i) {
    reach[i] = pending[i].spec.region;
    for (int d = 0; d < 3; ++d) {
      reach[i].lo[d] -= pending[i].radius;
      reach[i].hi[d] += pending[i].radius;
    }
  }
  std::vector<std::size_t> by_x(n), parent(n);
  for (std::size_t i = 0; i < n; ++i) by_x[i] = parent[i] = i;
  std::sort(by_x.begin(), by_x.end(), [&](std::size_t a, std::size_t b) {
    return reach[a].lo[0] < reach[b].lo[0] || (reach[a].lo[0] == reach[b].lo[0] && a < b);
  });
  for (std::size_t a = 0; a < n; ++a)
    for (std::size_t b = a + 1; b < n && reach[by_x[b]].lo[0] <= reach[by_x[a]].hi[0]; ++b)
      if (reach[by_x[a]].overlaps(reach[by_x[b]])) parent[find_root(parent, by_x[a])] = find_root(parent, by_x[b]);
  std::vector<std::vector<std::size_t>> groups;  // entries in scene order, groups by their first entry
  std::vector<std::size_t> group_of_root(n, n);
  for (std::size_t i = 0; i < n; ++i) {
    std::size_t& g = group_of_root[find_root(parent, i)];
    if (g == n) {
      g = groups.size();
      groups.emplace_back();
    }
    groups[g].push_back(i);
  }

  // Groups to parts: the most copies first (ties: the earlier group), each to the part
  // with the fewest copies so far (ties: the lower part). Every part computes the same.
  const bool shared = limits.parts > 1 && limits.gather;
  const int parts = shared ? limits.parts : 1, part = shared ? limits.part : 0;
  std::vector<double> copies(groups.size(), 0);
  for (std::size_t g = 0; g < groups.size(); ++g)
    for (std::size_t i : groups[g]) copies[g] += pending[i].spec.random_count;
  std::vector<std::size_t> order(groups.size());
  for (std::size_t g = 0; g < order.size(); ++g) order[g] = g;
  std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return copies[a] > copies[b]; });
  std::vector<double> load(static_cast<std::size_t>(parts), 0);
  std::vector<double> mine;
  for (std::size_t g : order) {
    const std::size_t p = static_cast<std::size_t>(std::min_element(load.begin(), load.end()) - load.begin());
    load[p] += copies[g];
    if (static_cast<int>(p) != part) continue;
    for (std::size_t i : groups[g])
      if (!place_entry(i, pending[i], hold_meshes, objects, mine)) break;  // the rest of the group cannot matter
  }
  const std::vector<double> all = shared ? limits.gather(mine) : mine;

  // Every copy from the records: the same rotation, offset and box on every part.
  std::optional<PlacementFailure> failed;
  for (std::size_t at = 0; at < all.size();) {
    const std::size_t i = static_cast<std::size_t>(all[at]);
    const int placed = static_cast<int>(all[at + 1]);
    const PendingRandom& e = pending[i];
    if (all[at + 2] != 0 && (!failed || i < failed->entry)) {
      std::ostringstream s;
      s << "could place only " << placed << " of " << e.spec.random_count
        << " non-overlapping copies in 'random.region' after " << static_cast<std::int64_t>(all[at + 3]) << " attempts ("
        << static_cast<std::int64_t>(all[at + 4]) << " for copy " << placed + 1 << "); enlarge the region or lower the count";
      failed = PlacementFailure{i, s.str()};
    }
    at += kEntryHeader;
    for (int k = 0; k < placed; ++k, at += kCopyDoubles) {
      SceneObject& o = objects[e.first + static_cast<std::size_t>(k)];
      std::copy_n(&all[at], 9, o.placement.rotation.begin());
      std::copy_n(&all[at + 9], 3, o.placement.offset.begin());
      if (hold_meshes) {
        if (o.mesh.points.empty()) o.mesh = o.placement.place();  // placed on another part
        o.shape.reset();
      } else {
        std::copy_n(&all[at + 12], 3, o.shape->box.lo.begin());
        std::copy_n(&all[at + 15], 3, o.shape->box.hi.begin());
      }
    }
  }
  return failed;
}

}  // namespace softcontact
