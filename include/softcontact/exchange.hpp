#pragma once
// What the physics needs from the parallel layer, without MPI (docs/architecture.md,
// "Layers"): sparse messages between neighbour ranks, and a gather of every rank's rows
// to rank 0 and back (the coupled closure's direct solve). The contact response's
// cross-rank sums are written against this interface; parallel/halo.cpp implements it
// over MPI (Halo), and a null pointer means one rank: every contribution is local and
// the sums fold in place.
#include <cstddef>
#include <cstring>
#include <vector>

namespace softcontact {

class NeighbourExchange {
public:
  virtual ~NeighbourExchange() = default;

  /// Ranks this rank exchanges with, ascending (empty on one rank).
  virtual const std::vector<int>& neighbors() const = 0;
  /// Sends send[k] to neighbors()[k] and returns what each neighbour sent, in the same
  /// order. Collective over the neighbours (every neighbour must call it too).
  virtual std::vector<std::vector<char>> exchange_bytes(const std::vector<std::vector<char>>& send) = 0;
  /// Sends send[k] to peers[k] (ascending, any ranks but this one) and returns what each
  /// peer sent, in the same order. Collective over the peers: each must list this rank.
  /// (Objects split for their forces, split_forces.hpp, exchange with ranks that need not
  /// be neighbours.) An exchange without it throws.
  virtual std::vector<std::vector<char>> exchange_with(const std::vector<int>& peers,
                                                       const std::vector<std::vector<char>>& send);
  /// exchange_with for messages of doubles, into buffers the caller keeps from one call
  /// to the next: recv[k] is resized to what peers[k] sent, so a buffer of that size
  /// already is neither reallocated nor cleared (a step's exchanges of the same sizes
  /// allocate and zero nothing). An exchange without it throws, as for exchange_with.
  virtual void exchange_doubles(const std::vector<int>& peers, const std::vector<std::vector<double>>& send,
                                std::vector<std::vector<double>>& recv);

  /// This rank, and the number of ranks, of the communicator.
  virtual int rank() const = 0;
  virtual int ranks() const = 0;
  /// Collective: rank 0 receives every rank's `mine`, in rank order; the others get an
  /// empty list.
  virtual std::vector<std::vector<char>> gather_to_root(const std::vector<char>& mine) = 0;
  /// Collective: rank 0 sends parts[r] to rank r (parts is ignored elsewhere); returns
  /// this rank's part, whose size (`my_bytes`) the caller knows.
  virtual std::vector<char> scatter_from_root(const std::vector<std::vector<char>>& parts, std::size_t my_bytes) = 0;
  /// Collective: rank 0's `bytes` bytes at `data` to every rank.
  virtual void broadcast_from_root(void* data, std::size_t bytes) = 0;
};

/// Packs trivially copyable records into a byte buffer and back.
template <class T>
void append_records(std::vector<char>& buf, const T* rec, std::size_t n) {
  const std::size_t at = buf.size();
  buf.resize(at + n * sizeof(T));
  if (n) std::memcpy(buf.data() + at, rec, n * sizeof(T));
}
template <class T>
std::vector<T> read_records(const std::vector<char>& buf) {
  std::vector<T> out(buf.size() / sizeof(T));
  if (!out.empty()) std::memcpy(out.data(), buf.data(), out.size() * sizeof(T));
  return out;
}

}  // namespace softcontact
