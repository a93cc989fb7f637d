#pragma once
// Halo exchange between ranks (design.md, "Parallel shape"; docs/architecture.md).
//
// A rank holds its owned objects and, as ghosts, whole objects of other ranks that lie
// within reach of its own (World::ghost_objects). Two patterns move data:
//
//  - Halo::update: owner -> ghost copies of per-vertex data (positions), a PetscSF
//    broadcast whose roots are the owned vertices and whose leaves are the ghost
//    vertices. The graph changes only when the ghost set does.
//  - exchange_bytes: sparse messages between neighbour ranks (the owners of this rank's
//    ghosts, which are also the ranks that hold this rank's objects as ghosts: "within
//    reach" is symmetric). The contact response sends its per-vertex contributions this
//    way, with the keys that let the owner add them in global collision order; PetscSF's
//    reduce would add them in arrival order, which depends on the rank count. One
//    message per peer and direction: the receiver probes for its size (MPI_Mprobe).
#include <mpi.h>

#include <cstdint>
#include <vector>

#include "softcontact/exchange.hpp"
#include "softcontact/world.hpp"

namespace softcontact {

/// Local index of each object's first vertex on its owner (owned objects ascending,
/// contiguous, as build_world lays them out), from the global layout alone.
std::vector<index_t> owner_vertex_offsets(const World& w);

class Halo final : public NeighbourExchange {
public:
  /// Collective over `comm`: builds the broadcast graph of w's ghost vertices.
  Halo(MPI_Comm comm, const World& w);
  ~Halo();
  Halo(const Halo&) = delete;
  Halo& operator=(const Halo&) = delete;

  /// Copies the owners' rows of `xyz` (n_local,3) into the ghost rows. Forgets what
  /// keep_sent() kept (the array may be another one). Collective.
  void update(double* xyz);
  /// Keeps the owned rows of `xyz` that the neighbours' ghosts hold, as update() has just
  /// sent them, for update_changed().
  void keep_sent(const double* xyz);
  bool has_kept() const { return kept_valid_; }
  /// update()'s result when the ghost rows hold what is kept: each owner sends a
  /// neighbour only the rows that differ from it bitwise (per object the neighbour holds,
  /// in ascending order: a bit per row, padded to whole doubles, then those rows), and
  /// the other rows stay as they are; then keeps the rows sent, so that updates of the
  /// same array can follow one another. One message each way per neighbour; each
  /// object's segment is written once, whatever the neighbours that hold it. Collective
  /// over the neighbours.
  void update_changed(double* xyz);
  /// Owned rows kept for update_changed: each row that some neighbour holds, once, however
  /// many neighbours hold it (an object ghosted on every rank is kept once, not once per
  /// rank); 0 until keep_sent.
  std::size_t kept_rows() const { return kept_valid_ ? held_rows_ : 0; }

  // NeighbourExchange (exchange.hpp), over `comm`.
  const std::vector<int>& neighbors() const override { return neighbors_; }
  std::vector<std::vector<char>> exchange_bytes(const std::vector<std::vector<char>>& send) override;
  std::vector<std::vector<char>> exchange_with(const std::vector<int>& peers,
                                               const std::vector<std::vector<char>>& send) override;
  void exchange_doubles(const std::vector<int>& peers, const std::vector<std::vector<double>>& send,
                        std::vector<std::vector<double>>& recv) override;
  int rank() const override { return rank_; }
  int ranks() const override { return ranks_; }
  std::vector<std::vector<char>> gather_to_root(const std::vector<char>& mine) override;
  std::vector<char> scatter_from_root(const std::vector<std::vector<char>>& parts, std::size_t my_bytes) override;
  void broadcast_from_root(void* data, std::size_t bytes) override;

  MPI_Comm comm() const { return comm_; }

  /// Bytes this rank has received since construction (broadcasts and exchanges).
  std::int64_t bytes_received() const { return bytes_received_; }
  /// Rounds of messages with neighbours or peers since construction (each broadcast,
  /// update and exchange with at least one of them): the waits a step's latency adds up.
  std::int64_t rounds() const { return rounds_; }

private:
  MPI_Comm comm_;
  int rank_ = 0, ranks_ = 1;
  void* sf_ = nullptr;  // PetscSF
  MPI_Datatype xyz_type_ = MPI_DATATYPE_NULL;
  std::vector<int> neighbors_;
  // update_changed. Holder: per neighbour, this rank's ghost rows that neighbour owns, in
  // ghost-row order, and the length of each object's run in them. Owner: each owned
  // object some neighbour holds, once (its first row, rows, place in kept_ in rows, and
  // place of its segment in segments_), and per neighbour the objects it holds, in its
  // order (places in held_).
  std::vector<std::vector<index_t>> recv_rows_, recv_runs_;
  struct HeldObject {
    index_t first, rows;
    std::size_t kept, segment;
  };
  std::vector<HeldObject> held_;
  std::vector<std::vector<index_t>> send_objects_;
  std::size_t held_rows_ = 0;
  std::vector<double> kept_;                // the held objects' rows as last sent (3 per row)
  std::vector<char> segments_;              // each held object's message segment, sized for all its rows
  std::vector<std::size_t> segment_bytes_;  // per held object: its segment's bytes in this update
  std::vector<std::vector<char>> out_;      // per neighbour holding several objects: its message
  std::vector<char> in_;                    // update_changed's receive buffer
  static std::size_t segment_mask_bytes(std::size_t rows);
  static std::size_t segment_capacity(std::size_t rows);
  template <class T>
  void exchange_records(const std::vector<int>& peers, const std::vector<std::vector<T>>& send,
                        std::vector<std::vector<T>>& recv);
  bool kept_valid_ = false;
  std::int64_t ghost_rows_ = 0;
  std::int64_t bytes_received_ = 0;
  std::int64_t rounds_ = 0;
};

}  // namespace softcontact
