// The byte exchanges without MPI's int limits (alltoallv_bytes, broadcast_bytes; mpi_util.hpp)
// on 1 to 4 ranks (ctest mpi.npN). Reference: every byte is a function of (source,
// destination, position) computed here; the lengths differ per pair (some empty, one pair
// much longer than the rest), so that small `call_bytes` force the rounds, pairs ending in
// different rounds, and a last partial slice.
#include <gtest/gtest.h>
#include <mpi.h>

#include <cstdint>
#include <vector>

#include "softcontact/mpi_util.hpp"

using namespace softcontact;

namespace {

std::size_t pair_length(int from, int to) {
  if ((from + 2 * to) % 5 == 3) return 0;
  if (from == 1 && to == 0) return 5000;  // the long one (2 ranks or more)
  return static_cast<std::size_t>(37 * from + 11 * to + 3);
}
char pair_byte(int from, int to, std::size_t i) {
  return static_cast<char>((i * 131 + static_cast<std::size_t>(from) * 17 + static_cast<std::size_t>(to) * 7) & 0xff);
}

}  // namespace

TEST(Exchange, AlltoallvBytesDeliversEveryPairInAnyRounds) {
  const int rank = comm_rank(MPI_COMM_WORLD), n = comm_size(MPI_COMM_WORLD);
  std::vector<std::vector<char>> out(static_cast<std::size_t>(n));
  for (int to = 0; to < n; ++to)
    for (std::size_t i = 0; i < pair_length(rank, to); ++i) out[static_cast<std::size_t>(to)].push_back(pair_byte(rank, to, i));
  // One call (the default), rounds of 1 byte a pair, slices that do not divide the lengths,
  // and a limit that only rank 0's received total passes (on 3 and 4 ranks: every rank
  // must take the rounds all the same).
  for (std::size_t call : {kMaxCallBytes, std::size_t{1}, std::size_t{97}, std::size_t{4096}, std::size_t{5010}}) {
    const std::vector<std::vector<char>> in = alltoallv_bytes(MPI_COMM_WORLD, out, call);
    ASSERT_EQ(in.size(), static_cast<std::size_t>(n));
    for (int from = 0; from < n; ++from) {
      const std::vector<char>& got = in[static_cast<std::size_t>(from)];
      ASSERT_EQ(got.size(), pair_length(from, rank)) << "from rank " << from << ", call_bytes " << call;
      std::size_t wrong = 0;
      for (std::size_t i = 0; i < got.size(); ++i) wrong += got[i] != pair_byte(from, rank, i) ? 1 : 0;
      EXPECT_EQ(wrong, 0u) << "from rank " << from << ", call_bytes " << call;
    }
  }
  // Nothing to send anywhere: empty buffers back.
  const std::vector<std::vector<char>> none = alltoallv_bytes(MPI_COMM_WORLD, std::vector<std::vector<char>>(static_cast<std::size_t>(n)));
  for (const auto& b : none) EXPECT_TRUE(b.empty());
}

TEST(Exchange, BroadcastBytesInCallsOfAnySize) {
  const int rank = comm_rank(MPI_COMM_WORLD), n = comm_size(MPI_COMM_WORLD);
  for (int root = 0; root < n; ++root)
    for (std::size_t call : {kMaxCallBytes, std::size_t{1}, std::size_t{1000}}) {
      std::vector<char> b;
      if (rank == root)
        for (std::size_t i = 0; i < 4099; ++i) b.push_back(pair_byte(root, 0, i));
      else
        b.assign(17, 'x');  // replaced, size and all
      broadcast_bytes(MPI_COMM_WORLD, root, b, call);
      ASSERT_EQ(b.size(), 4099u) << "root " << root << ", call_bytes " << call;
      std::size_t wrong = 0;
      for (std::size_t i = 0; i < b.size(); ++i) wrong += b[i] != pair_byte(root, 0, i) ? 1 : 0;
      EXPECT_EQ(wrong, 0u) << "root " << root << ", call_bytes " << call;
    }
  std::vector<char> empty;
  if (rank != 0) empty.assign(5, 'y');
  broadcast_bytes(MPI_COMM_WORLD, 0, empty);
  EXPECT_TRUE(empty.empty());
}
