#include "softcontact/partition.hpp"

#include <metis.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numeric>
#include <string>

#include "softcontact/error.hpp"

namespace softcontact {
namespace {

// Any fixed value: the same seed gives the same partition on every rank and every call.
constexpr idx_t kMetisSeed = 20240607;
// METIS's default load tolerance (ufactor 30), the work's also with two constraints.
constexpr double kWorkTolerance = 1.03;
// The work imbalance a memory-balanced partition may add to the larger of the work-only
// partition's and kWorkTolerance, and still be taken (metis_parts).
constexpr double kMemoryWorkSlack = 0.01;
// The most objects repair_balance moves, per part.
constexpr std::size_t kRepairMovesPerPart = 16;
// Total vertex weight handed to METIS stays below this, whatever idx_t's width: METIS
// sums weights in idx_t and scales them by real_t (float) factors, so leave headroom.
constexpr std::int64_t kMaxMetisWeight = std::int64_t{1} << 30;
// kMetisCuts (partition.hpp) k-way partitions, seeds kMetisSeed + c, the smallest cut
// kept: about 9% less cut than one, for 4x the time of a step that takes milliseconds for
// 10^4 objects, unless the ranks share the runs (CutSearch).

[[noreturn]] void fail(const std::string& what) { throw RuntimeFailure("partition_objects: " + what); }

void validate(const PartitionInput& in) {
  if (in.weight.size() != in.box.size())
    fail(std::to_string(in.weight.size()) + " weights for " + std::to_string(in.box.size()) + " boxes");
  if (!in.memory.empty() && in.memory.size() != in.box.size())
    fail(std::to_string(in.memory.size()) + " memory weights for " + std::to_string(in.box.size()) + " boxes");
  std::int64_t memory = 0;
  for (std::size_t k = 0; k < in.memory.size(); ++k) {
    if (in.memory[k] < 0) fail("object " + std::to_string(k) + " has negative memory " + std::to_string(in.memory[k]));
    if (in.memory[k] > std::numeric_limits<std::int64_t>::max() / 2 - memory) fail("the total memory overflows");
    memory += in.memory[k];
  }
  if (in.box.size() > static_cast<std::size_t>(std::numeric_limits<std::int32_t>::max()))
    fail("too many objects (" + std::to_string(in.box.size()) + ")");
  if (!std::isfinite(in.reach) || in.reach < 0) fail("reach must be finite and >= 0, got " + std::to_string(in.reach));
  std::int64_t total = 0;
  for (std::size_t k = 0; k < in.box.size(); ++k) {
    if (in.weight[k] < 0) fail("object " + std::to_string(k) + " has negative weight " + std::to_string(in.weight[k]));
    if (in.weight[k] > std::numeric_limits<std::int64_t>::max() / 2 - total) fail("the total weight overflows");
    total += in.weight[k];
    const Box& b = in.box[k];
    for (int a = 0; a < 3; ++a)
      if (!std::isfinite(b.lo[a]) || !std::isfinite(b.hi[a]) || b.lo[a] > b.hi[a])
        fail("object " + std::to_string(k) + " has a non-finite or inverted bounding box");
  }
}

// Per-axis distance between two closed intervals (0 when they touch or overlap).
double axis_gap(const Box& a, const Box& b, int axis) {
  return std::max({0.0, b.lo[axis] - a.hi[axis], a.lo[axis] - b.hi[axis]});
}

struct Graph {
  std::vector<idx_t> xadj, adjncy, adjwgt, vwgt;  // vwgt: ncon per node
  idx_t ncon = 1;
};

// CSR adjacency of the edge list (ascending (i, j), so every node's neighbours come out
// ascending: first the smaller ones from edges (u, v), then the larger from (v, w)), and
// the vertex weights METIS gets: each >= 1, scaled down if their total would overflow.
Graph metis_graph(const PartitionInput& in, const std::vector<ObjectEdge>& edges, bool with_memory) {
  const std::size_t n = in.weight.size();
  if (2 * edges.size() > static_cast<std::size_t>(std::numeric_limits<idx_t>::max()))
    fail("too many graph edges for METIS (" + std::to_string(edges.size()) + ")");
  Graph g;
  g.xadj.assign(n + 1, 0);
  for (const ObjectEdge& e : edges) {
    ++g.xadj[e.i + 1];
    ++g.xadj[e.j + 1];
  }
  for (std::size_t v = 0; v < n; ++v) g.xadj[v + 1] += g.xadj[v];
  // One spare entry: METIS never reads it, but the arrays are never empty (null data()).
  g.adjncy.assign(2 * edges.size() + 1, 0);
  g.adjwgt.assign(2 * edges.size() + 1, 0);
  std::vector<idx_t> fill(g.xadj.begin(), g.xadj.end() - 1);
  for (const ObjectEdge& e : edges) {
    g.adjncy[fill[e.i]] = e.j;
    g.adjwgt[fill[e.i]++] = e.weight;
    g.adjncy[fill[e.j]] = e.i;
    g.adjwgt[fill[e.j]++] = e.weight;
  }

  // Per constraint (the work, then the memory when given), interleaved per node as
  // METIS reads them; each scaled on its own (METIS normalises each by its total).
  const std::size_t ncon = with_memory && !in.memory.empty() ? 2 : 1;
  g.vwgt.resize(ncon * n);
  for (std::size_t c = 0; c < ncon; ++c) {
    const std::vector<std::int64_t>& weight = c == 0 ? in.weight : in.memory;
    std::int64_t total = 0;
    for (std::int64_t w : weight) total += std::max<std::int64_t>(w, 1);
    const double scale =
        total > kMaxMetisWeight ? static_cast<double>(kMaxMetisWeight) / static_cast<double>(total) : 1.0;
    for (std::size_t v = 0; v < n; ++v) {
      const std::int64_t w = std::max<std::int64_t>(weight[v], 1);
      g.vwgt[ncon * v + c] =
          scale == 1.0 ? static_cast<idx_t>(w)
                       : static_cast<idx_t>(std::max<std::int64_t>(1, static_cast<std::int64_t>(w * scale)));
    }
  }
  g.ncon = static_cast<idx_t>(ncon);
  return g;
}

const char* metis_status(int status) {
  switch (status) {
    case METIS_ERROR_INPUT: return "METIS_ERROR_INPUT (invalid input)";
    case METIS_ERROR_MEMORY: return "METIS_ERROR_MEMORY (out of memory)";
    default: return "METIS_ERROR";
  }
}

// One k-way run with seed kMetisSeed + candidate; `cut` is its edge cut.
std::vector<int> run_metis(Graph& g, int nparts, int candidate, std::int64_t& cut) {
  idx_t nvtxs = static_cast<idx_t>(g.xadj.size() - 1);
  idx_t ncon = g.ncon;
  // The work's tolerance is METIS's default (ufactor 30); the memory's looser.
  std::array<real_t, 2> ubvec{static_cast<real_t>(kWorkTolerance), static_cast<real_t>(kMemoryTolerance)};
  idx_t np = nparts;
  idx_t objval = 0;
  idx_t options[METIS_NOPTIONS];
  METIS_SetDefaultOptions(options);
  options[METIS_OPTION_SEED] = kMetisSeed + candidate;
  options[METIS_OPTION_NUMBERING] = 0;
  options[METIS_OPTION_NCUTS] = 1;
  std::vector<idx_t> part(static_cast<std::size_t>(nvtxs), 0);
  const int status = METIS_PartGraphKway(&nvtxs, &ncon, g.xadj.data(), g.adjncy.data(), g.vwgt.data(), nullptr,
                                         g.adjwgt.data(), &np, nullptr, ncon > 1 ? ubvec.data() : nullptr, options,
                                         &objval, part.data());
  if (status != METIS_OK)
    fail(std::string("METIS_PartGraphKway failed with ") + metis_status(status) + " on " + std::to_string(nvtxs) +
         " objects, " + std::to_string(g.xadj.back() / 2) + " edges, " + std::to_string(nparts) + " parts");
  std::vector<int> out(part.size());
  for (std::size_t v = 0; v < part.size(); ++v) {
    if (part[v] < 0 || part[v] >= np) fail("METIS returned part " + std::to_string(part[v]) + " out of range");
    out[v] = static_cast<int>(part[v]);
  }
  cut = objval;
  return out;
}

// The smallest cut of the kMetisCuts runs (lowest candidate on ties), those of this rank
// computed here, the winner over the ranks from search.best.
std::vector<int> best_metis(Graph& g, int nparts, const CutSearch& search) {
  const bool shared = search.parts > 1 && search.best;
  std::int64_t best_cut = std::numeric_limits<std::int64_t>::max();
  int best_c = std::numeric_limits<int>::max();
  std::vector<int> best;
  std::string failed;
  for (int c = 0; c < kMetisCuts; ++c) {
    if (shared && c % search.parts != search.part) continue;
    std::int64_t cut = 0;
    std::vector<int> p;
    try {
      p = run_metis(g, nparts, c, cut);
    } catch (const RuntimeFailure& e) {
      if (!shared) throw;
      failed = e.what();  // the other ranks wait in search.best: tell them, then throw
      best_cut = -1;
      best_c = c;
      best.clear();
      break;
    }
    if (cut < best_cut) {  // ascending c: a tie keeps the lower
      best_cut = cut;
      best_c = c;
      best = std::move(p);
    }
  }
  if (!shared) return best;
  // A cut of -1 is a failed run: the smallest, so every rank learns of it.
  std::vector<int> chosen = search.best(best_cut, best_c, std::move(best));
  if (!failed.empty()) throw RuntimeFailure(failed);
  if (chosen.empty()) fail("METIS failed on another rank's candidate (its rank reports why)");
  if (chosen.size() != g.xadj.size() - 1) fail("the shared cut search returned " + std::to_string(chosen.size()) + " parts");
  return chosen;
}

PartitionQuality quality(const PartitionInput& in, const std::vector<ObjectEdge>& edges, const std::vector<int>& part,
                         int nparts) {
  PartitionQuality q;
  // max part load / mean part load of `weight` (1 when its total is 0).
  auto imbalance = [&](const std::vector<std::int64_t>& weight) {
    std::vector<std::int64_t> load(static_cast<std::size_t>(nparts), 0);
    std::int64_t total = 0;
    for (std::size_t k = 0; k < part.size(); ++k) {
      load[static_cast<std::size_t>(part[k])] += weight[k];
      total += weight[k];
    }
    return total > 0 ? static_cast<double>(*std::max_element(load.begin(), load.end())) /
                           (static_cast<double>(total) / nparts)
                     : 1.0;
  };
  q.imbalance = imbalance(in.weight);
  if (!in.memory.empty()) q.memory_imbalance = imbalance(in.memory);
  for (const ObjectEdge& e : edges)
    if (part[e.i] != part[e.j]) {
      ++q.cut_edges;
      q.cut_weight += e.weight;
    }
  return q;
}

// METIS may leave a part empty (it balances weight, not count). Fill each empty part,
// lowest first, with the lightest nonzero object of the heaviest part that has two or
// more; when at least nparts objects have nonzero weight such a part always exists.
void fill_empty_parts(const PartitionInput& in, std::vector<int>& part, int nparts) {
  const std::size_t np = static_cast<std::size_t>(nparts);
  const auto nonzero = std::count_if(in.weight.begin(), in.weight.end(), [](std::int64_t w) { return w > 0; });
  if (nonzero < nparts) return;
  std::vector<std::int64_t> load(np, 0), count(np, 0);
  for (std::size_t k = 0; k < part.size(); ++k)
    if (in.weight[k] > 0) {
      load[part[k]] += in.weight[k];
      ++count[part[k]];
    }
  for (std::size_t empty = 0; empty < np; ++empty) {
    if (count[empty] > 0) continue;
    std::size_t from = np;
    for (std::size_t p = 0; p < np; ++p)
      if (count[p] >= 2 && (from == np || load[p] > load[from])) from = p;
    SC_ASSERT(from < np);
    std::size_t pick = part.size();
    for (std::size_t k = 0; k < part.size(); ++k)
      if (static_cast<std::size_t>(part[k]) == from && in.weight[k] > 0 &&
          (pick == part.size() || in.weight[k] < in.weight[pick]))
        pick = k;
    part[pick] = static_cast<int>(empty);
    load[from] -= in.weight[pick];
    --count[from];
    load[empty] += in.weight[pick];
    ++count[empty];
  }
}

// METIS returns its smallest cut even where no split of few objects keeps its
// tolerance, and that can leave one part far heavier than a split that exists
// (tests/data/scenes/small.yaml on 2 ranks: both cubes on one rank, 1.83 times the mean,
// where a cube and the floor against the other cube is 1.09). Where the work imbalance is
// above kRepairTrigger, objects move out of the heaviest part, one at a time, while
// a move lowers its load below what it was: each time the move that adds the least cut
// weight (the object's edges into its part minus those into the part it joins), then the
// one leaving the lower larger load, then the lowest object and part. A move that raises
// the memory imbalance above the larger of its current value and `memory_ratio` is not
// made: kMemoryImbalanceTrigger after METIS by work alone (memory only has to fit; below
// that METIS is not asked for it), kMemoryTolerance after METIS with the memory as a
// constraint (what it balanced stays balanced). It stops at kWorkTolerance, or after
// kRepairMovesPerPart moves per part. Every move lowers the loads sorted descending
// (lexicographically); a move never empties a part of its weighted objects.
void repair_balance(const PartitionInput& in, const std::vector<ObjectEdge>& edges, std::vector<int>& part,
                    int nparts, double memory_ratio) {
  const std::size_t n = part.size(), np = static_cast<std::size_t>(nparts);
  std::vector<std::int64_t> load(np, 0), memory(np, 0);
  std::int64_t total = 0, memory_total = 0;
  for (std::size_t k = 0; k < n; ++k) {
    load[part[k]] += in.weight[k];
    total += in.weight[k];
    if (!in.memory.empty()) {
      memory[part[k]] += in.memory[k];
      memory_total += in.memory[k];
    }
  }
  if (total == 0) return;
  const double mean = static_cast<double>(total) / nparts;
  const double memory_mean = static_cast<double>(memory_total) / nparts;
  auto heaviest = [](const std::vector<std::int64_t>& v) {
    return static_cast<std::size_t>(std::max_element(v.begin(), v.end()) - v.begin());
  };
  if (static_cast<double>(load[heaviest(load)]) <= kRepairTrigger * mean) return;
  // Per object, its neighbours with the edges' weights (both directions).
  std::vector<std::size_t> first(n + 1, 0);
  for (const ObjectEdge& e : edges) {
    ++first[static_cast<std::size_t>(e.i) + 1];
    ++first[static_cast<std::size_t>(e.j) + 1];
  }
  for (std::size_t k = 0; k < n; ++k) first[k + 1] += first[k];
  std::vector<std::pair<std::int32_t, std::int32_t>> adj(first[n]);
  std::vector<std::size_t> fill(first.begin(), first.end() - 1);
  for (const ObjectEdge& e : edges) {
    adj[fill[e.i]++] = {e.j, e.weight};
    adj[fill[e.j]++] = {e.i, e.weight};
  }
  std::vector<std::int64_t> into(np, 0);  // one object's edge weight into each part
  // At most kRepairMovesPerPart moves per part: a repair for few objects, each move a
  // pass over the objects (where many objects leave a part this far above the mean,
  // METIS's cut is not the granularity's).
  for (std::size_t moves = 0; moves < kRepairMovesPerPart * np; ++moves) {
    const std::size_t from = heaviest(load);
    if (static_cast<double>(load[from]) <= kWorkTolerance * mean) return;
    const double memory_limit =
        memory_total > 0 ? std::max(static_cast<double>(memory[heaviest(memory)]), memory_ratio * memory_mean) : 0;
    std::size_t best_k = n, best_to = np;
    std::int64_t best_cut = 0, best_max = 0;
    for (std::size_t k = 0; k < n; ++k) {
      if (static_cast<std::size_t>(part[k]) != from || in.weight[k] <= 0) continue;
      std::fill(into.begin(), into.end(), 0);
      for (std::size_t a = first[k]; a < first[k + 1]; ++a) into[part[adj[a].first]] += adj[a].second;
      for (std::size_t to = 0; to < np; ++to) {
        if (to == from) continue;
        const std::int64_t larger = std::max(load[from] - in.weight[k], load[to] + in.weight[k]);
        if (larger >= load[from]) continue;
        if (memory_total > 0 && static_cast<double>(memory[to] + in.memory[k]) > memory_limit) continue;
        const std::int64_t cut = into[from] - into[to];
        if (best_k == n || cut < best_cut || (cut == best_cut && larger < best_max)) {
          best_k = k;
          best_to = to;
          best_cut = cut;
          best_max = larger;
        }
      }
    }
    if (best_k == n) return;
    load[from] -= in.weight[best_k];
    load[best_to] += in.weight[best_k];
    if (memory_total > 0) {
      memory[from] -= in.memory[best_k];
      memory[best_to] += in.memory[best_k];
    }
    part[best_k] = static_cast<int>(best_to);
  }
}

// Objects `ids` (ascending) into parts [first, first + nparts) with METIS k-way on the
// graph they induce; the identity when there are no more of them than parts.
void metis_parts(const PartitionInput& in, const std::vector<std::int32_t>& ids, int first, int nparts,
                 std::vector<int>& part, const CutSearch& search) {
  if (nparts == 1 || ids.size() <= static_cast<std::size_t>(nparts)) {
    for (std::size_t k = 0; k < ids.size(); ++k) part[ids[k]] = first + (nparts == 1 ? 0 : static_cast<int>(k));
    return;
  }
  PartitionInput sub;
  sub.reach = in.reach;
  sub.weight.reserve(ids.size());
  sub.box.reserve(ids.size());
  for (std::int32_t k : ids) {
    sub.weight.push_back(in.weight[k]);
    if (!in.memory.empty()) sub.memory.push_back(in.memory[k]);
    sub.box.push_back(in.box[k]);
  }
  const std::vector<ObjectEdge> edges = object_graph_edges(sub);
  auto parts_of = [&](bool with_memory) {
    Graph g = metis_graph(sub, edges, with_memory);
    std::vector<int> p = best_metis(g, nparts, search);
    fill_empty_parts(sub, p, nparts);
    return p;
  };
  std::vector<int> p = parts_of(false);
  bool with_memory = false;
  if (!sub.memory.empty()) {
    // The memory as a second constraint only where the work alone leaves it far out of
    // balance (memory only has to fit; two constraints cost cut: 16 equal cubes of
    // unequal cost, balanced by count as well, are no longer cut in one place), and only
    // if that keeps the work's balance (the pace): METIS, asked to balance a memory it
    // cannot (a split object's owner holds all its vertices), gives up work balance for
    // it (archway on 4 ranks: 1.03 -> 1.39).
    const PartitionQuality by_work = quality(sub, edges, p, nparts);
    if (by_work.memory_imbalance > kMemoryImbalanceTrigger) {
      std::vector<int> both = parts_of(true);
      const PartitionQuality q = quality(sub, edges, both, nparts);
      if (q.imbalance <= std::max(by_work.imbalance, kWorkTolerance) + kMemoryWorkSlack &&
          q.memory_imbalance < by_work.memory_imbalance) {
        p = std::move(both);
        with_memory = true;
      }
    }
  }
  repair_balance(sub, edges, p, nparts, with_memory ? kMemoryTolerance : kMemoryImbalanceTrigger);
  for (std::size_t k = 0; k < ids.size(); ++k) part[ids[k]] = first + p[k];
}

}  // namespace

std::vector<ObjectEdge> object_graph_edges(const PartitionInput& in) {
  validate(in);
  const auto pairs = boxes_within(in.box, in.reach);
  // Ascending (i, j): bucketed by i (a counting sort), each bucket sorted by j.
  std::vector<std::size_t> first(in.box.size() + 1, 0);
  for (const auto& pq : pairs) ++first[static_cast<std::size_t>(pq.first) + 1];
  for (std::size_t k = 0; k < in.box.size(); ++k) first[k + 1] += first[k];
  std::vector<ObjectEdge> edges(pairs.size());
  std::vector<std::size_t> fill(first.begin(), first.end() - 1);
  for (const auto& [p, q] : pairs) {
    const Box& a = in.box[static_cast<std::size_t>(p)];
    const Box& b = in.box[static_cast<std::size_t>(q)];
    const double gap = std::max({axis_gap(a, b, 0), axis_gap(a, b, 1), axis_gap(a, b, 2)});
    const double closeness = in.reach > 0 ? 1.0 - std::min(gap, in.reach) / in.reach : 1.0;
    const auto w = static_cast<std::int32_t>(1 + std::lround(100.0 * closeness));
    edges[fill[static_cast<std::size_t>(p)]++] = {p, q, w};
  }
  for (std::size_t k = 0; k < in.box.size(); ++k)
    std::sort(edges.begin() + static_cast<std::ptrdiff_t>(first[k]), edges.begin() + static_cast<std::ptrdiff_t>(first[k + 1]),
              [](const ObjectEdge& x, const ObjectEdge& y) { return x.j < y.j; });
  return edges;
}

std::vector<int> partition_objects(const PartitionInput& in, int nparts, const CutSearch& search) {
  validate(in);
  if (nparts < 1) fail("nparts must be >= 1, got " + std::to_string(nparts));
  const std::size_t n = in.weight.size();
  std::vector<int> part(n, 0);
  if (nparts == 1 || n == 0) return part;
  if (n <= static_cast<std::size_t>(nparts)) {
    std::iota(part.begin(), part.end(), 0);
    return part;
  }

  // Peel off the giants: an object weighing at least the mean of what is left per part
  // gets a part of its own (heaviest first, lowest index on ties; parts 0, 1, ...).
  // Sharing its part could only raise the largest load, and METIS, left to place it,
  // bisects degenerate graphs (printing "***Cannot bisect a graph with 0 vertices!" on
  // stdout) and may cut a chain next to the giant instead of at it.
  std::vector<std::int32_t> by_weight(n);
  std::iota(by_weight.begin(), by_weight.end(), 0);
  std::stable_sort(by_weight.begin(), by_weight.end(),
                   [&](std::int32_t a, std::int32_t b) { return in.weight[a] > in.weight[b]; });
  std::int64_t left = 0;
  for (std::int64_t w : in.weight) left += w;
  std::vector<char> peeled(n, 0);
  int next = 0;
  for (std::int32_t k : by_weight) {
    const std::int64_t w = in.weight[k], parts_left = nparts - next;
    const std::int64_t share = left / parts_left + (left % parts_left != 0);  // ceil(left / parts_left)
    if (parts_left <= 1 || w == 0 || w < share) break;
    part[k] = next++;
    peeled[k] = 1;
    left -= w;
  }

  std::vector<std::int32_t> rest;
  for (std::size_t k = 0; k < n; ++k)
    if (!peeled[k]) rest.push_back(static_cast<std::int32_t>(k));
  metis_parts(in, rest, next, nparts - next, part, search);
  return part;
}

PartGroups group_objects(const PartitionInput& in, int nparts, int parts_per_group) {
  validate(in);
  if (nparts < 1) fail("nparts must be >= 1, got " + std::to_string(nparts));
  if (parts_per_group < 1) fail("parts_per_group must be >= 1, got " + std::to_string(parts_per_group));
  const std::size_t n = in.box.size();
  PartGroups g;
  g.group.assign(n, 0);
  if (nparts <= parts_per_group || n <= static_cast<std::size_t>(nparts)) {
    g.first = {0};
    g.parts = {nparts};
    return g;
  }
  auto centre = [&](std::int32_t k, int a) {
    const Box& b = in.box[static_cast<std::size_t>(k)];
    return 0.5 * (b.lo[a] + b.hi[a]);
  };
  auto weight = [&](std::int32_t k) { return std::max<std::int64_t>(in.weight[static_cast<std::size_t>(k)], 1); };
  auto memory = [&](std::int32_t k) { return in.memory.empty() ? std::int64_t{0} : in.memory[static_cast<std::size_t>(k)]; };
  std::vector<std::int32_t> ids(n);
  std::iota(ids.begin(), ids.end(), 0);
  // Objects [b, e) of ids into parts [first, first + parts): halves of the parts, the
  // objects cut at the weighted position of the halves along the longest extent of
  // their centres (sorted by (centre, index): the same cut on every rank).
  auto split = [&](auto&& self, std::size_t b, std::size_t e, int first, int parts) -> void {
    if (parts <= parts_per_group || e - b <= 1) {
      for (std::size_t i = b; i < e; ++i) g.group[static_cast<std::size_t>(ids[i])] = static_cast<int>(g.first.size());
      g.first.push_back(first);
      g.parts.push_back(parts);
      return;
    }
    int axis = 0;
    double widest = -1;
    for (int a = 0; a < 3; ++a) {
      double lo = std::numeric_limits<double>::infinity(), hi = -lo;
      for (std::size_t i = b; i < e; ++i) {
        lo = std::min(lo, centre(ids[i], a));
        hi = std::max(hi, centre(ids[i], a));
      }
      if (hi - lo > widest) {
        widest = hi - lo;
        axis = a;
      }
    }
    std::sort(ids.begin() + static_cast<std::ptrdiff_t>(b), ids.begin() + static_cast<std::ptrdiff_t>(e),
              [&](std::int32_t x, std::int32_t y) {
                const double cx = centre(x, axis), cy = centre(y, axis);
                return cx != cy ? cx < cy : x < y;
              });
    const int left = parts / 2;
    long double total = 0, total_memory = 0;
    for (std::size_t i = b; i < e; ++i) {
      total += static_cast<long double>(weight(ids[i]));
      total_memory += static_cast<long double>(memory(ids[i]));
    }
    const long double target = total * left / parts, target_memory = total_memory * left / parts;
    // How far a cut with these sums on its lower side is from the halves: the work's
    // distance; with memory given, the larger of the two distances relative to their totals.
    auto off = [&](long double sum, long double sum_memory) {
      if (in.memory.empty()) return std::fabs(sum - target);
      return std::max(std::fabs(sum - target) / total,
                      total_memory > 0 ? std::fabs(sum_memory - target_memory) / total_memory : 0.0L);
    };
    // The cut after the first objects whose sums come nearest the targets (at least one
    // object on each side).
    std::size_t cut = b + 1;
    long double sum = static_cast<long double>(weight(ids[b])), sum_memory = static_cast<long double>(memory(ids[b]));
    long double best = off(sum, sum_memory);
    for (std::size_t i = b + 1; i + 1 < e; ++i) {
      sum += static_cast<long double>(weight(ids[i]));
      sum_memory += static_cast<long double>(memory(ids[i]));
      const long double d = off(sum, sum_memory);
      if (d < best) {
        best = d;
        cut = i + 1;
      }
    }
    self(self, b, cut, first, left);
    self(self, cut, e, first + left, parts - left);
  };
  split(split, 0, n, 0, nparts);
  return g;
}

std::vector<std::vector<std::int32_t>> group_members(const PartGroups& groups) {
  std::vector<std::vector<std::int32_t>> out(groups.first.size());
  for (std::size_t k = 0; k < groups.group.size(); ++k)
    out[static_cast<std::size_t>(groups.group[k])].push_back(static_cast<std::int32_t>(k));
  return out;
}

PartitionInput group_input(const PartitionInput& in, const std::vector<std::int32_t>& members) {
  PartitionInput sub;
  sub.reach = in.reach;
  sub.weight.reserve(members.size());
  sub.box.reserve(members.size());
  for (std::int32_t k : members) {
    sub.weight.push_back(in.weight[static_cast<std::size_t>(k)]);
    if (!in.memory.empty()) sub.memory.push_back(in.memory[static_cast<std::size_t>(k)]);
    sub.box.push_back(in.box[static_cast<std::size_t>(k)]);
  }
  return sub;
}

std::vector<int> partition_objects_grouped(const PartitionInput& in, int nparts, int parts_per_group) {
  const PartGroups groups = group_objects(in, nparts, parts_per_group);
  if (groups.first.size() == 1) return partition_objects(in, nparts);
  std::vector<int> part(in.box.size(), 0);
  const std::vector<std::vector<std::int32_t>> lists = group_members(groups);
  for (std::size_t g = 0; g < groups.first.size(); ++g) {
    const std::vector<std::int32_t>& members = lists[g];
    const std::vector<int> local = partition_objects(group_input(in, members), groups.parts[g]);
    for (std::size_t i = 0; i < members.size(); ++i)
      part[static_cast<std::size_t>(members[i])] = groups.first[g] + local[i];
  }
  return part;
}

PartitionQuality partition_quality(const PartitionInput& in, const std::vector<int>& part, int nparts) {
  validate(in);
  if (nparts < 1) throw RuntimeFailure("partition_quality: nparts must be >= 1, got " + std::to_string(nparts));
  if (part.size() != in.weight.size())
    throw RuntimeFailure("partition_quality: " + std::to_string(part.size()) + " parts for " +
                         std::to_string(in.weight.size()) + " objects");
  for (std::size_t k = 0; k < part.size(); ++k)
    if (part[k] < 0 || part[k] >= nparts)
      throw RuntimeFailure("partition_quality: object " + std::to_string(k) + " on part " + std::to_string(part[k]) +
                           ", outside 0.." + std::to_string(nparts - 1));
  return quality(in, object_graph_edges(in), part, nparts);
}

namespace {
// split_tet_parts above metis_max_tets.
std::vector<std::int32_t> split_tet_parts_bisection(const TetMesh& mesh, int nparts) {
  const std::size_t nt = mesh.num_tets();
  std::vector<std::int32_t> out(nt, 0);
  // Recursive coordinate bisection of the tets' centroids: a range of tets for `parts`
  // parts is cut across its widest extent into two ranges of (rounded) proportional
  // counts, by a selection in the strict order (coordinate, tet index), so that the
  // parts are the same on every rank and every library; O(tets log parts) time and 32
  // bytes per tet (centroid and index).
  std::vector<std::array<double, 3>> centre(nt);
  for (std::size_t t = 0; t < nt; ++t)
    for (std::size_t d = 0; d < 3; ++d) {
      double sum = 0;
      for (std::size_t c = 0; c < 4; ++c) sum += mesh.points[3 * static_cast<std::size_t>(mesh.tets[4 * t + c]) + d];
      centre[t][d] = 0.25 * sum;
    }
  std::vector<std::size_t> tet(nt);
  std::iota(tet.begin(), tet.end(), std::size_t{0});
  struct Range {
    std::size_t begin, end;
    std::int32_t first, parts;
  };
  std::vector<Range> todo{{0, nt, 0, nparts}};
  while (!todo.empty()) {
    const Range r = todo.back();
    todo.pop_back();
    if (r.parts == 1 || r.end - r.begin <= 1) {
      for (std::size_t i = r.begin; i < r.end; ++i) out[tet[i]] = r.first;
      continue;
    }
    std::array<double, 3> lo{}, hi{};
    lo.fill(std::numeric_limits<double>::infinity());
    hi.fill(-std::numeric_limits<double>::infinity());
    for (std::size_t i = r.begin; i < r.end; ++i)
      for (std::size_t d = 0; d < 3; ++d) {
        lo[d] = std::min(lo[d], centre[tet[i]][d]);
        hi[d] = std::max(hi[d], centre[tet[i]][d]);
      }
    std::size_t axis = 0;
    for (std::size_t d = 1; d < 3; ++d)
      if (hi[d] - lo[d] > hi[axis] - lo[axis]) axis = d;
    const std::int32_t left = r.parts / 2;
    const std::size_t n = r.end - r.begin;
    const std::size_t mid = r.begin + (n * static_cast<std::size_t>(left) + static_cast<std::size_t>(r.parts) / 2) /
                                          static_cast<std::size_t>(r.parts);
    std::nth_element(tet.begin() + static_cast<std::ptrdiff_t>(r.begin), tet.begin() + static_cast<std::ptrdiff_t>(mid),
                     tet.begin() + static_cast<std::ptrdiff_t>(r.end), [&](std::size_t a, std::size_t b) {
                       const double ca = centre[a][axis], cb = centre[b][axis];
                       return ca != cb ? ca < cb : a < b;
                     });
    todo.push_back({mid, r.end, r.first + left, r.parts - left});
    todo.push_back({r.begin, mid, r.first, left});
  }
  return out;
}

// split_tet_parts up to metis_max_tets.
std::vector<std::int32_t> split_tet_parts_metis(const TetMesh& mesh, int nparts) {
  const std::size_t nt = mesh.num_tets();
  std::vector<std::int32_t> out(nt, 0);
  if (nt > static_cast<std::size_t>(std::numeric_limits<idx_t>::max() / 4))
    throw RuntimeFailure("split_tet_parts: " + std::to_string(nt) + " tets exceed METIS's index type");
  idx_t ne = static_cast<idx_t>(nt), nn = static_cast<idx_t>(mesh.num_vertices());
  std::vector<idx_t> eptr(nt + 1), eind(mesh.tets.begin(), mesh.tets.end());
  for (std::size_t t = 0; t <= nt; ++t) eptr[t] = static_cast<idx_t>(4 * t);
  idx_t ncommon = 3, np = nparts, objval = 0;
  idx_t options[METIS_NOPTIONS];
  METIS_SetDefaultOptions(options);
  options[METIS_OPTION_SEED] = kMetisSeed;
  options[METIS_OPTION_NUMBERING] = 0;
  std::vector<idx_t> epart(nt, 0), npart(mesh.num_vertices(), 0);
  const int status = METIS_PartMeshDual(&ne, &nn, eptr.data(), eind.data(), nullptr, nullptr, &ncommon, &np, nullptr,
                                        options, &objval, epart.data(), npart.data());
  if (status != METIS_OK)
    throw RuntimeFailure(std::string("split_tet_parts: METIS_PartMeshDual failed with ") + metis_status(status) + " on " +
                         std::to_string(nt) + " tets, " + std::to_string(nparts) + " parts");
  for (std::size_t t = 0; t < nt; ++t) {
    if (epart[t] < 0 || epart[t] >= np) throw RuntimeFailure("split_tet_parts: METIS returned part " + std::to_string(epart[t]));
    out[t] = static_cast<std::int32_t>(epart[t]);
  }
  return out;
}
}  // namespace

std::vector<std::int32_t> split_tet_parts(const TetMesh& mesh, int nparts, std::size_t metis_max_tets) {
  if (nparts <= 1 || mesh.num_tets() == 0) return std::vector<std::int32_t>(mesh.num_tets(), 0);
  return mesh.num_tets() <= metis_max_tets ? split_tet_parts_metis(mesh, nparts) : split_tet_parts_bisection(mesh, nparts);
}

}  // namespace softcontact
