#pragma once
// Between the YAML parser and the placement of objects: one scene entry before it is
// instantiated into objects.
#include <array>
#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "softcontact/scene.hpp"

namespace softcontact {

using Mat3 = std::array<double, 9>;  ///< row-major 3x3

Mat3 rotation_xyz_degrees(const Vec3& angles);           ///< R = Rz * Ry * Rx (x applied first)
Mat3 rotation_axis_angle(const Vec3& axis, double deg);  ///< Rodrigues' formula

struct EntrySpec {
  enum class Instancing { single, grid, random };
  std::string name;
  std::string source;
  int index = -1;                 ///< position among the scene's entries (SceneObject::entry)
  int material = 0;
  TetMesh mesh;                   ///< in the mesh's own coordinates
  /// Makes `mesh` again, bitwise (the file read again, the primitive generated again);
  /// none: the entry's objects keep their meshes (Placement::Kind::kept).
  std::function<TetMesh()> remake;
  Vec3 scale{1, 1, 1};
  Mat3 rotation{1, 0, 0, 0, 1, 0, 0, 0, 1};
  Vec3 translate{};
  Vec3 velocity{};
  bool kinematic = false;
  std::vector<Box> fixed;
  Motion motion;
  Instancing instancing = Instancing::single;
  std::array<int, 3> grid_count{1, 1, 1};
  Vec3 grid_spacing{};
  int random_count = 0;
  Box region;
  std::uint64_t seed = 1;
  bool random_rotate = false;
};

/// A random entry whose copies have their slots in the scene's objects, [first, first +
/// spec.random_count), but are not placed yet: place_random places them. Each slot's
/// Placement already holds the entry's transformed mesh and its bounding sphere's centre;
/// `radius` is that sphere's radius.
struct PendingRandom {
  EntrySpec spec;  ///< without its mesh (the slots' Placement::base holds it)
  double radius = 0;
  std::size_t first = 0;
};

/// Places the entry's copies (x' = R (S x) + t, then the instance offset) and appends
/// them to `objects`. Random placement rejects copies whose bounding sphere overlaps an
/// object placed before; throws InputError(detail) when the region is too small.
/// With hold_meshes false, the copies of a grid or random entry keep only their shape and
/// placement (SceneObject::mesh empty; Scene::mesh makes it).
/// With `pending`, a random entry's copies only take their slots (names, counts, the
/// recipe without rotation and offset) and the entry joins `pending`, for place_random.
void instantiate(const EntrySpec& spec, std::vector<SceneObject>& objects, bool hold_meshes = true,
                 std::vector<PendingRandom>* pending = nullptr);

/// The object of a single-copy entry whose mesh another rank made (parse_objects: each
/// single-copy entry's mesh is made by one rank): no mesh here; its placement makes it
/// again from the entry's source when this rank needs it, checked against `digest`, the
/// one that rank computed; `shape` is what that rank measured. spec.remake must be set.
SceneObject single_made_elsewhere(const EntrySpec& spec, std::uint64_t digest, const ObjectShape& shape);

/// A random entry that could not be placed: its position in `pending`, and why.
struct PlacementFailure {
  std::size_t entry = 0;
  std::string detail;
};

/// Places the copies of the pending random entries, exactly as one by one in scene order.
/// An entry's placement depends only on the objects before it that come within one copy
/// radius of its region, so entries whose regions (each widened by its copy radius) do
/// not overlap, directly or through others, are independent: these groups are shared out
/// over limits.parts (the most copies first, each to the part with the fewest so far),
/// each part places its groups, and limits.gather gives every part every copy's rotation,
/// offset and box (18 doubles), the same to the bit as one part placing all. Without
/// limits.gather (or with one part) every group is placed here. Returns the first entry,
/// in scene order, that does not fit its region.
std::optional<PlacementFailure> place_random(std::vector<PendingRandom>& pending, std::vector<SceneObject>& objects,
                                             bool hold_meshes, const SceneLimits& limits);

namespace detail {
std::size_t edit_distance(const std::string& a, const std::string& b);
std::string nearest(const std::string& word, const std::vector<std::string>& candidates);
}  // namespace detail

}  // namespace softcontact
