#pragma once
// What the collision detector precomputes once from the World's connectivity, which
// never changes during a run: per-object lists, the mesh edges as vertex adjacency, the
// surface vertices and their incident triangles, and each tet face's neighbour (another
// tet, or the surface triangle that the face is).
//
// Objects are numbered locally by "slot": the objects present in the World in
// ascending global order. All lists are ascending, so every loop over them has a fixed
// order.
#include <cstdint>
#include <limits>
#include <vector>

#include "softcontact/world.hpp"

namespace softcontact::collide {

/// face_neighbour value of a tet face with no neighbour and no surface triangle (a
/// boundary the World's triangle list does not close); walks stop there.
inline constexpr index_t kOpenFace = std::numeric_limits<index_t>::min();

struct ObjectInfo {
  std::int32_t object = -1;              ///< global object index
  std::vector<index_t> vertices;         ///< all its local vertices
  std::vector<index_t> surface_vertices; ///< those on its surface triangles
  std::vector<index_t> tets;
  std::vector<index_t> triangles;        ///< surface triangles (rows of World::triangles)
  double thickness = 0;                  ///< see thickness.hpp [m]
};

struct CollisionTopology {
  std::vector<ObjectInfo> objects;        ///< by slot
  std::vector<std::int32_t> vertex_slot;  ///< (n_local)
  std::vector<std::int32_t> tet_slot;     ///< (m_local)
  std::vector<std::int32_t> triangle_slot;///< (s_local)

  /// Mesh edges (edges of the tets, each once): neighbours of v are
  /// edge_to[edge_begin[v] .. edge_begin[v + 1]), ascending.
  std::vector<std::size_t> edge_begin;
  std::vector<index_t> edge_to;
  std::vector<std::uint8_t> surface;      ///< (n_local) 1 for a vertex of a surface triangle

  /// Surface triangles incident to vertex v: tri_of[tri_begin[v] .. tri_begin[v + 1]), ascending.
  std::vector<std::size_t> tri_begin;
  std::vector<index_t> tri_of;

  /// (m_local,4): across face j of tet t (the face opposite corner j) lies tet
  /// face_neighbour[4t + j] >= 0, or surface triangle -(face_neighbour[4t + j] + 1), or
  /// kOpenFace.
  std::vector<index_t> face_neighbour;
  /// (m_local) bit j (0..3): face j is not shared with another tet; bit 4 + c: corner c is
  /// a surface vertex (the mask point_in_tet.hpp takes).
  std::vector<std::uint8_t> boundary_mask;

  double mean_edge_length = 0;            ///< over the distinct mesh edges at construction [m]
  std::int64_t open_faces = 0;            ///< faces with neither a neighbour tet nor a triangle
};

/// Builds the topology from the World's tets and triangles (positions: for the mean
/// edge length and the objects' thickness only). `previous`: the topology of an earlier
/// World of the same scene (before a ghost-set change or a migration); the faces and
/// edges of every object it held alike (matching_slots) are taken from it, moved to
/// their new local indices, and only the others are built. The result is the same to the
/// bit as without it.
CollisionTopology build_collision_topology(const World& w, const CollisionTopology* previous = nullptr);

/// Per slot of `now`, the slot of `before` that held the same object numbered alike up
/// to a shift: the same numbers of vertices, tets and surface triangles, each list a
/// contiguous range of local indices in both (World::append_object numbers an object
/// from its mesh, the same way for an owner and a ghost, and the meshes never change
/// during a run). -1: none; the object's pieces are built.
std::vector<std::int32_t> matching_slots(const CollisionTopology& now, const CollisionTopology& before);

}  // namespace softcontact::collide
