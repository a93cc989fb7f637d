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
//    reduce would add them in arrival order, which depends on the rank count.
#include <mpi.h>

#include <cstdint>
#include <cstring>
#include <vector>

#include "softcontact/world.hpp"

namespace softcontact {

/// Local index of each object's first vertex on its owner (owned objects ascending,
/// contiguous, as build_world lays them out), from the global layout alone.
std::vector<index_t> owner_vertex_offsets(const World& w);

class Halo {
public:
  /// Collective over `comm`: builds the broadcast graph of w's ghost vertices.
  Halo(MPI_Comm comm, const World& w);
  ~Halo();
  Halo(const Halo&) = delete;
  Halo& operator=(const Halo&) = delete;

  /// Copies the owners' rows of `xyz` (n_local,3) into the ghost rows. Collective.
  void update(double* xyz);

  /// Ranks this rank exchanges with, ascending (empty on one rank).
  const std::vector<int>& neighbors() const { return neighbors_; }

  /// Sends send[k] to neighbors()[k] and returns what each neighbour sent, in the same
  /// order. Collective over the neighbours (every neighbour must call it too).
  std::vector<std::vector<char>> exchange_bytes(const std::vector<std::vector<char>>& send);

  MPI_Comm comm() const { return comm_; }

  /// Bytes this rank has received since construction (broadcasts and exchanges).
  std::int64_t bytes_received() const { return bytes_received_; }

private:
  MPI_Comm comm_;
  void* sf_ = nullptr;  // PetscSF
  MPI_Datatype xyz_type_ = MPI_DATATYPE_NULL;
  std::vector<int> neighbors_;
  std::int64_t ghost_rows_ = 0;
  std::int64_t bytes_received_ = 0;
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
