// Objects split over ranks for their internal forces (split_forces.hpp).
#include "softcontact/split_forces.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <limits>
#include <string>

#include "softcontact/error.hpp"
#include "softcontact/exchange.hpp"
#include "softcontact/forces.hpp"
#include "softcontact/phase_times.hpp"

namespace softcontact {

namespace {
bool candidate_of(const Scene& scene, std::size_t k, int nranks, double total_tets) {
  if (nranks <= 1 || !scene.sim.split_objects || scene.sim.integrator == IntegratorKind::implicit_euler ||
      scene.objects[k].kinematic())
    return false;
  return static_cast<double>(scene.shape(k).tets) * nranks > total_tets;
}
}  // namespace

bool split_candidate(const Scene& scene, std::size_t k, int nranks) {
  return candidate_of(scene, k, nranks, static_cast<double>(scene.num_tets()));
}

std::vector<char> split_mask(const Scene& scene, int nranks) {
  std::vector<char> mask(scene.objects.size(), 0);
  if (nranks <= 1 || !scene.sim.split_objects) return mask;
  const double total = static_cast<double>(scene.num_tets());
  for (std::size_t k = 0; k < mask.size(); ++k) mask[k] = candidate_of(scene, k, nranks, total) ? 1 : 0;
  return mask;
}

std::vector<int> split_candidates(const Scene& scene, int nranks) {
  const std::vector<char> mask = split_mask(scene, nranks);
  std::vector<int> out;
  for (std::size_t k = 0; k < mask.size(); ++k)
    if (mask[k]) out.push_back(static_cast<int>(k));
  return out;
}

int split_part_count(std::int64_t tets, std::int64_t total_tets, int nranks) {
  if (nranks <= 1 || tets <= 0 || total_tets <= 0) return 1;
  // ceil(2 tets nranks / total): exact in 64-bit integers where the product fits (any
  // object below 2^62 / nranks tets), else in long double (the same on every rank).
  const std::int64_t twice = 2 * std::min(tets, total_tets);
  if (twice <= std::numeric_limits<std::int64_t>::max() / nranks) {
    const std::int64_t t = twice * nranks;
    return static_cast<int>(std::min<std::int64_t>(t / total_tets + (t % total_tets != 0 ? 1 : 0), nranks));
  }
  const long double parts = std::ceil(static_cast<long double>(twice) * nranks / static_cast<long double>(total_tets));
  return parts >= static_cast<long double>(nranks) ? nranks : static_cast<int>(parts);
}

namespace {

// Each vertex's incident tets (object-local ids, ascending): a CSR.
struct Incidence {
  std::vector<std::int64_t> offset;
  std::vector<std::int32_t> tet;
};

Incidence incidence_of(const TetMesh& m) {
  Incidence inc;
  const std::size_t nv = m.num_vertices(), nt = m.num_tets();
  inc.offset.assign(nv + 1, 0);
  for (index_t v : m.tets) ++inc.offset[static_cast<std::size_t>(v) + 1];
  for (std::size_t i = 0; i < nv; ++i) inc.offset[i + 1] += inc.offset[i];
  inc.tet.resize(static_cast<std::size_t>(inc.offset.back()));
  std::vector<std::int64_t> fill(inc.offset.begin(), inc.offset.end() - 1);
  for (std::size_t t = 0; t < nt; ++t)
    for (int c = 0; c < 4; ++c) inc.tet[static_cast<std::size_t>(fill[static_cast<std::size_t>(m.tets[4 * t + c])]++)] =
        static_cast<std::int32_t>(t);
  return inc;
}

// Per vertex: the part holding all its tets, or -1 when its tets lie in several parts
// (or it has none).
std::vector<std::int32_t> interior_parts(const Incidence& inc, const std::vector<std::int32_t>& tet_part) {
  const std::size_t nv = inc.offset.size() - 1;
  std::vector<std::int32_t> out(nv, -1);
  for (std::size_t i = 0; i < nv; ++i) {
    const std::int64_t b = inc.offset[i], e = inc.offset[i + 1];
    if (b == e) continue;
    const std::int32_t p = tet_part[static_cast<std::size_t>(inc.tet[static_cast<std::size_t>(b)])];
    bool one = true;
    for (std::int64_t k = b + 1; k < e && one; ++k) one = tet_part[static_cast<std::size_t>(inc.tet[static_cast<std::size_t>(k)])] == p;
    if (one) out[i] = p;
  }
  return out;
}

}  // namespace

std::vector<std::int32_t> split_interior_parts(const TetMesh& m, const std::vector<std::int32_t>& tet_part) {
  if (tet_part.size() != m.num_tets()) throw RuntimeFailure("split_interior_parts: a part per tet expected");
  return interior_parts(incidence_of(m), tet_part);
}

std::vector<SplitPartMesh> cut_split_parts(const TetMesh& m, const std::vector<std::int32_t>& tet_part,
                                           const std::vector<std::int32_t>& interior,
                                           const std::vector<std::int32_t>& parts) {
  if (tet_part.size() != m.num_tets() || interior.size() != m.num_vertices())
    throw RuntimeFailure("cut_split_parts: a part per tet and a flag per vertex expected");
  // One pass over the tets puts each into its part's list (slot: a part's place in
  // `parts`), so that cutting P parts costs one pass over the mesh, not P; then per part
  // its distinct vertices, found with a stamp per vertex of the mesh and sorted.
  std::int32_t top = -1;
  for (std::int32_t q : parts) top = std::max(top, q);
  std::vector<std::int32_t> slot(static_cast<std::size_t>(top + 1), -1);
  for (std::size_t i = 0; i < parts.size(); ++i) {
    if (parts[i] < 0 || slot[static_cast<std::size_t>(parts[i])] >= 0)
      throw RuntimeFailure("cut_split_parts: parts must be distinct and not negative");
    slot[static_cast<std::size_t>(parts[i])] = static_cast<std::int32_t>(i);
  }
  std::vector<SplitPartMesh> out(parts.size());
  for (std::size_t t = 0; t < m.num_tets(); ++t) {
    const std::int32_t q = tet_part[t];
    if (q >= 0 && q <= top && slot[static_cast<std::size_t>(q)] >= 0)
      out[static_cast<std::size_t>(slot[static_cast<std::size_t>(q)])].tets.push_back(static_cast<std::int32_t>(t));
  }
  std::vector<index_t> at(m.num_vertices(), -1);  // a vertex's place in the part being cut
  for (std::size_t i = 0; i < parts.size(); ++i) {
    SplitPartMesh& p = out[i];
    for (std::int32_t t : p.tets)
      for (int c = 0; c < 4; ++c) {
        const index_t v = m.tets[4 * static_cast<std::size_t>(t) + static_cast<std::size_t>(c)];
        if (at[static_cast<std::size_t>(v)] < 0) {
          at[static_cast<std::size_t>(v)] = 0;
          p.verts.push_back(v);
        }
      }
    std::sort(p.verts.begin(), p.verts.end());
    p.points.reserve(3 * p.verts.size());
    p.fold.reserve(p.verts.size());
    for (std::size_t j = 0; j < p.verts.size(); ++j) {
      const auto v = static_cast<std::size_t>(p.verts[j]);
      at[v] = static_cast<index_t>(j);
      p.points.insert(p.points.end(), &m.points[3 * v], &m.points[3 * v] + 3);
      p.fold.push_back(interior[v] == parts[i] ? 1 : 0);
    }
    p.corners.reserve(4 * p.tets.size());
    for (std::int32_t t : p.tets)
      for (int c = 0; c < 4; ++c)
        p.corners.push_back(at[static_cast<std::size_t>(m.tets[4 * static_cast<std::size_t>(t) + static_cast<std::size_t>(c)])]);
    for (std::int32_t v : p.verts) at[static_cast<std::size_t>(v)] = -1;
  }
  return out;
}

SplitPartMesh cut_split_part(const TetMesh& m, const std::vector<std::int32_t>& tet_part,
                             const std::vector<std::int32_t>& interior, std::int32_t part) {
  return std::move(cut_split_parts(m, tet_part, interior, {part}).front());
}

std::vector<std::int32_t> part_indices(const SplitPartMesh& part) {
  std::vector<std::int32_t> out;
  out.reserve(1 + part.tets.size() + part.verts.size() + part.corners.size());
  out.push_back(static_cast<std::int32_t>(part.tets.size()));
  out.insert(out.end(), part.tets.begin(), part.tets.end());
  out.insert(out.end(), part.verts.begin(), part.verts.end());
  out.insert(out.end(), part.corners.begin(), part.corners.end());
  return out;
}

std::vector<double> part_vertex_data(const SplitPartMesh& part) {
  std::vector<double> out;
  out.reserve(4 * part.verts.size());
  for (std::size_t i = 0; i < part.verts.size(); ++i) {
    out.insert(out.end(), &part.points[3 * i], &part.points[3 * i] + 3);
    out.push_back(part.fold[i] ? 1.0 : 0.0);
  }
  return out;
}

SplitPartMesh part_from_indices(const std::vector<std::int32_t>& indices) {
  const std::int64_t nt = indices.empty() ? -1 : indices[0];
  if (nt < 0 || static_cast<std::uint64_t>(indices.size()) < 1 + 5 * static_cast<std::uint64_t>(nt))
    throw RuntimeFailure("part_from_indices: " + std::to_string(indices.size()) + " indices for " + std::to_string(nt) +
                         " tets (the count, then the tets, the vertices and 4 corners per tet expected)");
  const auto t = static_cast<std::size_t>(nt);
  const std::size_t nv = indices.size() - 1 - 5 * t;
  SplitPartMesh out;
  const auto at = [&](std::size_t i) { return indices.begin() + static_cast<std::ptrdiff_t>(i); };
  out.tets.assign(at(1), at(1 + t));
  out.verts.assign(at(1 + t), at(1 + t + nv));
  out.corners.assign(at(1 + t + nv), indices.end());
  for (std::size_t e = 0; e < t; ++e)
    if (out.tets[e] < 0 || (e > 0 && out.tets[e] <= out.tets[e - 1]))
      throw RuntimeFailure("part_from_indices: the tets are not ascending");
  for (std::size_t j = 0; j < nv; ++j)
    if (out.verts[j] < 0 || (j > 0 && out.verts[j] <= out.verts[j - 1]))
      throw RuntimeFailure("part_from_indices: the vertices are not ascending");
  for (index_t c : out.corners)
    if (c < 0 || static_cast<std::size_t>(c) >= nv)
      throw RuntimeFailure("part_from_indices: corner " + std::to_string(c) + " of " + std::to_string(nv) + " vertices");
  return out;
}

void set_part_vertex_data(SplitPartMesh& part, const std::vector<double>& data) {
  if (data.size() != 4 * part.verts.size())
    throw RuntimeFailure("set_part_vertex_data: " + std::to_string(data.size()) + " doubles for " +
                         std::to_string(part.verts.size()) + " vertices (4 each expected)");
  part.points.resize(3 * part.verts.size());
  part.fold.resize(part.verts.size());
  for (std::size_t i = 0; i < part.verts.size(); ++i) {
    for (int d = 0; d < 3; ++d) part.points[3 * i + static_cast<std::size_t>(d)] = data[4 * i + static_cast<std::size_t>(d)];
    part.fold[i] = data[4 * i + 3] != 0 ? 1 : 0;
  }
}

namespace {

// The rows first + j of xyz (3 doubles each) for every j of `rows`, appended to buf.
void append_rows(std::vector<double>& buf, const std::vector<double>& xyz, std::size_t first,
                 const std::vector<std::int32_t>& rows) {
  const std::size_t at = buf.size();
  buf.resize(at + 3 * rows.size());
  double* out = buf.data() + at;
  for (std::int32_t j : rows) {
    const double* row = &xyz[3 * (first + static_cast<std::size_t>(j))];
    out[0] = row[0];
    out[1] = row[1];
    out[2] = row[2];
    out += 3;
  }
}

double wall_seconds() { return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count(); }

}  // namespace

// This rank's part of one split object: its tets as a World of their own (the part's
// vertices, ascending global id), with the forces' rest data.
struct SplitForces::Part {
  int object = 0, owner = 0;
  std::size_t first = 0;           // the owner's local row of the object's first vertex (owner only)
  bool needs_v = false;            // stiffness damping: the part needs the velocities
  bool from_ghost = false;         // positions from this rank's ghost rows of the object (not owner)
  World mini;
  std::unique_ptr<ElasticForces> forces;
  std::vector<std::int32_t> verts; // mini vertex -> object-local vertex
  std::vector<char> fold;          // mini vertex: all its tets are in this part (send their sum)
  std::vector<std::size_t> offset; // mini vertex: where its corner forces start in the stream
  std::size_t stream_doubles = 0;  // the stream's length (write_vertex_corners over verts)
  std::vector<double> stream;      // this step's corner forces for the owner
};

// An owned split object: each vertex's incident tets and their parts, to fold the parts'
// streams in tet order, and each part's vertices, to send it their state.
struct SplitForces::Merge {
  int object = 0;
  std::size_t first = 0;           // local row of the object's first vertex
  double alpha = 0;                // Rayleigh mass damping of its material
  bool send_v = false;             // the material has stiffness damping
  Incidence inc;
  std::vector<std::int32_t> tet_part, interior;
  std::vector<std::vector<std::int32_t>> part_vertices;  // per part (= rank): its vertices, ascending
  std::vector<std::size_t> part_doubles;                 // per part (= rank): the doubles of its stream
  std::vector<char> holds;         // per part (= rank): it holds the object as a ghost (no positions sent)
  std::vector<double> sums;        // merge(): each vertex's corner forces folded in tet order
};

SplitForces::SplitForces(const Scene& scene, const World& w, std::vector<SplitObject> plan) {
  for (SplitObject& so : plan) {
    const auto k = static_cast<std::size_t>(so.object);
    if (so.owner != w.rank && !so.part) {
      // No part of it here: an idle entry (the plan's order), no mesh needed.
      auto p = std::make_unique<Part>();
      p->object = so.object;
      p->owner = so.owner;
      p->mini.rank = w.rank;
      parts_.push_back(std::move(p));
      continue;
    }
    const ObjectLayout& L = w.layout[k];
    const bool own = so.owner == w.rank;
    if (L.rank != so.owner || (own && (so.part || so.tet_part.size() != static_cast<std::size_t>(L.tet_count))))
      throw RuntimeFailure("SplitForces: the plan of object " + std::to_string(k) + " does not match the scene");
    if (own && w.vertex_offset[k] < 0) throw RuntimeFailure("SplitForces: object " + std::to_string(k) + " is not here");
    const bool needs_v = scene.materials[scene.objects[k].material].damping_stiffness > 0;

    // This rank's part: sent by the owner, or, on the owner, cut from the mesh, with the
    // merge made from the whole mesh.
    std::unique_ptr<Merge> g;
    SplitPartMesh cut;
    if (!own) {
      cut = std::move(*so.part);
    } else {
      const Scene::MeshView view = scene.view_mesh(k);
      const TetMesh& m = view.get();
      if (m.num_tets() != so.tet_part.size())
        throw RuntimeFailure("SplitForces: the plan of object " + std::to_string(k) + " does not match its mesh");
      Incidence inc = incidence_of(m);
      std::vector<std::int32_t> interior = interior_parts(inc, so.tet_part);
      cut = cut_split_part(m, so.tet_part, interior, w.rank);
      g = std::make_unique<Merge>();
      std::int32_t nparts = 0;
      for (std::int32_t q : so.tet_part) nparts = std::max(nparts, q + 1);
      g->object = so.object;
      g->first = static_cast<std::size_t>(w.vertex_offset[k]);
      g->alpha = scene.materials[scene.objects[k].material].damping_mass;
      g->send_v = needs_v;
      g->part_vertices.resize(static_cast<std::size_t>(nparts));
      g->holds.assign(static_cast<std::size_t>(nparts), 0);
      std::vector<std::int32_t> seen(static_cast<std::size_t>(nparts), -1);  // the last vertex each part took
      for (std::size_t j = 0; j + 1 < inc.offset.size(); ++j)
        for (std::int64_t e = inc.offset[j]; e < inc.offset[j + 1]; ++e) {
          const auto q = static_cast<std::size_t>(so.tet_part[static_cast<std::size_t>(inc.tet[static_cast<std::size_t>(e)])]);
          if (seen[q] == static_cast<std::int32_t>(j)) continue;
          seen[q] = static_cast<std::int32_t>(j);
          g->part_vertices[q].push_back(static_cast<std::int32_t>(j));
        }
      for (std::size_t q = 0; q < g->part_vertices.size(); ++q)
        if (static_cast<int>(q) != w.rank && !g->part_vertices[q].empty()) peers_.push_back(static_cast<int>(q));
      // What each part's stream holds: a vertex inside it, its sum; on a cut, an entry
      // per incident tet of the part.
      g->part_doubles.assign(static_cast<std::size_t>(nparts), 0);
      for (std::size_t j = 0; j + 1 < inc.offset.size(); ++j) {
        if (interior[j] >= 0) {
          g->part_doubles[static_cast<std::size_t>(interior[j])] += 3;
          continue;
        }
        for (std::int64_t e = inc.offset[j]; e < inc.offset[j + 1]; ++e)
          g->part_doubles[static_cast<std::size_t>(so.tet_part[static_cast<std::size_t>(inc.tet[static_cast<std::size_t>(e)])])] += 3;
      }
      g->inc = std::move(inc);
      g->tet_part = std::move(so.tet_part);
      g->interior = std::move(interior);
    }

    auto p = std::make_unique<Part>();
    p->object = so.object;
    p->owner = so.owner;
    p->needs_v = needs_v;
    if (own) p->first = static_cast<std::size_t>(w.vertex_offset[k]);
    // The part's World holds its vertices and tets only: no table of the whole scene
    // (the layout and vertex offsets, 64 bytes per object of the scene), which its
    // forces never read (ElasticForces reads them only for objects excluded or held
    // elsewhere, and a part has none).
    World& mw = p->mini;
    mw.rank = w.rank;
    mw.owned_objects = {so.object};
    const std::size_t nv = cut.verts.size();
    for (std::size_t i = 0; i < nv; ++i) {
      const std::int32_t j = cut.verts[i];
      if (j < 0 || j >= L.vertex_count)
        throw RuntimeFailure("SplitForces: a part of object " + std::to_string(k) + " names vertex " + std::to_string(j) +
                             " of " + std::to_string(L.vertex_count));
      mw.vertex_gid.push_back(L.vertex_begin + static_cast<gid_t>(j));
      mw.vertex_object.push_back(so.object);
    }
    p->verts = std::move(cut.verts);
    p->fold = std::move(cut.fold);
    mw.x = std::move(cut.points);
    mw.v.assign(3 * nv, 0.0);
    mw.x_prev = mw.x;
    mw.mass.assign(nv, 0.0);      // (the merge on the owner applies -alpha m v)
    mw.inv_mass.assign(nv, 0.0);
    for (std::size_t e = 0; e < cut.tets.size(); ++e) {
      const index_t* tet = &cut.corners[4 * e];
      mw.tets.insert(mw.tets.end(), tet, tet + 4);
      mw.tet_gid.push_back(L.tet_begin + static_cast<gid_t>(cut.tets[e]));
      mw.tet_object.push_back(so.object);
      // As build_world computes it, so that the rest data are the owner's to the bit.
      mw.rest_volume.push_back(
          signed_tet_volume(&mw.x[3 * tet[0]], &mw.x[3 * tet[1]], &mw.x[3 * tet[2]], &mw.x[3 * tet[3]]));
    }
    mw.n_owned = nv;
    mw.m_owned = mw.tet_gid.size();
    if (mw.m_owned > 0) {
      p->forces = std::make_unique<ElasticForces>(scene, mw);
      p->offset.resize(nv);
      for (std::size_t i = 0; i < nv; ++i) {
        p->offset[i] = p->stream_doubles;
        p->stream_doubles += p->forces->vertex_corner_doubles(i, p->fold[i] != 0);
      }
    }
    evaluated_tets_ += static_cast<std::int64_t>(mw.m_owned);
    if (!own) {
      helped_tets_ += static_cast<std::int64_t>(mw.m_owned);
      if (mw.m_owned > 0) peers_.push_back(so.owner);
    }
    parts_.push_back(std::move(p));
    if (g) {
      merges_.push_back(std::move(g));
      owned_.push_back(so.object);
    }
  }
  std::sort(peers_.begin(), peers_.end());
  peers_.erase(std::unique(peers_.begin(), peers_.end()), peers_.end());
}

SplitForces::~SplitForces() = default;

void SplitForces::set_ghost_holders(const std::vector<char>& held) {
  const std::size_t n = parts_.size();
  if (n == 0) return;
  if (held.size() % n != 0)
    throw RuntimeFailure("SplitForces: " + std::to_string(held.size()) + " ghost flags for " + std::to_string(n) +
                         " split objects");
  const std::size_t nranks = held.size() / n;
  auto holds = [&](std::size_t r, std::size_t i) { return r < nranks && held[r * n + i] != 0; };
  std::size_t g = 0;
  for (std::size_t i = 0; i < n; ++i) {
    Part& p = *parts_[i];
    p.from_ghost = p.owner != p.mini.rank && holds(static_cast<std::size_t>(p.mini.rank), i);
    if (g < merges_.size() && merges_[g]->object == p.object) {
      Merge& m = *merges_[g++];
      for (std::size_t q = 0; q < m.holds.size(); ++q)
        m.holds[q] = static_cast<int>(q) != p.owner && holds(q, i) ? 1 : 0;
    }
  }
}

int SplitForces::helping_parts() const {
  int n = 0;
  for (const std::unique_ptr<Part>& p : parts_) n += p->owner != p->mini.rank && p->forces ? 1 : 0;
  return n;
}

int SplitForces::parts_from_ghosts() const {
  int n = 0;
  for (const std::unique_ptr<Part>& p : parts_) n += p->from_ghost && p->forces ? 1 : 0;
  return n;
}

std::size_t SplitForces::peer_index(int r, int object) const {
  const auto at = std::lower_bound(peers_.begin(), peers_.end(), r);
  if (at == peers_.end() || *at != r)
    throw RuntimeFailure("SplitForces: rank " + std::to_string(r) + ", which shares object " + std::to_string(object) +
                         ", is not a peer");
  return static_cast<std::size_t>(at - peers_.begin());
}

// One exchange of doubles with the peers, send_ out and `recv` in (both kept from one
// step to the next); its wall and CPU time are the caller's wait.
void SplitForces::timed_exchange(NeighbourExchange* exchange, std::vector<std::vector<double>>& recv) {
  for (const std::vector<double>& b : send_) doubles_sent_ += static_cast<std::int64_t>(b.size());
  const double wall0 = wall_seconds(), cpu0 = process_cpu_seconds();
  exchange->exchange_doubles(peers_, send_, recv);
  exchange_wall_ += wall_seconds() - wall0;
  exchange_cpu_ += process_cpu_seconds() - cpu0;
}

void SplitForces::add(const World& w, std::vector<double>& f, bool damping, NeighbourExchange* exchange) {
  evaluate(w, damping, exchange);
  merge(w, f, damping);
}

void SplitForces::evaluate(const World& w, bool damping, NeighbourExchange* exchange) {
  if (!peers_.empty() && !exchange) throw RuntimeFailure("SplitForces: objects shared with other ranks need an exchange");
  evaluated_ = true;
  // 1. Each part's state from the owner: positions, and velocities where the stiffness
  // damping needs them, of its vertices in ascending order.
  std::vector<std::vector<double>>& in = state_in_;  // one buffer per peer, resized in place by the exchange
  if (!exchange) {
    in.clear();
  } else {
    send_.resize(peers_.size());
    for (std::vector<double>& b : send_) b.clear();
    for (const std::unique_ptr<Merge>& gp : merges_) {
      const Merge& g = *gp;
      for (std::size_t q = 0; q < g.part_vertices.size(); ++q) {
        if (static_cast<int>(q) == w.rank || g.part_vertices[q].empty()) continue;
        std::vector<double>& buf = send_[peer_index(static_cast<int>(q), g.object)];
        if (!g.holds[q]) append_rows(buf, w.x, g.first, g.part_vertices[q]);
        if (g.send_v && damping) append_rows(buf, w.v, g.first, g.part_vertices[q]);
      }
    }
    timed_exchange(exchange, in);
  }
  std::vector<std::size_t> read(in.size(), 0);  // doubles read from each peer
  auto take = [&](std::size_t q, std::size_t n, int object, const char* what) {
    if (in[q].size() < read[q] + n)
      throw RuntimeFailure("SplitForces: rank " + std::to_string(peers_[q]) + " sent too few " + what + " for object " +
                           std::to_string(object));
    const double* at = in[q].data() + read[q];
    read[q] += n;
    return at;
  };
  // 2. This rank's parts at that state.
  for (const std::unique_ptr<Part>& pp : parts_) {
    Part& p = *pp;
    if (!p.forces) {
      p.stream.clear();
      continue;
    }
    const std::size_t nv = p.verts.size();
    if (p.owner == w.rank) {
      for (std::size_t i = 0; i < nv; ++i)
        for (std::size_t d = 0; d < 3; ++d) {
          const std::size_t row = 3 * (p.first + static_cast<std::size_t>(p.verts[i])) + d;
          p.mini.x[3 * i + d] = w.x[row];
          p.mini.v[3 * i + d] = w.v[row];
        }
    } else {
      const std::size_t q = peer_index(p.owner, p.object);
      if (p.from_ghost) {
        // The owner's x^t, to the bit: the halo copied it into the ghost rows at the end
        // of the last step (or when the ghost set was built).
        const index_t first = w.vertex_offset[static_cast<std::size_t>(p.object)];
        if (first < 0 || w.owns_object(p.object))
          throw RuntimeFailure("SplitForces: object " + std::to_string(p.object) +
                               " is not a ghost here any more (set_ghost_holders was not called after the ghost set changed)");
        for (std::size_t i = 0; i < nv; ++i)
          for (std::size_t d = 0; d < 3; ++d)
            p.mini.x[3 * i + d] = w.x[3 * (static_cast<std::size_t>(first) + static_cast<std::size_t>(p.verts[i])) + d];
      } else {
        const double* x = take(q, 3 * nv, p.object, "positions");
        std::copy(x, x + 3 * nv, p.mini.x.begin());
      }
      if (p.needs_v && damping) {
        const double* v = take(q, 3 * nv, p.object, "velocities");
        std::copy(v, v + 3 * nv, p.mini.v.begin());
      }
    }
    p.stream.resize(p.stream_doubles);  // the same length every step: kept, not cleared (every double is written)
    p.forces->stream_vertex_corners(p.mini, damping, p.fold, p.offset, p.stream.data());
  }
  for (std::size_t q = 0; q < in.size(); ++q)
    if (read[q] != in[q].size())
      throw RuntimeFailure("SplitForces: rank " + std::to_string(peers_[q]) + " sent " + std::to_string(in[q].size()) +
                           " state components, " + std::to_string(read[q]) + " used");
  // 3. The parts of other ranks' objects to their owners, in ascending object order.
  if (!exchange) forces_in_.clear();
  if (exchange) {
    for (std::vector<double>& b : send_) b.clear();
    for (const std::unique_ptr<Part>& p : parts_)
      if (p->owner != w.rank && !p->stream.empty()) {
        std::vector<double>& buf = send_[peer_index(p->owner, p->object)];
        buf.insert(buf.end(), p->stream.begin(), p->stream.end());
      }
    timed_exchange(exchange, forces_in_);
  }
}

void SplitForces::merge(const World& w, std::vector<double>& f, bool damping) {
  if (!evaluated_) throw RuntimeFailure("SplitForces: merge() before evaluate()");
  evaluated_ = false;
  const std::vector<std::vector<double>>& in = forces_in_;
  std::vector<std::size_t> read(in.size(), 0);  // doubles read from each peer
  // 4. Each owned object's vertices: every corner force in ascending tet id, from the
  // part that evaluated it (a vertex inside one part: that part's sum), folded from zero.
  // Each part's stream is checked for its length first, so the fold reads no further.
  for (const std::unique_ptr<Merge>& gp : merges_) {
    Merge& g = *gp;
    const std::size_t np = g.part_vertices.size();
    std::vector<const double*> at(np, nullptr);
    for (std::size_t q = 0; q < np; ++q) {
      if (g.part_doubles[q] == 0) continue;
      std::size_t have = 0;
      if (static_cast<int>(q) == w.rank) {
        const auto it = std::find_if(parts_.begin(), parts_.end(), [&](const auto& p) { return p->object == g.object; });
        at[q] = (*it)->stream.data();
        have = (*it)->stream.size();
      } else {
        const std::size_t r = peer_index(static_cast<int>(q), g.object);
        at[q] = in[r].data() + read[r];
        have = in[r].size() - read[r];
        read[r] += g.part_doubles[q];
      }
      if (have < g.part_doubles[q] || (static_cast<int>(q) == w.rank && have != g.part_doubles[q]))
        throw RuntimeFailure("SplitForces: part " + std::to_string(q) + " of object " + std::to_string(g.object) +
                             " has " + std::to_string(have) + " force components for its vertices, " +
                             std::to_string(g.part_doubles[q]) + " expected");
    }
    const std::size_t nv = g.inc.offset.size() - 1;
    g.sums.resize(3 * nv);
    for (std::size_t j = 0; j < nv; ++j) {
      double acc[3] = {0, 0, 0};
      auto add = [&](std::size_t q) {
        const double* c = at[q];
        acc[0] += c[0];
        acc[1] += c[1];
        acc[2] += c[2];
        at[q] = c + 3;
      };
      if (g.interior[j] >= 0) {
        add(static_cast<std::size_t>(g.interior[j]));
      } else {
        for (std::int64_t e = g.inc.offset[j]; e < g.inc.offset[j + 1]; ++e)
          add(static_cast<std::size_t>(g.tet_part[static_cast<std::size_t>(g.inc.tet[static_cast<std::size_t>(e)])]));
      }
      for (std::size_t d = 0; d < 3; ++d) g.sums[3 * j + d] = acc[d];
    }
    ElasticForces::add_vertex_sums(w, f, damping, g.alpha, g.first, g.sums.data(), nv);
  }
  for (std::size_t q = 0; q < in.size(); ++q)
    if (read[q] != in[q].size())
      throw RuntimeFailure("SplitForces: rank " + std::to_string(peers_[q]) + " sent " + std::to_string(in[q].size()) +
                           " force components, " + std::to_string(read[q]) + " used");
}

}  // namespace softcontact
