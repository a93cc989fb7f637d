// KeyedSums (include/softcontact/keyed_sums.hpp): per-vertex sums over collisions that
// add every vertex's contributions in the order of the collisions' keys, whichever rank
// holds which collision. Reference: the one-rank fold of all contributions in key order.
// The ranks are threads here, exchanging through an in-memory NeighbourExchange, so the
// merge is tested without MPI; the suite's MPI scene tests cover the Halo transport.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <barrier>
#include <cmath>
#include <cstring>
#include <map>
#include <random>
#include <stdexcept>
#include <thread>
#include <vector>

#include "softcontact/keyed_sums.hpp"

using namespace softcontact;
using Gid = softcontact::gid_t;

namespace {

// Sparse messages between `ranks` threads: a mailbox per (from, to), and a barrier on
// either side of the reads.
class ThreadExchange final : public NeighbourExchange {
public:
  struct Shared {
    explicit Shared(int ranks) : ranks(ranks), box(static_cast<std::size_t>(ranks * ranks)), sync(ranks) {}
    int ranks;
    std::vector<std::vector<char>> box;
    std::barrier<> sync;
  };
  ThreadExchange(Shared& s, int rank) : s_(s), rank_(rank) {
    for (int r = 0; r < s.ranks; ++r)
      if (r != rank) nbr_.push_back(r);
  }
  const std::vector<int>& neighbors() const override { return nbr_; }
  std::vector<std::vector<char>> exchange_bytes(const std::vector<std::vector<char>>& send) override {
    ++exchanges_;
    for (std::size_t k = 0; k < nbr_.size(); ++k) s_.box[idx(rank_, nbr_[k])] = send[k];
    s_.sync.arrive_and_wait();
    std::vector<std::vector<char>> recv;
    for (int r : nbr_) recv.push_back(s_.box[idx(r, rank_)]);
    s_.sync.arrive_and_wait();
    return recv;
  }
  int rank() const override { return rank_; }
  int exchanges() const { return exchanges_; }
  int ranks() const override { return s_.ranks; }
  std::vector<std::vector<char>> gather_to_root(const std::vector<char>& mine) override {
    s_.box[idx(rank_, 0)] = mine;
    s_.sync.arrive_and_wait();
    std::vector<std::vector<char>> all;
    if (rank_ == 0)
      for (int r = 0; r < s_.ranks; ++r) all.push_back(s_.box[idx(r, 0)]);
    s_.sync.arrive_and_wait();
    return all;
  }
  std::vector<char> scatter_from_root(const std::vector<std::vector<char>>& parts, std::size_t my_bytes) override {
    if (rank_ == 0)
      for (int r = 0; r < s_.ranks; ++r) s_.box[idx(0, r)] = parts[static_cast<std::size_t>(r)];
    s_.sync.arrive_and_wait();
    std::vector<char> mine = s_.box[idx(0, rank_)];
    s_.sync.arrive_and_wait();
    if (mine.size() != my_bytes) throw std::logic_error("scatter: wrong size");
    return mine;
  }
  void broadcast_from_root(void* data, std::size_t bytes) override {
    if (rank_ == 0) s_.box[0].assign(static_cast<char*>(data), static_cast<char*>(data) + bytes);
    s_.sync.arrive_and_wait();
    if (rank_ != 0) std::memcpy(data, s_.box[0].data(), bytes);
    s_.sync.arrive_and_wait();
  }

private:
  std::size_t idx(int from, int to) const { return static_cast<std::size_t>(from * s_.ranks + to); }
  Shared& s_;
  int rank_;
  std::vector<int> nbr_;
  int exchanges_ = 0;
};

// A collision: its key and its contributions (vertex gid, value).
struct TestCollision {
  KeyedSums::Key key;
  std::vector<std::pair<Gid, std::array<double, 3>>> adds;
};

constexpr int kVertices = 12;

// Contributions of wildly different magnitudes and signs, so that adding them in another
// order changes the rounded sums.
std::vector<TestCollision> make_collisions(unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_int_distribution<int> vert(0, kVertices - 1);
  std::uniform_real_distribution<double> mant(-1, 1), expo(-8, 16);
  std::vector<TestCollision> col;
  for (Gid p = 0; p < 40; ++p)
    for (Gid t = 0; t < 3; ++t) {
      TestCollision c{{p, 100 + t}, {}};
      // Four distinct vertices, as a collision's point and triangle are.
      std::vector<Gid> vs;
      while (vs.size() < 4) {
        const Gid g = vert(rng);
        if (std::find(vs.begin(), vs.end(), g) == vs.end()) vs.push_back(g);
      }
      for (Gid g : vs) {
        std::array<double, 3> v;
        for (double& x : v) x = mant(rng) * std::pow(10.0, expo(rng));
        c.adds.emplace_back(g, v);
      }
      col.push_back(c);
    }
  std::sort(col.begin(), col.end(), [](const TestCollision& a, const TestCollision& b) { return a.key < b.key; });
  return col;
}

// One rank's part: the collisions `mine` (sorted), vertices owned by gid % ranks, sums of
// `dim` components (component d of a contribution: its value d % 3 times 1 + d / 3).
// Returns, per vertex gid this rank has a slot for, (sum, owned?).
using Sums = std::map<Gid, std::pair<std::array<double, KeyedSums::kMaxDim>, bool>>;
Sums run_rank(const std::vector<TestCollision>& mine, NeighbourExchange* ex, int ranks, int dim = 3,
              bool reduce = true) {
  const int me = ex ? ex->rank() : 0;
  std::vector<Gid> gid;
  std::map<Gid, std::int32_t> slot;
  auto slot_of = [&](Gid g) {
    auto [it, added] = slot.emplace(g, static_cast<std::int32_t>(gid.size()));
    if (added) gid.push_back(g);
    return it->second;
  };
  for (const TestCollision& c : mine)
    for (const auto& a : c.adds) slot_of(a.first);
  std::vector<int> owner;
  for (Gid g : gid) owner.push_back(static_cast<int>(g % ranks) == me ? -1 : static_cast<int>(g % ranks));
  KeyedSums sums;
  sums.plan(ex, owner, gid, slot_of);
  // The neighbours' slots are added during the first exchange: the sums grow with them.
  std::vector<std::array<double, KeyedSums::kMaxDim>> total;
  auto at = [&](std::int32_t k) {
    if (static_cast<std::size_t>(k) >= total.size()) total.resize(static_cast<std::size_t>(k) + 1, {});
    return total[static_cast<std::size_t>(k)].data();
  };
  if (reduce)
    sums.reduce(
        mine.size(), [&](std::size_t q) { return mine[q].key; }, dim,
        [&](std::size_t q, auto&& f) {
          for (const auto& a : mine[q].adds) {
            std::array<double, KeyedSums::kMaxDim> v{};
            for (int d = 0; d < dim; ++d) v[static_cast<std::size_t>(d)] = a.second[d % 3] * (1 + d / 3);
            f(slot.at(a.first), v.data());
          }
        },
        at);
  // Without a sum, the owners' values are their vertices' gids (component 0).
  sums.reply(dim, [&](std::int32_t k) {
    double* v = at(k);
    if (!reduce && sums.owned(static_cast<std::size_t>(k))) v[0] = static_cast<double>(gid[static_cast<std::size_t>(k)]);
    return v;
  });
  EXPECT_EQ(sums.slots(), gid.size());
  Sums out;
  for (std::size_t k = 0; k < gid.size(); ++k) {
    at(static_cast<std::int32_t>(k));
    out[gid[k]] = {total[k], sums.owned(k)};
  }
  return out;
}

// Runs run_rank on `ranks` threads over the collisions dealt round-robin by key, so that
// every vertex gets contributions from several ranks, interleaved in key order. Counts
// the exchanges each rank makes.
std::vector<Sums> run_ranks(const std::vector<TestCollision>& col, int ranks, int dim, bool reduce,
                            std::vector<int>* exchanges = nullptr) {
  std::vector<std::vector<TestCollision>> part(static_cast<std::size_t>(ranks));
  for (std::size_t q = 0; q < col.size(); ++q) part[(q * 7 + q / 5) % static_cast<std::size_t>(ranks)].push_back(col[q]);
  ThreadExchange::Shared shared(ranks);
  std::vector<Sums> got(static_cast<std::size_t>(ranks));
  if (exchanges) exchanges->assign(static_cast<std::size_t>(ranks), 0);
  std::vector<std::thread> th;
  for (int r = 0; r < ranks; ++r)
    th.emplace_back([&, r] {
      ThreadExchange ex(shared, r);
      got[static_cast<std::size_t>(r)] = run_rank(part[static_cast<std::size_t>(r)], &ex, ranks, dim, reduce);
      if (exchanges) (*exchanges)[static_cast<std::size_t>(r)] = ex.exchanges();
    });
  for (std::thread& t : th) t.join();
  return got;
}

}  // namespace

TEST(KeyedSums, OneRankFoldsInKeyOrder) {
  const auto col = make_collisions(1);
  const auto got = run_rank(col, nullptr, 1);
  // Reference: each vertex's contributions added one by one in key order.
  std::map<Gid, std::array<double, 3>> ref, reversed;
  for (const TestCollision& c : col)
    for (const auto& [g, v] : c.adds)
      for (int d = 0; d < 3; ++d) ref[g][d] += v[d];
  for (auto c = col.rbegin(); c != col.rend(); ++c)
    for (auto a = c->adds.rbegin(); a != c->adds.rend(); ++a)
      for (int d = 0; d < 3; ++d) reversed[a->first][d] += a->second[d];
  ASSERT_EQ(got.size(), ref.size());
  int order_sensitive = 0;
  for (const auto& [g, s] : ref) {
    EXPECT_TRUE(got.at(g).second);
    for (int d = 0; d < 3; ++d) {
      EXPECT_EQ(got.at(g).first[d], s[d]) << "vertex " << g << " component " << d;
      order_sensitive += reversed[g][d] != s[d];
    }
  }
  // The data can tell orders apart, so the multi-rank test below can fail.
  EXPECT_GT(order_sensitive, 0);
}

TEST(KeyedSums, AnySplitOverRanksGivesTheOneRankSums) {
  const auto col = make_collisions(2);
  for (int dim : {3, KeyedSums::kMaxDim}) {
    const auto ref = run_rank(col, nullptr, 1, dim);
    for (int ranks : {2, 3, 4}) {
      std::vector<int> exchanges;
      const std::vector<Sums> got = run_ranks(col, ranks, dim, true, &exchanges);
      for (int r = 0; r < ranks; ++r) {
        // The plan's requests travel with the sum: one exchange for the sum, one for the reply.
        EXPECT_EQ(exchanges[static_cast<std::size_t>(r)], 2) << "ranks " << ranks << " rank " << r;
        for (const auto& [g, s] : got[static_cast<std::size_t>(r)]) {
          // Owned slots hold the complete sums, ghost slots the owner's reply: bitwise the
          // one-rank fold either way.
          EXPECT_EQ(s.second, static_cast<int>(g % ranks) == r) << "ranks " << ranks << " rank " << r << " vertex " << g;
          for (int d = 0; d < dim; ++d)
            EXPECT_EQ(s.first[static_cast<std::size_t>(d)], ref.at(g).first[static_cast<std::size_t>(d)])
                << "dim " << dim << " ranks " << ranks << " rank " << r << " vertex " << g << " component " << d;
        }
      }
    }
  }
}

// A step whose first exchange is a reply: the requests travel alone first, and every
// ghost slot gets its owner's value.
TEST(KeyedSums, AReplyWithoutASumStillServesEveryGhost) {
  const auto col = make_collisions(3);
  for (int ranks : {2, 3}) {
    std::vector<int> exchanges;
    const std::vector<Sums> got = run_ranks(col, ranks, 3, false, &exchanges);
    for (int r = 0; r < ranks; ++r) {
      EXPECT_EQ(exchanges[static_cast<std::size_t>(r)], 2) << "ranks " << ranks << " rank " << r;
      int ghosts = 0;
      for (const auto& [g, s] : got[static_cast<std::size_t>(r)]) {
        EXPECT_EQ(s.first[0], static_cast<double>(g)) << "ranks " << ranks << " rank " << r << " vertex " << g;
        ghosts += !s.second;
      }
      EXPECT_GT(ghosts, 0);
    }
  }
}

// solve_in_key_order: rank 0 sees every rank's rows merged into the one-rank key order,
// and each rank gets the value of each of its rows back in its own order.
TEST(KeyedSums, SolveInKeyOrderSeesTheOneRankListOnAnySplit) {
  struct Row {
    KeyedSums::Key key;
    double payload;
  };
  std::vector<Row> rows;  // keys (p, t) for p < 30, t < 2, in key order
  for (Gid p = 0; p < 30; ++p)
    for (Gid t = 0; t < 2; ++t) rows.push_back({{p, 5 + t}, static_cast<double>(7 * p + t)});
  auto key = [](const Row& r) { return r.key; };
  // The "solve": the row's position in the list it is given, plus its payload / 1000;
  // the stats count the rows.
  auto solve = [](const std::vector<Row>& all, std::int64_t& count) {
    std::vector<double> x;
    for (std::size_t i = 0; i < all.size(); ++i) x.push_back(static_cast<double>(i) + all[i].payload / 1000);
    count = static_cast<std::int64_t>(all.size());
    return x;
  };
  std::int64_t one_count = 0;
  const std::vector<double> ref = solve_in_key_order(nullptr, rows, key, solve, one_count);
  ASSERT_EQ(one_count, 60);
  for (int ranks : {2, 3}) {
    std::vector<std::vector<Row>> part(static_cast<std::size_t>(ranks));
    std::vector<std::vector<std::size_t>> at(static_cast<std::size_t>(ranks));  // index in `rows`
    for (std::size_t i = 0; i < rows.size(); ++i) {
      const std::size_t r = (i * 5 + i / 3) % static_cast<std::size_t>(ranks);
      part[r].push_back(rows[i]);
      at[r].push_back(i);
    }
    ThreadExchange::Shared shared(ranks);
    std::vector<std::vector<double>> got(static_cast<std::size_t>(ranks));
    std::vector<std::int64_t> count(static_cast<std::size_t>(ranks), -1);
    std::vector<std::thread> th;
    for (int r = 0; r < ranks; ++r)
      th.emplace_back([&, r] {
        ThreadExchange ex(shared, r);
        const auto u = static_cast<std::size_t>(r);
        got[u] = solve_in_key_order(&ex, part[u], key, solve, count[u]);
      });
    for (std::thread& t : th) t.join();
    for (std::size_t r = 0; r < static_cast<std::size_t>(ranks); ++r) {
      EXPECT_EQ(count[r], 60) << "ranks " << ranks << " rank " << r;
      ASSERT_EQ(got[r].size(), at[r].size());
      for (std::size_t k = 0; k < at[r].size(); ++k)
        EXPECT_EQ(got[r][k], ref[at[r][k]]) << "ranks " << ranks << " rank " << r << " row " << at[r][k];
    }
  }
}
