#pragma once
// The rank-local simulation state (design.md, "Data"): structure of arrays, interleaved
// xyz per vertex, global ids that never change, owned entities first and ghosts after.
// Ghosts are whole objects of other ranks that lie within reach of this rank's objects
// (docs/architecture.md, "Parallel step"): their static data (masses, tets, surface) is
// built from the scene, their positions come through the halo exchange.
//
// Global numbering: objects in scene order; an object's vertices, tets and surface
// triangles take consecutive global ids, so global order = scene order everywhere
// (HDF5 rows, diagnostics, summation order).

#include <cstdint>
#include <string>
#include <vector>

#include "softcontact/mesh.hpp"
#include "softcontact/scene.hpp"
#include "softcontact/surface.hpp"

namespace softcontact {

/// Where one object sits in the global numbering, and which rank owns it.
struct ObjectLayout {
  gid_t vertex_begin = 0, vertex_count = 0;
  gid_t tet_begin = 0, tet_count = 0;
  gid_t triangle_begin = 0, triangle_count = 0;
  int rank = 0;
};

struct World {
  // ---- global, identical on every rank
  std::vector<ObjectLayout> layout;     ///< per object
  gid_t global_vertices = 0, global_tets = 0, global_triangles = 0;

  // ---- rank-local
  std::vector<int> owned_objects;       ///< ascending object indices owned by this rank
  /// Per owned object (owned_objects' order): the prescribed motion of its fixed vertices.
  /// Only the owned objects' (a step moves only owned vertices): a table of the whole
  /// scene's would be 40 bytes per object on every rank, and scanned every step.
  std::vector<Motion> owned_motion;
  std::vector<int> ghost_objects;       ///< ascending object indices held as ghosts
  std::vector<index_t> vertex_offset;   ///< per object: local index of its first vertex, -1 if absent
  std::size_t n_owned = 0;              ///< vertices [0, n_owned) are owned
  std::size_t m_owned = 0;              ///< tets [0, m_owned) belong to owned objects
  std::size_t s_owned = 0;              ///< surface triangles [0, s_owned) belong to owned objects
  std::vector<gid_t> vertex_gid;        ///< (n_local)
  std::vector<std::int32_t> vertex_object;
  std::vector<double> x;                ///< (n_local,3) positions x^t [m]
  std::vector<double> x_prev;           ///< (n_local,3) the previous step's positions: x^(t-dt) between steps (position
                                        ///< Verlet's second state), x^t within a step once x holds x~
  std::vector<double> v;                ///< (n_local,3) velocities [m/s]
  std::vector<double> mass;             ///< (n_local) lumped mass [kg] (finite, also for fixed vertices)
  std::vector<double> inv_mass;         ///< (n_local) 1/m, 0 for kinematic vertices

  std::vector<index_t> tets;            ///< (m_local,4) local vertex indices
  std::vector<gid_t> tet_gid;
  std::vector<std::int32_t> tet_object;
  std::vector<double> rest_volume;      ///< (m_local) [m^3]

  std::vector<index_t> triangles;       ///< (s_local,3) local vertex indices, outward
  std::vector<gid_t> triangle_gid;

  std::size_t n_local() const { return vertex_gid.size(); }
  /// Local index of a global vertex id of an object present on this rank.
  index_t local_vertex(int object, gid_t gid) const {
    return vertex_offset[static_cast<std::size_t>(object)] +
           static_cast<index_t>(gid - layout[static_cast<std::size_t>(object)].vertex_begin);
  }
  bool owns_object(int object) const { return layout[static_cast<std::size_t>(object)].rank == rank; }
  int rank = 0;                         ///< this rank
};

/// Objects -> ranks in contiguous blocks of about equal tet count. Objects are never
/// split. (Simulations partition with METIS, partition.hpp; this is for tests and tools.)
std::vector<int> block_partition(const Scene& scene, int nranks);

/// Builds the rank-local state of `rank`: global layout of all objects, then the owned
/// objects' vertices (lumped masses: a quarter of each incident tet's mass), tets and
/// outward surface triangles. Vertices of kinematic objects and inside `fixed` boxes get
/// inverse mass 0. No ghosts (set_ghost_objects adds them).
/// Every object's counts come from Scene::shape, the owned objects' meshes from Scene::mesh.
World build_world(const Scene& scene, const std::vector<int>& object_rank, int rank);

/// Replaces the ghost part of `w` by the objects `ghosts` (ascending, none owned): their
/// vertices, tets and surface triangles from the scene, with initial positions (the halo
/// exchange overwrites them). The owned part, and so every owned local index, is kept.
void set_ghost_objects(World& w, const Scene& scene, const std::vector<int>& ghosts);

/// Contiguous runs [begin, begin+count) of global vertex ids owned by this rank, in
/// ascending order (what a rank writes to the global datasets).
struct GidRun {
  gid_t begin, count;
};
std::vector<GidRun> owned_vertex_runs(const World& w);
std::vector<GidRun> owned_tet_runs(const World& w);
std::vector<GidRun> owned_triangle_runs(const World& w);

}  // namespace softcontact
