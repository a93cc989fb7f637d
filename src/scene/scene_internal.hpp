#pragma once
// Between the YAML parser and the placement of objects: one scene entry before it is
// instantiated into objects.
#include <array>
#include <cstdint>
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

/// Places the entry's copies (x' = R (S x) + t, then the instance offset) and appends
/// them to `objects`. Random placement rejects copies whose bounding sphere overlaps an
/// object placed before; throws InputError(detail) when the region is too small.
/// With hold_meshes false, the copies of a grid or random entry keep only their shape and
/// placement (SceneObject::mesh empty; Scene::mesh makes it).
void instantiate(const EntrySpec& spec, std::vector<SceneObject>& objects, bool hold_meshes = true);

namespace detail {
std::size_t edit_distance(const std::string& a, const std::string& b);
std::string nearest(const std::string& word, const std::vector<std::string>& candidates);
}  // namespace detail

}  // namespace softcontact
