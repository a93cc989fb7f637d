#pragma once
// Small MPI conveniences shared by the library and the MPI tests.
#include <mpi.h>

#include <cstdint>
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

}  // namespace softcontact
