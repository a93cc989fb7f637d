// Exact selection over ranks (mpi_util.hpp): radix selection on the bit patterns of
// non-negative doubles, which order like the numbers themselves. And an all-gather of
// doubles of any count per rank, and its converse, a scatter.
#include <array>
#include <cstring>
#include <limits>
#include <stdexcept>

#include "softcontact/mpi_util.hpp"

namespace softcontact {

namespace {
std::uint64_t bits_of(double x) {
  if (x == 0) return 0;                                               // -0.0 is 0.0
  if (!(x > 0)) return std::numeric_limits<std::uint64_t>::max();   // NaN last
  std::uint64_t b = 0;
  std::memcpy(&b, &x, sizeof b);
  return b;
}
}  // namespace

double kth_smallest(MPI_Comm comm, const std::vector<double>& values, std::int64_t k) {
  // Radix selection on the bit patterns, most significant byte first: each round counts
  // the candidates left by their next byte (one MPI_Allreduce of 256 counts), finds the
  // byte of the k-th, and keeps only the candidates with it. Eight rounds; each scans only
  // what the earlier rounds kept.
  std::vector<std::uint64_t> left(values.size());
  for (std::size_t i = 0; i < values.size(); ++i) left[i] = bits_of(values[i]);
  std::uint64_t answer = 0;
  std::int64_t rank_in_left = k;  // the k-th overall is the rank_in_left-th of those left
  for (int shift = 56; shift >= 0; shift -= 8) {
    std::array<std::int64_t, 256> count{};
    for (std::uint64_t b : left) ++count[(b >> shift) & 0xff];
    MPI_Allreduce(MPI_IN_PLACE, count.data(), 256, MPI_INT64_T, MPI_SUM, comm);
    std::size_t digit = 0;
    while (digit < 256 && rank_in_left >= count[digit]) rank_in_left -= count[digit++];
    if (digit == 256) return std::numeric_limits<double>::quiet_NaN();  // k beyond the total: alike on every rank
    answer |= static_cast<std::uint64_t>(digit) << shift;
    std::size_t kept = 0;
    for (std::uint64_t b : left)
      if (((b >> shift) & 0xff) == digit) left[kept++] = b;
    left.resize(kept);
  }
  if (answer == std::numeric_limits<std::uint64_t>::max()) return std::numeric_limits<double>::quiet_NaN();
  double x = 0;
  std::memcpy(&x, &answer, sizeof x);
  return x;
}

std::vector<double> allgather_doubles(MPI_Comm comm, const std::vector<double>& mine) {
  const int n = comm_size(comm);
  // The counts as 64-bit integers, so that every rank sees a total too large for MPI's int
  // counts and fails alike, instead of one rank leaving the collective.
  const std::int64_t count = static_cast<std::int64_t>(mine.size());
  std::vector<std::int64_t> counts(static_cast<std::size_t>(n));
  MPI_Allgather(&count, 1, MPI_INT64_T, counts.data(), 1, MPI_INT64_T, comm);
  std::vector<int> sizes(static_cast<std::size_t>(n)), displs(static_cast<std::size_t>(n));
  std::int64_t total = 0;
  for (std::size_t r = 0; r < counts.size(); ++r) {
    displs[r] = static_cast<int>(total);
    sizes[r] = static_cast<int>(counts[r]);
    total += counts[r];
    if (total > std::numeric_limits<int>::max())
      throw std::length_error("allgather_doubles: more than 2^31 - 1 values in all ranks together");
  }
  std::vector<double> all(static_cast<std::size_t>(total));
  MPI_Allgatherv(mine.data(), static_cast<int>(count), MPI_DOUBLE, all.data(), sizes.data(), displs.data(), MPI_DOUBLE,
                 comm);
  return all;
}

std::vector<double> scatter_doubles(MPI_Comm comm, int root, const std::vector<double>& all,
                                    const std::vector<int>& counts) {
  const int n = comm_size(comm), me = comm_rank(comm);
  if (counts.size() != static_cast<std::size_t>(n)) throw std::invalid_argument("scatter_doubles: one count per rank");
  std::vector<int> displs(counts.size());
  std::int64_t total = 0;
  for (std::size_t r = 0; r < counts.size(); ++r) {
    if (total > std::numeric_limits<int>::max()) throw std::length_error("scatter_doubles: more than 2^31 - 1 values");
    displs[r] = static_cast<int>(total);
    total += counts[r];
  }
  if (me == root && static_cast<std::int64_t>(all.size()) != total)
    throw std::invalid_argument("scatter_doubles: the root's values are not the counts' sum");
  std::vector<double> piece(static_cast<std::size_t>(counts[static_cast<std::size_t>(me)]));
  MPI_Scatterv(all.data(), counts.data(), displs.data(), MPI_DOUBLE, piece.data(), static_cast<int>(piece.size()),
               MPI_DOUBLE, root, comm);
  return piece;
}

}  // namespace softcontact
