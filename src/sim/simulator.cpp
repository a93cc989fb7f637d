#include "softcontact/simulator.hpp"

#include <petscsys.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <cmath>
#include <cstring>
#include <iostream>
#include <limits>

#include "softcontact/error.hpp"
#include "softcontact/forces.hpp"
#include "softcontact/halo.hpp"
#include "softcontact/mpi_util.hpp"
#include "softcontact/implicit_euler.hpp"
#include "softcontact/motion.hpp"
#include "softcontact/integrator.hpp"

namespace softcontact {

namespace {

// Mean and median edge length over every tet edge of the scene (an edge counts once per
// tet), from the scene alone: the same on every rank.
void scene_edge_lengths(const Scene& scene, double& mean, double& median) {
  std::vector<double> len;
  len.reserve(6 * scene.num_tets());
  double sum = 0;
  for (const SceneObject& o : scene.objects)
    for (std::size_t t = 0; t < o.mesh.num_tets(); ++t)
      for (const auto& e : kTetEdges) {
        const double* a = &o.mesh.points[3 * o.mesh.tets[4 * t + e[0]]];
        const double* b = &o.mesh.points[3 * o.mesh.tets[4 * t + e[1]]];
        len.push_back(std::hypot(a[0] - b[0], a[1] - b[1], a[2] - b[2]));
        sum += len.back();
      }
  mean = median = 0;
  if (len.empty()) return;
  mean = sum / static_cast<double>(len.size());
  std::nth_element(len.begin(), len.begin() + static_cast<std::ptrdiff_t>(len.size() / 2), len.end());
  median = len[len.size() / 2];
}

ObjectBox empty_box() {
  ObjectBox b;
  for (int d = 0; d < 3; ++d) {
    b.lo[d] = std::numeric_limits<double>::infinity();
    b.hi[d] = -std::numeric_limits<double>::infinity();
  }
  return b;
}

void add_point(ObjectBox& b, const double* p) {
  for (int d = 0; d < 3; ++d) {
    if (!(p[d] >= b.lo[d])) b.lo[d] = p[d];
    if (!(p[d] <= b.hi[d])) b.hi[d] = p[d];
  }
}

std::int64_t object_work(const Scene& scene, const std::vector<Surface>& surfaces, std::size_t k) {
  // Kinematic objects cost no forces, only their share of detection.
  return scene.objects[k].kinematic ? static_cast<std::int64_t>(surfaces[k].num_triangles() / 10)
                                    : static_cast<std::int64_t>(scene.objects[k].mesh.num_tets());
}

// Median over objects of the largest side of their box: objects closer than this are
// neighbours in the partition graph.
double median_object_size(const std::vector<ObjectBox>& box) {
  std::vector<double> size;
  for (const ObjectBox& b : box) size.push_back(std::max({b.hi[0] - b.lo[0], b.hi[1] - b.lo[1], b.hi[2] - b.lo[2]}));
  if (size.empty()) return 0;
  std::nth_element(size.begin(), size.begin() + static_cast<std::ptrdiff_t>(size.size() / 2), size.end());
  return size[size.size() / 2];
}

bool grown_overlap(const ObjectBox& a, const ObjectBox& b, double margin) {
  for (int d = 0; d < 3; ++d)
    if (a.lo[d] > b.hi[d] + margin || b.lo[d] > a.hi[d] + margin) return false;
  return true;
}

}  // namespace

namespace {
// Each object's box at its initial positions.
std::vector<ObjectBox> scene_boxes(const Scene& scene) {
  std::vector<ObjectBox> boxes;
  for (const SceneObject& o : scene.objects) {
    ObjectBox b = empty_box();
    for (std::size_t v = 0; v < o.mesh.num_vertices(); ++v) add_point(b, &o.mesh.points[3 * v]);
    boxes.push_back(b);
  }
  return boxes;
}
}  // namespace

std::vector<int> partition_at(const Scene& scene, const std::vector<Surface>& surfaces, std::vector<ObjectBox> boxes,
                              int nranks) {
  const std::size_t no = scene.objects.size();
  if (nranks <= 1) return std::vector<int>(no, 0);
  PartitionInput in;
  for (std::size_t k = 0; k < no; ++k) {
    in.weight.push_back(object_work(scene, surfaces, k));
    for (int d = 0; d < 3; ++d)
      if (!std::isfinite(boxes[k].lo[d]) || !std::isfinite(boxes[k].hi[d]) || !(boxes[k].lo[d] <= boxes[k].hi[d]))
        boxes[k].lo[d] = boxes[k].hi[d] = 0;  // a blown-up object
  }
  in.box = std::move(boxes);
  in.reach = median_object_size(in.box);
  return partition_objects(in, nranks);
}

std::vector<int> initial_partition(const Scene& scene, const std::vector<Surface>& surfaces, int nranks) {
  return partition_at(scene, surfaces, scene_boxes(scene), nranks);
}

Simulator::Simulator(MPI_Comm comm, const Scene& scene, std::vector<int> partition)
    : comm_(comm), rank_(comm_rank(comm)), nranks_(comm_size(comm)), scene_(scene), surfaces_(extract_surfaces(scene)) {
  partition_ = partition.empty() ? initial_partition(scene, surfaces_, nranks_) : std::move(partition);
  if (partition_.size() != scene.objects.size())
    throw RuntimeFailure("Simulator: the partition names " + std::to_string(partition_.size()) + " objects, the scene has " +
                         std::to_string(scene.objects.size()));
  for (int r : partition_)
    if (r < 0 || r >= nranks_) throw RuntimeFailure("Simulator: the partition names rank " + std::to_string(r));
  double mean_edge = 0;
  scene_edge_lengths(scene, mean_edge, median_edge_);
  // One cell size for every rank: detection's tolerances scale with it.
  collision_settings_.self_collisions = scene.sim.self_collisions;
  collision_settings_.edge_contacts = scene.sim.edge_contacts;
  collision_settings_.cell_size = mean_edge > 0 ? mean_edge : 1.0;
  skin_ = collision_settings_.cell_size;
  max_skin_ = median_object_size(scene_boxes(scene));
  world_ = build_world(scene, surfaces_, partition_, rank_);
  build_components();
  rebuild_ghosts(true);
  {
    CollisionStats st;
    detector_->detect(world_, nullptr, residual_, st);
    // Overlaps between two fixed sides (walls built flush against a floor) exert no
    // force and move nothing: not worth a warning.
    auto movable = [&](index_t v) { return world_.inv_mass[static_cast<std::size_t>(v)] != 0; };
    for (const Collision& c : residual_) {
      if (!movable(c.point) && (c.point2 < 0 || !movable(c.point2)) && !movable(c.triangle[0]) && !movable(c.triangle[1]) && !movable(c.triangle[2])) continue;
      ++initial_overlaps_;
      initial_overlap_depth_ = std::max(initial_overlap_depth_, std::hypot(c.depth[0], c.depth[1], c.depth[2]));
    }
    MPI_Allreduce(MPI_IN_PLACE, &initial_overlaps_, 1, MPI_INT64_T, MPI_SUM, comm_);
    MPI_Allreduce(MPI_IN_PLACE, &initial_overlap_depth_, 1, MPI_DOUBLE, MPI_MAX, comm_);
  }
  motion_->forces(world_, f_);
  motion_->start(world_, f_);
  if (halo_) halo_->update(world_.x_prev.data());
}

// Everything that depends on which objects this rank owns: forces and the implicit
// solver (their rest shapes from world_.x, which must hold the scene's initial
// positions here) and the contact response.
void Simulator::build_components() {
  motion_.reset();  // the old implicit solver goes before the new one is made
  motion_ = std::make_unique<UnconstrainedMotion>(scene_, world_);
  contact_ = std::make_unique<ContactResponse>(scene_, world_);
}

// Every object's box at the current positions, on every rank (collective). Every object
// has one owner: a min-reduction of the lo corners and a max of the hi corners assembles
// them. An object with a non-finite position has a box that compares false.
std::vector<ObjectBox> Simulator::current_boxes() {
  const std::size_t no = scene_.objects.size();
  std::vector<ObjectBox> box(no, empty_box());
  for (int k : world_.owned_objects) {
    const ObjectLayout& L = world_.layout[static_cast<std::size_t>(k)];
    const auto off = static_cast<std::size_t>(world_.vertex_offset[static_cast<std::size_t>(k)]);
    for (gid_t i = 0; i < L.vertex_count; ++i)
      add_point(box[static_cast<std::size_t>(k)], &world_.x[3 * (off + static_cast<std::size_t>(i))]);
  }
  std::vector<double> lo(3 * no), hi(3 * no);
  for (std::size_t k = 0; k < no; ++k)
    for (std::size_t d = 0; d < 3; ++d) {
      lo[3 * k + d] = box[k].lo[d];
      hi[3 * k + d] = box[k].hi[d];
    }
  MPI_Allreduce(MPI_IN_PLACE, lo.data(), static_cast<int>(3 * no), MPI_DOUBLE, MPI_MIN, comm_);
  MPI_Allreduce(MPI_IN_PLACE, hi.data(), static_cast<int>(3 * no), MPI_DOUBLE, MPI_MAX, comm_);
  for (std::size_t k = 0; k < no; ++k)
    for (std::size_t d = 0; d < 3; ++d) {
      box[k].lo[d] = lo[3 * k + d];
      box[k].hi[d] = hi[3 * k + d];
    }
  return box;
}

// The ghost set: every other rank's object whose box, grown by skin/2, overlaps the box
// of one of ours grown likewise. While no owned vertex has moved skin/2 since, no
// ghosted pair's boxes can have come to overlap at x~ without being ghosted: the set
// stays valid (a Verlet list, as in molecular dynamics).
void Simulator::rebuild_ghosts(bool force) {
  if (nranks_ == 1) {
    if (force || !detector_) make_detector();
    f_.resize(3 * world_.n_local(), 0.0);
    return;
  }
  const std::size_t no = scene_.objects.size();
  const std::vector<ObjectBox> box = current_boxes();
  std::vector<int> ghosts;
  for (std::size_t b = 0; b < no; ++b) {
    if (partition_[b] == rank_ || !(box[b].lo[0] <= box[b].hi[0])) continue;
    for (int a : world_.owned_objects)
      if (grown_overlap(box[static_cast<std::size_t>(a)], box[b], skin_)) {
        ghosts.push_back(static_cast<int>(b));
        break;
      }
  }
  int changed = force || ghosts != world_.ghost_objects ? 1 : 0;
  MPI_Allreduce(MPI_IN_PLACE, &changed, 1, MPI_INT, MPI_LOR, comm_);
  x_at_ghosts_.assign(world_.x.begin(), world_.x.begin() + static_cast<std::ptrdiff_t>(3 * world_.n_owned));
  steps_since_ghosts_ = 0;
  if (!changed) {
    // The same ghosts: their positions still have to be brought up to date (the caller
    // skips its own halo update when it asked for a rebuild).
    if (halo_) halo_->update(world_.x.data());
    return;
  }
  const bool local_change = force || ghosts != world_.ghost_objects || !detector_;
  if (local_change) set_ghost_objects(world_, scene_, surfaces_, ghosts);
  if (halo_) halo_bytes_before_ += halo_->bytes_received();
  halo_ = std::make_unique<Halo>(comm_, world_);
  halo_->update(world_.x.data());
  halo_->update(world_.x_prev.data());
  if (local_change) make_detector();
  f_.resize(3 * world_.n_local(), 0.0);
  ++ghost_rebuilds_;
}

void Simulator::make_detector() {
  std::vector<double> rest(3 * world_.n_local());
  for (std::size_t i = 0; i < world_.n_local(); ++i) {
    const int k = world_.vertex_object[i];
    const TetMesh& m = scene_.objects[static_cast<std::size_t>(k)].mesh;
    const auto j = static_cast<std::size_t>(world_.vertex_gid[i] - world_.layout[static_cast<std::size_t>(k)].vertex_begin);
    for (std::size_t d = 0; d < 3; ++d) rest[3 * i + d] = m.points[3 * j + d];
  }
  detector_ = std::make_unique<CollisionDetector>(world_, collision_settings_, rest.data());
}

// True (on every rank) when some owned vertex has moved skin/2 since the ghost set was
// built. Before a rebuild, the skin adapts to how fast things move: wide enough for about
// kStepsPerBuild steps at the observed largest speed, between the mean edge length and
// the median object size (a rebuild costs a new halo graph and, where the ghost set
// changed, a new detector; a wide skin costs ghost traffic). The reduced maximum is the
// same on every rank, and the ghost set never changes results, only work.
bool Simulator::ghosts_stale() {
  double worst = 0;
  const double* x = world_.x.data();
  for (std::size_t k = 0; k < x_at_ghosts_.size(); k += 3) {
    const double d2 = (x[k] - x_at_ghosts_[k]) * (x[k] - x_at_ghosts_[k]) +
                      (x[k + 1] - x_at_ghosts_[k + 1]) * (x[k + 1] - x_at_ghosts_[k + 1]) +
                      (x[k + 2] - x_at_ghosts_[k + 2]) * (x[k + 2] - x_at_ghosts_[k + 2]);
    if (!(d2 <= worst)) worst = std::isnan(d2) ? std::numeric_limits<double>::infinity() : d2;
  }
  MPI_Allreduce(MPI_IN_PLACE, &worst, 1, MPI_DOUBLE, MPI_MAX, comm_);
  ++steps_since_ghosts_;
  if (worst <= 0.25 * skin_ * skin_) return false;
  constexpr double kStepsPerBuild = 40;
  const double per_step = std::sqrt(worst) / static_cast<double>(steps_since_ghosts_);
  if (std::isfinite(per_step))
    skin_ = std::clamp(2 * kStepsPerBuild * per_step, collision_settings_.cell_size,
                       std::max(collision_settings_.cell_size, max_skin_));
  return true;
}

std::int64_t Simulator::halo_bytes() const { return halo_bytes_before_ + (halo_ ? halo_->bytes_received() : 0); }

Simulator::~Simulator() = default;

namespace {
// The phases of a step as PETSc log events, so that PETSC_OPTIONS=-log_view reports them
// beside PETSc's own (KSPSolve of implicit Euler). Registered once, on first use after
// PetscInitialize; without PETSc (not initialised) nothing is logged.
struct PhaseEvents {
  bool on = false;
  PetscLogEvent forces = 0, integrate = 0, collide = 0, contact = 0;
};

const PhaseEvents& phase_events() {
  static const PhaseEvents ev = [] {
    PhaseEvents e;
    PetscBool init = PETSC_FALSE;
    if (PetscInitialized(&init) != 0 || !init) return e;
    PetscClassId cls = 0;
    e.on = PetscClassIdRegister("softcontact", &cls) == 0 && PetscLogEventRegister("scForces", cls, &e.forces) == 0 &&
           PetscLogEventRegister("scIntegrate", cls, &e.integrate) == 0 &&
           PetscLogEventRegister("scDetectDepth", cls, &e.collide) == 0 &&
           PetscLogEventRegister("scContact", cls, &e.contact) == 0;
    return e;
  }();
  return ev;
}

// Begins a phase's event on construction and ends it on destruction.
class PhaseLog {
public:
  PhaseLog(const PhaseEvents& ev, PetscLogEvent e) : on_(ev.on), e_(e) {
    if (on_) (void)PetscLogEventBegin(e_, nullptr, nullptr, nullptr, nullptr);
  }
  ~PhaseLog() {
    if (on_) (void)PetscLogEventEnd(e_, nullptr, nullptr, nullptr, nullptr);
  }
  PhaseLog(const PhaseLog&) = delete;
  PhaseLog& operator=(const PhaseLog&) = delete;

private:
  bool on_;
  PetscLogEvent e_;
};
}  // namespace

// Item 7 of "Penetration vectors" (docs/collision.md): a record and its partner (the
// record of its triangle's heavy vertex against its own body) may be on two ranks; each
// rank sends the keys of its records whose heavy vertex is a ghost to its neighbours, so
// that both halves of a cross-rank pair are decided from the same two records (the heavy
// vertex is a vertex of the record's other body, a ghost when this rank does not own it).
void Simulator::settle_mutual_records() {
  record_keys_.clear();
  CollisionDetector::record_keys(world_, collisions_, record_keys_);
  if (halo_) {
    const double t = MPI_Wtime();
    std::vector<char> buf;
    for (const RecordKey& k : record_keys_)  // the heavy vertex is B's: a ghost when B is
      if (!world_.owns_object(k.other_object)) append_records(buf, &k, 1);
    const std::vector<std::vector<char>> recv =
        halo_->exchange_bytes(std::vector<std::vector<char>>(halo_->neighbors().size(), buf));
    for (const std::vector<char>& r : recv) {
      const std::vector<RecordKey> in = read_records<RecordKey>(r);
      record_keys_.insert(record_keys_.end(), in.begin(), in.end());
    }
    times_.comm += MPI_Wtime() - t;
  }
  collision_stats_.mutual_settled = detector_->settle_mutual(world_, collisions_, record_keys_);
}

// One step, the paper's Algorithm 1 (docs/architecture.md, "One step"); the two ghost
// refreshes are the parallel layer's part and do nothing on one rank.
void Simulator::step() {
  maybe_rebalance();
  forces_phase();                // p(x^t, v^t): gravity, internal forces, damping
  unconstrained_motion();        // x~ from p (explicit or implicit), prescribed motion
  refresh_predicted_ghosts();    // ghost rows of x~ and x^t from their owners
  detection_and_depth();         // colliding points and their consistent penetration depths
  contact_response();            // contact forces: x^{t+h} and v^{t+h} of the colliding points
  refresh_final_ghosts();        // ghost rows of x^{t+h}, stiction anchors
  ++step_;
  ++timed_steps_;
}

namespace {
// Runs f as one phase: its PETSc log event around it; returns its wall seconds.
template <class F>
double timed_phase(PetscLogEvent PhaseEvents::*event, F&& f) {
  const PhaseEvents& ev = phase_events();
  const double t = MPI_Wtime();
  {
    PhaseLog log(ev, ev.*event);
    f();
  }
  return MPI_Wtime() - t;
}
}  // namespace

void Simulator::forces_phase() {
  const double s = timed_phase(&PhaseEvents::forces, [this] { motion_->forces(world_, f_); });
  times_.forces += s;
  work_seconds_ += s;
}

void Simulator::unconstrained_motion() {
  times_.integrate += timed_phase(&PhaseEvents::integrate, [this] { motion_->advance(world_, f_, time()); });
}

// Ghost rows: x^t is what the last step ended with; x~ comes from the owners (and the
// ghost set is rebuilt when objects have moved far enough to need it).
void Simulator::refresh_predicted_ghosts() {
  if (!halo_) return;
  const double t = MPI_Wtime();
  std::copy(world_.x.begin() + static_cast<std::ptrdiff_t>(3 * world_.n_owned), world_.x.end(),
            world_.x_prev.begin() + static_cast<std::ptrdiff_t>(3 * world_.n_owned));
  if (ghosts_stale()) rebuild_ghosts(false);
  else halo_->update(world_.x.data());
  times_.comm += MPI_Wtime() - t;
}

// The detector times its two parts itself.
void Simulator::detection_and_depth() {
  timed_phase(&PhaseEvents::collide, [this] {
    detector_->detect(world_, world_.x_prev.data(), collisions_, collision_stats_);
    if (scene_.sim.mutual_pairs) settle_mutual_records();
  });
  times_.detect += collision_stats_.detection_seconds;
  times_.depth += collision_stats_.depth_seconds;
  work_seconds_ += collision_stats_.detection_seconds + collision_stats_.depth_seconds;
}

void Simulator::contact_response() {
  times_.contact += timed_phase(&PhaseEvents::contact, [this] {
    contact_->respond(world_, collisions_, scene_.sim.dt, contact_stats_, halo_.get());
  });
}

// The final positions, for the anchors and the next step; the collisions that crossed ranks.
void Simulator::refresh_final_ghosts() {
  if (!halo_) return;
  const double t = MPI_Wtime();
  halo_->update(world_.x.data());
  times_.comm += MPI_Wtime() - t;
  contact_->update_anchors(world_, collisions_);
  cross_collisions_ = 0;
  for (const Collision& c : collisions_) cross_collisions_ += world_.owns_object(c.other_object) ? 0 : 1;
}

// Every check_every steps: repartition with METIS at the current boxes when the work per
// rank (measured seconds of forces, detection and contact) is out of balance or too many
// collisions cross ranks, and migrate the objects that change rank.
void Simulator::maybe_rebalance() {
  if (nranks_ == 1 || rebalance_.check_every <= 0 || step_ == 0 || step_ % rebalance_.check_every != 0) return;
  // Compute phases only (forces to depth): the response includes waits for other ranks.
  double local[3] = {work_seconds_, static_cast<double>(cross_collisions_), static_cast<double>(collisions_.size())};
  work_seconds_ = 0;
  double mx = 0, sum[3] = {0, 0, 0};
  MPI_Allreduce(local, &mx, 1, MPI_DOUBLE, MPI_MAX, comm_);
  MPI_Allreduce(local, sum, 3, MPI_DOUBLE, MPI_SUM, comm_);
  const double imbalance = sum[0] > 0 ? mx / (sum[0] / nranks_) : 1;
  const double cross = sum[2] > 0 ? sum[1] / sum[2] : 0;
  // Both figures are reduced, so every rank takes the same decision.
  if (!(imbalance > rebalance_.max_imbalance) && !(cross > rebalance_.max_cross_fraction)) return;
  const std::size_t no = scene_.objects.size();
  std::vector<int> next = partition_at(scene_, surfaces_, current_boxes(), nranks_);
  std::vector<std::int64_t> weight(no);
  for (std::size_t k = 0; k < no; ++k) weight[k] = object_work(scene_, surfaces_, k);
  // Keep objects where they are as far as the new parts allow: relabel each new part as
  // the old rank it shares the most work with (greedy, heaviest overlaps first).
  std::vector<std::vector<std::int64_t>> overlap(static_cast<std::size_t>(nranks_), std::vector<std::int64_t>(static_cast<std::size_t>(nranks_), 0));
  for (std::size_t k = 0; k < no; ++k) overlap[static_cast<std::size_t>(next[k])][static_cast<std::size_t>(partition_[k])] += weight[k] + 1;
  std::vector<int> label(static_cast<std::size_t>(nranks_), -1), taken(static_cast<std::size_t>(nranks_), 0);
  for (int round = 0; round < nranks_; ++round) {
    std::int64_t best = -1;
    int bp = -1, br = -1;
    for (int p = 0; p < nranks_; ++p)
      for (int r = 0; r < nranks_; ++r)
        if (label[static_cast<std::size_t>(p)] < 0 && !taken[static_cast<std::size_t>(r)] && overlap[static_cast<std::size_t>(p)][static_cast<std::size_t>(r)] > best) {
          best = overlap[static_cast<std::size_t>(p)][static_cast<std::size_t>(r)];
          bp = p;
          br = r;
        }
    label[static_cast<std::size_t>(bp)] = br;
    taken[static_cast<std::size_t>(br)] = 1;
  }
  for (int& p : next) p = label[static_cast<std::size_t>(p)];
  std::int64_t moved = 0;
  for (std::size_t k = 0; k < no; ++k) moved += next[k] != partition_[k] ? 1 : 0;
  if (rank_ == 0)
    std::cerr << "softcontact: step " << step_ << ": repartitioning (work imbalance " << imbalance
              << ", cross-rank collisions " << cross * 100 << "%): " << moved << " of " << no << " objects move\n";
  ++repartitions_;
  if (moved > 0) migrate(next);
}

// Per vertex of a migrating object: what the next steps need.
namespace {
struct VertexState {
  double x[3], x_prev[3], v[3];
  StictionAnchor anchor;
};
}  // namespace

void Simulator::migrate(const std::vector<int>& next) {
  if (next.size() != partition_.size()) throw RuntimeFailure("migrate: the partition has the wrong size");
  // Send every owned object that changes rank, whole, in ascending object order.
  const StepState now = snapshot();
  auto row = [&now](std::size_t v) {
    VertexState s;
    for (std::size_t d = 0; d < 3; ++d) {
      s.x[d] = now.x[3 * v + d];
      s.x_prev[d] = now.x_prev[3 * v + d];
      s.v[d] = now.v[3 * v + d];
    }
    s.anchor = now.anchors[v];
    return s;
  };
  std::vector<std::vector<VertexState>> out(static_cast<std::size_t>(nranks_));
  for (int k : world_.owned_objects) {
    const int to = next[static_cast<std::size_t>(k)];
    if (to == rank_) continue;
    const auto off = static_cast<std::size_t>(world_.vertex_offset[static_cast<std::size_t>(k)]);
    for (gid_t i = 0; i < world_.layout[static_cast<std::size_t>(k)].vertex_count; ++i)
      out[static_cast<std::size_t>(to)].push_back(row(off + static_cast<std::size_t>(i)));
  }
  std::vector<int> scount(static_cast<std::size_t>(nranks_)), rcount(static_cast<std::size_t>(nranks_)),
      sdisp(static_cast<std::size_t>(nranks_)), rdisp(static_cast<std::size_t>(nranks_));
  std::vector<char> sbuf;
  for (int r = 0; r < nranks_; ++r) {
    sdisp[static_cast<std::size_t>(r)] = static_cast<int>(sbuf.size());
    append_records(sbuf, out[static_cast<std::size_t>(r)].data(), out[static_cast<std::size_t>(r)].size());
    scount[static_cast<std::size_t>(r)] = static_cast<int>(sbuf.size()) - sdisp[static_cast<std::size_t>(r)];
  }
  MPI_Alltoall(scount.data(), 1, MPI_INT, rcount.data(), 1, MPI_INT, comm_);
  int total = 0;
  for (int r = 0; r < nranks_; ++r) {
    rdisp[static_cast<std::size_t>(r)] = total;
    total += rcount[static_cast<std::size_t>(r)];
  }
  std::vector<char> rbuf(static_cast<std::size_t>(total));
  MPI_Alltoallv(sbuf.data(), scount.data(), sdisp.data(), MPI_BYTE, rbuf.data(), rcount.data(), rdisp.data(), MPI_BYTE,
                comm_);

  World next_world = build_world(scene_, surfaces_, next, rank_);  // initial positions
  StepState then;  // the same state in the next World's owned order
  then.step = now.step;
  then.anchor_step = now.anchor_step;
  then.x.resize(3 * next_world.n_owned);
  then.x_prev.resize(3 * next_world.n_owned);
  then.v.resize(3 * next_world.n_owned);
  then.anchors.resize(next_world.n_owned);
  // Objects that stay: copy. Objects that arrive: from each sender's buffer, in
  // ascending object order (the order they were packed in).
  std::vector<std::size_t> read(static_cast<std::size_t>(nranks_), 0);
  for (int k : next_world.owned_objects) {
    const auto to = static_cast<std::size_t>(next_world.vertex_offset[static_cast<std::size_t>(k)]);
    const gid_t count = next_world.layout[static_cast<std::size_t>(k)].vertex_count;
    const int from = partition_[static_cast<std::size_t>(k)];
    for (gid_t i = 0; i < count; ++i) {
      const std::size_t v = to + static_cast<std::size_t>(i);
      VertexState s;
      if (from == rank_) {
        s = row(static_cast<std::size_t>(world_.vertex_offset[static_cast<std::size_t>(k)]) + static_cast<std::size_t>(i));
      } else {
        std::size_t& at = read[static_cast<std::size_t>(from)];
        std::memcpy(&s, rbuf.data() + rdisp[static_cast<std::size_t>(from)] + at, sizeof(VertexState));
        at += sizeof(VertexState);
      }
      for (std::size_t d = 0; d < 3; ++d) {
        then.x[3 * v + d] = s.x[d];
        then.x_prev[3 * v + d] = s.x_prev[d];
        then.v[3 * v + d] = s.v[d];
      }
      then.anchors[v] = s.anchor;
    }
  }
  partition_ = next;
  world_ = std::move(next_world);
  detector_.reset();
  halo_.reset();
  build_components();  // rest shapes from the initial positions, then the state
  restore(then);
}

StepState Simulator::snapshot() const {
  StepState s;
  const auto rows = static_cast<std::ptrdiff_t>(3 * world_.n_owned);
  s.step = step_;
  s.anchor_step = contact_->anchor_step();
  s.x.assign(world_.x.begin(), world_.x.begin() + rows);
  s.x_prev.assign(world_.x_prev.begin(), world_.x_prev.begin() + rows);
  s.v.assign(world_.v.begin(), world_.v.begin() + rows);
  s.anchors.assign(contact_->anchors().begin(), contact_->anchors().begin() + static_cast<std::ptrdiff_t>(world_.n_owned));
  return s;
}

void Simulator::restore(const StepState& s) {
  SC_ASSERT(s.x.size() == 3 * world_.n_owned && s.x_prev.size() == s.x.size() && s.v.size() == s.x.size() &&
            s.anchors.size() == world_.n_owned);
  std::copy(s.x.begin(), s.x.end(), world_.x.begin());
  std::copy(s.x_prev.begin(), s.x_prev.end(), world_.x_prev.begin());
  std::copy(s.v.begin(), s.v.end(), world_.v.begin());
  std::copy(s.anchors.begin(), s.anchors.end(), contact_->anchors().begin());
  step_ = s.step;
  contact_->set_anchor_step(s.anchor_step);
  // The halo broadcast fills ghost rows of x and x_prev from their owners.
  rebuild_ghosts(true);
}

void Simulator::measure(StepDiagnostics& d, const VerifyFrame* check) {
  d.step = step_;
  d.time = time();
  ElasticMeasures em;
  motion_->elastic().measure(world_, em);
  // Contact forces of this step's response; their balance is summed per object in
  // vertex order, then over objects in object order (any rank count: the same bits).
  reduce_mechanics(comm_, scene_, world_, d, &em, contact_->force().data());
  // Residual penetration: not the detector's own depths (a second detection pass would
  // repeat its assumptions) but the independent check's deepest surface vertex (verify.hpp).
  const double residual = (check ? *check : verify(false)).surface_depth();

  std::int64_t counts[2] = {collision_stats_.colliding_points, collision_stats_.edge_contacts}, totals[2] = {0, 0};
  MPI_Allreduce(counts, totals, 2, MPI_INT64_T, MPI_SUM, comm_);
  d.contacts = totals[0];
  d.edge_contacts = totals[1];
  d.residual_penetration = residual;
}

VerifyFrame Simulator::verify(bool full) {
  // Owned rows (global id, x, v) to rank 0, which puts them in global order.
  const int mine = static_cast<int>(world_.n_owned);
  std::vector<int> counts(static_cast<std::size_t>(nranks_)), displs(static_cast<std::size_t>(nranks_));
  MPI_Gather(&mine, 1, MPI_INT, counts.data(), 1, MPI_INT, 0, comm_);
  std::vector<double> xv(6 * world_.n_owned);
  for (std::size_t i = 0; i < world_.n_owned; ++i)
    for (std::size_t d = 0; d < 3; ++d) {
      xv[6 * i + d] = world_.x[3 * i + d];
      xv[6 * i + 3 + d] = world_.v[3 * i + d];
    }
  int total = 0;
  for (int r = 0; r < nranks_; ++r) {
    displs[static_cast<std::size_t>(r)] = total;
    total += counts[static_cast<std::size_t>(r)];
  }
  std::vector<gid_t> gids(rank_ == 0 ? static_cast<std::size_t>(total) : 0);
  std::vector<double> all(rank_ == 0 ? 6 * static_cast<std::size_t>(total) : 0);
  MPI_Gatherv(world_.vertex_gid.data(), mine, MPI_INT64_T, gids.data(), counts.data(), displs.data(), MPI_INT64_T, 0,
              comm_);
  for (int r = 0; r < nranks_; ++r) {
    counts[static_cast<std::size_t>(r)] *= 6;
    displs[static_cast<std::size_t>(r)] *= 6;
  }
  MPI_Gatherv(xv.data(), 6 * mine, MPI_DOUBLE, all.data(), counts.data(), displs.data(), MPI_DOUBLE, 0, comm_);
  // In-run checks: what the response did about each vertex in this step (its deepest
  // vertex record), to count the vertices left inside by cause.
  std::vector<std::int8_t> status, all_status(full && rank_ == 0 ? static_cast<std::size_t>(total) : 0);
  if (full) {
    contact_->record_status(collisions_, world_.n_owned, status);
    for (int r = 0; r < nranks_; ++r) {
      counts[static_cast<std::size_t>(r)] /= 6;
      displs[static_cast<std::size_t>(r)] /= 6;
    }
    MPI_Gatherv(status.data(), mine, MPI_INT8_T, all_status.data(), counts.data(), displs.data(), MPI_INT8_T, 0,
                comm_);
  }
  VerifyFrame f;
  if (rank_ == 0) {
    if (!verify_mesh_) {
      verify_mesh_ = std::make_unique<VerifyMesh>(verify_mesh_of(scene_, surfaces_));
      free_fall_speed_ = free_fall_speed(scene_);
    }
    const std::size_t n = verify_mesh_->num_vertices();
    std::vector<double> x(3 * n), v(3 * n);
    for (std::size_t k = 0; k < gids.size(); ++k)
      for (std::size_t d = 0; d < 3; ++d) {
        x[3 * static_cast<std::size_t>(gids[k]) + d] = all[6 * k + d];
        v[3 * static_cast<std::size_t>(gids[k]) + d] = all[6 * k + 3 + d];
      }
    std::vector<std::int8_t> record(full ? n : 0, kNoRecord);
    for (std::size_t k = 0; full && k < gids.size(); ++k) record[static_cast<std::size_t>(gids[k])] = all_status[k];
    VerifyOptions opt;
    opt.interior = opt.crossings = full;
    // Self checks cost a pass over every surface edge against its own body: in the run only
    // where the run claims self-contact (softcontact verify on the frames always has them).
    opt.self = full && scene_.sim.self_collisions;
    opt.free_fall_speed = free_fall_speed_;
    if (full) opt.record = record.data();
    f = verify_frame(*verify_mesh_, x.data(), v.data(), opt);
  }
  MPI_Bcast(&f, static_cast<int>(sizeof f), MPI_BYTE, 0, comm_);  // trivially copyable (verify.hpp)
  f.step = step_;
  f.time = time();
  return f;
}

PhaseTimes Simulator::take_times(std::int64_t& steps) {
  const PhaseTimes t = times_;
  steps = timed_steps_;
  times_ = PhaseTimes{};
  timed_steps_ = 0;
  return t;
}

}  // namespace softcontact
