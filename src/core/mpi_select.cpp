// Exact selection over ranks (mpi_util.hpp): bisection on the bit patterns of
// non-negative doubles, which order like the numbers themselves. And an all-gather of
// doubles of any count per rank.
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
  std::vector<std::uint64_t> bits(values.size());
  for (std::size_t i = 0; i < values.size(); ++i) bits[i] = bits_of(values[i]);
  // The answer is the smallest pattern b with more than k values at or below it.
  std::uint64_t lo = 0, hi = std::numeric_limits<std::uint64_t>::max();
  while (lo < hi) {
    const std::uint64_t mid = lo + (hi - lo) / 2;
    std::int64_t below = 0;
    for (std::uint64_t b : bits) below += b <= mid ? 1 : 0;
    MPI_Allreduce(MPI_IN_PLACE, &below, 1, MPI_INT64_T, MPI_SUM, comm);
    if (below > k) hi = mid;
    else lo = mid + 1;
  }
  if (lo == std::numeric_limits<std::uint64_t>::max()) return std::numeric_limits<double>::quiet_NaN();
  double x = 0;
  std::memcpy(&x, &lo, sizeof x);
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

}  // namespace softcontact
