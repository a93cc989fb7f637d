#pragma once
// Memory known before the run (docs/reliability.md, "Memory"): an estimate of the peak
// resident memory per rank from the scene's tets and vertices, the limits it must fit
// (the rank's address-space limit, the node's memory shared by its ranks), and the peak
// a run actually reached.
#include <mpi.h>

#include <cstdint>
#include <string>

#include "softcontact/scene.hpp"

namespace softcontact {

/// The estimate of one rank's peak resident memory [bytes] on `nranks` ranks.
struct MemoryEstimate {
  double per_rank = 0;            ///< fixed + scene (on every rank) + owned share
  double fixed = 0;               ///< MPI, PETSc, HDF5 and the program itself
  std::int64_t tets = 0, vertices = 0;              ///< the whole scene
  std::int64_t rank_tets = 0, rank_vertices = 0;    ///< the largest share of one rank
};

/// The model, fitted to measured peaks (docs/reliability.md, "Memory"): every rank holds
/// the meshes of the single-copy entries and a record of every object, and the simulation
/// state of the objects it owns (copies of multi-copy entries only where owned or
/// ghosted). Objects are never split for their state, so a rank's share is at least the
/// largest object (the parts of objects split for their forces are not counted).
MemoryEstimate estimate_memory(const Scene& scene, int nranks);

/// The model's share for owned state [bytes]: what the owner of `tets` tets and `vertices`
/// vertices holds for them (forces, collision, contact, output), beyond what every rank
/// holds. estimate_memory's owned share, and the memory weight of the partition
/// (rebalance.cpp, partition_at).
double owned_state_bytes(double tets, double vertices);

/// What this rank may use [bytes]: its address-space limit (RLIMIT_AS, 0 when none) and
/// the node's available memory divided by the ranks on the node (0 when unknown).
struct MemoryLimits {
  double address_space = 0;
  double node_share = 0;
  double node_available = 0;
  int ranks_on_node = 1;
};
/// Collective (counts the ranks on this node).
MemoryLimits memory_limits(MPI_Comm comm);

/// The address space a run of estimate `e` needs [bytes]: the estimate plus what this
/// process has mapped beyond its resident memory (libraries, MPI's shared segments).
double address_space_needed(const MemoryEstimate& e);

/// Throws InputError, on every rank, when the estimate exceeds this rank's address-space
/// limit (with the process's address-space overhead added) or its share of the node's
/// memory on any rank: both figures and what to try. Collective.
void check_memory_fits(MPI_Comm comm, const MemoryEstimate& e, const std::string& where);

/// The peak resident memory of this process so far [bytes] (VmHWM).
double peak_rss_bytes();
/// The process's current and peak virtual size [bytes] (VmSize, VmPeak).
double virtual_size_bytes();
/// Bytes the C heap has handed out and not taken back, all arenas (glibc's mallinfo2:
/// blocks in use plus mmapped ones); -1 where the C library cannot tell (another C library,
/// or an allocator that replaces glibc's, such as AddressSanitizer's). Unlike the
/// resident size it counts neither freed blocks the heap keeps nor MPI's shared segments,
/// so a difference between two calls is what the code between them still holds.
double heap_in_use_bytes();

/// "1.23 GiB", "456 MiB".
std::string format_bytes(double bytes);

}  // namespace softcontact
