// Exact selection over ranks (mpi_util.hpp): bisection on the bit patterns of
// non-negative doubles, which order like the numbers themselves.
#include <cstring>
#include <limits>

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

}  // namespace softcontact
