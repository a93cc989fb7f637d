#pragma once
// Per-vertex sums over collisions in a fixed key order, on any number of ranks
// (docs/architecture.md, "Keyed sums"). The contact response keeps a compact row per
// vertex that takes part in this step's collisions (a "slot"); each collision adds to
// the slots of its vertices, and every sum must add a vertex's contributions in the order
// of their collisions' keys (point_gid, triangle_gid) so that the result does not depend
// on how collisions are spread over threads and ranks.
//
// One rank (no exchange): every slot is owned, the collisions come sorted by key, and a
// sum folds in place in one pass. Several ranks: a slot may be a ghost (a vertex another
// rank owns). reduce() sends the contributions to ghost slots, with their keys, to the
// owner, which merges them with its own in key order and folds; reply() sends the owners'
// values of the vertices a neighbour asked for back into its ghost slots. Only the
// transport (NeighbourExchange) knows about MPI.
#include <algorithm>
#include <cstdint>
#include <cstring>
#include <functional>
#include <utility>
#include <vector>

#include "softcontact/error.hpp"
#include "softcontact/exchange.hpp"
#include "softcontact/world.hpp"

namespace softcontact {

class KeyedSums {
public:
  /// The collision key that orders a vertex's contributions.
  struct Key {
    gid_t point, triangle;
    bool operator<(const Key& o) const { return point != o.point ? point < o.point : triangle < o.triangle; }
  };

  /// Most components a sum may have per slot.
  static constexpr int kMaxDim = 6;

  /// Starts a step over `exchange` (null: one rank). `owner[k]` is the rank that owns
  /// slot k's vertex (-1 or this rank: owned), `gid[k]` its global id. Neighbours ask
  /// for the sums of owned vertices: `slot_of(gid)` returns the slot of such a vertex
  /// (the caller adds one if it has none; new slots are numbered on from owner.size()).
  /// No message here: the global ids of the ghost slots travel to their owners with the
  /// first reduce() (or reply()) of the step, which is when the neighbours' slots are
  /// added (slots() grows then, and target()/value() may be called for them), so
  /// `slot_of` must stay callable until then. Every rank makes the same sequence of
  /// calls, also with no slots.
  void plan(NeighbourExchange* exchange, const std::vector<int>& owner, const std::vector<gid_t>& gid,
            std::function<std::int32_t(gid_t)> slot_of);

  /// One rank: `n` slots, all owned; no exchange. (plan() with a null exchange, without
  /// building its lists.)
  void plan_local(std::size_t n);

  /// Slots: the ones given to plan(), and from the step's first exchange on those added
  /// for neighbours.
  std::size_t slots() const { return nb_.size(); }
  /// Whether slot k's vertex belongs to this rank (its sums are complete after reduce()).
  bool owned(std::size_t k) const { return nb_[k] < 0; }
  /// No neighbour: every sum is local.
  bool local() const { return request_.empty(); }

  /// Sums a quantity of `dim` (<= kMaxDim) components per slot over the collisions
  /// 0..n-1, whose keys `key(q)` ascend. emit(q, f) calls f(slot, value) for every
  /// contribution of collision q; target(slot) is the sum to add to (zero before).
  /// Owned slots get their complete sums, ghost slots none (reply() fills what is
  /// needed). Collective over the neighbours.
  template <class KeyOf, class Emit, class Target>
  void reduce(std::size_t n, KeyOf&& key, int dim, Emit&& emit, Target&& target);

  /// Owners send value(slot) (dim components) of every vertex a neighbour asked for;
  /// the answers land in the neighbour's ghost slots through value(slot) as a
  /// destination. Collective over the neighbours.
  template <class Value>
  void reply(int dim, Value&& value);

private:
  // A contribution to an owned vertex's sum from another rank, with its collision's key.
  // On the wire: the three global ids, then `dim` doubles (write_record, receive).
  struct Record {
    gid_t vertex;
    Key key;
    double v[kMaxDim];
  };
  struct Contribution {
    std::int32_t slot;
    Key key;
    double v[kMaxDim];
  };
  static void write_record(std::vector<char>& buf, gid_t vertex, const Key& key, const double* v, int dim);
  std::int32_t served_slot(gid_t vertex) const;
  // The send buffers of an exchange, emptied; with the plan's requests first when they
  // have not travelled yet.
  std::vector<std::vector<char>>& start_messages();
  // The neighbours' requests (when start_messages() wrote ours), then their records of
  // `dim` components.
  void receive(const std::vector<std::vector<char>>& recv, int dim);
  // Reads a request list at the start of each message, adds the served slots; returns
  // where each message's rest begins.
  std::vector<std::size_t> receive_requests(const std::vector<std::vector<char>>& recv);

  NeighbourExchange* exchange_ = nullptr;
  std::vector<std::int32_t> nb_;                   // per slot: its owner's index among the neighbours, -1 owned
  std::vector<gid_t> gid_;                         // per slot given to plan(): the vertex's global id
  std::vector<char> remote_flag_;                  // per slot: owned, with contributions from other ranks now
  std::vector<std::vector<std::int32_t>> request_; // per neighbour: our ghost slots it owns
  std::vector<std::vector<std::int32_t>> served_;  // per neighbour: our owned slots it asked for
  std::vector<gid_t> served_gids_;                 // sorted gids of all served vertices
  std::vector<std::int32_t> served_slots_;         // their slots
  std::vector<Record> remote_;                     // received contributions (one sum at a time)
  std::vector<Contribution> merge_;                // every contribution to slots with remote ones
  std::function<std::int32_t(gid_t)> slot_of_;     // plan()'s, until the requests have travelled
  bool requests_pending_ = false;                  // our requests go with the next exchange
  std::vector<std::vector<char>> send_;            // per neighbour: the message being built (kept)
};

/// One problem over every rank's rows, solved on rank 0 in key order (the coupled
/// closure's direct solve): each rank's `rows` (in ascending key(row) order; keys unique
/// across ranks) are gathered to rank 0, merged by key into the one-rank list,
/// solve(all, stats) returns one value per row, and each rank gets the values of its own
/// rows back, in its order. `stats` (trivially copyable) is rank 0's, broadcast. With no
/// exchange: solve(rows, stats). Collective over all ranks.
template <class Row, class KeyOf, class Solve, class Stats>
std::vector<double> solve_in_key_order(NeighbourExchange* exchange, const std::vector<Row>& rows, KeyOf&& key,
                                       Solve&& solve, Stats& stats) {
  if (!exchange || exchange->ranks() == 1) return solve(rows, stats);
  std::vector<char> mine;
  append_records(mine, rows.data(), rows.size());
  const std::vector<std::vector<char>> parts = exchange->gather_to_root(mine);
  std::vector<std::vector<char>> answers;
  if (exchange->rank() == 0) {
    std::vector<Row> all;
    std::vector<std::size_t> first(parts.size() + 1, 0);  // rows of rank p: [first[p], first[p + 1])
    for (std::size_t p = 0; p < parts.size(); ++p) {
      const std::vector<Row> r = read_records<Row>(parts[p]);
      all.insert(all.end(), r.begin(), r.end());
      first[p + 1] = all.size();
    }
    std::vector<std::int32_t> order(all.size());
    for (std::size_t i = 0; i < all.size(); ++i) order[i] = static_cast<std::int32_t>(i);
    std::sort(order.begin(), order.end(), [&](std::int32_t a, std::int32_t b) {
      return key(all[static_cast<std::size_t>(a)]) < key(all[static_cast<std::size_t>(b)]);
    });
    std::vector<Row> sorted(all.size());
    for (std::size_t i = 0; i < all.size(); ++i) sorted[i] = all[static_cast<std::size_t>(order[i])];
    const std::vector<double> xo = solve(sorted, stats);
    std::vector<double> xs(all.size());  // per row of `all`, in the order received
    for (std::size_t i = 0; i < all.size(); ++i) xs[static_cast<std::size_t>(order[i])] = xo[i];
    answers.resize(parts.size());
    for (std::size_t p = 0; p < parts.size(); ++p) append_records(answers[p], xs.data() + first[p], first[p + 1] - first[p]);
  }
  std::vector<double> x = read_records<double>(exchange->scatter_from_root(answers, rows.size() * sizeof(double)));
  exchange->broadcast_from_root(&stats, sizeof stats);
  return x;
}

template <class KeyOf, class Emit, class Target>
void KeyedSums::reduce(std::size_t n, KeyOf&& key, int dim, Emit&& emit, Target&& target) {
  SC_ASSERT(dim >= 1 && dim <= kMaxDim);
  remote_.clear();
  const std::size_t nn = request_.size();
  if (nn == 0) {  // one rank (or no neighbour): every slot owned, every contribution here
    for (std::size_t q = 0; q < n; ++q)
      emit(q, [&](std::int32_t k, const double* v) {
        double* t = target(k);
        for (int d = 0; d < dim; ++d) t[d] += v[d];
      });
    return;
  }
  {  // contributions to ghost slots go to their owners, with their keys
    std::vector<std::vector<char>>& send = start_messages();
    for (std::size_t q = 0; q < n; ++q)
      emit(q, [&](std::int32_t k, const double* v) {
        const std::int32_t nb = nb_[static_cast<std::size_t>(k)];
        if (nb >= 0) write_record(send[static_cast<std::size_t>(nb)], gid_[static_cast<std::size_t>(k)], key(q), v, dim);
      });
    receive(exchange_->exchange_bytes(send), dim);
  }
  // Slots without contributions from other ranks: theirs are all here, in key order.
  for (std::size_t q = 0; q < n; ++q)
    emit(q, [&](std::int32_t k, const double* v) {
      const auto s = static_cast<std::size_t>(k);
      if (nb_[s] >= 0 || remote_flag_[s]) return;
      double* t = target(k);
      for (int d = 0; d < dim; ++d) t[d] += v[d];
    });
  if (remote_.empty()) return;
  // Vertices with contributions from other ranks: merge theirs and ours by key.
  merge_.clear();
  for (std::size_t q = 0; q < n; ++q)
    emit(q, [&](std::int32_t k, const double* v) {
      if (!remote_flag_[static_cast<std::size_t>(k)]) return;
      Contribution c{k, key(q), {}};
      for (int d = 0; d < dim; ++d) c.v[d] = v[d];
      merge_.push_back(c);
    });
  for (const Record& r : remote_) {
    Contribution c{served_slot(r.vertex), r.key, {}};
    for (int d = 0; d < dim; ++d) c.v[d] = r.v[d];
    merge_.push_back(c);
  }
  std::sort(merge_.begin(), merge_.end(), [](const Contribution& a, const Contribution& b) {
    return a.slot != b.slot ? a.slot < b.slot : a.key < b.key;
  });
  for (const Contribution& c : merge_) {
    double* t = target(c.slot);
    for (int d = 0; d < dim; ++d) t[d] += c.v[d];
  }
  for (const Contribution& c : merge_) remote_flag_[static_cast<std::size_t>(c.slot)] = 0;
}

template <class Value>
void KeyedSums::reply(int dim, Value&& value) {
  const std::size_t nn = request_.size();
  if (nn == 0) return;
  if (requests_pending_) {  // no reduce this step: the requests travel alone first
    receive_requests(exchange_->exchange_bytes(start_messages()));
  }
  std::vector<std::vector<char>>& send = start_messages();
  for (std::size_t m = 0; m < nn; ++m)
    for (std::int32_t k : served_[m]) {
      const double* v = value(k);
      append_records(send[m], v, static_cast<std::size_t>(dim));
    }
  const auto recv = exchange_->exchange_bytes(send);
  const std::size_t row = static_cast<std::size_t>(dim) * sizeof(double);
  for (std::size_t m = 0; m < nn; ++m) {
    SC_ASSERT(recv[m].size() == row * request_[m].size());
    for (std::size_t i = 0; i < request_[m].size(); ++i) std::memcpy(value(request_[m][i]), recv[m].data() + row * i, row);
  }
}

}  // namespace softcontact
