// The ghost set of one rank (ghosts.hpp).
#include "softcontact/ghosts.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>

#include "softcontact/error.hpp"
#include "softcontact/halo.hpp"
#include "softcontact/mesh_io.hpp"
#include "softcontact/mpi_util.hpp"

namespace softcontact {

std::vector<Box> scene_boxes(const Scene& scene) {
  std::vector<Box> boxes;
  for (std::size_t k = 0; k < scene.objects.size(); ++k) boxes.push_back(scene.shape(k).box);
  return boxes;
}

double median_object_size(const std::vector<Box>& box) {
  std::vector<double> size;
  for (const Box& b : box) size.push_back(std::max({b.hi[0] - b.lo[0], b.hi[1] - b.lo[1], b.hi[2] - b.lo[2]}));
  if (size.empty()) return 0;
  std::nth_element(size.begin(), size.begin() + static_cast<std::ptrdiff_t>(size.size() / 2), size.end());
  return size[size.size() / 2];
}

// Every object has one owner: a min-reduction of the lo corners and a max of the hi
// corners assembles the boxes. An object with a non-finite position has a box that
// compares false.
std::vector<Box> object_boxes(MPI_Comm comm, const Scene& scene, const World& w) {
  const std::size_t no = scene.objects.size();
  std::vector<Box> box(no, Box::none());
  for (int k : w.owned_objects) {
    const ObjectLayout& L = w.layout[static_cast<std::size_t>(k)];
    const auto off = static_cast<std::size_t>(w.vertex_offset[static_cast<std::size_t>(k)]);
    for (gid_t i = 0; i < L.vertex_count; ++i) add_point(box[static_cast<std::size_t>(k)], &w.x[3 * (off + static_cast<std::size_t>(i))]);
  }
  std::vector<double> lo(3 * no), hi(3 * no);
  for (std::size_t k = 0; k < no; ++k)
    for (std::size_t d = 0; d < 3; ++d) {
      lo[3 * k + d] = box[k].lo[d];
      hi[3 * k + d] = box[k].hi[d];
    }
  MPI_Allreduce(MPI_IN_PLACE, lo.data(), static_cast<int>(3 * no), MPI_DOUBLE, MPI_MIN, comm);
  MPI_Allreduce(MPI_IN_PLACE, hi.data(), static_cast<int>(3 * no), MPI_DOUBLE, MPI_MAX, comm);
  for (std::size_t k = 0; k < no; ++k)
    for (std::size_t d = 0; d < 3; ++d) {
      box[k].lo[d] = lo[3 * k + d];
      box[k].hi[d] = hi[3 * k + d];
    }
  return box;
}

GhostSet::GhostSet(MPI_Comm comm, const Scene& scene, double cell_size)
    : comm_(comm), rank_(comm_rank(comm)), nranks_(comm_size(comm)), scene_(scene),
      cell_size_(cell_size), skin_(cell_size), max_skin_(median_object_size(scene_boxes(scene))) {}

GhostSet::~GhostSet() = default;

NeighbourExchange* GhostSet::exchange() { return halo_.get(); }

std::int64_t GhostSet::bytes_received() const { return bytes_before_ + (halo_ ? halo_->bytes_received() : 0); }
std::int64_t GhostSet::rounds() const { return rounds_before_ + (halo_ ? halo_->rounds() : 0); }

void GhostSet::update(double* xyz) {
  if (halo_) halo_->update(xyz);
}

void GhostSet::drop() {
  if (halo_) {
    bytes_before_ += halo_->bytes_received();
    rounds_before_ += halo_->rounds();
  }
  halo_.reset();
}

void GhostSet::update_final(World& w) {
  if (!halo_) return;
  if (halo_->has_kept()) {
    halo_->update_changed(w.x.data());
  } else {
    halo_->update(w.x.data());
    halo_->keep_sent(w.x.data());
  }
}

namespace {

// One object's box on its way to a rank that may ghost it.
struct SentBox {
  std::int64_t object;
  Box box;
};

}  // namespace

bool needs_owner_mesh(const Scene& scene, int k) {
  const SceneObject& o = scene.objects[static_cast<std::size_t>(k)];
  return o.mesh.points.empty() && o.placement.kind == Placement::Kind::entry && o.placement.base != nullptr;
}

std::int64_t fetch_meshes_if_needed(MPI_Comm comm, const Scene& scene, const std::vector<int>& objects,
                                    const std::vector<int>& owners) {
  if (objects.size() != owners.size()) throw RuntimeFailure("fetch_meshes_if_needed: an owner per object expected");
  std::vector<int> wanted, from;
  for (std::size_t i = 0; i < objects.size(); ++i)
    if (needs_owner_mesh(scene, objects[i])) {
      wanted.push_back(objects[i]);
      from.push_back(owners[i]);
    }
  int fetch = wanted.empty() ? 0 : 1;
  MPI_Allreduce(MPI_IN_PLACE, &fetch, 1, MPI_INT, MPI_MAX, comm);
  return fetch ? fetch_object_meshes(comm, scene, wanted, from) : 0;
}

// Two exchanges: the object ids to their owners, then each owner's meshes back (an
// object id and append_mesh_bytes each), checked against the digest of the mesh the scene
// made first.
std::int64_t fetch_object_meshes(MPI_Comm comm, const Scene& scene, const std::vector<int>& wanted,
                                 const std::vector<int>& from) {
  const auto nr = static_cast<std::size_t>(comm_size(comm));
  std::vector<std::vector<char>> ask(nr);
  for (std::size_t i = 0; i < wanted.size(); ++i) {
    const std::int64_t k = wanted[i];
    const auto* c = reinterpret_cast<const char*>(&k);
    ask[static_cast<std::size_t>(from[i])].insert(ask[static_cast<std::size_t>(from[i])].end(), c, c + sizeof k);
  }
  const std::vector<std::vector<char>> asked = alltoallv_bytes(comm, ask);
  std::vector<std::vector<char>> reply(nr);
  for (std::size_t r = 0; r < nr; ++r)
    for (std::size_t at = 0; at + sizeof(std::int64_t) <= asked[r].size(); at += sizeof(std::int64_t)) {
      std::int64_t k = 0;
      std::memcpy(&k, asked[r].data() + at, sizeof k);
      reply[r].insert(reply[r].end(), asked[r].data() + at, asked[r].data() + at + sizeof k);
      append_mesh_bytes(reply[r], scene.view_mesh(static_cast<std::size_t>(k)).get());
    }
  std::int64_t got = 0;
  for (const std::vector<char>& b : alltoallv_bytes(comm, reply))
    for (std::size_t at = 0; at < b.size();) {
      std::int64_t k = 0;
      if (b.size() - at < sizeof k) throw RuntimeFailure("fetch_object_meshes: a reply ends early");
      std::memcpy(&k, b.data() + at, sizeof k);
      at += sizeof k;
      const SceneObject& o = scene.objects[static_cast<std::size_t>(k)];
      TetMesh m = take_mesh_bytes(b, at);
      if (mesh_digest(m) != o.placement.base->digest())
        throw RuntimeFailure("the mesh of object '" + o.name + "' sent by its owner is not the one the scene made");
      if (o.mesh.points.empty()) o.mesh = std::move(m);
      ++got;
    }
  return got;
}

// Each rank's hull of its own boxes (and whether they are all finite) is all-gathered;
// then each rank sends every other rank the boxes of its own objects that pass that
// rank's hull test (the test the receiver would make first, and monotone in the owned
// box: a box not within reach of the hull is within reach of no owned box), and the
// receiver tests them against its own boxes. An owned box that is not finite leaves its
// rank with no hull test: it is sent every box, as the whole scene's test would try them
// all. Counts by MPI_Alltoall (P integers per rank), boxes by MPI_Alltoallv.
std::vector<int> objects_within_reach(MPI_Comm comm, const World& w, double skin, std::int64_t* received,
                                      std::vector<int>* owners) {
  const int nranks = comm_size(comm), rank = comm_rank(comm);
  std::vector<Box> own(w.owned_objects.size(), Box::none());
  for (std::size_t j = 0; j < own.size(); ++j) {
    const auto k = static_cast<std::size_t>(w.owned_objects[j]);
    const ObjectLayout& L = w.layout[k];
    const auto off = static_cast<std::size_t>(w.vertex_offset[k]);
    for (gid_t i = 0; i < L.vertex_count; ++i) add_point(own[j], &w.x[3 * (off + static_cast<std::size_t>(i))]);
  }
  // This rank's hull: lo, hi and 1 when every own box is finite.
  double mine[7];
  {
    Box hull = Box::none();
    bool finite = true;
    for (const Box& o : own) {
      for (int d = 0; d < 3; ++d) {
        finite = finite && std::isfinite(o.lo[d]) && std::isfinite(o.hi[d]);
        hull.lo[d] = std::min(hull.lo[d], o.lo[d]);
        hull.hi[d] = std::max(hull.hi[d], o.hi[d]);
      }
    }
    for (int d = 0; d < 3; ++d) {
      mine[d] = hull.lo[d];
      mine[3 + d] = hull.hi[d];
    }
    mine[6] = finite ? 1 : 0;
  }
  std::vector<double> hulls(7 * static_cast<std::size_t>(nranks));
  MPI_Allgather(mine, 7, MPI_DOUBLE, hulls.data(), 7, MPI_DOUBLE, comm);

  // To each rank the own boxes its hull test lets through (a rank without objects gets none).
  std::vector<std::vector<char>> out(static_cast<std::size_t>(nranks));
  for (int r = 0; r < nranks; ++r) {
    const double* h = &hulls[7 * static_cast<std::size_t>(r)];
    if (r == rank || (!(h[0] <= h[3]) && h[6] != 0)) continue;
    Box hull;
    for (int d = 0; d < 3; ++d) {
      hull.lo[d] = h[d];
      hull.hi[d] = h[3 + d];
    }
    for (std::size_t j = 0; j < own.size(); ++j) {
      if (own[j].empty()) continue;
      if (h[6] != 0 && !hull.within(own[j], skin)) continue;
      const SentBox b{w.owned_objects[j], own[j]};
      const auto* c = reinterpret_cast<const char*>(&b);
      out[static_cast<std::size_t>(r)].insert(out[static_cast<std::size_t>(r)].end(), c, c + sizeof b);
    }
  }
  // The boxes received with the rank that sent each (its owner), by object.
  std::vector<std::pair<SentBox, int>> rbuf;
  const std::vector<std::vector<char>> in = alltoallv_bytes(comm, out);
  for (std::size_t r = 0; r < in.size(); ++r)
    for (std::size_t at = 0; at + sizeof(SentBox) <= in[r].size(); at += sizeof(SentBox)) {
      SentBox b;
      std::memcpy(&b, in[r].data() + at, sizeof b);
      rbuf.emplace_back(b, static_cast<int>(r));
    }
  if (received) *received = static_cast<std::int64_t>(rbuf.size());
  std::sort(rbuf.begin(), rbuf.end(), [](const auto& a, const auto& b) { return a.first.object < b.first.object; });
  std::vector<int> ghosts;
  if (owners) owners->clear();
  for (const auto& [b, from] : rbuf)
    for (const Box& o : own)
      if (o.within(b.box, skin)) {
        ghosts.push_back(static_cast<int>(b.object));
        if (owners) owners->push_back(from);
        break;
      }
  return ghosts;
}

// While no owned vertex has moved skin/2 since the set was built, no ghosted pair's boxes
// can have come to overlap at x~ without being ghosted: the set stays valid.
bool GhostSet::rebuild(World& w, bool force) {
  if (nranks_ == 1) return force;
  std::int64_t received = 0;
  std::vector<int> owners;
  const std::vector<int> ghosts = objects_within_reach(comm_, w, skin_, &received, &owners);
  boxes_received_ += received;
  ++reach_tests_;
  // Whether the set changed here, and whether some ghost's mesh must come from its owner
  // (a single-copy mesh not held here): the same two answers on every rank.
  std::vector<int> wanted, from;
  for (std::size_t i = 0; i < ghosts.size(); ++i)
    if (needs_owner_mesh(scene_, ghosts[i])) {
      wanted.push_back(ghosts[i]);
      from.push_back(owners[i]);
    }
  int flags[2] = {force || ghosts != w.ghost_objects ? 1 : 0, wanted.empty() ? 0 : 1};
  MPI_Allreduce(MPI_IN_PLACE, flags, 2, MPI_INT, MPI_MAX, comm_);
  const int changed = flags[0];
  if (flags[1]) meshes_fetched_ += fetch_object_meshes(comm_, scene_, wanted, from);
  x_at_build_.assign(w.x.begin(), w.x.begin() + static_cast<std::ptrdiff_t>(3 * w.n_owned));
  steps_since_ = 0;
  if (!changed) {
    // The same ghosts: their positions still have to be brought up to date (the caller
    // skips its own halo update when it asked for a rebuild).
    if (halo_) halo_->update(w.x.data());
    return false;
  }
  const bool local_change = force || ghosts != w.ghost_objects;
  if (local_change) set_ghost_objects(w, scene_, ghosts);
  if (halo_) {
    bytes_before_ += halo_->bytes_received();
    rounds_before_ += halo_->rounds();
  }
  halo_ = std::make_unique<Halo>(comm_, w);
  halo_->update(w.x.data());
  halo_->update(w.x_prev.data());
  ++rebuilds_;
  return local_change;
}

bool GhostSet::refresh_predicted(World& w) {
  if (!halo_) return false;
  std::copy(w.x.begin() + static_cast<std::ptrdiff_t>(3 * w.n_owned), w.x.end(),
            w.x_prev.begin() + static_cast<std::ptrdiff_t>(3 * w.n_owned));
  bool changed = false;
  if (stale(w)) {
    changed = rebuild(w, false);  // sends x~ in full, new halo or not
    halo_->keep_sent(w.x.data());
  } else if (halo_->has_kept()) {
    // The ghosts hold x^t, as the last update_final left them: only the rows the
    // unconstrained motion moved travel (not a kinematic object's, nor fixed vertices').
    halo_->update_changed(w.x.data());
  } else {
    halo_->update(w.x.data());
    halo_->keep_sent(w.x.data());
  }
  return changed;
}

// True (on every rank) when some owned vertex has moved skin/2 since the set was built.
// Before a rebuild, the skin adapts to how fast things move: wide enough for about
// kStepsPerBuild steps at the observed largest speed, between the cell size and the
// median object size (a rebuild costs a new halo graph and, where the ghost set changed,
// a new detector; a wide skin costs ghost traffic). The reduced maximum is the same on
// every rank.
bool GhostSet::stale(const World& w) {
  double worst = 0;
  const double* x = w.x.data();
  for (std::size_t k = 0; k < x_at_build_.size(); k += 3) {
    const double d2 = (x[k] - x_at_build_[k]) * (x[k] - x_at_build_[k]) +
                      (x[k + 1] - x_at_build_[k + 1]) * (x[k + 1] - x_at_build_[k + 1]) +
                      (x[k + 2] - x_at_build_[k + 2]) * (x[k + 2] - x_at_build_[k + 2]);
    if (!(d2 <= worst)) worst = std::isnan(d2) ? std::numeric_limits<double>::infinity() : d2;
  }
  MPI_Allreduce(MPI_IN_PLACE, &worst, 1, MPI_DOUBLE, MPI_MAX, comm_);
  ++steps_since_;
  if (worst <= 0.25 * skin_ * skin_) return false;
  constexpr double kStepsPerBuild = 40;
  const double per_step = std::sqrt(worst) / static_cast<double>(steps_since_);
  if (std::isfinite(per_step)) skin_ = std::clamp(2 * kStepsPerBuild * per_step, cell_size_, std::max(cell_size_, max_skin_));
  return true;
}

}  // namespace softcontact
