// Objects over ranks as the run goes (rebalance.hpp).
#include "softcontact/rebalance.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <numeric>
#include <iostream>

#include "softcontact/error.hpp"
#include "softcontact/exchange.hpp"
#include "softcontact/ghosts.hpp"
#include "softcontact/memory.hpp"
#include "softcontact/mpi_util.hpp"
#include "softcontact/split_forces.hpp"

namespace softcontact {

// Kinematic objects cost no forces, only their share of detection.
std::int64_t static_work(const Scene& scene, std::size_t k) {
  const ObjectShape& s = scene.shape(k);
  return scene.objects[k].kinematic() ? static_cast<std::int64_t>(s.triangles / 10) : static_cast<std::int64_t>(s.tets);
}

std::int64_t merge_work(const Scene& scene, std::size_t k) {
  return static_cast<std::int64_t>(std::llround(kMergeWorkPerVertex * static_cast<double>(scene.shape(k).vertices)));
}

namespace {
// Per object: the parts a split object is cut into (split_part_count), 0 for the rest.
std::vector<int> parts_per_object(const Scene& scene, int nranks) {
  const std::vector<char> split = split_mask(scene, nranks);
  std::vector<int> parts(split.size(), 0);
  const auto total = static_cast<std::int64_t>(scene.num_tets());
  for (std::size_t k = 0; k < split.size(); ++k)
    if (split[k]) parts[k] = split_part_count(static_cast<std::int64_t>(scene.shape(k).tets), total, nranks);
  return parts;
}

// A split object's force work is shared by the ranks evaluating its parts
// (split_forces.hpp); its owner evaluates one of them. `parts`: parts_per_object. An
// object with a part on every rank loads every rank alike, which the partition need not
// balance: none of its work is the owner's node's. (Until 2026-11-29 the owner's node
// carried its part, which no other rank's did: soft_floor on 4 ranks left the owner with
// a fifth of the bodies the others had, 1.14 times the mean work.)
//
// The owner also merges the parts' corner forces into every vertex of the object
// (SplitForces::merge) and sends the parts their state: work no part carries, which the
// node carries as kMergeWorkPerVertex tets per vertex. (Without it soft_floor on 4
// ranks gave the floor's owner as many bodies as the others, and its forces took 4.1 ms
// per step against 2.0 to 2.3; docs/benchmarks.md, "the owner's merge".)
std::int64_t shared_work(const Scene& scene, std::size_t k, const std::vector<int>& parts, int nranks) {
  const std::int64_t w = static_work(scene, k);
  if (parts[k] <= 0) return w;
  return (parts[k] >= nranks ? 0 : w / parts[k]) + merge_work(scene, k);
}

// The other parts of the split objects cut into fewer parts than ranks, in split_hosts'
// order (parts 1 .. parts - 1; the owner's node carries part 0): each is a node of the
// partition of its own, of its share of the object's work, so that the ranks that will
// evaluate the parts keep room for them. (An object with a part per rank loads every
// rank alike: no nodes.)
struct PartNodes {
  std::vector<std::size_t> object;  // per node: the split object
  std::vector<std::int64_t> work;   // per node: the object's static work / its parts
};

// The memory model's owned state of object k's tets and vertices / `parts` [bytes].
std::int64_t state_bytes(const Scene& scene, std::size_t k, int parts) {
  const ObjectShape& s = scene.shape(k);
  return static_cast<std::int64_t>(
      std::llround(owned_state_bytes(static_cast<double>(s.tets), static_cast<double>(s.vertices)) / std::max(parts, 1)));
}

// The memory an object's owner holds for it (the partition's second constraint): its
// owned state; a split object's owner holds the whole object's vertex state and one part's
// share of its tets and vertices (its part's World). The memory of a part node (part_nodes):
// that share alone. The ghosts a rank holds are not counted.
std::int64_t owner_memory(const Scene& scene, std::size_t k, const std::vector<int>& parts) {
  if (parts[k] <= 0) return state_bytes(scene, k, 1);
  const ObjectShape& s = scene.shape(k);
  return static_cast<std::int64_t>(std::llround(owned_state_bytes(0, static_cast<double>(s.vertices)))) +
         state_bytes(scene, k, parts[k]);
}

PartNodes part_nodes(const Scene& scene, int nranks, const std::vector<int>& parts) {
  PartNodes n;
  for (std::size_t k = 0; k < parts.size(); ++k) {
    if (parts[k] <= 0 || parts[k] >= nranks) continue;
    for (int i = 1; i < parts[k]; ++i) {
      n.object.push_back(k);
      n.work.push_back(static_work(scene, k) / parts[k]);
    }
  }
  return n;
}
}  // namespace

SplitHosts split_hosts(const Scene& scene, const std::vector<int>& partition, int nranks) {
  const std::size_t no = scene.objects.size();
  if (partition.size() != no)
    throw RuntimeFailure("split_hosts: a partition of " + std::to_string(partition.size()) + " objects for " +
                         std::to_string(no));
  SplitHosts hosts;
  if (nranks <= 1) return hosts;
  const std::vector<int> parts = parts_per_object(scene, nranks);
  std::vector<std::int64_t> load(static_cast<std::size_t>(nranks), 0);
  for (std::size_t k = 0; k < no; ++k) {
    if (partition[k] < 0 || partition[k] >= nranks)
      throw RuntimeFailure("split_hosts: object " + std::to_string(k) + " on rank " + std::to_string(partition[k]));
    load[static_cast<std::size_t>(partition[k])] += shared_work(scene, k, parts, nranks);
  }
  for (std::size_t k = 0; k < no; ++k) {
    if (parts[k] <= 0) continue;
    std::vector<int> h(static_cast<std::size_t>(parts[k]));
    if (parts[k] >= nranks) {
      std::iota(h.begin(), h.end(), 0);
    } else {
      h[0] = partition[k];  // the owner's own part, in its load already
      for (std::size_t i = 1; i < h.size(); ++i) {
        h[i] = static_cast<int>(std::min_element(load.begin(), load.end()) - load.begin());  // the first: lowest rank
        load[static_cast<std::size_t>(h[i])] += static_work(scene, k) / parts[k];
      }
    }
    hosts.push_back(std::move(h));
  }
  return hosts;
}

PartitionLoads partition_loads(const Scene& scene, const std::vector<int>& partition, const SplitHosts& hosts,
                               int nranks) {
  const std::size_t no = scene.objects.size();
  if (partition.size() != no || nranks < 1)
    throw RuntimeFailure("partition_loads: a partition of " + std::to_string(partition.size()) + " objects for " +
                         std::to_string(no) + " on " + std::to_string(nranks) + " ranks");
  PartitionLoads l;
  l.work.assign(static_cast<std::size_t>(nranks), 0.0);
  l.memory.assign(static_cast<std::size_t>(nranks), 0.0);
  const std::vector<int> parts = nranks > 1 ? parts_per_object(scene, nranks) : std::vector<int>(no, 0);
  auto rank_of = [&](int r) {
    if (r < 0 || r >= nranks) throw RuntimeFailure("partition_loads: rank " + std::to_string(r) + " out of range");
    return static_cast<std::size_t>(r);
  };
  std::size_t split = 0;
  for (std::size_t k = 0; k < no; ++k) {
    const std::size_t owner = rank_of(partition[k]);
    l.memory[owner] += static_cast<double>(owner_memory(scene, k, parts));
    if (parts[k] <= 0) {
      l.work[owner] += static_cast<double>(static_work(scene, k));
      continue;
    }
    // Its parts, on the ranks that evaluate them (the owner's own among them: the first of
    // the hosts, or its place among every rank), whose memory the owner's counts already;
    // the owner's merge of their forces.
    if (split >= hosts.size()) throw RuntimeFailure("partition_loads: fewer split hosts than split objects");
    l.work[owner] += static_cast<double>(merge_work(scene, k));
    bool owner_seen = false;
    for (int r : hosts[split++]) {
      l.work[rank_of(r)] += static_cast<double>(static_work(scene, k) / parts[k]);
      if (rank_of(r) == owner && !owner_seen) owner_seen = true;
      else l.memory[rank_of(r)] += static_cast<double>(state_bytes(scene, k, parts[k]));
    }
  }
  auto imbalance = [&](const std::vector<double>& v) {
    double most = 0, sum = 0;
    for (double x : v) {
      most = std::max(most, x);
      sum += x;
    }
    return sum > 0 ? most / (sum / nranks) : 1.0;
  };
  l.work_imbalance = imbalance(l.work);
  l.memory_imbalance = imbalance(l.memory);
  return l;
}

bool split_hosts_fit(const Scene& scene, const std::vector<int>& partition, int nranks, const SplitHosts& hosts) {
  const SplitHosts shape = split_hosts(scene, partition, nranks);
  bool fits = hosts.size() == shape.size();
  for (std::size_t i = 0; fits && i < hosts.size(); ++i) {
    fits = hosts[i].size() == shape[i].size() && !hosts[i].empty() && hosts[i][0] == shape[i][0];
    for (int r : hosts[i]) fits = fits && r >= 0 && r < nranks;
  }
  return fits;
}

namespace {
// The ranks of the split objects' part nodes (part_nodes' order) under `part` and its
// hosts (none: split_hosts'); part 0 of each is the owner's, in its object's node.
// `who` names the caller in errors.
std::vector<std::size_t> part_node_ranks(const Scene& scene, const std::vector<int>& part, const SplitHosts& hosts_in,
                                         std::size_t nr, std::size_t part_nodes_count, const std::string& who) {
  std::vector<std::size_t> host;
  for (const std::vector<int>& h : hosts_in.empty() ? split_hosts(scene, part, static_cast<int>(nr)) : hosts_in) {
    if (h.empty()) throw RuntimeFailure(who + ": a split object without hosts");
    if (h.size() < nr)
      for (int r : std::vector<int>(h.begin() + 1, h.end())) {
        if (r < 0 || static_cast<std::size_t>(r) >= nr) throw RuntimeFailure(who + ": a split part on rank " + std::to_string(r));
        host.push_back(static_cast<std::size_t>(r));
      }
  }
  if (host.size() != part_nodes_count) throw RuntimeFailure(who + ": the split objects' parts do not match");
  return host;
}
}  // namespace

double predicted_max_load(const Scene& scene, const std::vector<int>& part, const SplitHosts& hosts,
                          const std::vector<std::int64_t>& weights, int nranks) {
  const std::size_t no = scene.objects.size(), nr = static_cast<std::size_t>(nranks);
  if (part.size() != no || weights.size() < no)
    throw RuntimeFailure("predicted_max_load: " + std::to_string(weights.size()) + " weights, a partition of " +
                         std::to_string(part.size()) + " for " + std::to_string(no) + " objects");
  const std::vector<std::size_t> host = part_node_ranks(scene, part, hosts, nr, weights.size() - no, "predicted_max_load");
  std::vector<double> load(nr, 0.0);
  for (std::size_t j = 0; j < weights.size(); ++j) {
    const std::size_t r = j < no ? static_cast<std::size_t>(part[j]) : host[j - no];
    if (r >= nr) throw RuntimeFailure("predicted_max_load: the partition names rank " + std::to_string(r));
    load[r] += static_cast<double>(weights[j]);
  }
  return *std::max_element(load.begin(), load.end());
}

std::vector<std::int64_t> measured_weights(const Scene& scene, const std::vector<int>& part,
                                           const std::vector<double>& rank_seconds,
                                           const std::vector<std::int64_t>& contacts, const SplitHosts& hosts_in) {
  const std::size_t no = scene.objects.size();
  if (part.size() != no) throw RuntimeFailure("measured_weights: the partition has the wrong size");
  if (!contacts.empty() && contacts.size() != no) throw RuntimeFailure("measured_weights: the contacts have the wrong size");
  std::vector<std::int64_t> w(no);
  const int nranks = std::max(1, static_cast<int>(rank_seconds.size()));
  const std::vector<int> parts = parts_per_object(scene, nranks);
  for (std::size_t k = 0; k < no; ++k) w[k] = shared_work(scene, k, parts, nranks) + 1;
  const PartNodes nodes = part_nodes(scene, nranks, parts);
  for (std::int64_t p : nodes.work) w.push_back(p + 1);
  bool measured = !rank_seconds.empty();
  for (double t : rank_seconds) measured = measured && std::isfinite(t) && t > 0;
  if (!measured) return w;
  const std::size_t nr = rank_seconds.size();
  auto contact = [&](std::size_t k) { return contacts.empty() ? 0.0 : static_cast<double>(std::max<std::int64_t>(contacts[k], 0)); };
  std::vector<double> S(nr, 0.0), C(nr, 0.0);
  for (std::size_t k = 0; k < no; ++k) {
    const auto r = static_cast<std::size_t>(part[k]);
    if (part[k] < 0 || r >= nr) throw RuntimeFailure("measured_weights: the partition names rank " + std::to_string(part[k]));
    S[r] += static_cast<double>(w[k]);
    C[r] += contact(k);
  }
  const std::vector<std::size_t> host = part_node_ranks(scene, part, hosts_in, nr, nodes.work.size(), "measured_weights");
  for (std::size_t j = 0; j < host.size(); ++j) S[host[j]] += static_cast<double>(w[no + j]);
  // The objects with a part on every rank (no node: shared_work) still cost each rank
  // its part: static work E on every rank, in S for the fit and withheld from the
  // nodes' weights below. Spread over a rank's objects instead, it made the objects of
  // the ranks with the fewest look the dearest (soft_floor on 4 ranks: the floor half of
  // the tets, each repartition predicted 0.74 to 0.81 of the slowest rank and left 1.26
  // to 1.39).
  double E = 0;
  for (std::size_t k = 0; k < no; ++k)
    if (parts[k] >= nranks) E += static_cast<double>(static_work(scene, k) / parts[k]);
  for (double& x : S) x += E;
  // Least squares for T = a S + b C over the ranks (normal equations, 2 x 2).
  double ss = 0, sc = 0, cc = 0, st = 0, ct = 0;
  for (std::size_t r = 0; r < nr; ++r) {
    ss += S[r] * S[r];
    sc += S[r] * C[r];
    cc += C[r] * C[r];
    st += S[r] * rank_seconds[r];
    ct += C[r] * rank_seconds[r];
  }
  const double det = ss * cc - sc * sc;
  double a = det > 0 ? (st * cc - ct * sc) / det : 0, b = det > 0 ? (ss * ct - sc * st) / det : 0;
  if (!(det > 1e-12 * ss * cc) || !(a > 0) || !(b >= 0) || !std::isfinite(a) || !std::isfinite(b)) {
    a = ss > 0 ? st / ss : 1;
    b = 0;
  }
  // Nodes: the objects, then the parts (no contacts of their own: the owner's detection
  // finds the object's).
  const std::size_t nn = w.size();
  auto rank_of = [&](std::size_t j) { return j < no ? static_cast<std::size_t>(part[j]) : host[j - no]; };
  std::vector<double> model(nn), rank_model(nr, a * E);
  for (std::size_t j = 0; j < nn; ++j) {
    model[j] = a * static_cast<double>(w[j]) + (j < no ? b * contact(j) : 0.0);
    rank_model[rank_of(j)] += model[j];
  }
  for (std::size_t j = 0; j < nn; ++j) {
    const std::size_t r = rank_of(j);
    const double us = rank_model[r] > 0 ? 1e6 * rank_seconds[r] * model[j] / rank_model[r] : 1;
    w[j] = std::max<std::int64_t>(1, std::llround(std::min(us, 1e15)));
  }
  return w;
}

RebalancePolicy rebalance_policy(const Simulation& sim) {
  RebalancePolicy p;
  p.check_every = sim.rebalance_every;
  p.max_imbalance = sim.rebalance_max_imbalance;
  p.max_cross_fraction = sim.rebalance_max_cross_fraction;
  p.measured_weights = sim.rebalance_weights == RebalanceWeights::measured;
  return p;
}

namespace {
std::int64_t object_work(const Scene& scene, std::size_t k) { return static_work(scene, k); }

// Keep objects where they are as far as the new parts allow: relabel each new part as the
// old rank it shares the most work with (greedy, heaviest overlaps first).
void keep_objects_in_place(const Scene& scene, const std::vector<int>& current,
                           int nranks, std::vector<int>& next, SplitHosts* hosts) {
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
  if (hosts)
    for (std::vector<int>& h : *hosts)
      if (h.size() < nr)  // (a part per rank stays in rank order)
        for (int& p : h) p = label[static_cast<std::size_t>(p)];
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

CutSearch shared_cut_search(MPI_Comm comm) {
  CutSearch search;
  if (comm == MPI_COMM_NULL || comm_size(comm) == 1) return search;
  search.part = comm_rank(comm);
  search.parts = comm_size(comm);
  search.best = [comm, size = search.parts, rank = search.part](std::int64_t cut, int candidate, std::vector<int> parts) {
    std::int64_t best_cut = cut;
    MPI_Allreduce(MPI_IN_PLACE, &best_cut, 1, MPI_INT64_T, MPI_MIN, comm);
    int best = cut == best_cut ? candidate : std::numeric_limits<int>::max();
    MPI_Allreduce(MPI_IN_PLACE, &best, 1, MPI_INT, MPI_MIN, comm);
    if (best_cut < 0) return std::vector<int>();  // a run failed (its rank throws)
    const int root = best % size;  // candidate c is computed by the rank c % size
    long long n = rank == root ? static_cast<long long>(parts.size()) : 0;
    MPI_Bcast(&n, 1, MPI_LONG_LONG, root, comm);
    parts.resize(static_cast<std::size_t>(n));
    MPI_Bcast(parts.data(), static_cast<int>(n), MPI_INT, root, comm);
    return parts;
  };
  return search;
}

std::vector<int> partition_objects_over(const PartitionInput& in, int nparts, MPI_Comm comm, int parts_per_group) {
  if (comm == MPI_COMM_NULL || comm_size(comm) == 1) return partition_objects_grouped(in, nparts, parts_per_group);
  const PartGroups groups = group_objects(in, nparts, parts_per_group);
  const int ng = static_cast<int>(groups.first.size());
  if (ng == 1) return partition_objects(in, nparts, shared_cut_search(comm));
  const int rank = comm_rank(comm), size = comm_size(comm);
  if (size != nparts)
    throw RuntimeFailure("partition_objects_over: " + std::to_string(nparts) + " parts on " + std::to_string(size) +
                         " ranks (one part per rank)");
  // This rank's group is the one holding its part; the group's ranks share its search.
  int mine = 0;
  while (mine + 1 < ng && groups.first[static_cast<std::size_t>(mine) + 1] <= rank) ++mine;
  const std::vector<std::vector<std::int32_t>> member_lists = group_members(groups);
  const std::vector<std::int32_t>& members = member_lists[static_cast<std::size_t>(mine)];
  MPI_Comm group_comm = MPI_COMM_NULL;
  MPI_Comm_split(comm, mine, rank, &group_comm);
  std::vector<int> local;
  std::string failed;
  try {
    local = partition_objects(group_input(in, members), groups.parts[static_cast<std::size_t>(mine)],
                              shared_cut_search(group_comm));
  } catch (const RuntimeFailure& e) {
    failed = e.what();  // every rank of the group throws it (CutSearch); tell the others
  }
  MPI_Comm_free(&group_comm);
  int bad = failed.empty() ? 0 : 1;
  MPI_Allreduce(MPI_IN_PLACE, &bad, 1, MPI_INT, MPI_MAX, comm);
  if (bad) throw RuntimeFailure(failed.empty() ? "partition_objects_over: METIS failed in another group (its ranks report why)" : failed);
  // Each group's first rank sends its parts; every rank puts them back by object.
  std::vector<int> counts(static_cast<std::size_t>(size), 0), displs(static_cast<std::size_t>(size), 0);
  int total = 0;
  for (int g = 0; g < ng; ++g) {
    const int leader = groups.first[static_cast<std::size_t>(g)];
    counts[static_cast<std::size_t>(leader)] = static_cast<int>(member_lists[static_cast<std::size_t>(g)].size());
  }
  for (int r = 0; r < size; ++r) {
    displs[static_cast<std::size_t>(r)] = total;
    total += counts[static_cast<std::size_t>(r)];
  }
  const bool leader = groups.first[static_cast<std::size_t>(mine)] == rank;
  std::vector<int> all(static_cast<std::size_t>(total) + 1, 0);
  MPI_Allgatherv(local.data(), leader ? static_cast<int>(local.size()) : 0, MPI_INT, all.data(), counts.data(),
                 displs.data(), MPI_INT, comm);
  std::vector<int> part(in.box.size(), 0);
  for (int g = 0; g < ng; ++g) {
    const auto& m = member_lists[static_cast<std::size_t>(g)];
    const int at = displs[static_cast<std::size_t>(groups.first[static_cast<std::size_t>(g)])];
    for (std::size_t i = 0; i < m.size(); ++i)
      part[static_cast<std::size_t>(m[i])] = groups.first[static_cast<std::size_t>(g)] + all[static_cast<std::size_t>(at) + i];
  }
  return part;
}

std::vector<int> partition_at(const Scene& scene, std::vector<Box> boxes, int nranks,
                              std::vector<std::int64_t> weights, MPI_Comm comm, SplitHosts* hosts, double min_reach) {
  const std::size_t no = scene.objects.size();
  if (hosts) hosts->clear();
  if (nranks <= 1) return std::vector<int>(no, 0);
  const std::vector<int> parts = parts_per_object(scene, nranks);
  const PartNodes nodes = part_nodes(scene, nranks, parts);
  const std::size_t nn = no + nodes.object.size();
  if (!weights.empty() && weights.size() != nn)
    throw RuntimeFailure("partition_at: " + std::to_string(weights.size()) + " weights for " + std::to_string(no) +
                         " objects and " + std::to_string(nodes.object.size()) + " parts of split objects");
  PartitionInput in;
  const bool tet_weights = weights.empty();
  in.weight = std::move(weights);
  in.memory.reserve(nn);
  for (std::size_t k = 0; k < no; ++k) {
    if (tet_weights) in.weight.push_back(shared_work(scene, k, parts, nranks));
    in.memory.push_back(owner_memory(scene, k, parts));
    for (int d = 0; d < 3; ++d)
      if (!std::isfinite(boxes[k].lo[d]) || !std::isfinite(boxes[k].hi[d]) || !(boxes[k].lo[d] <= boxes[k].hi[d]))
        boxes[k].lo[d] = boxes[k].hi[d] = 0;  // a blown-up object
  }
  in.reach = std::max(median_object_size(boxes), std::isfinite(min_reach) ? min_reach : 0.0);
  // The parts of split objects as nodes at their object's box: near what touches it, so
  // that their ranks tend to hold it as a ghost (and read its positions there).
  boxes.reserve(nn);
  for (std::size_t j = 0; j < nodes.object.size(); ++j) {
    if (tet_weights) in.weight.push_back(nodes.work[j]);
    in.memory.push_back(state_bytes(scene, nodes.object[j], parts[nodes.object[j]]));
    const Box b = boxes[nodes.object[j]];
    boxes.push_back(b);
  }
  in.box = std::move(boxes);
  std::vector<int> part = partition_objects_over(in, nranks, comm);
  if (hosts) {
    // Per candidate: every rank in order, or its owner (part 0) and its part nodes' ranks.
    std::size_t j = 0;
    for (std::size_t k = 0; k < no; ++k) {
      if (parts[k] <= 0) continue;
      std::vector<int> h;
      if (parts[k] >= nranks) {
        h.resize(static_cast<std::size_t>(nranks));
        std::iota(h.begin(), h.end(), 0);
      } else {
        h.push_back(part[k]);
        while (j < nodes.object.size() && nodes.object[j] == k) h.push_back(part[no + j++]);
      }
      hosts->push_back(std::move(h));
    }
  }
  part.resize(no);
  return part;
}

bool rebalance_due(const RebalancePolicy& policy, std::int64_t step) {
  return policy.check_every > 0 && step > 0 && step % policy.check_every == 0;
}

std::vector<int> initial_partition(const Scene& scene, int nranks, MPI_Comm comm, SplitHosts* hosts, double min_reach) {
  return partition_at(scene, scene_boxes(scene), nranks, {}, comm, hosts, min_reach);
}

namespace {
// The cross-rank fraction's trigger: above the policy's and above what the current
// partition achieved plus kCrossRetryMargin.
bool cross_wanted(const RebalancePolicy& policy, double cross, const RebalanceHistory& h) {
  return cross > policy.max_cross_fraction && cross > h.achieved_cross + kCrossRetryMargin;
}
}  // namespace

bool rebalance_wanted(const RebalancePolicy& policy, double imbalance, double cross, RebalanceHistory& h) {
  if (h.measure_cross) {
    h.achieved_cross = cross;
    h.measure_cross = false;
  }
  const bool stuck = policy.max_imbalance >= 1 && h.unmoved_imbalance > 0 &&
                     imbalance <= h.unmoved_imbalance + kImbalanceRetryMargin;
  const bool by_work = imbalance > policy.max_imbalance && !stuck;
  return by_work || cross_wanted(policy, cross, h);
}

bool rebalance(MPI_Comm comm, const Scene& scene, const World& w,
               const std::vector<int>& current, const RebalancePolicy& policy, std::int64_t step, const RankWork& work,
               std::vector<int>& next, RebalanceHistory& history, SplitHosts* hosts) {
  const int nranks = comm_size(comm);
  if (nranks == 1 || !rebalance_due(policy, step)) return false;
  double local[3] = {work.seconds, static_cast<double>(work.cross), static_cast<double>(work.collisions)};
  double mx = 0, sum[3] = {0, 0, 0};
  MPI_Allreduce(local, &mx, 1, MPI_DOUBLE, MPI_MAX, comm);
  MPI_Allreduce(local, sum, 3, MPI_DOUBLE, MPI_SUM, comm);
  const double imbalance = sum[0] > 0 ? mx / (sum[0] / nranks) : 1;
  const double cross = sum[2] > 0 ? sum[1] / sum[2] : 0;
  // Both figures are reduced, so every rank takes the same decision.
  if (!rebalance_wanted(policy, imbalance, cross, history)) return false;
  history.measure_cross = true;
  // Every rank's seconds (a gather copies them: the same bits everywhere), so every rank
  // computes the same weights and METIS the same parts.
  std::vector<std::int64_t> weights;
  if (policy.measured_weights) {
    std::vector<double> seconds(static_cast<std::size_t>(nranks));
    MPI_Allgather(&work.seconds, 1, MPI_DOUBLE, seconds.data(), 1, MPI_DOUBLE, comm);
    // Each object's contacts come from the ranks that found them (integers: exact sums).
    std::vector<std::int64_t> contacts(scene.objects.size(), 0);
    if (work.contacts.size() == contacts.size()) contacts = work.contacts;
    MPI_Allreduce(MPI_IN_PLACE, contacts.data(), static_cast<int>(contacts.size()), MPI_INT64_T, MPI_SUM, comm);
    weights = measured_weights(scene, current, seconds, contacts, hosts ? *hosts : SplitHosts());
  }
  const SplitHosts hosts_now = hosts ? *hosts : SplitHosts();
  next = partition_at(scene, object_boxes(comm, scene, w), nranks, weights, comm, hosts, policy.min_reach);
  keep_objects_in_place(scene, current, nranks, next, hosts);
  // A repartition for the work alone is taken only where the measured weights predict
  // its slowest rank at least kRepartitionGain below the current partition's: few objects
  // on many ranks (archway on 8) cannot come under max_imbalance, and each repartition
  // moved objects to another imbalance as large (docs/benchmarks.md).
  const bool by_cross = cross_wanted(policy, cross, history);  // (achieved_cross as rebalance_wanted left it)
  double predicted[2] = {0, 0};
  if (policy.measured_weights && policy.max_imbalance >= 1 && !by_cross) {
    predicted[0] = predicted_max_load(scene, current, hosts_now, weights, nranks);
    predicted[1] = predicted_max_load(scene, next, hosts ? *hosts : SplitHosts(), weights, nranks);
    if (!(predicted[1] < (1 - kRepartitionGain) * predicted[0])) {
      next = current;
      if (hosts) *hosts = hosts_now;
    }
  }
  std::int64_t moved = 0;
  for (std::size_t k = 0; k < next.size(); ++k) moved += next[k] != current[k] ? 1 : 0;
  history.unmoved_imbalance = moved == 0 ? imbalance : 0;
  if (comm_rank(comm) == 0)
    std::cerr << "softcontact: step " << step << ": repartitioning by " << (policy.measured_weights ? "measured cost" : "tets")
              << " (work imbalance " << imbalance
              << ", cross-rank collisions " << cross * 100 << "%): " << moved << " of " << next.size()
              << " objects move";
  if (comm_rank(comm) == 0 && predicted[0] > 0)
    std::cerr << " (slowest rank predicted " << predicted[1] / predicted[0] << " of the current"
              << (moved == 0 ? ", not enough to move" : "") << ")";
  if (comm_rank(comm) == 0) std::cerr << '\n';
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
  std::vector<std::vector<char>> bytes(nr);
  for (std::size_t r = 0; r < nr; ++r) append_records(bytes[r], out[r].data(), out[r].size());
  std::vector<std::vector<VertexState>>().swap(out);
  const std::vector<std::vector<char>> in = alltoallv_bytes(comm, bytes);
  std::vector<std::vector<char>>().swap(bytes);

  // The single-copy meshes of arriving objects not held here come from their old owners
  // (no file is read again).
  std::vector<int> arriving, from;
  for (std::size_t k = 0; k < next.size(); ++k)
    if (next[k] == rank && current[k] != rank) {
      arriving.push_back(static_cast<int>(k));
      from.push_back(current[k]);
    }
  (void)fetch_meshes_if_needed(comm, scene, arriving, from);

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
        std::memcpy(&s, in[static_cast<std::size_t>(from)].data() + at, sizeof(VertexState));
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
