#include "softcontact/halo.hpp"

#include <petscsf.h>

#include <algorithm>

#include "softcontact/error.hpp"
#include "softcontact/mpi_util.hpp"

namespace softcontact {

namespace {
void petsc_check(PetscErrorCode e, const char* what) {
  if (e != 0) throw RuntimeFailure(std::string("PETSc failed in ") + what + " (error " + std::to_string(e) + ")");
}
constexpr int kTagSize = 7101, kTagData = 7102;
}  // namespace

std::vector<index_t> owner_vertex_offsets(const World& w) {
  std::vector<index_t> off(w.layout.size(), 0);
  std::vector<index_t> next;  // per rank
  for (std::size_t k = 0; k < w.layout.size(); ++k) {
    const int r = w.layout[k].rank;
    if (static_cast<std::size_t>(r) >= next.size()) next.resize(static_cast<std::size_t>(r) + 1, 0);
    off[k] = next[static_cast<std::size_t>(r)];
    next[static_cast<std::size_t>(r)] += static_cast<index_t>(w.layout[k].vertex_count);
  }
  return off;
}

Halo::Halo(MPI_Comm comm, const World& w) : comm_(comm) {
  rank_ = comm_rank(comm_);
  ranks_ = comm_size(comm_);
  MPI_Type_contiguous(3, MPI_DOUBLE, &xyz_type_);
  MPI_Type_commit(&xyz_type_);
  const std::vector<index_t> owner_off = owner_vertex_offsets(w);
  const std::size_t n = w.n_local(), no = w.n_owned;
  ghost_rows_ = static_cast<std::int64_t>(n - no);
  std::vector<PetscInt> leaf(n - no);
  std::vector<PetscSFNode> remote(n - no);
  for (std::size_t i = no; i < n; ++i) {
    const int k = w.vertex_object[i];
    const ObjectLayout& L = w.layout[static_cast<std::size_t>(k)];
    leaf[i - no] = static_cast<PetscInt>(i);
    remote[i - no].rank = L.rank;
    remote[i - no].index = static_cast<PetscInt>(owner_off[static_cast<std::size_t>(k)] + (w.vertex_gid[i] - L.vertex_begin));
  }
  for (int k : w.ghost_objects) neighbors_.push_back(w.layout[static_cast<std::size_t>(k)].rank);
  std::sort(neighbors_.begin(), neighbors_.end());
  neighbors_.erase(std::unique(neighbors_.begin(), neighbors_.end()), neighbors_.end());

  PetscSF sf = nullptr;
  petsc_check(PetscSFCreate(comm, &sf), "PetscSFCreate");
  sf_ = sf;
  petsc_check(PetscSFSetGraph(sf, static_cast<PetscInt>(no), static_cast<PetscInt>(n - no), leaf.data(),
                              PETSC_COPY_VALUES, remote.data(), PETSC_COPY_VALUES),
              "PetscSFSetGraph");
  petsc_check(PetscSFSetUp(sf), "PetscSFSetUp");
}

Halo::~Halo() {
  PetscSF sf = static_cast<PetscSF>(sf_);
  if (sf) PetscSFDestroy(&sf);
  if (xyz_type_ != MPI_DATATYPE_NULL) MPI_Type_free(&xyz_type_);
}

void Halo::update(double* xyz) {
  PetscSF sf = static_cast<PetscSF>(sf_);
  // Roots are rows [0, n_owned) and leaves rows [n_owned, n_local) of the same array:
  // the two ranges never overlap.
  petsc_check(PetscSFBcastBegin(sf, xyz_type_, xyz, xyz, MPI_REPLACE), "PetscSFBcastBegin");
  petsc_check(PetscSFBcastEnd(sf, xyz_type_, xyz, xyz, MPI_REPLACE), "PetscSFBcastEnd");
  bytes_received_ += ghost_rows_ * 3 * static_cast<std::int64_t>(sizeof(double));
}

std::vector<std::vector<char>> Halo::exchange_bytes(const std::vector<std::vector<char>>& send) {
  return exchange_with(neighbors_, send);
}

std::vector<std::vector<char>> Halo::exchange_with(const std::vector<int>& peers,
                                                   const std::vector<std::vector<char>>& send) {
  SC_ASSERT(send.size() == peers.size());
  const std::size_t nn = peers.size();
  std::vector<std::vector<char>> recv(nn);
  if (nn == 0) return recv;
  std::vector<std::int64_t> out_size(nn), in_size(nn);
  std::vector<MPI_Request> req(2 * nn);
  for (std::size_t k = 0; k < nn; ++k) {
    out_size[k] = static_cast<std::int64_t>(send[k].size());
    MPI_Irecv(&in_size[k], 1, MPI_INT64_T, peers[k], kTagSize, comm_, &req[k]);
    MPI_Isend(&out_size[k], 1, MPI_INT64_T, peers[k], kTagSize, comm_, &req[nn + k]);
  }
  MPI_Waitall(static_cast<int>(2 * nn), req.data(), MPI_STATUSES_IGNORE);
  for (std::size_t k = 0; k < nn; ++k) {
    recv[k].resize(static_cast<std::size_t>(in_size[k]));
    bytes_received_ += in_size[k] + static_cast<std::int64_t>(sizeof(std::int64_t));
    MPI_Irecv(recv[k].data(), static_cast<int>(in_size[k]), MPI_BYTE, peers[k], kTagData, comm_, &req[k]);
    MPI_Isend(send[k].data(), static_cast<int>(send[k].size()), MPI_BYTE, peers[k], kTagData, comm_,
              &req[nn + k]);
  }
  MPI_Waitall(static_cast<int>(2 * nn), req.data(), MPI_STATUSES_IGNORE);
  return recv;
}

// The collective patterns below are not counted in bytes_received(): they serve the
// coupled closure's direct solve, a gather of whole rows to rank 0, not the halo.
std::vector<std::vector<char>> Halo::gather_to_root(const std::vector<char>& mine) {
  const int bytes = static_cast<int>(mine.size());
  std::vector<int> counts(static_cast<std::size_t>(ranks_), 0), displs(static_cast<std::size_t>(ranks_), 0);
  MPI_Gather(&bytes, 1, MPI_INT, counts.data(), 1, MPI_INT, 0, comm_);
  std::vector<char> all;
  if (rank_ == 0) {
    std::int64_t total = 0;
    for (int p = 0; p < ranks_; ++p) {
      displs[static_cast<std::size_t>(p)] = static_cast<int>(total);
      total += counts[static_cast<std::size_t>(p)];
    }
    all.resize(static_cast<std::size_t>(total));
  }
  MPI_Gatherv(mine.data(), bytes, MPI_BYTE, all.data(), counts.data(), displs.data(), MPI_BYTE, 0, comm_);
  std::vector<std::vector<char>> out;
  if (rank_ != 0) return out;
  out.resize(static_cast<std::size_t>(ranks_));
  for (std::size_t p = 0; p < out.size(); ++p)
    out[p].assign(all.begin() + displs[p], all.begin() + displs[p] + counts[p]);
  return out;
}

std::vector<char> Halo::scatter_from_root(const std::vector<std::vector<char>>& parts, std::size_t my_bytes) {
  std::vector<int> counts, displs;
  std::vector<char> all;
  if (rank_ == 0) {
    SC_ASSERT(parts.size() == static_cast<std::size_t>(ranks_));
    for (const auto& p : parts) {
      displs.push_back(static_cast<int>(all.size()));
      counts.push_back(static_cast<int>(p.size()));
      all.insert(all.end(), p.begin(), p.end());
    }
  }
  std::vector<char> mine(my_bytes);
  MPI_Scatterv(all.data(), counts.data(), displs.data(), MPI_BYTE, mine.data(), static_cast<int>(my_bytes), MPI_BYTE, 0,
               comm_);
  return mine;
}

void Halo::broadcast_from_root(void* data, std::size_t bytes) {
  MPI_Bcast(data, static_cast<int>(bytes), MPI_BYTE, 0, comm_);
}

}  // namespace softcontact
