#pragma once
// Internal forces of the deformation models: the "black box" p(x) of step 1 of the
// paper's Algorithm 1 (method.md), plus Rayleigh damping. docs/models.md describes the
// models (energies, stresses, parameters) and the damping.
//
// Assembly without atomics and in a fixed order (style.md, after LAMMPS reduce_thr):
//  1. per tet (OpenMP over blocks of tets): corner forces (4,3) into a per-tet buffer;
//  2. per vertex (OpenMP over vertices): the sum of its corners' entries, taken over the
//     incident tets in increasing tet global id (a CSR incidence built once).
// Every tet's forces depend only on that tet, and every sum has a fixed order, so the
// result is bitwise the same for any number of threads (and of ranks: an object split
// over ranks has its vertices' sums formed the same way from its parts, split_forces.hpp).
//
// Objects can use different models; each object's tets are one contiguous segment with
// one material. Fully kinematic objects are skipped (they never deform).
#include <cstdint>
#include <vector>

#include "softcontact/scene.hpp"
#include "softcontact/world.hpp"

namespace softcontact {

/// Per owned object, in World::owned_objects order.
struct ElasticMeasures {
  std::vector<double> energy;          ///< strain energy sum_T V_T Psi(F_T) [J]
  std::vector<std::int64_t> inverted;  ///< tets with det F <= 0 (inverted or flat)
};

/// Highest angular frequency [rad/s] of one tet at rest with its own lumped mass (a quarter
/// of rho V on each corner): omega_T = sqrt(lambda_max(K_T) / (rho V / 4)), K_T the rest
/// stiffness of the material's model (Hooke's law for the FEM models, the springs for
/// mass_spring). X: rest corners (4,3) [m]. Without damping, position Verlet and
/// symplectic Euler are stable for dt <= 2 / max_T omega_T (Irons' element eigenvalue
/// theorem; docs/models.md); with damping see damped_stable_step.
double tet_max_frequency(const double X[12], const Material& m);

/// Lanczos steps of mesh_max_frequency (fewer when the mesh has fewer degrees of freedom).
inline constexpr int kMeshLanczosSteps = 60;

/// The highest angular frequency of a whole mesh at rest (`dt_bound: mesh`): omega_max =
/// sqrt(lambda_max(M^-1 K)), K the assembled rest stiffness of the material's model (the
/// K_T of tet_max_frequency summed), M the lumped masses. An upper bound that is certified,
/// not estimated, and at most the element bound.
struct MeshFrequency {
  double omega = 0;       ///< [rad/s] the bound: >= omega_max, <= element
  double element = 0;     ///< [rad/s] the element bound it was given
  double estimate = 0;    ///< [rad/s] Lanczos's largest Ritz value, a lower bound on omega_max
  double residual = 0;    ///< [1/s^2] that Ritz pair's residual norm (on omega^2)
  int steps = 0;          ///< Lanczos steps taken
  int tries = 0;          ///< LDL^T factorisations of mu I - M^-1/2 K M^-1/2 tried
  bool certified = false; ///< a candidate below the element bound was certified (else omega = element)
};

/// mesh_max_frequency: Lanczos on M^-1/2 K M^-1/2 (kMeshLanczosSteps steps from a fixed
/// start, serial: the same result on any number of threads) proposes theta <= lambda_max;
/// mu = theta (1 + d), d = 2^-10, 2^-8, ..., is certified >= lambda_max by a sparse
/// L D L^T of mu I - M^-1/2 K M^-1/2 with all pivots positive (Sylvester's law of inertia),
/// plus the factorisation's rounding. omega = sqrt of the first certified mu, or
/// omega_element (tet_max_frequency's maximum over the mesh, an upper bound by Irons'
/// theorem) when that is smaller. docs/models.md, "Stability limit and `dt: auto`". Tests
/// pass fewer `lanczos_steps` to exercise the certificate on a poor estimate.
MeshFrequency mesh_max_frequency(const TetMesh& mesh, const Material& m, double omega_element,
                                 int lanczos_steps = kMeshLanczosSteps);

/// Largest step [s] for which position Verlet and symplectic Euler are stable on a mode of
/// angular frequency omega [rad/s] under the explicit Rayleigh damping -alpha m v - beta K v
/// (alpha [1/s], beta [s]): dt^2 omega^2 + 2 dt (alpha + beta omega^2) <= 4, i.e.
/// dt <= 4 / (c + sqrt(c^2 + 4 omega^2)) = (2 / omega)(sqrt(1 + xi^2) - xi) with
/// c = alpha + beta omega^2 = 2 xi omega (derivation in src/model/stability.cpp). 2 / omega
/// without damping, 2 / alpha for omega = 0, +inf when all three are 0. Decreasing in omega,
/// so the bound at max_T omega_T holds for every mode (docs/models.md).
double damped_stable_step(double omega, double alpha, double beta);

/// Which stiffness K = -df/dx an element reports.
enum class StiffnessKind {
  implicit,  ///< what implicit Euler solves with: linear exact, corotational warped R K0 R^T (SPD)
  exact,     ///< the exact tangent of every model (may be indefinite)
};

class ElasticForces {
public:
  /// One object's tets [begin, end) (local tet indices) and its material.
  struct Segment {
    std::size_t begin = 0, end = 0;
    int object = 0;          ///< scene object index
    int owned = 0;           ///< position in World::owned_objects
    ModelKind model = ModelKind::corotational;
    double lambda = 0, mu = 0, young = 0;  ///< Lame parameters and E [Pa]
    double alpha = 0, beta = 0;            ///< Rayleigh damping: mass [1/s], stiffness [s]
    bool active = true;                    ///< false for kinematic objects (skipped)
    std::size_t padded_begin = 0;          ///< first tet's position in the chunked force buffer
  };

  /// Precomputes the rest state from `world` as built by build_world (World::x holds the
  /// rest positions): Dm^-1 and volume per tet, inverse spring rest lengths, the vertex -> (tet,
  /// corner) incidence, the segments.
  ///
  /// `held_elsewhere`: owned objects whose internal forces another component computes
  /// from the start (objects split over ranks, split_forces.hpp). Their tets get no rest
  /// data here (the whole object's would be its size again on the owner, for nothing),
  /// add_forces leaves their vertices alone, as after exclude_objects, and measure()
  /// computes their energy from their rest mesh on the fly, to the bit what it would be
  /// with their rest data held. Local tet indices (segments, tet_forces, the stiffness)
  /// then count only the tets held.
  ElasticForces(const Scene& scene, const World& world, std::vector<int> held_elsewhere = {});

  /// Tets whose rest data this holds.
  std::size_t held_tets() const { return volume_.size(); }

  /// f (n_local,3) [N] += internal forces -dU/dx at World::x. With `damping`, also the
  /// Rayleigh damping at World::v: -alpha m v on movable vertices and the models'
  /// stiffness-proportional damping -beta K v (docs/models.md). Implicit Euler passes
  /// false: it treats damping inside its linear system.
  ///
  /// Objects of at most kFusedTets tets are evaluated one at a time, the gather of its
  /// vertices right after its kernels while its corner forces are still in the core's
  /// cache (the separate gather read them back from memory: as long as the kernels on
  /// the torus drop); larger objects in the two phases below. The same kernels and the
  /// same sums in the same order: bitwise the result of the two phases.
  void add_forces(const World& w, std::vector<double>& f, bool damping);

  /// The two phases of add_forces, separately, over every object (benchmarks, tests):
  /// the per-tet kernels into the internal buffer, then the per-vertex gather (and the
  /// -alpha m v term) into f.
  void compute_tet_forces(const World& w, bool damping);
  void gather_forces(const World& w, std::vector<double>& f, bool damping) const;

  /// Objects whose internal forces another component computes (objects split over ranks,
  /// split_forces.hpp): add_forces skips their tets and their vertices from now on (an
  /// empty list restores them). measure() and the stiffness still cover them. The list
  /// must hold every object built without rest data (held_elsewhere): a RuntimeFailure
  /// otherwise, never an object left without forces.
  void exclude_objects(const World& w, const std::vector<int>& objects);

  /// After compute_tet_forces: the corner forces of local vertex i written from `out` on
  /// in incidence order (ascending tet global id); returns the end of what was written.
  /// With `fold`, their sum, 3 doubles, taken exactly as add_forces takes it; else each
  /// entry, 3 doubles apiece (vertex_corner_doubles(i, fold) in all).
  double* write_vertex_corners(std::size_t i, bool fold, double* out) const;
  std::size_t vertex_corner_doubles(std::size_t i, bool fold) const;
  /// compute_tet_forces, then write_vertex_corners(i, fold[i], out + offset[i]) for every
  /// owned vertex i, in add_forces' stages (each vertex's corners written while they are
  /// still in cache). The same doubles as the two phases one after the other; with an
  /// object excluded (exclude_objects), its vertices are not written.
  void stream_vertex_corners(const World& w, bool damping, const std::vector<char>& fold,
                             const std::vector<std::size_t>& offset, double* out);

  /// add_forces' last step for the n local vertices first .. first + n - 1 from their
  /// corner forces summed elsewhere: `sums` (n,3) holds each vertex's corner forces
  /// folded from zero in incidence order (a fold of write_vertex_corners' entries, or its
  /// folded sum); adds the -alpha m v term with `damping` (alpha [1/s], the vertices'
  /// Rayleigh mass damping), then f_i += the sum. Bitwise add_forces' result
  /// (split_forces.hpp relies on it).
  static void add_vertex_sums(const World& w, std::vector<double>& f, bool damping, double alpha, std::size_t first,
                              const double* sums, std::size_t n);

  /// Strain energy and inverted-tet count per owned object at World::x (summed in tet
  /// order, so deterministic).
  void measure(const World& w, ElasticMeasures& out) const;

  /// Stiffness K = -df/dx (12,12) of local tet t at positions x (n_local,3), row 3a+i,
  /// column 3b+k for corners a, b and axes i, k [N/m]. StiffnessKind::implicit is only
  /// defined for the linear and corotational models (the others give their exact
  /// tangent).
  void tet_stiffness(std::size_t t, const double* x, StiffnessKind kind, double K[144]) const;

  /// Corner forces (4,3) [N] of local tet t at positions x, without damping: the same
  /// kernel as add_forces, one tet at a time (for tests).
  void tet_forces(std::size_t t, const double* x, double f[12]) const;

  const std::vector<Segment>& segments() const { return segments_; }
  /// Segment of each local tet.
  std::int32_t segment_of(std::size_t t) const { return tet_segment_[t]; }
  /// Rest volume of local tet t [m^3].
  double rest_volume(std::size_t t) const { return volume_[t]; }
  /// Vertex -> offsets into the per-tet force buffer of its (tet, corner) entries, sorted
  /// by tet global id.
  const std::vector<std::int64_t>& incidence_offsets() const { return inc_offset_; }
  const std::vector<std::int32_t>& incidence_slots() const { return inc_slot_; }

private:
  std::vector<Segment> segments_;
  const Scene* scene_ = nullptr;
  std::vector<int> held_elsewhere_;       ///< ascending: owned objects without rest data here
  std::vector<std::int32_t> tet_segment_;  ///< (m_local)
  // Rest data, structure of arrays (one array per component) so that the per-tet
  // kernels load consecutive tets with vector loads.
  std::vector<index_t> corner_[4];        ///< (4)(m_local) local vertex index of each corner
  std::vector<double> dm_inv_[9];         ///< (9)(m_local) Dm^-1, row-major entries [1/m]
  std::vector<double> volume_;            ///< (m_local) rest volume [m^3]
  std::vector<double> inv_rest_length_[6];  ///< (6)(m_local) 1 / spring rest length [1/m], mass_spring tets only
  struct Block {
    std::size_t begin;
    std::int32_t count, segment;
  };
  std::vector<Block> blocks_;             ///< active tets in blocks of at most kBlock, one segment each
  /// add_forces' plan: objects evaluated whole (their blocks [block_begin, block_end) and
  /// their vertices [vertex_begin, vertex_end), which only their own tets touch), then
  /// the blocks and the vertex ranges of everything else in two phases.
  struct FusedObject {
    std::size_t block_begin, block_end, vertex_begin, vertex_end;
  };
  std::vector<FusedObject> fused_;
  std::vector<std::size_t> unfused_blocks_;                      ///< indices into blocks_
  std::vector<std::pair<std::size_t, std::size_t>> unfused_vertices_;  ///< ascending ranges [begin, end)
  /// The unfused blocks and vertices in stages (plan_stages): stage k runs the blocks
  /// unfused_blocks_[block_begin, block_end), then gathers the vertices
  /// staged_vertices_[vertex_begin, vertex_end), those whose last tet is in one of them,
  /// while their corner forces are still in cache.
  struct Stage {
    std::size_t block_begin, block_end, vertex_begin, vertex_end;
  };
  std::vector<Stage> stages_;
  std::vector<std::uint32_t> staged_vertices_;
  void plan_stages();
  /// The plan with no object excluded (exclude_objects filters it).
  std::vector<FusedObject> all_fused_;
  std::vector<std::size_t> all_unfused_blocks_;
  std::vector<std::pair<std::size_t, std::size_t>> all_unfused_vertices_;
  template <class PerVertex>
  void run_plan(const World& w, bool damping, const PerVertex& per_vertex);
  void run_block(const World& w, bool damping, std::size_t k);
  std::vector<double> vertex_alpha_;      ///< (n_local) Rayleigh alpha of the vertex's material [1/s]
  std::vector<std::int64_t> inc_offset_;  ///< (n_owned + 1) CSR offsets into inc_slot_
  std::vector<std::int32_t> inc_slot_;    ///< (4 m_local) buffer offset of (tet, corner); components at +0, +kLanes, +2 kLanes
  /// Per-tet corner forces of the last evaluation [N], in chunks of kLanes tets (see
  /// tet_kernels.hpp): (chunks, 12, kLanes), each segment starting on a new chunk.
  std::vector<double> tet_force_;
};

}  // namespace softcontact
