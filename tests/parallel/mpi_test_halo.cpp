// Halo::exchange_doubles: every peer's doubles arrive, and buffers of the right size are
// reused, not reallocated. Then the halo's update of changed rows only (Halo::keep_sent, Halo::update_changed): after a
// full broadcast, updates that send each neighbour only the owned rows that differ
// bitwise from what it holds must leave every ghost row exactly as a full broadcast
// would, one after another, and must carry a bit per held row (whole doubles per object)
// plus 24 bytes per changed row; each owned row is kept once however many neighbours
// hold it. On 1 to 4
// ranks (ctest mpi.npN), every rank ghosting every other rank's objects, then every rank
// ghosting only the first object of each other rank (a neighbour that holds one object
// is sent that object's segment as it lies, not a copy). Reference: the rows' values as
// functions of their global ids, computed here, not by the halo.
#include <gtest/gtest.h>
#include <mpi.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <map>

#include "softcontact/error.hpp"
#include "softcontact/halo.hpp"
#include "softcontact/mpi_util.hpp"
#include "softcontact/scene.hpp"
#include "softcontact/world.hpp"

using namespace softcontact;

namespace {

const Scene& pile() {
  static const Scene s = load_scene(std::string(SOFTCONTACT_TEST_DATA) + "/scenes/pile.yaml");
  return s;
}

// Component d of global vertex g before the change: a value unique to (g, d), with exact
// zeros in every 11th vertex's x (whose change to -0.0 compares equal as a number).
double before(softcontact::gid_t g, std::size_t d) {
  if (g % 11 == 0 && d == 0) return 0.0;
  return 0.001 * static_cast<double>(g) + static_cast<double>(d) + 0.25;
}
// After: every 3rd vertex moved; every 11th vertex's zero made -0.0; every 13th moved by
// one rounding step in z (nextafter); the rest unchanged.
double after(softcontact::gid_t g, std::size_t d) {
  const double b = before(g, d);
  if (g % 11 == 0 && d == 0) return -0.0;
  if (g % 3 == 0) return b + 0.5 * static_cast<double>(d + 1);
  if (g % 13 == 0 && d == 2) return std::nextafter(b, 10.0);
  return b;
}
bool changed(softcontact::gid_t g) { return g % 11 == 0 || g % 3 == 0 || g % 13 == 0; }

// The checks on a world where this rank ghosts, of every other rank, all its objects
// (`first_only` false) or only its lowest-numbered one.
void check_changed_updates(bool first_only) {
  const int n = comm_size(MPI_COMM_WORLD), rank = comm_rank(MPI_COMM_WORLD);
  const Scene& scene = pile();
  const std::vector<int> part = block_partition(scene, n);
  World w = build_world(scene, part, rank);
  std::vector<int> others;
  std::vector<char> seen(static_cast<std::size_t>(n), 0);
  for (std::size_t k = 0; k < scene.objects.size(); ++k) {
    const auto r = static_cast<std::size_t>(part[k]);
    if (part[k] == rank || (first_only && seen[r])) continue;
    seen[r] = 1;
    others.push_back(static_cast<int>(k));
  }
  set_ghost_objects(w, scene, others);
  Halo halo(MPI_COMM_WORLD, w);
  // Rows of this rank's objects that other ranks hold: all owned rows, or those of its
  // first object.
  std::size_t held = w.n_owned;
  if (first_only) {
    held = 0;
    for (std::size_t i = 0; i < w.n_owned; ++i) held += w.vertex_object[i] == w.vertex_object[0] ? 1 : 0;
  }

  const std::size_t nl = w.n_local(), no = w.n_owned;
  auto fill_owned = [&](double (*f)(softcontact::gid_t, std::size_t)) {
    for (std::size_t i = 0; i < no; ++i)
      for (std::size_t d = 0; d < 3; ++d) w.x[3 * i + d] = f(w.vertex_gid[i], d);
  };
  // Every ghost row must hold f of its global id, to the bit.
  auto ghost_rows_hold = [&](double (*f)(softcontact::gid_t, std::size_t)) {
    std::size_t wrong = 0;
    for (std::size_t i = no; i < nl; ++i)
      for (std::size_t d = 0; d < 3; ++d) {
        const double want = f(w.vertex_gid[i], d);
        wrong += std::memcmp(&w.x[3 * i + d], &want, sizeof(double)) != 0 ? 1 : 0;
      }
    return wrong;
  };

  fill_owned(before);
  for (std::size_t i = no; i < nl; ++i)
    for (std::size_t d = 0; d < 3; ++d) w.x[3 * i + d] = std::numeric_limits<double>::quiet_NaN();
  halo.update(w.x.data());
  EXPECT_EQ(ghost_rows_hold(before), 0u);
  EXPECT_EQ(halo.kept_rows(), 0u);
  halo.keep_sent(w.x.data());
  // Every other rank ghosts the same objects of this rank, so every held row is held by
  // n - 1 neighbours and kept once: `held` rows, not (n - 1) x held.
  EXPECT_EQ(halo.kept_rows(), n > 1 ? held : 0u) << "rank " << rank;

  // The bytes expected: per ghost object, its rows' mask (a bit per row, whole doubles),
  // then 24 bytes per changed row.
  std::map<int, std::int64_t> rows_of, changed_of;
  for (std::size_t i = no; i < nl; ++i) {
    const int object = w.vertex_object[i];
    ++rows_of[object];
    changed_of[object] += changed(w.vertex_gid[i]) ? 1 : 0;
  }
  std::int64_t expected = 0, changed_rows = 0;
  for (const auto& [object, rows] : rows_of) {
    expected += 8 * ((rows + 63) / 64) + 24 * changed_of[object];
    changed_rows += changed_of[object];
  }
  if (n > 1) EXPECT_GT(changed_rows, 0);

  fill_owned(after);
  const std::int64_t bytes0 = halo.bytes_received();
  halo.update_changed(w.x.data());
  EXPECT_EQ(ghost_rows_hold(after), 0u) << "rank " << rank;
  EXPECT_EQ(halo.bytes_received() - bytes0, expected) << "rank " << rank;

  // The rows sent are kept: a second update with nothing changed sends only the masks
  // and leaves every row.
  const std::int64_t bytes1 = halo.bytes_received();
  halo.update_changed(w.x.data());
  std::int64_t masks = 0;
  for (const auto& [object, rows] : rows_of) masks += 8 * ((rows + 63) / 64);
  EXPECT_EQ(halo.bytes_received() - bytes1, masks);
  EXPECT_EQ(ghost_rows_hold(after), 0u);

  // And back: the same rows change again, relative to what was sent last.
  fill_owned(before);
  const std::int64_t bytes2 = halo.bytes_received();
  halo.update_changed(w.x.data());
  EXPECT_EQ(ghost_rows_hold(before), 0u) << "rank " << rank;
  EXPECT_EQ(halo.bytes_received() - bytes2, expected) << "rank " << rank;

  // A full update (of any array) forgets the kept rows: update_changed needs keep_sent.
  halo.update(w.x.data());
  EXPECT_FALSE(halo.has_kept());
  EXPECT_THROW(halo.update_changed(w.x.data()), RuntimeFailure);
}

}  // namespace

TEST(Halo, UpdateOfChangedRowsEqualsTheFullBroadcast) {
  check_changed_updates(false);
  check_changed_updates(true);

  // Every rank's verdict on rank 0, which alone prints.
  int ok = ::testing::Test::HasFailure() ? 0 : 1;
  MPI_Allreduce(MPI_IN_PLACE, &ok, 1, MPI_INT, MPI_MIN, MPI_COMM_WORLD);
  EXPECT_EQ(ok, 1) << "some rank failed";
}

// Each pair (from, to) sends `len` doubles of value from * 1e6 + to * 1e3 + i (+ a
// round's offset); rank r's peers are all the other ranks. Rounds of the same lengths
// must land in the same buffers (the pointers kept), and shorter and longer rounds must
// be resized to the new length.
TEST(Halo, ExchangeDoublesFillsTheCallersBuffersInPlace) {
  const int n = comm_size(MPI_COMM_WORLD), rank = comm_rank(MPI_COMM_WORLD);
  const Scene& scene = pile();
  World w = build_world(scene, block_partition(scene, n), rank);
  Halo halo(MPI_COMM_WORLD, w);
  std::vector<int> peers;
  for (int r = 0; r < n; ++r)
    if (r != rank) peers.push_back(r);
  auto length = [](int from, int to, std::size_t base) { return base + static_cast<std::size_t>(3 * from + 5 * to); };
  auto value = [](int from, int to, std::size_t i, int round) {
    return 1e6 * from + 1e3 * to + static_cast<double>(i) + 0.5 * round;
  };
  std::vector<std::vector<double>> send(peers.size()), recv;
  std::vector<const double*> where;
  const std::size_t bases[] = {40, 40, 7, 300};
  for (int round = 0; round < 4; ++round) {
    const std::size_t base = bases[round];
    for (std::size_t k = 0; k < peers.size(); ++k) {
      send[k].clear();
      for (std::size_t i = 0; i < length(rank, peers[k], base); ++i) send[k].push_back(value(rank, peers[k], i, round));
    }
    halo.exchange_doubles(peers, send, recv);
    EXPECT_EQ(recv.size(), peers.size());
    std::size_t wrong = 0;
    for (std::size_t k = 0; k < std::min(peers.size(), recv.size()); ++k) {
      EXPECT_EQ(recv[k].size(), length(peers[k], rank, base)) << "from rank " << peers[k] << ", round " << round;
      for (std::size_t i = 0; i < recv[k].size(); ++i) wrong += recv[k][i] != value(peers[k], rank, i, round) ? 1 : 0;
      if (round == 1) EXPECT_EQ(recv[k].data(), where[k]) << "a buffer of the right size was reallocated";
    }
    EXPECT_EQ(wrong, 0u) << "round " << round;
    where.clear();
    for (const std::vector<double>& b : recv) where.push_back(b.data());
  }
  // No peers: no messages, an empty list back.
  halo.exchange_doubles({}, {}, recv);
  EXPECT_TRUE(recv.empty());

  int ok = ::testing::Test::HasFailure() ? 0 : 1;
  MPI_Allreduce(MPI_IN_PLACE, &ok, 1, MPI_INT, MPI_MIN, MPI_COMM_WORLD);
  EXPECT_EQ(ok, 1) << "some rank failed";
}
