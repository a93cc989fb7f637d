#include "softcontact/halo.hpp"

#include <petscsf.h>

#include <algorithm>
#include <cstring>
#include <limits>

#include "softcontact/error.hpp"
#include "softcontact/mpi_util.hpp"

namespace softcontact {

namespace {
void petsc_check(PetscErrorCode e, const char* what) {
  if (e != 0) throw RuntimeFailure(std::string("PETSc failed in ") + what + " (error " + std::to_string(e) + ")");
}
constexpr int kTagData = 7102, kTagChanged = 7104;

// The next message from `peer` with `tag`, of whatever size (MPI_Mprobe), into `into`;
// returns its bytes.
int receive_probed(MPI_Comm comm, int peer, int tag, std::vector<char>& into) {
  MPI_Message msg;
  MPI_Status st;
  MPI_Mprobe(peer, tag, comm, &msg, &st);
  int count = 0;
  MPI_Get_count(&st, MPI_BYTE, &count);
  into.resize(static_cast<std::size_t>(count));
  MPI_Mrecv(into.data(), count, MPI_BYTE, &msg, MPI_STATUS_IGNORE);
  return count;
}
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

  // For update_changed: each rank tells the owners of its ghosts which of their rows it
  // holds (the roots' indices, in its ghost-row order), so that an owner can send a row
  // by its place in that list. The neighbours are symmetric ("within reach" is), so
  // every rank expects a list from each of its neighbours.
  const std::size_t nn = neighbors_.size();
  recv_rows_.assign(nn, {});
  std::vector<std::vector<char>> want(nn);
  for (std::size_t i = no; i < n; ++i) {
    const auto at = std::lower_bound(neighbors_.begin(), neighbors_.end(), static_cast<int>(remote[i - no].rank));
    const auto k = static_cast<std::size_t>(at - neighbors_.begin());
    recv_rows_[k].push_back(static_cast<index_t>(i));
    const auto root = static_cast<index_t>(remote[i - no].index);
    const char* b = reinterpret_cast<const char*>(&root);
    want[k].insert(want[k].end(), b, b + sizeof(index_t));
  }
  const std::int64_t before = bytes_received_;
  const std::vector<std::vector<char>> asked = exchange_with(neighbors_, want);
  bytes_received_ = before;  // set-up traffic, not the halo's per-step figure
  // Each owned row that several neighbours hold is kept and compared once: the kept
  // rows grow with the rows held, not with how many ranks hold them.
  std::vector<std::vector<index_t>> send_rows(nn);
  for (std::size_t k = 0; k < nn; ++k) {
    send_rows[k].resize(asked[k].size() / sizeof(index_t));
    std::memcpy(send_rows[k].data(), asked[k].data(), send_rows[k].size() * sizeof(index_t));
    for (index_t r : send_rows[k])
      if (r < 0 || static_cast<std::size_t>(r) >= no)
        throw RuntimeFailure("Halo: rank " + std::to_string(neighbors_[k]) + " asks for row " + std::to_string(r) +
                             " of " + std::to_string(no) + " owned rows");
    held_rows_.insert(held_rows_.end(), send_rows[k].begin(), send_rows[k].end());
  }
  std::sort(held_rows_.begin(), held_rows_.end());
  held_rows_.erase(std::unique(held_rows_.begin(), held_rows_.end()), held_rows_.end());
  held_rows_.shrink_to_fit();
  std::vector<index_t> place(held_rows_.empty() ? 0 : static_cast<std::size_t>(held_rows_.back()) + 1, 0);
  for (std::size_t h = 0; h < held_rows_.size(); ++h) place[static_cast<std::size_t>(held_rows_[h])] = static_cast<index_t>(h);
  send_at_.assign(nn, {});
  for (std::size_t k = 0; k < nn; ++k) {
    send_at_[k].resize(send_rows[k].size());
    for (std::size_t j = 0; j < send_rows[k].size(); ++j)
      send_at_[k][j] = place[static_cast<std::size_t>(send_rows[k][j])];
  }
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
  if (!neighbors_.empty()) ++rounds_;
  kept_valid_ = false;
}

void Halo::keep_sent(const double* xyz) {
  kept_.resize(3 * held_rows_.size());
  for (std::size_t h = 0; h < held_rows_.size(); ++h)
    std::memcpy(&kept_[3 * h], xyz + 3 * static_cast<std::size_t>(held_rows_[h]), 3 * sizeof(double));
  kept_valid_ = true;
}

void Halo::update_changed(double* xyz) {
  if (!kept_valid_) throw RuntimeFailure("Halo::update_changed without the rows of the last update (keep_sent)");
  const std::size_t nn = neighbors_.size();
  if (nn > 0) ++rounds_;
  // Which held rows differ bitwise from what was sent last, each compared once; the kept
  // rows become the ones sent now.
  changed_.resize(held_rows_.size());
  for (std::size_t h = 0; h < held_rows_.size(); ++h) {
    const double* now = xyz + 3 * static_cast<std::size_t>(held_rows_[h]);
    const bool c = std::memcmp(now, &kept_[3 * h], 3 * sizeof(double)) != 0;
    changed_[h] = c ? 1 : 0;
    if (c) std::memcpy(&kept_[3 * h], now, 3 * sizeof(double));
  }
  // The messages are written into buffers kept from one update to the next: sized once
  // for every row, where a fresh one was allocated, zeroed and faulted in each time
  // (the same peak: all are in flight together); only the mask is cleared.
  out_.resize(nn);
  std::vector<MPI_Request> req(nn);
  for (std::size_t k = 0; k < nn; ++k) {
    // A bit per listed row (1: changed), padded to whole doubles, then the changed rows.
    const std::vector<index_t>& at_held = send_at_[k];
    const std::size_t mask_bytes = 8 * ((at_held.size() + 63) / 64);
    std::vector<char>& m = out_[k];
    m.resize(mask_bytes + 3 * sizeof(double) * at_held.size());
    std::memset(m.data(), 0, mask_bytes);
    std::size_t at = mask_bytes;
    for (std::size_t j = 0; j < at_held.size(); ++j) {
      const auto h = static_cast<std::size_t>(at_held[j]);
      if (!changed_[h]) continue;
      m[j / 8] = static_cast<char>(m[j / 8] | (1 << (j % 8)));
      std::memcpy(m.data() + at, &kept_[3 * h], 3 * sizeof(double));
      at += 3 * sizeof(double);
    }
    MPI_Isend(m.data(), static_cast<int>(at), MPI_BYTE, neighbors_[k], kTagChanged, comm_, &req[k]);
  }
  std::vector<char>& in = in_;
  for (std::size_t k = 0; k < nn; ++k) {
    const int count = receive_probed(comm_, neighbors_[k], kTagChanged, in);
    bytes_received_ += count;
    const std::vector<index_t>& rows = recv_rows_[k];
    const std::size_t mask_bytes = 8 * ((rows.size() + 63) / 64);
    std::size_t at = mask_bytes;
    if (in.size() < mask_bytes)
      throw RuntimeFailure("Halo: rank " + std::to_string(neighbors_[k]) + " sent " + std::to_string(count) +
                           " bytes of changed rows, less than the mask of " + std::to_string(rows.size()) + " rows");
    for (std::size_t j = 0; j < rows.size(); ++j) {
      if (!((static_cast<unsigned char>(in[j / 8]) >> (j % 8)) & 1u)) continue;
      if (at + 3 * sizeof(double) > in.size())
        throw RuntimeFailure("Halo: rank " + std::to_string(neighbors_[k]) + " sent too few changed rows");
      std::memcpy(xyz + 3 * static_cast<std::size_t>(rows[j]), in.data() + at, 3 * sizeof(double));
      at += 3 * sizeof(double);
    }
    if (at != in.size())
      throw RuntimeFailure("Halo: rank " + std::to_string(neighbors_[k]) + " sent " + std::to_string(in.size() - at) +
                           " bytes more than its changed rows");
  }
  MPI_Waitall(static_cast<int>(nn), req.data(), MPI_STATUSES_IGNORE);
}

std::vector<std::vector<char>> Halo::exchange_bytes(const std::vector<std::vector<char>>& send) {
  return exchange_with(neighbors_, send);
}

// One message per peer and direction, of any size up to 2^31 - 1 bytes: each peer's
// message is matched by a probe (MPI_Mprobe), so no separate round of sizes goes first.
// Between two ranks the exchanges come in the same order on both sides, and MPI keeps
// the order of messages of one tag between a pair, so each probe finds this exchange's.
std::vector<std::vector<char>> Halo::exchange_with(const std::vector<int>& peers,
                                                   const std::vector<std::vector<char>>& send) {
  SC_ASSERT(send.size() == peers.size());
  const std::size_t nn = peers.size();
  std::vector<std::vector<char>> recv(nn);
  if (nn == 0) return recv;
  ++rounds_;
  std::vector<MPI_Request> req(nn);
  for (std::size_t k = 0; k < nn; ++k) {
    if (send[k].size() > static_cast<std::size_t>(std::numeric_limits<int>::max()))
      throw RuntimeFailure("Halo: a message of " + std::to_string(send[k].size()) + " bytes to rank " +
                           std::to_string(peers[k]) + " is over MPI's 2^31 - 1 bytes per message");
    MPI_Isend(send[k].data(), static_cast<int>(send[k].size()), MPI_BYTE, peers[k], kTagData, comm_, &req[k]);
  }
  for (std::size_t k = 0; k < nn; ++k) bytes_received_ += receive_probed(comm_, peers[k], kTagData, recv[k]);
  MPI_Waitall(static_cast<int>(nn), req.data(), MPI_STATUSES_IGNORE);
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
