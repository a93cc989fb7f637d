#pragma once
// An independent check of a simulated state (docs/validation.md, "softcontact verify"):
// how deep bodies are inside each other, whether their surfaces cross, inverted tets and
// runaway speeds. It shares no code with the collision detector (src/collide): its own
// barycentric point-in-tet test, its own grid of cells, exact point-triangle distances
// and segment-triangle crossings, so that it can judge the detector and the contact
// response instead of repeating their assumptions.
//
// The core works on the whole scene as plain global arrays (global ids as in frames.h5:
// objects in scene order, each object's vertices, tets and triangles consecutive), with
// no MPI: `softcontact verify` reads them from a run's output. A run checks each rank's
// own objects against its own and ghost objects (VerifyOptions::counted, VerifyReduction)
// and merges the parts (merge_verify_part; Simulator::verify, `softcontact run
// --verify-every`): the same result to the bit.
//
// Definitions (all distances in metres; h = the median tet edge length at rest):
//  - A vertex of body A is *inside* body B (B != A, not both kinematic) when it lies in a
//    closed tet of B (barycentric coordinates >= -1e-12) and its distance to B's surface
//    exceeds 1e-9 h. Its *depth* is that distance: the minimum over B's surface triangles
//    of the exact point-triangle distance. A vertex inside several bodies counts once,
//    with the largest depth.
//  - A surface vertex of body A is *inside itself* (self-contact) when it lies in a closed
//    tet of A that shares no vertex with its star (the vertex and its mesh neighbours;
//    in a mesh with no inverted tet no vertex lies in another tet, so only a fold of A
//    onto itself puts it there) and its distance to A's surface triangles that touch no
//    vertex of the star exceeds 1e-9 h. That distance is its self depth: the surface
//    near the vertex is left out, so the depth is the true one up to about one edge and
//    at most about one edge beyond that.
//  - A *self crossing* is a crossing (as below) of a surface edge of A with a surface
//    triangle of A that touches no vertex of the stars of the edge's two ends; its depth
//    is taken the same way, in A's tets and to A's surface triangles that touch neither
//    star.
//  - A *crossing* is a pair (surface edge of A, surface triangle of B) where the edge's
//    endpoints lie on opposite sides of the triangle's plane, each farther from it than
//    1e-9 h, and the crossing point inside the closed triangle (barycentric coordinates
//    >= -1e-12). Its depth is the largest depth in B of the part of the edge inside B that
//    it bounds: from the crossing towards the triangle's inner side, up to the edge's
//    next crossing with B's surface or the edge's end. That maximum is searched by up to
//    kCrossingSamples + 1 evenly spaced points and a golden-section refinement around
//    the deepest to 1e-4 h (verify.cpp, deepest_on_segment). A crossing counts when its
//    depth exceeds 1e-9 h, like a vertex; shallower ones are `grazing`.
//  - A tet is *inverted* when its signed volume, times the sign of its rest volume, is
//    <= 0 (flat tets count).
#include <cstdint>
#include <iosfwd>
#include <string>
#include <type_traits>
#include <vector>

#include "softcontact/mesh.hpp"
#include "softcontact/scene.hpp"
#include "softcontact/surface.hpp"

namespace softcontact {

/// Points sampled on the inner part of a crossing edge for the crossing's depth.
inline constexpr int kCrossingSamples = 8;

/// The scene's connectivity in global ids. Fill the first six arrays, then call
/// prepare_verify_mesh() with the rest positions for the rest.
struct VerifyMesh {
  std::vector<gid_t> tets;                     ///< (m,4) global vertex ids
  std::vector<std::int32_t> tet_object;        ///< (m) body of each tet
  std::vector<std::int32_t> vertex_object;     ///< (n) body of each vertex
  std::vector<gid_t> triangles;                ///< (s,3) outward surface triangles (global vertex ids)
  std::vector<std::int32_t> triangle_object;   ///< (s) body of each triangle; filled from its first vertex when empty
  std::vector<char> object_fixed;              ///< (objects) 1 for kinematic bodies; sized from the ids when empty

  // ---- derived by prepare_verify_mesh
  std::vector<signed char> rest_sign;          ///< (m) sign of each tet's rest volume (+1 for a flat one)
  std::vector<char> surface_vertex;            ///< (n) 1 for vertices of a surface triangle
  std::vector<gid_t> edges;                    ///< (e,2) the surface's edges, once each, a < b, sorted
  std::vector<gid_t> object_triangle_begin;    ///< (objects+1) CSR of object_triangles
  std::vector<gid_t> object_triangles;         ///< surface triangles of each body, ascending
  std::vector<gid_t> neighbour_begin;          ///< (n+1) CSR of neighbours
  std::vector<gid_t> neighbours;               ///< mesh (tet edge) neighbours of each vertex, ascending
  double median_edge = 0;                      ///< median over tets of their six rest edge lengths [m]

  std::size_t num_vertices() const { return vertex_object.size(); }
  std::size_t num_tets() const { return tet_object.size(); }
  std::size_t num_triangles() const { return triangles.size() / 3; }
  std::size_t num_objects() const { return object_fixed.size(); }
};

/// Checks the arrays' sizes and every id (throws InputError naming `source` and the
/// first bad row), then fills the derived arrays from the rest positions `rest` (n,3).
/// The median edge is taken like the simulator's (each tet's six edges, edges shared by
/// several tets counted once per tet), so depths / median edge mean the same in both.
void prepare_verify_mesh(VerifyMesh& mesh, const double* rest, const std::string& source);

/// The scene's VerifyMesh (objects in scene order, each with its extract_surface), prepared
/// with the scene's initial positions as rest positions. Meshes this rank dropped are made
/// for the pass and not kept (Scene::view_mesh).
VerifyMesh verify_mesh_of(const Scene& scene);

/// The scene's initial positions as one (n,3) array in global vertex order.
std::vector<double> initial_positions(const Scene& scene);

/// Fastest speed a free fall in the scene reaches: v_ff = sqrt(v0^2 + 2 |g| H), where H
/// is the height of the highest vertex of `x0` (n,3) above the lowest one, measured along
/// g (every vertex, kinematic ones included), and v0 the largest initial speed [m/s].
double free_fall_speed(const double* x0, std::size_t n, const Vec3& gravity, double v0);
/// The heights along g of the lowest and highest of the points `x0` (n,3), non-finite
/// ones left out, folded into lo and hi (start from +inf and -inf).
void height_range(const double* x0, std::size_t n, const Vec3& gravity, double& lo, double& hi);
/// v_ff from the height range of every vertex (height_range; lo > hi: none).
double free_fall_speed(double lo, double hi, const Vec3& gravity, double v0);
/// The largest of the scene's objects' initial velocities and prescribed motions [m/s]:
/// free_fall_speed's v0.
double initial_speed(const Scene& scene);
/// The same for a scene: x0 its initial positions, v0 its initial_speed.
double free_fall_speed(const Scene& scene);

/// What the run's contact response did in the step just checked about a surface vertex
/// (in-run checks: Simulator::verify): the status of the vertex's deepest vertex
/// collision record. Explains a vertex left inside (docs/validation.md).
enum RecordStatus : std::int8_t {
  kNoRecord = 0,      ///< no vertex record: the detector did not find it, or the response pushed it in
  kCapped = 1,        ///< deeper than the step's approach allows: removed at the separation speed
  kUnderClosed = 2,   ///< the normal corrections of all collisions closed less than 90 % of its applied depth
  kClosed = 3,        ///< closed along its depth vector (so d was not the way out, or other corrections moved it)
};
constexpr int kRecordStatuses = 4;

/// The collective steps of a check split over processes (Simulator::verify): each
/// process checks the vertices, surface edges and tets of its own bodies
/// (VerifyOptions::counted) against its own and its neighbours' bodies, and these combine
/// what must be known over all of them before the check goes on. Every process calls
/// them in the same order (one verify_frame each, with the same options).
struct VerifyReduction {
  virtual ~VerifyReduction() = default;
  /// The largest of every process's `local`.
  virtual double max(double local) const = 0;
  /// The q-quantile (nearest rank: the value at index ceil(q N) - 1 of the N values of
  /// all processes, ascending), 0 when N = 0. May reorder `local`.
  virtual double quantile(std::vector<double>& local, double q) const = 0;
};

/// What to check besides the surface vertices; `free_fall_speed` <= 0 leaves the speed
/// ratio at 0.
struct VerifyOptions {
  bool interior = true;          ///< also vertices that are not on a surface
  bool crossings = true;         ///< surface edge / surface triangle crossings
  double free_fall_speed = 0;    ///< v_ff [m/s] for VerifyFrame::speed_ratio
  bool self = true;              ///< surface vertices inside their own body (self-contact)
  /// Per vertex (global order) a RecordStatus, or null: surface vertices deeper than
  /// record_limit median edges are then counted by it (VerifyFrame::deep_by_record).
  const std::int8_t* record = nullptr;
  double record_limit = 0.005;
  /// Per body (num_objects), or null for all: only the vertices, surface edges and tets
  /// of bodies marked 1 are checked and counted; the others are there to be inside of
  /// and to be crossed. For a part of a check split over processes (merge_verify_part).
  const char* counted = nullptr;
  /// With `counted`: how the processes combine the crossing pass's threshold and the
  /// percentiles, so that each part's percentiles are the whole check's. Null: this
  /// process alone.
  const VerifyReduction* reduction = nullptr;
};

/// Vertices inside other bodies (surface or interior ones).
struct InsideStats {
  std::int64_t count = 0;
  double max_depth = 0;          ///< [m]
  double p99_depth = 0;          ///< [m] 99th percentile of the counted depths (nearest rank)
  gid_t vertex = -1;             ///< the deepest vertex
  std::int32_t object = -1;      ///< its body
  std::int32_t in_object = -1;   ///< the body it is deepest in
};

struct CrossingStats {
  std::int64_t count = 0;        ///< crossing (edge, triangle) pairs deeper than the tolerance
  /// ... of which neither edge endpoint is inside the triangle's body nor any triangle
  /// corner inside the edge's body: surfaces that pass through each other edge on edge.
  std::int64_t without_inside_vertex = 0;
  /// Pairs that cross geometrically but whose inside part is no deeper than the tolerance
  /// (an edge through a triangle's rim where two surfaces touch): not in `count`.
  std::int64_t grazing = 0;
  double max_depth = 0;          ///< [m]
  gid_t edge[2] = {-1, -1};      ///< the deepest crossing: edge (global vertex ids) ...
  gid_t triangle = -1;           ///< ... and the triangle it crosses
  std::int32_t object = -1, in_object = -1;  ///< the edge's and the triangle's bodies
};

/// The check of one state. Trivially copyable (broadcast as bytes).
struct VerifyFrame {
  std::int64_t step = 0;
  double time = 0;               ///< [s]
  double median_edge = 0;        ///< h [m]
  InsideStats surface;           ///< surface vertices inside other bodies
  InsideStats interior;          ///< interior vertices inside other bodies (with VerifyOptions::interior)
  InsideStats self;              ///< surface vertices inside their own body (with VerifyOptions::self)
  CrossingStats self_crossings;  ///< surface edges through their own body's surface (with self and crossings; no grazing / without_inside_vertex)
  CrossingStats crossings;       ///< with VerifyOptions::crossings
  std::int64_t inverted = 0;     ///< inverted or flat tets
  gid_t first_inverted = -1;     ///< the lowest such tet id
  std::int64_t nonfinite = 0;    ///< vertices with a non-finite position or velocity
  double max_speed = 0;          ///< [m/s] fastest vertex
  gid_t fastest = -1;            ///< its id (the lowest on a tie)
  double speed_ratio = 0;        ///< max_speed / v_ff
  /// With VerifyOptions::record: surface vertices deeper than its record_limit inside
  /// another body, by RecordStatus.
  std::int64_t deep_by_record[kRecordStatuses] = {0, 0, 0, 0};

  double surface_depth() const { return surface.max_depth / median_edge; }    ///< in median edges
  double interior_depth() const { return interior.max_depth / median_edge; }  ///< in median edges
  double self_depth() const { return self.max_depth / median_edge; }          ///< in median edges
  double self_crossing_depth() const { return self_crossings.max_depth / median_edge; }  ///< in median edges
  double crossing_depth() const { return crossings.max_depth / median_edge; } ///< in median edges
};
static_assert(std::is_trivially_copyable_v<VerifyFrame>, "VerifyFrame is broadcast as bytes");

/// Checks positions `x` (n,3) and velocities `v` (n,3, or null: no speeds) of `mesh`.
/// OpenMP over vertices, edges and tets; the result does not depend on the thread count.
VerifyFrame verify_frame(const VerifyMesh& mesh, const double* x, const double* v, const VerifyOptions& opt = {});

/// Combines `part`, the check of other bodies' vertices, edges and tets (disjoint from
/// those of `total`; VerifyOptions::counted), into `total`: counts summed, each maximum
/// the larger with the lower global id on a tie (the deepest crossing: the lower edge,
/// as (first, second) vertex), the lowest inverted tet. Ids must be global. The
/// percentiles are `total`'s (a split check takes them over every process already);
/// speed_ratio is left to the caller. The result does not depend on the order in which
/// parts are merged.
void merge_verify_part(VerifyFrame& total, const VerifyFrame& part);

/// A maximum over checks, with the step and time where it occurred.
struct VerifyPeak {
  double value = 0;
  std::int64_t step = -1;
  double time = 0;
};

/// The worst of several checks (in-run checks every N steps, the frames of an output).
struct VerifyMaxima {
  std::int64_t checks = 0;
  VerifyPeak surface_count, surface_depth;     ///< depth in median edges
  VerifyPeak interior_count, interior_depth;
  VerifyPeak self_count, self_depth, self_crossings, self_crossing_depth;
  VerifyPeak crossings, crossings_without_inside_vertex, crossing_depth;
  VerifyPeak inverted, nonfinite, max_speed, speed_ratio;
  gid_t fastest_vertex = -1;                   ///< the vertex of max_speed (the first check's on a tie)
  VerifyFrame deepest;                         ///< the check with the deepest surface vertex
  /// The deepest surface vertex of every check, in median edges (for the distribution:
  /// one transient deep step moves the maximum, not the median or the counts).
  std::vector<double> surface_depths;
  /// VerifyFrame::deep_by_record summed over the checks (vertex-checks).
  std::int64_t deep_by_record[kRecordStatuses] = {0, 0, 0, 0};

  void add(const VerifyFrame& f);
  /// Checks whose deepest surface vertex exceeds `limit` median edges.
  std::int64_t checks_deeper_than(double limit) const;
  /// The q-quantile (0..1, nearest rank) of the per-check deepest surface vertex.
  double surface_depth_quantile(double q) const;
};

/// One check as a JSON object (one line; non-finite numbers as null).
std::string to_json(const VerifyFrame& f);
/// The maxima as a JSON object.
std::string to_json(const VerifyMaxima& m);

/// Limits of `softcontact verify`; a negative or infinite limit is not checked.
struct VerifyThresholds {
  double max_depth = 0.005;            ///< surface-vertex depth, in median edges, every frame
  double max_interior_depth = -1;      ///< interior-vertex depth, in median edges (unlimited)
  double max_self_depth = -1;          ///< self depth of a surface vertex, in median edges, every frame (unlimited)
  std::int64_t max_crossings = -1;     ///< crossings per frame (unlimited)
  std::int64_t max_inverted = 0;       ///< inverted tets at the last checked frame
  double max_speed_ratio = 3;          ///< max speed / v_ff, every frame
};

/// How several processes share the frames of verify_output (the command line gives one
/// over MPI; this layer knows no MPI). Process p checks the selected frames p, p + size,
/// p + 2 size, ...; process 0 gathers the results and reports them in frame order.
class VerifyFrameShare {
public:
  virtual ~VerifyFrameShare() = default;
  virtual int rank() const = 0;
  virtual int size() const = 0;
  /// Collective. On process 0 every process's bytes, process after process; elsewhere
  /// empty.
  virtual std::vector<char> gather(const std::vector<char>& mine) const = 0;
  /// Collective. The message of the lowest process with a non-empty one, on every
  /// process; empty when none has one.
  virtual std::string first_error(const std::string& mine) const = 0;
};

/// Options of `softcontact verify OUTPUT_DIR`.
struct VerifyOutputOptions {
  std::string frames = "all";          ///< all | last | first | comma list of N and A:B[:STEP], negative from the end
  VerifyThresholds thresholds;
  std::string json;                    ///< the JSON summary ("" : OUTPUT_DIR/verify.json)
  double skip_before = 0;              ///< frames at earlier times are not checked [s]
  bool skip = false;                   ///< skip_before applies
  /// Several processes share the frames (null, or one process: this one checks them all,
  /// printing each line as its frame is done).
  const VerifyFrameShare* share = nullptr;
};

/// Checks the frames of a run's output directory (mesh.h5, frames/NNNNNN.h5, scene.yaml
/// for gravity and initial velocities), prints one line per frame and a summary to `out`
/// and writes the JSON summary. Returns 0 when every limit holds, 1 otherwise. Throws
/// InputError naming the file for a missing directory or file, or one HDF5 cannot read.
/// With `opt.share` of several processes, every process calls it: each reads the mesh
/// and checks its frames, process 0 prints, writes the JSON and returns the status (the
/// others return 0), and an InputError on any process is thrown on every process (the
/// lowest process's message). Each frame's check is the same on any process and thread
/// count, so the report is the one process's to the bit (but the seconds it took).
int verify_output(const std::string& dir, const VerifyOutputOptions& opt, std::ostream& out, std::ostream& err);

}  // namespace softcontact
