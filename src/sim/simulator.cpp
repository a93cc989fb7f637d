#include "softcontact/simulator.hpp"

#include <petscsys.h>

#ifdef __GLIBC__
#include <malloc.h>
#endif

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <cmath>
#include <cstring>
#include <ctime>
#include <iostream>
#include <limits>

#include "local_check.hpp"
#include "softcontact/diagnostics.hpp"
#include "softcontact/error.hpp"
#include "softcontact/forces.hpp"
#include "softcontact/ghosts.hpp"
#include "softcontact/mpi_util.hpp"
#include "softcontact/implicit_euler.hpp"
#include "softcontact/memory.hpp"
#include "softcontact/mesh_io.hpp"
#include "softcontact/motion.hpp"
#include "softcontact/partition.hpp"
#include "softcontact/split_forces.hpp"
#include "softcontact/stepper.hpp"
#include "softcontact/integrator.hpp"

namespace softcontact {

Simulator::Simulator(MPI_Comm comm, const Scene& scene, std::vector<int> partition, SplitHosts hosts,
                     std::optional<EdgeStatistics> edges)
    : comm_(comm), rank_(comm_rank(comm)), nranks_(comm_size(comm)), scene_(scene) {
  double t = MPI_Wtime();
  auto stage = [&](const char* name) {  // closes the stage that ends here
    const double now = MPI_Wtime();
    setup_stages_.emplace_back(name, now - t);
    setup_heap_.push_back(heap_in_use_bytes());
    t = now;
  };
  rebalance_ = rebalance_policy(scene.sim);
  // Before the partition: the ghosts' first skin (the detector's cell, the mean edge) is
  // the least reach of the partition's graph.
  if (!edges) edges = scene_edge_statistics(comm_, scene_);
  median_edge_ = edges->median;
  collision_settings_ = collision_settings_for(scene, edges->mean);
  rebalance_.min_reach = collision_settings_.cell_size;
  stage("edge statistics");
  const bool given = !partition.empty();
  partition_ = given ? std::move(partition)
                     : initial_partition(scene, nranks_, comm_, &split_hosts_, rebalance_.min_reach);
  if (partition_.size() != scene.objects.size())
    throw RuntimeFailure("Simulator: the partition names " + std::to_string(partition_.size()) + " objects, the scene has " +
                         std::to_string(scene.objects.size()));
  for (int r : partition_)
    if (r < 0 || r >= nranks_) throw RuntimeFailure("Simulator: the partition names rank " + std::to_string(r));
  if (given) {
    split_hosts_ = softcontact::split_hosts(scene, partition_, nranks_);
    if (!hosts.empty()) {
      // The partition's own hosts, where they have the shape of the fallback's.
      if (!split_hosts_fit(scene, partition_, nranks_, hosts))
        throw RuntimeFailure("Simulator: the split objects' hosts do not fit the partition");
      split_hosts_ = std::move(hosts);
    }
  }
  stage("partition");
  hand_over_made_meshes();
  stage("hand-over");
  world_ = build_world(scene, partition_, rank_);
  stage("world");
  ghosts_ = std::make_unique<GhostSet>(comm, scene_, collision_settings_.cell_size);
  drop_unneeded_meshes();  // the ghosts' meshes are made again as the ghost set takes them
  split_candidates_ = split_candidates(scene_, nranks_);
  stage("halo");
  build_components();
  stage("components");
  rebuild_ghosts(true);
  stage("ghosts");
  core_->initial_overlaps(initial_overlaps_, initial_overlap_depth_);
  MPI_Allreduce(MPI_IN_PLACE, &initial_overlaps_, 1, MPI_INT64_T, MPI_SUM, comm_);
  MPI_Allreduce(MPI_IN_PLACE, &initial_overlap_depth_, 1, MPI_DOUBLE, MPI_MAX, comm_);
  stage("initial overlaps");
  prepare_split();
  stage("split plan");
  core_->start(ghosts_->exchange());
  ghosts_->update(world_.x_prev.data());
  trim_dropped();
  stage("start");
}

// Everything that depends on which objects this rank owns: the serial core (forces and
// the implicit solver, their rest shapes from world_.x, which must hold the scene's
// initial positions here, and the contact response; the detector follows the ghosts).
void Simulator::build_components() {
  release_components();  // the old implicit solver goes before the new one is made
  // The owned objects prepare_split will split (on more than one rank every candidate
  // is): their forces come from their parts, so no rest data of theirs is built for the
  // whole object here (ElasticForces' held_elsewhere).
  std::vector<int> split_owned;
  if (nranks_ > 1)
    for (int k : split_candidates_)
      if (partition_[static_cast<std::size_t>(k)] == rank_) split_owned.push_back(k);
  core_ = std::make_unique<SerialStepper>(scene_, world_, collision_settings_, std::move(split_owned));
  // A split object's points inside a body are found by that body's owner (docs/
  // architecture.md, "Contact of a split object").
  if (delegates_detection())
    core_->delegate_detection(std::vector<std::int32_t>(split_candidates_.begin(), split_candidates_.end()));
  split_dirty_ = true;
}

// The serial core goes, its counters kept for the run's totals.
void Simulator::release_components() {
  if (!core_) return;
  if (core_->split()) split_doubles_before_ += core_->split()->doubles_sent();
  delegated_before_[0] += core_->delegated_sent();
  delegated_before_[1] += core_->delegated_received();
  core_.reset();
}

// Objects split for their forces (split_forces.hpp): every candidate is cut into
// split_part_count parts (METIS with a fixed seed on the object's dual graph, computed
// by its owner and sent to the ranks that take part, each keeping them:
// share_split_parts), each evaluated by its host
// (split_hosts_: one part per rank, or the ranks the partition kept room on). The plan
// is made again after a migration. A rank that neither owns nor hosts an object needs
// nothing of it.
void Simulator::prepare_split() {
  if (split_candidates_.empty() || !ghosts_->active()) return;
  if (!split_dirty_) {
    if (ghosts_->rebuilds() != split_ghost_generation_) share_ghost_holders();
    return;
  }
  const SplitHosts& hosts = split_hosts_;
  if (hosts.size() != split_candidates_.size()) throw RuntimeFailure("Simulator: the split objects' hosts do not match");
  auto takes_part = [&](std::size_t i) {
    const int k = split_candidates_[i];
    return partition_[static_cast<std::size_t>(k)] == rank_ ||
           std::find(hosts[i].begin(), hosts[i].end(), rank_) != hosts[i].end();
  };
  // The owner keeps the parts of every tet and sends each other host its part.
  std::vector<std::optional<SplitPartMesh>> given = share_split_parts(takes_part);
  std::vector<SplitObject> plan;
  split_ranks_ = 0;
  for (std::size_t i = 0; i < split_candidates_.size(); ++i) {
    const int k = split_candidates_[i];
    const std::vector<int>& h = hosts[i];
    split_ranks_ = std::max(split_ranks_, static_cast<int>(h.size()));
    std::vector<std::int32_t> tet_part;
    if (partition_[static_cast<std::size_t>(k)] == rank_) {
      const std::vector<std::int32_t>& parts = split_parts_.at(k);
      tet_part.reserve(parts.size());
      for (std::int32_t q : parts) tet_part.push_back(h[static_cast<std::size_t>(q)]);
    }
    plan.push_back({k, partition_[static_cast<std::size_t>(k)], std::move(tet_part), std::move(given[i])});
  }
  if (core_->split()) split_doubles_before_ += core_->split()->doubles_sent();
  core_->set_split(std::make_unique<SplitForces>(scene_, world_, std::move(plan)));
  split_dirty_ = false;
  split_count_ = static_cast<int>(split_candidates_.size());
  share_ghost_holders();
}

// The parts of a split object's tets (split_tet_parts: METIS on the object's dual graph,
// or a coordinate bisection past kSplitMetisMaxTets tets) are computed by its owner alone
// and kept by it: no other rank repeats the work or holds its memory (METIS's graph of a
// 2^21-tet object is 352 MiB), nor the part of every tet (4 bytes per tet). A new owner
// after a migration takes them from a rank that kept them (the old owner) rather than
// computing them again. Every other rank taking part is sent its part of the mesh by the
// owner (SplitPartMesh: its tets, vertices and tets' corners, then its vertices' rest
// positions and fold flags, about 28 bytes per part tet; cut_split_parts, one pass for
// all), whether or not it holds the mesh as a ghost: the owner sends about 28 bytes per
// tet of the object in all, where the parts of every tet to every host would be 4 bytes
// per tet and host. Who needs a part and who keeps the parts is one MPI_Allgather of a
// byte per candidate. Each object's messages happen in candidate order on every rank
// (the parts to the owner, then a star from it), so no rank waits on a later object.
// Collective.
std::vector<std::optional<SplitPartMesh>> Simulator::share_split_parts(
    const std::function<bool(std::size_t)>& takes_part) {
  const std::size_t n = split_candidates_.size();
  constexpr char kNeedsPart = 1, kKeepsParts = 2;  // per rank and candidate
  std::vector<char> mine(n, 0), all(n * static_cast<std::size_t>(nranks_), 0);
  for (std::size_t i = 0; i < n; ++i) {
    const int k = split_candidates_[i];
    if (takes_part(i) && partition_[static_cast<std::size_t>(k)] != rank_) mine[i] |= kNeedsPart;
    if (split_parts_.count(k)) mine[i] |= kKeepsParts;
  }
  MPI_Allgather(mine.data(), static_cast<int>(n), MPI_CHAR, all.data(), static_cast<int>(n), MPI_CHAR, comm_);
  std::vector<std::optional<SplitPartMesh>> given(n);
  constexpr int kTag = 0x5b1;
  for (std::size_t i = 0; i < n; ++i) {
    const int k = split_candidates_[i];
    const int owner = partition_[static_cast<std::size_t>(k)];
    const std::vector<int>& hosts = split_hosts_[i];
    const auto of = [&](int r) { return all[static_cast<std::size_t>(r) * n + i]; };
    // The parts to an owner that lacks them, from the lowest rank that kept them.
    int keeper = -1;
    if (!(of(owner) & kKeepsParts))
      for (int r = 0; r < nranks_ && keeper < 0; ++r)
        if (of(r) & kKeepsParts) keeper = r;
    if (rank_ == keeper) {
      const std::vector<std::int32_t>& parts = split_parts_.at(k);
      MPI_Send(parts.data(), static_cast<int>(parts.size()), MPI_INT32_T, owner, kTag, comm_);
      split_part_bytes_[0] += static_cast<std::int64_t>(sizeof(std::int32_t) * parts.size());
    }
    if (rank_ != owner) {
      split_parts_.erase(k);  // (kept as its owner before a migration: the owner keeps them now)
      if (!(mine[i] & kNeedsPart)) continue;
      MPI_Status status;
      MPI_Probe(owner, kTag, comm_, &status);
      int count = 0;
      MPI_Get_count(&status, MPI_INT32_T, &count);
      std::vector<std::int32_t> indices(static_cast<std::size_t>(count));
      MPI_Recv(indices.data(), count, MPI_INT32_T, owner, kTag, comm_, MPI_STATUS_IGNORE);
      SplitPartMesh part = part_from_indices(indices);
      std::vector<double> data(4 * part.verts.size());
      MPI_Recv(data.data(), static_cast<int>(data.size()), MPI_DOUBLE, owner, kTag, comm_, MPI_STATUS_IGNORE);
      set_part_vertex_data(part, data);
      split_part_bytes_[1] +=
          static_cast<std::int64_t>(sizeof(std::int32_t) * indices.size() + sizeof(double) * data.size());
      ++split_part_meshes_received_;
      split_part_tets_received_ += static_cast<std::int64_t>(part.tets.size());
      given[i] = std::move(part);
      continue;
    }
    const Scene::MeshView view = scene_.view_mesh(static_cast<std::size_t>(k));  // held: the owner's
    std::vector<std::int32_t>& parts = split_parts_[k];
    if (keeper >= 0) {
      parts.resize(scene_.shape(static_cast<std::size_t>(k)).tets);
      MPI_Recv(parts.data(), static_cast<int>(parts.size()), MPI_INT32_T, keeper, kTag, comm_, MPI_STATUS_IGNORE);
      split_part_bytes_[1] += static_cast<std::int64_t>(sizeof(std::int32_t) * parts.size());
    } else if (parts.empty()) {
      const SplitParts how = scene_.sim.split_parts;
      const std::size_t metis_max = how == SplitParts::metis       ? std::numeric_limits<std::size_t>::max()
                                    : how == SplitParts::bisection ? 0
                                                                   : kSplitMetisMaxTets;
      parts = split_tet_parts(view.get(), static_cast<int>(hosts.size()), metis_max);
      ++split_parts_computed_;
    }
    // Every other host's part of the mesh, cut in one pass: by each tet's host rank, with
    // each vertex's interior rank.
    std::vector<std::int32_t> cut_for;
    for (int r = 0; r < nranks_; ++r)
      if (of(r) & kNeedsPart) cut_for.push_back(r);
    if (cut_for.empty()) continue;
    std::vector<std::int32_t> tet_rank;
    tet_rank.reserve(parts.size());
    for (std::int32_t q : parts) tet_rank.push_back(hosts[static_cast<std::size_t>(q)]);
    std::vector<SplitPartMesh> cuts =
        cut_split_parts(view.get(), tet_rank, split_interior_parts(view.get(), tet_rank), cut_for);
    for (std::size_t c = 0; c < cut_for.size(); ++c) {
      const std::vector<std::int32_t> indices = part_indices(cuts[c]);
      const std::vector<double> data = part_vertex_data(cuts[c]);
      cuts[c] = SplitPartMesh();  // packed: its memory goes as the sends go
      MPI_Send(indices.data(), static_cast<int>(indices.size()), MPI_INT32_T, cut_for[c], kTag, comm_);
      MPI_Send(data.data(), static_cast<int>(data.size()), MPI_DOUBLE, cut_for[c], kTag, comm_);
      split_part_bytes_[0] +=
          static_cast<std::int64_t>(sizeof(std::int32_t) * indices.size() + sizeof(double) * data.size());
    }
  }
  return given;
}

// Which ranks hold each split object as a ghost, so that their parts take its positions
// from the ghost rows rather than from a message (SplitForces::set_ghost_holders). Again
// after every change of the ghost sets: GhostSet::rebuilds() counts those alike on every
// rank, so every rank comes here together. Collective.
void Simulator::share_ghost_holders() {
  const std::size_t n = split_candidates_.size();
  std::vector<char> mine(n, 0), all(n * static_cast<std::size_t>(nranks_), 0);
  for (std::size_t i = 0; i < n; ++i) {
    const auto k = static_cast<std::size_t>(split_candidates_[i]);
    mine[i] = world_.vertex_offset[k] >= 0 && !world_.owns_object(static_cast<int>(k)) ? 1 : 0;
  }
  MPI_Allgather(mine.data(), static_cast<int>(n), MPI_CHAR, all.data(), static_cast<int>(n), MPI_CHAR, comm_);
  core_->split()->set_ghost_holders(all);
  split_ghost_generation_ = ghosts_->rebuilds();
}

std::vector<Box> Simulator::current_boxes() { return object_boxes(comm_, scene_, world_); }

// The ghost set (ghosts.hpp) at the current positions; the detector follows it.
void Simulator::rebuild_ghosts(bool force) {
  if (ghosts_->rebuild(world_, force) || !core_->has_detector()) follow_ghosts();
}

// The World's ghost part changed: a detector for it, the force buffer sized to it.
void Simulator::follow_ghosts() {
  local_verify_.reset();
  drop_unneeded_meshes();
  core_->make_detector();
  core_->resize();
  trim_dropped();
}

// The mean and median of the scene's tet edges, each object's measured by one rank (its
// mesh's maker, or rank k % ranks): no rank reads the meshes of the whole scene or holds
// its lengths. The mean is the objects' sums in scene order (mean_of_object_sums; each
// sum comes from one rank, the others add exact zeros), the median an exact selection
// over the ranks (kth_smallest).
EdgeStatistics scene_edge_statistics(MPI_Comm comm, const Scene& scene) {
  const int rank = comm_rank(comm), nranks = comm_size(comm);
  std::vector<double> sums(scene.objects.size(), 0.0), len, own;
  for (std::size_t k = 0; k < scene.objects.size(); ++k) {
    // (A maker outside this communicator: a scene read over more ranks than this run's,
    // as a one-rank reference run in the tests.)
    const int maker = scene.objects[k].maker;
    const int by = maker >= 0 && maker < nranks ? maker : static_cast<int>(k % static_cast<std::size_t>(nranks));
    if (by != rank) continue;
    const Scene::MeshView v = scene.view_mesh(k);  // a copy placed for the moment, not held
    sums[k] = object_edge_sum(v.get(), own);
    len.insert(len.end(), own.begin(), own.end());
  }
  if (nranks > 1) MPI_Allreduce(MPI_IN_PLACE, sums.data(), static_cast<int>(sums.size()), MPI_DOUBLE, MPI_SUM, comm);
  std::int64_t total = 0;
  for (std::size_t k = 0; k < scene.objects.size(); ++k) total += 6 * static_cast<std::int64_t>(scene.shape(k).tets);
  EdgeStatistics e;
  e.mean = mean_of_object_sums(sums, total);
  e.median = total > 0 ? kth_smallest(comm, len, total / 2) : 0;
  return e;
}

void Simulator::hand_over_made_meshes() {
  if (nranks_ == 1) return;
  // Each message: per mesh its object (8 bytes) and the mesh (append_mesh_bytes), in
  // object order.
  std::vector<std::vector<char>> out(static_cast<std::size_t>(nranks_));
  bool any = false;
  for (std::size_t k = 0; k < scene_.objects.size(); ++k) {
    const SceneObject& o = scene_.objects[k];
    if (o.maker < 0) continue;
    any = true;
    const int owner = partition_[k];
    if (o.maker != rank_ || owner == rank_ || o.mesh.points.empty()) continue;
    std::vector<char>& b = out[static_cast<std::size_t>(owner)];
    const std::uint64_t object = k;
    const auto* c = reinterpret_cast<const char*>(&object);
    b.insert(b.end(), c, c + sizeof object);
    append_mesh_bytes(b, o.mesh);
  }
  if (!any) return;  // the same on every rank: the makers are the scene's
  const std::vector<std::vector<char>> in = alltoallv_bytes(comm_, out);
  std::vector<std::vector<char>>().swap(out);
  for (const std::vector<char>& rbuf : in)
    for (std::size_t at = 0; at < rbuf.size();) {
      std::uint64_t object = 0;
      std::memcpy(&object, rbuf.data() + at, sizeof object);
      at += sizeof object;
      const SceneObject& o = scene_.objects[object];
      TetMesh m = take_mesh_bytes(rbuf, at);
      // The maker's mesh is the one its digest was taken from: a difference is a fault here.
      if (!o.placement.base || mesh_digest(m) != o.placement.base->digest())
        throw RuntimeFailure("the mesh of object '" + o.name + "' handed over by rank " + std::to_string(o.maker) +
                             " is not the one it read");
      if (o.mesh.points.empty()) o.mesh = std::move(m);
    }
}

// A rank keeps the meshes of its own objects and its ghosts: a migration or the next
// ghost set makes the others again from their entries' meshes when it needs them.
void Simulator::drop_unneeded_meshes() {
  if (nranks_ == 1) return;
  std::vector<char> keep(scene_.objects.size(), 0);
  for (int k : world_.owned_objects) keep[static_cast<std::size_t>(k)] = 1;
  for (int k : world_.ghost_objects) keep[static_cast<std::size_t>(k)] = 1;
  dropped_bytes_ += scene_.drop_meshes(keep);
}

// Not at the drop itself: the first set-up stages after it (the forces' per-tet data,
// the detector) reuse the freed heap, and trimming first made them fault the same pages
// in again (a third more page faults per rank at 2 ranks than at 1, +8 ms of the
// "components" stage alone; docs/benchmarks.md).
void Simulator::trim_dropped() {
#ifdef __GLIBC__
  // Meshes are many small blocks inside the heap: hand their pages back to the system,
  // or the resident size keeps them.
  if (dropped_bytes_ > 0) malloc_trim(0);
#endif
  dropped_bytes_ = 0;
}

std::int64_t Simulator::halo_bytes() const { return ghosts_->bytes_received(); }
std::int64_t Simulator::halo_rounds() const { return ghosts_->rounds(); }
std::int64_t Simulator::split_bytes_sent() const {
  const SplitForces* s = core_ ? core_->split() : nullptr;
  return static_cast<std::int64_t>(sizeof(double)) * (split_doubles_before_ + (s ? s->doubles_sent() : 0));
}
std::int64_t Simulator::split_helped_tets() const {
  const SplitForces* s = core_ ? core_->split() : nullptr;
  return s ? s->helped_tets() : 0;
}
std::int64_t Simulator::split_evaluated_tets() const {
  const SplitForces* s = core_ ? core_->split() : nullptr;
  return s ? s->evaluated_tets() : 0;
}
int Simulator::split_helping_parts() const {
  const SplitForces* s = core_ ? core_->split() : nullptr;
  return s ? s->helping_parts() : 0;
}
int Simulator::split_parts_from_ghosts() const {
  const SplitForces* s = core_ ? core_->split() : nullptr;
  return s ? s->parts_from_ghosts() : 0;
}
std::int64_t Simulator::delegated_records_sent() const {
  return delegated_before_[0] + (core_ ? core_->delegated_sent() : 0);
}
std::int64_t Simulator::delegated_records_received() const {
  return delegated_before_[1] + (core_ ? core_->delegated_received() : 0);
}
std::int64_t Simulator::ghost_rebuilds() const { return ghosts_->rebuilds(); }
std::int64_t Simulator::ghost_reach_tests() const { return ghosts_->reach_tests(); }
std::int64_t Simulator::ghost_boxes_received() const { return ghosts_->boxes_received(); }

Simulator::~Simulator() = default;

const std::vector<Collision>& Simulator::collisions() const { return core_->collisions(); }
const CollisionStats& Simulator::collision_stats() const { return core_->collision_stats(); }
const ContactStats& Simulator::contact_stats() const { return core_->contact_stats(); }
const std::vector<double>& Simulator::contact_force() { return core_->response().force(); }
const std::vector<double>& Simulator::penetration() { return core_->response().penetration(); }

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

// With split objects the phase includes the exchange of their parts' forces: its wall
// time is communication, its CPU time not work (a rank waiting for another's part).
void Simulator::forces_phase() {
  const double t0 = MPI_Wtime();
  prepare_split();  // a new plan when the ghosts changed (collective): communication
  times_.comm += MPI_Wtime() - t0;
  const double cpu = process_cpu_seconds();
  double wait_wall = 0, wait_cpu = 0;
  const double wall = timed_phase(&PhaseEvents::forces, [&] {
    const SplitForces* split = core_->split();
    const double w0 = split ? split->exchange_wall_seconds() : 0, c0 = split ? split->exchange_cpu_seconds() : 0;
    core_->forces(ghosts_->exchange());
    if (split) {
      wait_wall = split->exchange_wall_seconds() - w0;
      wait_cpu = split->exchange_cpu_seconds() - c0;
    }
  });
  times_.forces += wall - wait_wall;
  times_.comm += wait_wall;
  const double used = process_cpu_seconds() - cpu - wait_cpu;
  work_seconds_ += used;
  times_.work_cpu += used;
}

void Simulator::unconstrained_motion() {
  times_.integrate += timed_phase(&PhaseEvents::integrate, [this] { core_->unconstrained_motion(time()); });
}

// Ghost rows: x^t is what the last step ended with; x~ comes from the owners (and the
// ghost set is rebuilt when objects have moved far enough to need it).
void Simulator::refresh_predicted_ghosts() {
  if (!ghosts_->active()) return;
  const double t = MPI_Wtime();
  if (ghosts_->refresh_predicted(world_)) follow_ghosts();
  times_.comm += MPI_Wtime() - t;
}

// The detector times its two parts itself; its exchanges (the delegated records, the
// mutual records' keys) are communication, their CPU no work.
void Simulator::detection_and_depth() {
  const double exchanged = core_->exchange_seconds(), exchanged_cpu = core_->exchange_cpu_seconds();
  const double cpu = process_cpu_seconds();
  timed_phase(&PhaseEvents::collide, [this] { core_->detection_and_depth(ghosts_->exchange()); });
  const double used = process_cpu_seconds() - cpu - (core_->exchange_cpu_seconds() - exchanged_cpu);
  work_seconds_ += used;
  times_.work_cpu += used;
  const CollisionStats& st = core_->collision_stats();
  times_.detect += st.detection_seconds;
  times_.depth += st.depth_seconds;
  times_.comm += core_->exchange_seconds() - exchanged;
}

void Simulator::contact_response() {
  times_.contact += timed_phase(&PhaseEvents::contact, [this] {
    core_->contact_response(ghosts_->exchange());
  });
}

// The final positions, for the anchors and the next step; the collisions that crossed ranks.
void Simulator::refresh_final_ghosts() {
  if (!ghosts_->active()) return;
  const double t = MPI_Wtime();
  ghosts_->update_final(world_);
  times_.comm += MPI_Wtime() - t;
  core_->update_anchors();
  cross_collisions_ = 0;
  for (const Collision& c : core_->collisions()) cross_collisions_ += world_.owns_object(c.other_object) ? 0 : 1;
  // Colliding surface vertices per object for the rebalance's weights (vertex records, by
  // the object whose owner found them: their point's, but for a split object's points,
  // which the owner of the body they are in finds: "Contact of a split object").
  if (nranks_ > 1 && rebalance_.check_every > 0 && rebalance_.measured_weights) {
    window_contacts_.resize(scene_.objects.size(), 0);
    const bool delegated = delegates_detection();
    for (const Collision& c : core_->collisions()) {
      if (c.point2 >= 0) continue;
      const int k = world_.vertex_object[static_cast<std::size_t>(c.point)];
      const bool by_body = delegated && std::binary_search(split_candidates_.begin(), split_candidates_.end(), k);
      ++window_contacts_[static_cast<std::size_t>(by_body ? c.other_object : k)];
    }
  }
}

// Every check_every steps: repartition with METIS at the current boxes, weighted by the
// measured cost, when the work per rank (CPU seconds of forces, detection and depth) is out of balance or too many
// collisions cross ranks, and migrate the objects that change rank (rebalance.hpp).
void Simulator::maybe_rebalance() {
  if (nranks_ == 1 || !rebalance_due(rebalance_, step_)) return;
  RankWork work{work_seconds_, cross_collisions_, static_cast<std::int64_t>(core_->collisions().size()), {}};
  work.contacts.swap(window_contacts_);
  work_seconds_ = 0;
  std::vector<int> next;
  SplitHosts hosts = split_hosts_;
  if (!rebalance(comm_, scene_, world_, partition_, rebalance_, step_, work, next, rebalance_history_, &hosts)) return;
  ++repartitions_;
  if (next != partition_) migrate(next, std::move(hosts));
}

void Simulator::migrate(const std::vector<int>& next) { migrate(next, softcontact::split_hosts(scene_, next, nranks_)); }

void Simulator::migrate(const std::vector<int>& next, SplitHosts hosts) {
  split_hosts_ = std::move(hosts);
  StepState now = snapshot(), then;
  // The old forces, response and detector go before the next World is made: the
  // migration's peak then holds one set of them, not the old one beside the new World
  // (soft floor, 4 ranks: docs/benchmarks.md, "a migration's peak").
  local_verify_.reset();
  release_components();
  World next_world = migrate_objects(comm_, scene_, world_, now, partition_, next, then);
  now = StepState();
  partition_ = next;
  ghosts_->drop();
  world_ = std::move(next_world);
  build_components();  // rest shapes from the initial positions, then the state
  restore(then);
}

StepState Simulator::snapshot() const {
  StepState s;
  const auto rows = static_cast<std::ptrdiff_t>(3 * world_.n_owned);
  s.step = step_;
  s.anchor_step = core_->response().anchor_step();
  s.x.assign(world_.x.begin(), world_.x.begin() + rows);
  s.x_prev.assign(world_.x_prev.begin(), world_.x_prev.begin() + rows);
  s.v.assign(world_.v.begin(), world_.v.begin() + rows);
  s.anchors.assign(core_->response().anchors().begin(), core_->response().anchors().begin() + static_cast<std::ptrdiff_t>(world_.n_owned));
  return s;
}

void Simulator::restore(const StepState& s) {
  SC_ASSERT(s.x.size() == 3 * world_.n_owned && s.x_prev.size() == s.x.size() && s.v.size() == s.x.size() &&
            s.anchors.size() == world_.n_owned);
  std::copy(s.x.begin(), s.x.end(), world_.x.begin());
  std::copy(s.x_prev.begin(), s.x_prev.end(), world_.x_prev.begin());
  std::copy(s.v.begin(), s.v.end(), world_.v.begin());
  std::copy(s.anchors.begin(), s.anchors.end(), core_->response().anchors().begin());
  step_ = s.step;
  core_->response().set_anchor_step(s.anchor_step);
  // The halo broadcast fills ghost rows of x and x_prev from their owners.
  rebuild_ghosts(true);
}

void Simulator::measure(StepDiagnostics& d, const VerifyFrame* check) {
  d.step = step_;
  d.time = time();
  ElasticMeasures em;
  core_->motion().elastic().measure(world_, em);
  // Contact forces of this step's response; their balance is summed per object in
  // vertex order, then over objects in object order (any rank count: the same bits).
  reduce_mechanics(comm_, scene_, world_, d, &em, core_->response().force().data());
  // Residual penetration: not the detector's own depths (a second detection pass would
  // repeat its assumptions) but the independent check's deepest surface vertex (verify.hpp).
  const double residual = check ? check->surface_depth() : residual_surface_depth();

  std::int64_t counts[2] = {core_->collision_stats().colliding_points, core_->collision_stats().edge_contacts}, totals[2] = {0, 0};
  MPI_Allreduce(counts, totals, 2, MPI_INT64_T, MPI_SUM, comm_);
  d.contacts = totals[0];
  d.edge_contacts = totals[1];
  d.residual_penetration = residual;
}

PhaseTimes Simulator::take_times(std::int64_t& steps) {
  const PhaseTimes t = times_;
  steps = timed_steps_;
  times_ = PhaseTimes{};
  timed_steps_ = 0;
  return t;
}

}  // namespace softcontact
