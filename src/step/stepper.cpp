// The serial core of a step (stepper.hpp). No MPI: what crosses ranks goes through the
// NeighbourExchange the parallel layer passes in.
#include "softcontact/stepper.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <unordered_map>

#include "softcontact/error.hpp"
#include "softcontact/exchange.hpp"
#include "softcontact/motion.hpp"
#include "softcontact/forces.hpp"
#include "softcontact/phase_times.hpp"
#include "softcontact/split_forces.hpp"

namespace softcontact {

// Mean and median edge length over every tet edge of the scene (an edge counts once per
// tet), from the scene alone: the same on every rank.
void append_edge_lengths(const TetMesh& m, std::vector<double>& len) {
  for (std::size_t t = 0; t < m.num_tets(); ++t)
    for (const auto& e : kTetEdges) {
      const double* a = &m.points[3 * m.tets[4 * t + e[0]]];
      const double* b = &m.points[3 * m.tets[4 * t + e[1]]];
      len.push_back(std::hypot(a[0] - b[0], a[1] - b[1], a[2] - b[2]));
    }
}

double object_edge_sum(const TetMesh& m, std::vector<double>& len) {
  len.clear();
  append_edge_lengths(m, len);
  double sum = 0;
  for (double l : len) sum += l;
  return sum;
}

double mean_of_object_sums(const std::vector<double>& sums, std::int64_t count) {
  double sum = 0;
  for (double s : sums) sum += s;
  return count > 0 ? sum / static_cast<double>(count) : 0;
}

namespace {
// The lengths object by object: each object's sum in tet order, then those sums in scene
// order (mean_of_object_sums), so the mean is bitwise the same however the objects are
// spread over ranks (Simulator::edge_statistics sums each rank's own objects).
template <class F>
double sum_edge_lengths(const Scene& scene, std::int64_t& count, F&& each_object) {
  std::vector<double> sums(scene.objects.size(), 0.0), len;
  count = 0;
  for (std::size_t k = 0; k < scene.objects.size(); ++k) {
    const Scene::MeshView view = scene.view_mesh(k);
    sums[k] = object_edge_sum(view.get(), len);
    count += static_cast<std::int64_t>(len.size());
    each_object(len);
  }
  return mean_of_object_sums(sums, count);
}
}  // namespace

double scene_mean_edge(const Scene& scene) {
  std::int64_t n = 0;
  return sum_edge_lengths(scene, n, [](const std::vector<double>&) {});
}

void scene_edge_lengths(const Scene& scene, double& mean, double& median) {
  std::vector<double> len;
  len.reserve(6 * scene.num_tets());
  std::int64_t n = 0;
  mean = sum_edge_lengths(scene, n, [&](const std::vector<double>& l) { len.insert(len.end(), l.begin(), l.end()); });
  median = 0;
  if (len.empty()) return;
  std::nth_element(len.begin(), len.begin() + static_cast<std::ptrdiff_t>(len.size() / 2), len.end());
  median = len[len.size() / 2];
}

// One cell size for every rank: detection's tolerances scale with it.
CollisionSettings collision_settings_for(const Scene& scene) {
  return collision_settings_for(scene, scene_mean_edge(scene));
}

CollisionSettings collision_settings_for(const Scene& scene, double mean) {
  CollisionSettings s;
  s.self_collisions = scene.sim.self_collisions;
  s.edge_contacts = scene.sim.edge_contacts;
  s.cell_size = mean > 0 ? mean : 1.0;
  return s;
}

SerialStepper::SerialStepper(const Scene& scene, World& world, const CollisionSettings& settings,
                             std::vector<int> split_owned)
    : scene_(scene), world_(world), settings_(settings) {
  motion_ = std::make_unique<UnconstrainedMotion>(scene_, world_, std::move(split_owned));
  contact_ = std::make_unique<ContactResponse>(scene_, world_);
  gaps_ = self_gap_cache_for(scene_);
}

SelfGapCache self_gap_cache_for(const Scene& scene) {
  SelfGapCache c;
  std::unordered_map<const EntryMesh*, std::int32_t> bases;
  c.entry.assign(scene.objects.size(), -1);
  for (std::size_t k = 0; k < scene.objects.size(); ++k) {
    const Placement& p = scene.objects[k].placement;
    if (p.is_copy()) c.entry[k] = bases.emplace(p.base.get(), static_cast<std::int32_t>(bases.size())).first->second;
  }
  return c;
}

SerialStepper::~SerialStepper() = default;

// The surface hierarchies are built from the rest shapes: the scene's mesh points, for
// owned and ghost vertices alike.
void SerialStepper::make_detector() {
  std::vector<double> rest(3 * world_.n_local());
  for (std::size_t i = 0; i < world_.n_local(); ++i) {
    const int k = world_.vertex_object[i];
    const TetMesh& m = scene_.mesh(static_cast<std::size_t>(k));
    const auto j = static_cast<std::size_t>(world_.vertex_gid[i] - world_.layout[static_cast<std::size_t>(k)].vertex_begin);
    for (std::size_t d = 0; d < 3; ++d) rest[3 * i + d] = m.points[3 * j + d];
  }
  // After a ghost-set change the detector of the World before gives the pieces of the
  // objects that stayed. A migration makes a new stepper, which has no detector before
  // (Simulator::migrate releases the old one first, for the migration's peak memory).
  detector_ = std::make_unique<CollisionDetector>(world_, settings_, rest.data(), &gaps_, detector_.get());
  if (!settings_.edge_contacts) detector_->delegate(delegated_);
}

void SerialStepper::delegate_detection(std::vector<std::int32_t> objects) { delegated_ = std::move(objects); }

void SerialStepper::resize() { f_.resize(3 * world_.n_owned, 0.0); }  // owned rows only (gravity_forces)

void SerialStepper::start(NeighbourExchange* exchange) {
  motion_->forces(world_, f_, split_.get(), exchange);
  motion_->start(world_, f_);
}

void SerialStepper::set_split(std::unique_ptr<SplitForces> split) {
  split_ = std::move(split);
  motion_->elastic().exclude_objects(world_, split_ ? split_->owned_objects() : std::vector<int>{});
}

// One step on one rank (docs/architecture.md, "One step").
void SerialStepper::step(double t) {
  forces();                        // p(x^t, v^t): gravity, internal forces, damping
  unconstrained_motion(t);         // x~ from p (explicit or implicit), prescribed motion
  detection_and_depth(nullptr);    // colliding points and their consistent penetration depths
  contact_response(nullptr);       // contact forces: x^{t+h} and v^{t+h} of the colliding points
}

void SerialStepper::forces(NeighbourExchange* exchange) { motion_->forces(world_, f_, split_.get(), exchange); }

void SerialStepper::unconstrained_motion(double t) { motion_->advance(world_, f_, t); }

void SerialStepper::detection_and_depth(NeighbourExchange* exchange) {
  detector_->detect(world_, world_.x_prev.data(), collisions_, collision_stats_);
  if (!delegated_.empty() && !settings_.edge_contacts) send_delegated_records(exchange);
  if (scene_.sim.mutual_pairs) settle_mutual_records(exchange);
}

namespace {
// A record of a delegated point as it travels to the point's owner: global ids in place
// of local indices (vertex records only: edge contacts are never delegated).
struct DelegatedRecord {
  gid_t point_gid;
  gid_t triangle_gid;
  gid_t corner_gid[3];
  double weight[3];
  double depth[3];
  std::int32_t object;
  std::int32_t other_object;
  std::int32_t fallback;
  std::int32_t pad;
};

DelegatedRecord to_wire(const World& w, const Collision& c) {
  if (c.point2 >= 0) throw RuntimeFailure("delegated detection: an edge record of a ghost point");
  DelegatedRecord r{};
  r.point_gid = c.point_gid;
  r.triangle_gid = c.triangle_gid;
  for (std::size_t j = 0; j < 3; ++j) {
    r.corner_gid[j] = w.vertex_gid[static_cast<std::size_t>(c.triangle[j])];
    r.weight[j] = c.weight[j];
    r.depth[j] = c.depth[j];
  }
  r.object = c.object;
  r.other_object = c.other_object;
  r.fallback = c.fallback ? 1 : 0;
  return r;
}

// The local index of vertex `g` of `object`, which this rank must hold.
index_t held_vertex(const World& w, std::int32_t object, gid_t g) {
  const auto o = static_cast<std::size_t>(object);
  if (object < 0 || o >= w.layout.size() || w.vertex_offset[o] < 0 || g < w.layout[o].vertex_begin ||
      g >= w.layout[o].vertex_begin + w.layout[o].vertex_count)
    throw RuntimeFailure("delegated detection: a record names object " + std::to_string(object) + ", which rank " +
                         std::to_string(w.rank) + " does not hold");
  return w.local_vertex(object, g);
}

Collision from_wire(const World& w, const DelegatedRecord& r) {
  if (r.object < 0 || static_cast<std::size_t>(r.object) >= w.layout.size() || !w.owns_object(r.object))
    throw RuntimeFailure("delegated detection: a record for a point not owned here");
  Collision c;
  c.point = held_vertex(w, r.object, r.point_gid);
  c.point_gid = r.point_gid;
  c.triangle_gid = r.triangle_gid;
  for (std::size_t j = 0; j < 3; ++j) {
    c.triangle[j] = held_vertex(w, r.other_object, r.corner_gid[j]);
    c.weight[j] = r.weight[j];
    c.depth[j] = r.depth[j];
  }
  c.object = r.object;
  c.other_object = r.other_object;
  c.fallback = r.fallback != 0;
  return c;
}
}  // namespace

// Delegated points (CollisionDetector::delegate; docs/architecture.md, "Contact of a
// split object"): the records this rank made for ghost points go to the points' owners,
// which take them as if they had found them, and the distinct points inside a body are
// counted once, by the owner, over every rank that found some.
void SerialStepper::send_delegated_records(NeighbourExchange* exchange) {
  const std::vector<index_t>& found = detector_->delegated_points();
  if (!exchange) {  // one rank: every point is its own
    collision_stats_.colliding_points += static_cast<std::int64_t>(found.size());
    return;
  }
  const std::vector<int>& nb = exchange->neighbors();
  auto neighbour_of = [&](std::int32_t object) {
    const int r = world_.layout[static_cast<std::size_t>(object)].rank;
    const auto it = std::find(nb.begin(), nb.end(), r);
    if (it == nb.end()) throw RuntimeFailure("delegated detection: the owner of a ghost object is no neighbour");
    return static_cast<std::size_t>(it - nb.begin());
  };
  const auto gid = [&](index_t v) { return world_.vertex_gid[static_cast<std::size_t>(v)]; };
  // Each message: the number of points, the points, then the records. The buffers keep
  // their capacity from step to step.
  delegated_points_.resize(nb.size());
  delegated_out_.resize(nb.size());
  for (std::vector<gid_t>& p : delegated_points_) p.clear();
  std::vector<gid_t> own;  // this rank's own delegated points inside a body
  for (index_t v : found) {
    const std::int32_t k = world_.vertex_object[static_cast<std::size_t>(v)];
    if (world_.owns_object(k)) own.push_back(gid(v));
    else delegated_points_[neighbour_of(k)].push_back(gid(v));
  }
  for (std::size_t q = 0; q < nb.size(); ++q) {
    std::vector<char>& msg = delegated_out_[q];
    msg.clear();
    const std::int64_t n = static_cast<std::int64_t>(delegated_points_[q].size());
    append_records(msg, &n, 1);
    append_records(msg, delegated_points_[q].data(), delegated_points_[q].size());
  }
  std::size_t kept = 0;
  for (const Collision& c : collisions_) {
    if (world_.owns_object(c.object)) {
      collisions_[kept++] = c;
      continue;
    }
    const DelegatedRecord r = to_wire(world_, c);
    append_records(delegated_out_[neighbour_of(c.object)], &r, 1);
    ++delegated_sent_;
  }
  collisions_.resize(kept);
  const auto t0 = std::chrono::steady_clock::now();
  const double cpu0 = process_cpu_seconds();
  const std::vector<std::vector<char>> recv = exchange->exchange_bytes(delegated_out_);
  exchange_cpu_seconds_ += process_cpu_seconds() - cpu0;
  exchange_seconds_ += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const std::size_t before = collisions_.size();
  for (const std::vector<char>& m : recv) {
    std::int64_t n = 0;
    if (m.size() < sizeof n) throw RuntimeFailure("delegated detection: a message shorter than its count");
    std::memcpy(&n, m.data(), sizeof n);
    if (n < 0 || static_cast<std::uint64_t>(n) > (m.size() - sizeof n) / sizeof(gid_t))
      throw RuntimeFailure("delegated detection: a message shorter than its points");
    const std::size_t head = sizeof n + static_cast<std::size_t>(n) * sizeof(gid_t);
    if ((m.size() - head) % sizeof(DelegatedRecord) != 0) throw RuntimeFailure("delegated detection: a torn record");
    const std::size_t at = own.size();
    own.resize(at + static_cast<std::size_t>(n));
    if (n > 0) std::memcpy(own.data() + at, m.data() + sizeof n, static_cast<std::size_t>(n) * sizeof(gid_t));
    const std::size_t nr = (m.size() - head) / sizeof(DelegatedRecord);
    for (std::size_t i = 0; i < nr; ++i) {
      DelegatedRecord r;
      std::memcpy(&r, m.data() + head + i * sizeof r, sizeof r);
      collisions_.push_back(from_wire(world_, r));
      ++delegated_received_;
    }
  }
  if (collisions_.size() != before) std::sort(collisions_.begin(), collisions_.end(), record_order);
  std::sort(own.begin(), own.end());
  collision_stats_.colliding_points +=
      static_cast<std::int64_t>(std::unique(own.begin(), own.end()) - own.begin());
  collision_stats_.collisions = static_cast<std::int64_t>(collisions_.size());
}

void SerialStepper::contact_response(NeighbourExchange* exchange) {
  contact_->respond(world_, collisions_, scene_.sim.dt, contact_stats_, exchange);
}

void SerialStepper::update_anchors() { contact_->update_anchors(world_, collisions_); }

// Item 7 of "Penetration vectors" (docs/collision.md): a record and its partner (the
// record of its triangle's heavy vertex against its own body) may be on two ranks; each
// rank sends the keys of its records whose heavy vertex is a ghost to its neighbours, so
// that both halves of a cross-rank pair are decided from the same two records (the heavy
// vertex is a vertex of the record's other body, a ghost when this rank does not own it).
void SerialStepper::settle_mutual_records(NeighbourExchange* exchange) {
  record_keys_.clear();
  CollisionDetector::record_keys(world_, collisions_, record_keys_);
  if (exchange) {
    const auto t0 = std::chrono::steady_clock::now();
    const double cpu0 = process_cpu_seconds();
    std::vector<char> buf;
    for (const RecordKey& k : record_keys_)  // the heavy vertex is B's: a ghost when B is
      if (!world_.owns_object(k.other_object)) append_records(buf, &k, 1);
    const std::vector<std::vector<char>> recv =
        exchange->exchange_bytes(std::vector<std::vector<char>>(exchange->neighbors().size(), buf));
    for (const std::vector<char>& r : recv) {
      const std::vector<RecordKey> in = read_records<RecordKey>(r);
      record_keys_.insert(record_keys_.end(), in.begin(), in.end());
    }
    exchange_seconds_ += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    exchange_cpu_seconds_ += process_cpu_seconds() - cpu0;
  }
  collision_stats_.mutual_settled = detector_->settle_mutual(world_, collisions_, record_keys_);
}

// Overlaps between two fixed sides (walls built flush against a floor) exert no force
// and move nothing: not counted.
void SerialStepper::initial_overlaps(std::int64_t& count, double& depth) {
  std::vector<Collision> found;
  CollisionStats st;
  detector_->detect(world_, nullptr, found, st);
  auto movable = [&](index_t v) { return world_.inv_mass[static_cast<std::size_t>(v)] != 0; };
  count = 0;
  depth = 0;
  for (const Collision& c : found) {
    if (!movable(c.point) && (c.point2 < 0 || !movable(c.point2)) && !movable(c.triangle[0]) &&
        !movable(c.triangle[1]) && !movable(c.triangle[2]))
      continue;
    ++count;
    depth = std::max(depth, std::hypot(c.depth[0], c.depth[1], c.depth[2]));
  }
}

}  // namespace softcontact
