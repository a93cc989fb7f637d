// Byte exchanges between ranks without MPI's int limits (mpi_util.hpp).
#include <algorithm>
#include <cstring>
#include <stdexcept>

#include "softcontact/mpi_util.hpp"

namespace softcontact {

std::vector<std::vector<char>> alltoallv_bytes(MPI_Comm comm, const std::vector<std::vector<char>>& out,
                                               std::size_t call_bytes) {
  const int n = comm_size(comm);
  const auto nr = static_cast<std::size_t>(n);
  if (out.size() != nr) throw std::invalid_argument("alltoallv_bytes: one buffer per rank expected");
  call_bytes = std::clamp<std::size_t>(call_bytes, 1, kMaxCallBytes);
  std::vector<std::uint64_t> scount(nr), rcount(nr);
  for (std::size_t r = 0; r < nr; ++r) scount[r] = out[r].size();
  MPI_Alltoall(scount.data(), 1, MPI_UINT64_T, rcount.data(), 1, MPI_UINT64_T, comm);
  std::vector<std::vector<char>> in(nr);
  for (std::size_t r = 0; r < nr; ++r) in[r].resize(static_cast<std::size_t>(rcount[r]));

  // One call when every rank's totals fit; else rounds of at most `quota` bytes a pair.
  std::uint64_t stotal = 0, rtotal = 0, largest = 0;
  for (std::size_t r = 0; r < nr; ++r) {
    stotal += scount[r];
    rtotal += rcount[r];
    largest = std::max({largest, scount[r], rcount[r]});
  }
  const std::uint64_t quota = std::max<std::uint64_t>(1, call_bytes / nr);
  std::uint64_t need[2] = {stotal > call_bytes || rtotal > call_bytes ? 1u : 0u, (largest + quota - 1) / quota};
  MPI_Allreduce(MPI_IN_PLACE, need, 2, MPI_UINT64_T, MPI_MAX, comm);
  const bool split = need[0] != 0;
  const std::uint64_t rounds = need[1] == 0 ? 0 : split ? need[1] : 1;  // nothing anywhere: no call

  std::vector<int> sc(nr), rc(nr), sd(nr), rd(nr);
  std::vector<char> sbuf, rbuf;
  for (std::uint64_t round = 0; round < rounds; ++round) {
    // This round's slice of each pair's bytes: [round * quota, +quota) when split.
    auto slice = [&](std::uint64_t count, std::uint64_t& from) {
      if (!split) {
        from = 0;
        return count;
      }
      from = std::min(count, round * quota);
      return std::min(count - from, quota);
    };
    int st = 0, rt = 0;
    for (std::size_t r = 0; r < nr; ++r) {
      std::uint64_t from = 0;
      sc[r] = static_cast<int>(slice(scount[r], from));
      sd[r] = st;
      st += sc[r];
      rc[r] = static_cast<int>(slice(rcount[r], from));
      rd[r] = rt;
      rt += rc[r];
    }
    sbuf.resize(static_cast<std::size_t>(st));
    rbuf.resize(static_cast<std::size_t>(rt));
    for (std::size_t r = 0; r < nr; ++r) {
      std::uint64_t from = 0;
      slice(scount[r], from);
      if (sc[r] > 0) std::memcpy(sbuf.data() + sd[r], out[r].data() + from, static_cast<std::size_t>(sc[r]));
    }
    MPI_Alltoallv(sbuf.data(), sc.data(), sd.data(), MPI_BYTE, rbuf.data(), rc.data(), rd.data(), MPI_BYTE, comm);
    for (std::size_t r = 0; r < nr; ++r) {
      std::uint64_t from = 0;
      slice(rcount[r], from);
      if (rc[r] > 0) std::memcpy(in[r].data() + from, rbuf.data() + rd[r], static_cast<std::size_t>(rc[r]));
    }
  }
  return in;
}

void broadcast_bytes(MPI_Comm comm, int root, std::vector<char>& bytes, std::size_t call_bytes) {
  call_bytes = std::clamp<std::size_t>(call_bytes, 1, kMaxCallBytes);
  std::uint64_t size = bytes.size();
  MPI_Bcast(&size, 1, MPI_UINT64_T, root, comm);
  bytes.resize(static_cast<std::size_t>(size));
  for (std::uint64_t at = 0; at < size; at += call_bytes) {
    const auto count = static_cast<int>(std::min<std::uint64_t>(call_bytes, size - at));
    MPI_Bcast(bytes.data() + at, count, MPI_BYTE, root, comm);
  }
}

}  // namespace softcontact
