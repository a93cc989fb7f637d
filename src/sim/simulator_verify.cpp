// The check of `softcontact verify` during a run (Simulator::verify, residual_surface_depth),
// split over the ranks: each rank checks its own objects' vertices, surface edges and
// tets against its own and its ghost objects, and the parts are merged. No rank holds
// or gathers the whole scene.
#include <mpi.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>

#include "local_check.hpp"
#include "softcontact/contact.hpp"
#include "softcontact/mpi_util.hpp"
#include "softcontact/simulator.hpp"
#include "softcontact/stepper.hpp"
#include "softcontact/verify.hpp"

namespace softcontact {

namespace {

// Indices 0..n-1 ordered by their global id.
template <class Gid>
std::vector<std::size_t> order_by(const Gid& gid) {
  std::vector<std::size_t> order(gid.size());
  std::iota(order.begin(), order.end(), std::size_t{0});
  std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return gid[a] < gid[b]; });
  return order;
}

// The collective steps of a check split over the ranks (verify.hpp).
class RankReduction final : public VerifyReduction {
public:
  explicit RankReduction(MPI_Comm comm) : comm_(comm) {}
  double max(double local) const override {
    MPI_Allreduce(MPI_IN_PLACE, &local, 1, MPI_DOUBLE, MPI_MAX, comm_);
    return local;
  }
  double quantile(std::vector<double>& local, double q) const override {
    std::int64_t n = static_cast<std::int64_t>(local.size());
    MPI_Allreduce(MPI_IN_PLACE, &n, 1, MPI_INT64_T, MPI_SUM, comm_);
    if (n == 0) return 0;
    const auto k = static_cast<std::int64_t>(std::ceil(q * static_cast<double>(n))) - 1;
    return kth_smallest(comm_, local, k);
  }

private:
  MPI_Comm comm_;
};

// MPI_Allreduce operation on VerifyFrame bytes: merge_verify_part (commutative: the
// tie-breaks go by global id).
void merge_frames(void* in, void* inout, int* len, MPI_Datatype*) {
  auto* a = static_cast<const VerifyFrame*>(in);
  auto* b = static_cast<VerifyFrame*>(inout);
  for (int i = 0; i < *len; ++i) merge_verify_part(b[i], a[i]);
}

// A part's local ids (mesh order) to global ids.
void to_global(VerifyFrame& f, const LocalCheck& c) {
  auto vertex = [&](gid_t& v) {
    if (v >= 0) v = c.vertex_gid[static_cast<std::size_t>(v)];
  };
  for (InsideStats* s : {&f.surface, &f.interior, &f.self}) vertex(s->vertex);
  for (CrossingStats* s : {&f.self_crossings, &f.crossings}) {
    vertex(s->edge[0]);
    vertex(s->edge[1]);
    if (s->triangle >= 0) s->triangle = c.triangle_gid[static_cast<std::size_t>(s->triangle)];
  }
  vertex(f.fastest);
  if (f.first_inverted >= 0) f.first_inverted = c.tet_gid[static_cast<std::size_t>(f.first_inverted)];
}

}  // namespace

LocalCheck& Simulator::local_check() {
  if (local_verify_) return *local_verify_;
  auto c = std::make_unique<LocalCheck>();
  const World& w = world_;
  const std::size_t n = w.n_local();
  const std::vector<std::size_t> vorder = order_by(w.vertex_gid);
  std::vector<index_t> row_to_mesh(n);
  c->vertex.resize(n);
  c->vertex_gid.resize(n);
  VerifyMesh& m = c->mesh;
  m.vertex_object.resize(n);
  std::vector<double> rest(3 * n);
  for (std::size_t j = 0; j < n; ++j) {
    const std::size_t i = vorder[j];
    c->vertex[j] = static_cast<index_t>(i);
    c->vertex_gid[j] = w.vertex_gid[i];
    row_to_mesh[i] = static_cast<index_t>(j);
    const auto k = static_cast<std::size_t>(w.vertex_object[i]);
    m.vertex_object[j] = w.vertex_object[i];
    // Rest positions: the scene's (initial) ones, as for the whole scene's check.
    const TetMesh& mesh = scene_.mesh(k);
    const auto r = static_cast<std::size_t>(w.vertex_gid[i] - w.layout[k].vertex_begin);
    std::copy_n(&mesh.points[3 * r], 3, &rest[3 * j]);
  }
  const std::vector<std::size_t> torder = order_by(w.tet_gid);
  m.tets.resize(4 * torder.size());
  m.tet_object.resize(torder.size());
  c->tet_gid.resize(torder.size());
  for (std::size_t j = 0; j < torder.size(); ++j) {
    const std::size_t t = torder[j];
    for (std::size_t d = 0; d < 4; ++d) m.tets[4 * j + d] = row_to_mesh[static_cast<std::size_t>(w.tets[4 * t + d])];
    m.tet_object[j] = w.tet_object[t];
    c->tet_gid[j] = w.tet_gid[t];
  }
  const std::vector<std::size_t> sorder = order_by(w.triangle_gid);
  m.triangles.resize(3 * sorder.size());
  c->triangle_gid.resize(sorder.size());
  for (std::size_t j = 0; j < sorder.size(); ++j) {
    const std::size_t t = sorder[j];
    for (std::size_t d = 0; d < 3; ++d) m.triangles[3 * j + d] = row_to_mesh[static_cast<std::size_t>(w.triangles[3 * t + d])];
    c->triangle_gid[j] = w.triangle_gid[t];
  }
  const std::size_t objects = scene_.objects.size();
  m.object_fixed.resize(objects);
  c->counted.assign(objects, 0);
  for (std::size_t k = 0; k < objects; ++k) m.object_fixed[k] = scene_.objects[k].kinematic() ? 1 : 0;
  for (int k : w.owned_objects) c->counted[static_cast<std::size_t>(k)] = 1;
  prepare_verify_mesh(m, rest.data(), scene_.path);

  if (!verify_median_known_) {
    // The whole scene's median edge as prepare_verify_mesh takes it (the six rest edges
    // of each tet, sqrt of the squared distance), from each rank's own tets.
    std::vector<double> len;
    len.reserve(6 * w.m_owned);
    for (std::size_t t = 0; t < m.num_tets(); ++t) {
      if (!c->counted[static_cast<std::size_t>(m.tet_object[t])]) continue;
      for (const auto& e : kTetEdges) {
        const double* a = &rest[3 * static_cast<std::size_t>(m.tets[4 * t + e[0]])];
        const double* b = &rest[3 * static_cast<std::size_t>(m.tets[4 * t + e[1]])];
        const double x = a[0] - b[0], y = a[1] - b[1], z = a[2] - b[2];
        len.push_back(std::sqrt(x * x + y * y + z * z));
      }
    }
    const std::int64_t total = 6 * static_cast<std::int64_t>(w.global_tets);
    verify_median_ = total > 0 ? kth_smallest(comm_, len, total / 2) : 0;
    verify_median_known_ = true;  // every rank passes here at its first call, together
  }
  m.median_edge = verify_median_;
  if (!free_fall_known_) {
    // v_ff (verify.hpp) of the whole scene: the height range of every object's initial
    // positions, from each rank's own objects, and the fastest initial or prescribed speed.
    double range[2] = {std::numeric_limits<double>::infinity(), -std::numeric_limits<double>::infinity()};
    for (int k : w.owned_objects) {
      const TetMesh& mesh = scene_.mesh(static_cast<std::size_t>(k));
      height_range(mesh.points.data(), mesh.num_vertices(), scene_.sim.gravity, range[0], range[1]);
    }
    range[0] = -range[0];
    MPI_Allreduce(MPI_IN_PLACE, range, 2, MPI_DOUBLE, MPI_MAX, comm_);
    free_fall_speed_ = free_fall_speed(-range[0], range[1], scene_.sim.gravity, initial_speed(scene_));
    free_fall_known_ = true;
  }
  local_verify_ = std::move(c);
  return *local_verify_;
}

double Simulator::residual_surface_depth() {
  LocalCheck& c = local_check();
  std::vector<double> x(3 * c.vertex.size());
  for (std::size_t j = 0; j < c.vertex.size(); ++j)
    std::copy_n(&world_.x[3 * static_cast<std::size_t>(c.vertex[j])], 3, &x[3 * j]);
  VerifyOptions opt;
  opt.interior = opt.crossings = opt.self = false;
  opt.counted = c.counted.data();  // no reduction: the maximum is all this needs, not the percentile
  double deepest = verify_frame(c.mesh, x.data(), nullptr, opt).surface.max_depth;
  MPI_Allreduce(MPI_IN_PLACE, &deepest, 1, MPI_DOUBLE, MPI_MAX, comm_);
  return deepest / verify_median_;
}

VerifyFrame Simulator::verify(bool full) {
  LocalCheck& c = local_check();
  const std::size_t n = c.vertex.size();
  std::vector<double> x(3 * n), v(3 * n);
  for (std::size_t j = 0; j < n; ++j) {
    const auto i = static_cast<std::size_t>(c.vertex[j]);
    std::copy_n(&world_.x[3 * i], 3, &x[3 * j]);
    std::copy_n(&world_.v[3 * i], 3, &v[3 * j]);
  }
  // In-run checks: what the response did about each owned vertex in this step (its
  // deepest vertex record), to count the vertices left inside by cause.
  std::vector<std::int8_t> status, record;
  VerifyOptions opt;
  if (full) {
    core_->response().record_status(core_->collisions(), world_.n_owned, status);
    record.assign(n, kNoRecord);
    for (std::size_t j = 0; j < n; ++j)
      if (static_cast<std::size_t>(c.vertex[j]) < status.size()) record[j] = status[static_cast<std::size_t>(c.vertex[j])];
    opt.record = record.data();
  }
  opt.interior = opt.crossings = full;
  // Self checks cost a pass over every surface edge against its own body: in the run only
  // where the run claims self-contact (softcontact verify on the frames always has them).
  opt.self = full && scene_.sim.self_collisions;
  opt.counted = c.counted.data();
  const RankReduction reduction(comm_);
  opt.reduction = &reduction;
  VerifyFrame f = verify_frame(c.mesh, x.data(), v.data(), opt);
  to_global(f, c);
  MPI_Datatype bytes;
  MPI_Op merge;
  MPI_Type_contiguous(static_cast<int>(sizeof f), MPI_BYTE, &bytes);  // trivially copyable (verify.hpp)
  MPI_Type_commit(&bytes);
  MPI_Op_create(&merge_frames, 1, &merge);
  MPI_Allreduce(MPI_IN_PLACE, &f, 1, bytes, merge, comm_);
  MPI_Op_free(&merge);
  MPI_Type_free(&bytes);
  f.speed_ratio = free_fall_speed_ > 0 ? f.max_speed / free_fall_speed_ : 0;
  f.step = step_;
  f.time = time();
  return f;
}

}  // namespace softcontact
