#pragma once
// The rank-local simulation state (design.md, "Data"): structure of arrays, interleaved
// xyz per vertex, global ids that never change, owned entities first and ghosts after
// (ghost ranges are empty until the MPI layer adds halos).
//
// Global numbering: objects in scene order; an object's vertices, tets and surface
// triangles take consecutive global ids, so global order = scene order everywhere
// (HDF5 rows, diagnostics, summation order).
#include <mpi.h>

#include <cstdint>
#include <string>
#include <vector>

#include "softcontact/mesh.hpp"
#include "softcontact/scene.hpp"

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
  std::vector<Motion> motion;           ///< per object: prescribed motion of its fixed vertices

  // ---- rank-local
  std::vector<int> owned_objects;       ///< ascending object indices owned by this rank
  std::size_t n_owned = 0;              ///< vertices [0, n_owned) are owned
  std::vector<gid_t> vertex_gid;        ///< (n_local)
  std::vector<std::int32_t> vertex_object;
  std::vector<double> x;                ///< (n_local,3) positions x^t [m]
  std::vector<double> x_prev;           ///< (n_local,3) x^(t-dt), for position Verlet
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
};

/// Objects -> ranks in contiguous blocks of about equal tet count. Objects are never
/// split. The METIS graph partition (objects near each other on one rank) of the MPI
/// work will replace it; until then contacts never cross ranks because there are none.
std::vector<int> block_partition(const Scene& scene, int nranks);

/// Builds the rank-local state of `rank`: global layout of all objects, then the owned
/// objects' vertices (lumped masses: a quarter of each incident tet's mass), tets and
/// outward surface triangles. Vertices of kinematic objects and inside `fixed` boxes get
/// inverse mass 0.
World build_world(const Scene& scene, const std::vector<int>& object_rank, int rank);

/// Contiguous runs [begin, begin+count) of global vertex ids owned by this rank, in
/// ascending order (what a rank writes to the global datasets).
struct GidRun {
  gid_t begin, count;
};
std::vector<GidRun> owned_vertex_runs(const World& w);
std::vector<GidRun> owned_tet_runs(const World& w);
std::vector<GidRun> owned_triangle_runs(const World& w);

}  // namespace softcontact
