#pragma once
// Small MPI conveniences shared by the library and the MPI tests.
#include <mpi.h>

#include <cstddef>
#include <cstdint>
#include <limits>
#include <vector>

namespace softcontact {

/// This process's rank in `comm`.
inline int comm_rank(MPI_Comm comm) {
  int r = 0;
  MPI_Comm_rank(comm, &r);
  return r;
}

/// The number of ranks of `comm`.
inline int comm_size(MPI_Comm comm) {
  int s = 1;
  MPI_Comm_size(comm, &s);
  return s;
}

/// The k-th smallest (from 0) of all ranks' values together, exactly: what
/// std::nth_element would give on their concatenation, without gathering them. The values
/// must be non-negative (lengths); a NaN counts as larger than every number. Eight rounds
/// of one MPI_Allreduce of 256 counts each (radix selection, a byte of the bit pattern a
/// round), every rank counting its own values still in the running. Collective;
/// requires 0 <= k < the total count (beyond it: NaN on every rank).
double kth_smallest(MPI_Comm comm, const std::vector<double>& values, std::int64_t k);

/// Every rank's `mine`, concatenated in rank order, on every rank (MPI_Allgatherv; counts
/// first by MPI_Allgather). Collective. The total must fit an int.
std::vector<double> allgather_doubles(MPI_Comm comm, const std::vector<double>& mine);

/// Rank r's `counts[r]` consecutive values of root's `all` (MPI_Scatterv; the pieces in
/// rank order), returned on every rank. `counts` is the same on every rank; `all` matters
/// on root only, where it must hold their sum. Collective.
std::vector<double> scatter_doubles(MPI_Comm comm, int root, const std::vector<double>& all,
                                    const std::vector<int>& counts);

/// The most bytes one MPI call of the exchanges below moves per rank: MPI's counts and
/// displacements are ints.
inline constexpr std::size_t kMaxCallBytes = static_cast<std::size_t>(std::numeric_limits<int>::max());

/// Each rank sends `out[r]` to rank r (out has one buffer per rank) and gets what every
/// rank sent it, one buffer per source rank. The byte counts travel as 64-bit integers
/// (MPI_Alltoall), the bytes by MPI_Alltoallv: in one call when every rank's total sent
/// and received fit `call_bytes`, else in rounds in which each pair moves at most
/// call_bytes / ranks (every rank computes each round's counts from the 64-bit ones; the
/// round count is agreed by one MPI_Allreduce). Collective; `call_bytes` must be the same
/// on every rank (smaller values only for tests).
std::vector<std::vector<char>> alltoallv_bytes(MPI_Comm comm, const std::vector<std::vector<char>>& out,
                                               std::size_t call_bytes = kMaxCallBytes);

/// `bytes` of rank `root` on every rank (resized there): the size by one MPI_Bcast of a
/// 64-bit integer, the bytes in MPI_Bcast calls of at most `call_bytes`. Collective.
void broadcast_bytes(MPI_Comm comm, int root, std::vector<char>& bytes, std::size_t call_bytes = kMaxCallBytes);

}  // namespace softcontact
