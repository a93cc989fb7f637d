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

// The next message from `peer` with `tag`, of whatever size (MPI_Mprobe), into `into`,
// resized to whole records of T (a buffer of that size already is not touched before the
// receive); returns its bytes.
template <class T>
int receive_probed(MPI_Comm comm, int peer, int tag, std::vector<T>& into) {
  MPI_Message msg;
  MPI_Status st;
  MPI_Mprobe(peer, tag, comm, &msg, &st);
  int count = 0;
  MPI_Get_count(&st, MPI_BYTE, &count);
  if (static_cast<std::size_t>(count) % sizeof(T) != 0) {
    std::vector<char> refused(static_cast<std::size_t>(count));  // received whole, so no receive is left pending
    MPI_Mrecv(refused.data(), count, MPI_BYTE, &msg, MPI_STATUS_IGNORE);
    throw RuntimeFailure("Halo: rank " + std::to_string(peer) + " sent " + std::to_string(count) + " bytes, not whole " +
                         std::to_string(sizeof(T)) + "-byte records");
  }
  into.resize(static_cast<std::size_t>(count) / sizeof(T));
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
  // every rank expects a list from each of its neighbours. Ghosts are whole objects, so
  // each list is whole owned objects, ascending, each in its rows' order: the holder
  // keeps the length of each object's run, the owner which objects the list names.
  const std::size_t nn = neighbors_.size();
  recv_rows_.assign(nn, {});
  recv_runs_.assign(nn, {});
  std::vector<std::vector<char>> want(nn);
  for (std::size_t i = no; i < n; ++i) {
    const auto at = std::lower_bound(neighbors_.begin(), neighbors_.end(), static_cast<int>(remote[i - no].rank));
    const auto k = static_cast<std::size_t>(at - neighbors_.begin());
    if (recv_rows_[k].empty() || w.vertex_object[static_cast<std::size_t>(recv_rows_[k].back())] != w.vertex_object[i])
      recv_runs_[k].push_back(0);
    ++recv_runs_[k].back();
    recv_rows_[k].push_back(static_cast<index_t>(i));
    const auto root = static_cast<index_t>(remote[i - no].index);
    const char* b = reinterpret_cast<const char*>(&root);
    want[k].insert(want[k].end(), b, b + sizeof(index_t));
  }
  const std::int64_t before = bytes_received_;
  const std::vector<std::vector<char>> asked = exchange_with(neighbors_, want);
  bytes_received_ = before;  // set-up traffic, not the halo's per-step figure
  // Each owned object that some neighbour holds is kept, compared and written into its
  // segment once, however many neighbours hold it: the owner's work and memory grow with
  // the rows held, not with the ranks that hold them.
  std::vector<index_t> held_of(w.layout.size(), -1);  // per object: its place in held_
  send_objects_.assign(nn, {});
  for (std::size_t k = 0; k < nn; ++k) {
    std::vector<index_t> rows(asked[k].size() / sizeof(index_t));
    std::memcpy(rows.data(), asked[k].data(), rows.size() * sizeof(index_t));
    for (std::size_t j = 0; j < rows.size();) {
      const index_t r = rows[j];
      if (r < 0 || static_cast<std::size_t>(r) >= no)
        throw RuntimeFailure("Halo: rank " + std::to_string(neighbors_[k]) + " asks for row " + std::to_string(r) +
                             " of " + std::to_string(no) + " owned rows");
      const int o = w.vertex_object[static_cast<std::size_t>(r)];
      const index_t first = w.vertex_offset[static_cast<std::size_t>(o)];
      const auto count = static_cast<std::size_t>(w.layout[static_cast<std::size_t>(o)].vertex_count);
      bool whole = r == first && j + count <= rows.size();
      for (std::size_t q = 0; whole && q < count; ++q) whole = rows[j + q] == first + static_cast<index_t>(q);
      if (!whole || (!send_objects_[k].empty() && held_[static_cast<std::size_t>(send_objects_[k].back())].first >= first))
        throw RuntimeFailure("Halo: rank " + std::to_string(neighbors_[k]) + " asks for rows that are not whole objects " +
                             "in ascending order (at row " + std::to_string(r) + ")");
      if (held_of[static_cast<std::size_t>(o)] < 0) {
        held_of[static_cast<std::size_t>(o)] = static_cast<index_t>(held_.size());
        held_.push_back({first, static_cast<index_t>(count), 0, 0});
      }
      send_objects_[k].push_back(held_of[static_cast<std::size_t>(o)]);
      j += count;
    }
  }
  std::size_t rows = 0, bytes = 0;
  for (HeldObject& h : held_) {
    h.kept = rows;
    h.segment = bytes;
    rows += static_cast<std::size_t>(h.rows);
    bytes += segment_capacity(static_cast<std::size_t>(h.rows));
  }
  held_rows_ = rows;
  segment_bytes_.assign(held_.size(), 0);
  segments_.resize(bytes);
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

std::size_t Halo::segment_mask_bytes(std::size_t rows) { return 8 * ((rows + 63) / 64); }
std::size_t Halo::segment_capacity(std::size_t rows) { return segment_mask_bytes(rows) + 3 * sizeof(double) * rows; }

void Halo::keep_sent(const double* xyz) {
  kept_.resize(3 * held_rows_);
  for (const HeldObject& h : held_)
    std::memcpy(&kept_[3 * h.kept], xyz + 3 * static_cast<std::size_t>(h.first),
                3 * sizeof(double) * static_cast<std::size_t>(h.rows));
  kept_valid_ = true;
}

void Halo::update_changed(double* xyz) {
  if (!kept_valid_) throw RuntimeFailure("Halo::update_changed without the rows of the last update (keep_sent)");
  const std::size_t nn = neighbors_.size();
  if (nn > 0) ++rounds_;
  // Each held object's segment, once: a bit per row (1: changed bitwise since the last
  // update), padded to whole doubles, then the changed rows; the kept rows become the
  // ones sent now. The segments stay from one update to the next, so only the masks are
  // cleared.
  for (std::size_t j = 0; j < held_.size(); ++j) {
    const HeldObject& h = held_[j];
    const auto nr = static_cast<std::size_t>(h.rows);
    char* m = segments_.data() + h.segment;
    const std::size_t mask_bytes = segment_mask_bytes(nr);
    std::memset(m, 0, mask_bytes);
    std::size_t at = mask_bytes;
    const double* now = xyz + 3 * static_cast<std::size_t>(h.first);
    double* kept = &kept_[3 * h.kept];
    for (std::size_t r = 0; r < nr; ++r, now += 3, kept += 3) {
      if (std::memcmp(now, kept, 3 * sizeof(double)) == 0) continue;
      std::memcpy(kept, now, 3 * sizeof(double));
      m[r / 8] = static_cast<char>(m[r / 8] | (1 << (r % 8)));
      std::memcpy(m + at, now, 3 * sizeof(double));
      at += 3 * sizeof(double);
    }
    segment_bytes_[j] = at;
  }
  // Each neighbour's message: the segments of the objects it holds, in its order, copied
  // whole into one buffer per neighbour, kept between updates. (Sent from where they
  // lie, by one MPI datatype of their places, it was slower: soft_floor on 4 ranks,
  // steps per second lower in 11 of 14 pairs, docs/benchmarks.md; a non-contiguous
  // message goes through Open MPI's shared-memory fragments, a contiguous one is copied
  // once.) A neighbour that holds one object gets its segment as it lies.
  out_.resize(nn);
  std::vector<MPI_Request> req(nn);
  for (std::size_t k = 0; k < nn; ++k) {
    const std::vector<index_t>& objs = send_objects_[k];
    std::size_t total = 0;
    for (index_t j : objs) total += segment_bytes_[static_cast<std::size_t>(j)];
    if (total > static_cast<std::size_t>(std::numeric_limits<int>::max()))
      throw RuntimeFailure("Halo: changed rows of " + std::to_string(total) + " bytes for rank " +
                           std::to_string(neighbors_[k]) + ", over MPI's 2^31 - 1 bytes per message");
    const char* data = nullptr;
    if (objs.size() == 1) {
      data = segments_.data() + held_[static_cast<std::size_t>(objs[0])].segment;
    } else if (!objs.empty()) {
      std::vector<char>& m = out_[k];
      if (m.size() < total) m.resize(total);
      std::size_t at = 0;
      for (index_t j : objs) {
        const std::size_t len = segment_bytes_[static_cast<std::size_t>(j)];
        std::memcpy(m.data() + at, segments_.data() + held_[static_cast<std::size_t>(j)].segment, len);
        at += len;
      }
      data = m.data();
    }
    MPI_Isend(data, static_cast<int>(total), MPI_BYTE, neighbors_[k], kTagChanged, comm_, &req[k]);
  }
  std::vector<char>& in = in_;
  for (std::size_t k = 0; k < nn; ++k) {
    const int count = receive_probed(comm_, neighbors_[k], kTagChanged, in);
    bytes_received_ += count;
    const std::vector<index_t>& rows = recv_rows_[k];
    std::size_t at = 0, row = 0;
    for (index_t run : recv_runs_[k]) {
      const auto nr = static_cast<std::size_t>(run);
      const std::size_t mask_bytes = segment_mask_bytes(nr);
      if (at + mask_bytes > in.size())
        throw RuntimeFailure("Halo: rank " + std::to_string(neighbors_[k]) + " sent " + std::to_string(count) +
                             " bytes of changed rows, too few for the masks of its objects' rows");
      const char* mask = in.data() + at;
      at += mask_bytes;
      for (std::size_t r = 0; r < nr; ++r) {
        if (!((static_cast<unsigned char>(mask[r / 8]) >> (r % 8)) & 1u)) continue;
        if (at + 3 * sizeof(double) > in.size())
          throw RuntimeFailure("Halo: rank " + std::to_string(neighbors_[k]) + " sent too few changed rows");
        std::memcpy(xyz + 3 * static_cast<std::size_t>(rows[row + r]), in.data() + at, 3 * sizeof(double));
        at += 3 * sizeof(double);
      }
      row += nr;
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
template <class T>
void Halo::exchange_records(const std::vector<int>& peers, const std::vector<std::vector<T>>& send,
                            std::vector<std::vector<T>>& recv) {
  SC_ASSERT(send.size() == peers.size());
  const std::size_t nn = peers.size();
  recv.resize(nn);
  if (nn == 0) return;
  ++rounds_;
  std::vector<MPI_Request> req(nn);
  for (std::size_t k = 0; k < nn; ++k) {
    const std::size_t bytes = send[k].size() * sizeof(T);
    if (bytes > static_cast<std::size_t>(std::numeric_limits<int>::max()))
      throw RuntimeFailure("Halo: a message of " + std::to_string(bytes) + " bytes to rank " +
                           std::to_string(peers[k]) + " is over MPI's 2^31 - 1 bytes per message");
    MPI_Isend(send[k].data(), static_cast<int>(bytes), MPI_BYTE, peers[k], kTagData, comm_, &req[k]);
  }
  for (std::size_t k = 0; k < nn; ++k) bytes_received_ += receive_probed(comm_, peers[k], kTagData, recv[k]);
  MPI_Waitall(static_cast<int>(nn), req.data(), MPI_STATUSES_IGNORE);
}

std::vector<std::vector<char>> Halo::exchange_with(const std::vector<int>& peers,
                                                   const std::vector<std::vector<char>>& send) {
  std::vector<std::vector<char>> recv;
  exchange_records(peers, send, recv);
  return recv;
}

void Halo::exchange_doubles(const std::vector<int>& peers, const std::vector<std::vector<double>>& send,
                            std::vector<std::vector<double>>& recv) {
  exchange_records(peers, send, recv);
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
