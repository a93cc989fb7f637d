// Objects over ranks as the run goes (rebalance.hpp).
#include "softcontact/rebalance.hpp"

#include <cmath>
#include <cstring>
#include <iostream>

#include "softcontact/error.hpp"
#include "softcontact/exchange.hpp"
#include "softcontact/ghosts.hpp"
#include "softcontact/mpi_util.hpp"

namespace softcontact {

namespace {
// Kinematic objects cost no forces, only their share of detection.
std::int64_t object_work(const Scene& scene, std::size_t k) {
  const ObjectShape& s = scene.shape(k);
  return scene.objects[k].kinematic ? static_cast<std::int64_t>(s.triangles / 10) : static_cast<std::int64_t>(s.tets);
}

// Keep objects where they are as far as the new parts allow: relabel each new part as the
// old rank it shares the most work with (greedy, heaviest overlaps first).
void keep_objects_in_place(const Scene& scene, const std::vector<int>& current,
                           int nranks, std::vector<int>& next) {
  const std::size_t no = scene.objects.size();
  const auto nr = static_cast<std::size_t>(nranks);
  std::vector<std::vector<std::int64_t>> overlap(nr, std::vector<std::int64_t>(nr, 0));
  for (std::size_t k = 0; k < no; ++k)
    overlap[static_cast<std::size_t>(next[k])][static_cast<std::size_t>(current[k])] += object_work(scene, k) + 1;
  std::vector<int> label(nr, -1), taken(nr, 0);
  for (std::size_t round = 0; round < nr; ++round) {
    std::int64_t best = -1;
    std::size_t bp = 0, br = 0;
    for (std::size_t p = 0; p < nr; ++p)
      for (std::size_t r = 0; r < nr; ++r)
        if (label[p] < 0 && !taken[r] && overlap[p][r] > best) {
          best = overlap[p][r];
          bp = p;
          br = r;
        }
    label[bp] = static_cast<int>(br);
    taken[br] = 1;
  }
  for (int& p : next) p = label[static_cast<std::size_t>(p)];
}

// Per vertex of a migrating object: what the next steps need (a StepState row).
struct VertexState {
  double x[3], x_prev[3], v[3];
  StictionAnchor anchor;
};

VertexState state_row(const StepState& s, std::size_t v) {
  VertexState r;
  for (std::size_t d = 0; d < 3; ++d) {
    r.x[d] = s.x[3 * v + d];
    r.x_prev[d] = s.x_prev[3 * v + d];
    r.v[d] = s.v[3 * v + d];
  }
  r.anchor = s.anchors[v];
  return r;
}
}  // namespace

std::vector<int> partition_at(const Scene& scene, std::vector<Box> boxes, int nranks) {
  const std::size_t no = scene.objects.size();
  if (nranks <= 1) return std::vector<int>(no, 0);
  PartitionInput in;
  for (std::size_t k = 0; k < no; ++k) {
    in.weight.push_back(object_work(scene, k));
    for (int d = 0; d < 3; ++d)
      if (!std::isfinite(boxes[k].lo[d]) || !std::isfinite(boxes[k].hi[d]) || !(boxes[k].lo[d] <= boxes[k].hi[d]))
        boxes[k].lo[d] = boxes[k].hi[d] = 0;  // a blown-up object
  }
  in.box = std::move(boxes);
  in.reach = median_object_size(in.box);
  return partition_objects(in, nranks);
}

bool rebalance_due(const RebalancePolicy& policy, std::int64_t step) {
  return policy.check_every > 0 && step > 0 && step % policy.check_every == 0;
}

std::vector<int> initial_partition(const Scene& scene, int nranks) {
  return partition_at(scene, scene_boxes(scene), nranks);
}

bool rebalance(MPI_Comm comm, const Scene& scene, const World& w,
               const std::vector<int>& current, const RebalancePolicy& policy, std::int64_t step, const RankWork& work,
               std::vector<int>& next) {
  const int nranks = comm_size(comm);
  if (nranks == 1 || !rebalance_due(policy, step)) return false;
  double local[3] = {work.seconds, static_cast<double>(work.cross), static_cast<double>(work.collisions)};
  double mx = 0, sum[3] = {0, 0, 0};
  MPI_Allreduce(local, &mx, 1, MPI_DOUBLE, MPI_MAX, comm);
  MPI_Allreduce(local, sum, 3, MPI_DOUBLE, MPI_SUM, comm);
  const double imbalance = sum[0] > 0 ? mx / (sum[0] / nranks) : 1;
  const double cross = sum[2] > 0 ? sum[1] / sum[2] : 0;
  // Both figures are reduced, so every rank takes the same decision.
  if (!(imbalance > policy.max_imbalance) && !(cross > policy.max_cross_fraction)) return false;
  next = partition_at(scene, object_boxes(comm, scene, w), nranks);
  keep_objects_in_place(scene, current, nranks, next);
  std::int64_t moved = 0;
  for (std::size_t k = 0; k < next.size(); ++k) moved += next[k] != current[k] ? 1 : 0;
  if (comm_rank(comm) == 0)
    std::cerr << "softcontact: step " << step << ": repartitioning (work imbalance " << imbalance
              << ", cross-rank collisions " << cross * 100 << "%): " << moved << " of " << next.size()
              << " objects move\n";
  return true;
}

World migrate_objects(MPI_Comm comm, const Scene& scene, const World& w,
                      const StepState& now, const std::vector<int>& current, const std::vector<int>& next,
                      StepState& then) {
  if (next.size() != current.size()) throw RuntimeFailure("migrate: the partition has the wrong size");
  const int rank = comm_rank(comm), nranks = comm_size(comm);
  const auto nr = static_cast<std::size_t>(nranks);
  // Send every owned object that changes rank, whole, in ascending object order.
  std::vector<std::vector<VertexState>> out(nr);
  for (int k : w.owned_objects) {
    const int to = next[static_cast<std::size_t>(k)];
    if (to == rank) continue;
    const auto off = static_cast<std::size_t>(w.vertex_offset[static_cast<std::size_t>(k)]);
    for (gid_t i = 0; i < w.layout[static_cast<std::size_t>(k)].vertex_count; ++i)
      out[static_cast<std::size_t>(to)].push_back(state_row(now, off + static_cast<std::size_t>(i)));
  }
  std::vector<int> scount(nr), rcount(nr), sdisp(nr), rdisp(nr);
  std::vector<char> sbuf;
  for (std::size_t r = 0; r < nr; ++r) {
    sdisp[r] = static_cast<int>(sbuf.size());
    append_records(sbuf, out[r].data(), out[r].size());
    scount[r] = static_cast<int>(sbuf.size()) - sdisp[r];
  }
  MPI_Alltoall(scount.data(), 1, MPI_INT, rcount.data(), 1, MPI_INT, comm);
  int total = 0;
  for (std::size_t r = 0; r < nr; ++r) {
    rdisp[r] = total;
    total += rcount[r];
  }
  std::vector<char> rbuf(static_cast<std::size_t>(total));
  MPI_Alltoallv(sbuf.data(), scount.data(), sdisp.data(), MPI_BYTE, rbuf.data(), rcount.data(), rdisp.data(), MPI_BYTE,
                comm);

  World next_world = build_world(scene, next, rank);  // initial positions
  then = StepState{};
  then.step = now.step;
  then.anchor_step = now.anchor_step;
  then.x.resize(3 * next_world.n_owned);
  then.x_prev.resize(3 * next_world.n_owned);
  then.v.resize(3 * next_world.n_owned);
  then.anchors.resize(next_world.n_owned);
  // Objects that stay: copy. Objects that arrive: from each sender's buffer, in
  // ascending object order (the order they were packed in).
  std::vector<std::size_t> read(nr, 0);
  for (int k : next_world.owned_objects) {
    const auto to = static_cast<std::size_t>(next_world.vertex_offset[static_cast<std::size_t>(k)]);
    const gid_t count = next_world.layout[static_cast<std::size_t>(k)].vertex_count;
    const int from = current[static_cast<std::size_t>(k)];
    for (gid_t i = 0; i < count; ++i) {
      const std::size_t v = to + static_cast<std::size_t>(i);
      VertexState s;
      if (from == rank) {
        s = state_row(now, static_cast<std::size_t>(w.vertex_offset[static_cast<std::size_t>(k)]) + static_cast<std::size_t>(i));
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
  return next_world;
}

}  // namespace softcontact
