#pragma once
// Objects split over ranks for their internal forces (docs/architecture.md, "Objects
// split for their forces"). An object with more tets than an even share of the scene's
// (a soft floor under a pile, a membrane) would set the pace of the rank that owns it.
// Its tets are cut into parts (METIS on the object's dual graph; one per rank, or fewer
// when the object is only a few shares: split_part_count); each part's rank
// evaluates its tets at the positions (and velocities) the owner sends it, and
// sends the owner, per vertex, either the sum of its corner forces (a vertex whose tets
// are all in the part) or each corner force (a vertex on a cut). The owner folds every
// vertex's corner forces in ascending tet global id, as ElasticForces::add_forces does on
// one rank, so the forces, and every result after them, are bitwise those of one rank.
// A part on a rank that holds the object as a ghost (the whole object's x^t in its ghost
// rows, which the halo refreshes at the end of every step) reads its positions there,
// and the owner sends it only the velocities, where the stiffness damping needs them
// (set_ghost_holders): the same doubles, sent once.
//
// No MPI here: the messages go through NeighbourExchange::exchange_with. Ownership,
// state, detection, contact, output and checkpoints stay with the owner; only the force
// work is shared. Explicit integrators only (implicit Euler's linear system is the
// owner's).
#include <cstdint>
#include <memory>
#include <optional>
#include <vector>

#include "softcontact/scene.hpp"
#include "softcontact/world.hpp"

namespace softcontact {

class ElasticForces;
class NeighbourExchange;

/// Whether object k's internal forces are shared over ranks on `nranks` ranks:
/// `simulation.split_objects` on, an explicit integrator, a deformable object with more
/// tets than an even share of the scene's (tets * nranks > all tets), nranks > 1.
/// One object's test sums the scene's tets: a loop over objects takes split_mask.
bool split_candidate(const Scene& scene, std::size_t k, int nranks);
/// split_candidate of every object (1: a candidate), with the scene's tets summed once.
std::vector<char> split_mask(const Scene& scene, int nranks);
/// Every split candidate, ascending.
std::vector<int> split_candidates(const Scene& scene, int nranks);
/// How many parts a split object of `tets` tets is cut into on `nranks` ranks: parts of
/// about half an even share of the scene's `total_tets` (2 tets nranks / total_tets,
/// rounded up), at most one per rank. On up to 3 ranks, and whenever the object holds
/// more than 3/8 of the scene on 4, that is one part per rank; a membrane of 1 % on 1,000
/// ranks is cut into 20 parts, not 1,000, so its owner exchanges with 20 ranks.
int split_part_count(std::int64_t tets, std::int64_t total_tets, int nranks);

/// One part of a split object as its host needs it: the part's tets and their vertices,
/// none of the rest of the object's mesh. The owner cuts every other host's
/// (cut_split_parts) and sends it (Simulator::share_split_parts), whether or not the host
/// holds the mesh; its own part it cuts itself.
struct SplitPartMesh {
  std::vector<std::int32_t> verts;   ///< object-local ids of the part's tets' vertices, ascending
  std::vector<double> points;        ///< their rest positions, 3 each
  std::vector<char> fold;            ///< per vertex: 1 when every tet of the vertex is in the part
  std::vector<std::int32_t> tets;    ///< the part's tets, object-local ids, ascending
  std::vector<index_t> corners;      ///< 4 per tet: positions in verts
};

/// Per vertex of m: the part (a value of tet_part, one per tet) holding all its tets, or -1
/// when its tets lie in several parts (or it has none).
std::vector<std::int32_t> split_interior_parts(const TetMesh& m, const std::vector<std::int32_t>& tet_part);
/// The tets t of m with tet_part[t] == part and their vertices; `interior` from
/// split_interior_parts(m, tet_part).
SplitPartMesh cut_split_part(const TetMesh& m, const std::vector<std::int32_t>& tet_part,
                             const std::vector<std::int32_t>& interior, std::int32_t part);
/// cut_split_part for each of `parts` (distinct), in one pass over m's tets.
std::vector<SplitPartMesh> cut_split_parts(const TetMesh& m, const std::vector<std::int32_t>& tet_part,
                                           const std::vector<std::int32_t>& interior,
                                           const std::vector<std::int32_t>& parts);
/// What the owner sends a host for its part, and the part the host makes of it: the
/// number of the part's tets, the tets, the part's vertices, then its tets' corners
/// (positions among the vertices), as one list (part_indices; part_from_indices checks it
/// and leaves `points` and `fold` empty)...
std::vector<std::int32_t> part_indices(const SplitPartMesh& part);
SplitPartMesh part_from_indices(const std::vector<std::int32_t>& indices);
/// ...then per vertex its rest position and fold flag (4 doubles: x, y, z, 1 or 0), set by
/// set_part_vertex_data, which checks the count.
std::vector<double> part_vertex_data(const SplitPartMesh& part);
void set_part_vertex_data(SplitPartMesh& part, const std::vector<double>& data);

/// One split object: its owner and, on the owner, the rank evaluating each of its tets
/// (its part's host, split_hosts in rebalance.hpp); on another host its part, as the owner
/// sent it. A rank with neither takes no part and needs no mesh.
struct SplitObject {
  int object = 0;
  int owner = 0;
  std::vector<std::int32_t> tet_part;   ///< owner: per object tet (object-local order), in [0, ranks)
  std::optional<SplitPartMesh> part;    ///< another host: its part
};

class SplitForces {
public:
  /// `plan`: every split object (the same list on every rank), ascending. Builds this
  /// rank's part of each (its tets' rest data: from the part the owner sent, or on the
  /// owner from the object's mesh) and, for the objects it owns, the merge (each
  /// vertex's incident tets and their parts, each part's vertices).
  SplitForces(const Scene& scene, const World& w, std::vector<SplitObject> plan);
  ~SplitForces();
  SplitForces(const SplitForces&) = delete;
  SplitForces& operator=(const SplitForces&) = delete;

  /// The split objects this rank owns (their forces come from add(), not ElasticForces).
  const std::vector<int>& owned_objects() const { return owned_; }
  /// Sends each part the positions (and, for the stiffness damping, the velocities) of
  /// its vertices, evaluates this rank's parts, sends their corner forces to the owners,
  /// and adds the owned split objects' internal forces (and -alpha m v) to f. Two
  /// exchanges with the peers (the ranks this rank shares a split object with),
  /// collective over them; every rank of a run with a split object calls it.
  /// evaluate() then merge().
  void add(const World& w, std::vector<double>& f, bool damping, NeighbourExchange* exchange);
  /// add()'s first part: the two exchanges and this rank's parts, the forces for the
  /// owned split objects kept for merge(). Collective over the peers. Called before the
  /// rank's other internal forces, so that both exchanges come around work of equal size
  /// on every rank (the parts) and the uneven rest of the forces phase waits for nothing.
  void evaluate(const World& w, bool damping, NeighbourExchange* exchange);
  /// add()'s second part: the owned split objects' forces into f, after evaluate(). Local;
  /// it touches only the split objects' vertices, so it may come before or after the
  /// other objects' forces with the same bits.
  void merge(const World& w, std::vector<double>& f, bool damping);

  /// Which ranks hold each split object as a ghost: held[r * plan size + i] for rank r and
  /// the i-th object of the plan (the same vector on every rank). Such a rank's part reads
  /// the object's positions from its ghost rows, which the halo fills with x^t from the
  /// owner at the end of every step, and its owner stops sending them (the velocities are
  /// still sent where the stiffness damping needs them: ghosts carry no velocities). To be
  /// called again, on every rank, after every change of the ghost sets and before the
  /// next evaluate(); until the first call every part's positions are sent.
  void set_ghost_holders(const std::vector<char>& held);
  /// This rank's parts of other ranks' objects (with tets), and of those the ones that read
  /// their positions from ghost rows.
  int helping_parts() const;
  int parts_from_ghosts() const;

  /// Doubles this rank has sent so far (states to parts, forces to owners).
  std::int64_t doubles_sent() const { return doubles_sent_; }
  /// Tets this rank evaluates for objects it does not own.
  std::int64_t helped_tets() const { return helped_tets_; }
  /// Tets this rank evaluates for split objects, its own included.
  std::int64_t evaluated_tets() const { return evaluated_tets_; }
  /// Wall and process CPU seconds spent in add()'s exchanges so far (waiting for the
  /// other parts is communication, not force work: the rebalance must not charge it).
  double exchange_wall_seconds() const { return exchange_wall_; }
  double exchange_cpu_seconds() const { return exchange_cpu_; }

private:
  struct Part;
  struct Merge;
  std::size_t peer_index(int r, int object) const;
  void timed_exchange(NeighbourExchange* exchange, std::vector<std::vector<double>>& recv);

  std::vector<std::unique_ptr<Part>> parts_;    // ascending object
  std::vector<std::unique_ptr<Merge>> merges_;  // ascending object: the owned split objects
  std::vector<int> owned_;
  std::vector<int> peers_;                      // ascending
  // evaluate()'s messages, per peer, kept from one step to the next (the exchanges of a
  // step have the same sizes as the last step's, so they allocate and zero nothing): what
  // this rank sends, the states the owners sent its parts, and the forces the parts sent
  // for its owned objects (read by merge()).
  std::vector<std::vector<double>> send_, state_in_, forces_in_;
  bool evaluated_ = false;
  std::int64_t doubles_sent_ = 0;
  std::int64_t helped_tets_ = 0, evaluated_tets_ = 0;
  double exchange_wall_ = 0, exchange_cpu_ = 0;
};

}  // namespace softcontact
