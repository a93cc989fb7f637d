// Floating-point contraction off for the whole file, as in every law's file, whose block
// kernels are compiled for several instruction sets (SOFTCONTACT_BLOCK_KERNEL,
// tet_kernels.hpp): without fused multiply-adds every variant rounds exactly like the
// others and like the scalar reference. sqrt never sets errno here (its arguments are
// squared lengths), which lets it vectorise.
#pragma GCC optimize("fp-contract=off", "no-math-errno")
// The lane vectors (simd.hpp) change the calling convention between instruction sets;
// every function taking them is inlined into one kernel (flatten), so it never matters.
#pragma GCC diagnostic ignored "-Wpsabi"

#include "softcontact/forces.hpp"
#include "softcontact/error.hpp"
#include "softcontact/mesh.hpp"
#include "softcontact/scene.hpp"

#include <omp.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <string>

#include "material_registry.hpp"
#include "tet_kernels.hpp"

namespace softcontact {

using namespace model;

namespace {

/// Tets per work block: small enough to balance threads on small objects, large
/// enough that the per-block dispatch costs nothing.
constexpr std::size_t kBlock = 256;
static_assert(kBlock % (2 * kLanes) == 0, "blocks must start on whole chunks (and chunk pairs)");

/// Below this many vertices the gather runs on one thread: starting a team costs more
/// than it saves. (Which thread adds what never changes the result.)
constexpr std::ptrdiff_t kParallelVertices = 4096;

/// add_forces evaluates an object of at most this many tets whole, kernels then gather:
/// its corner forces, 96 bytes a tet (384 KiB), stay in a core's L2 cache (1 MiB on the
/// machine of docs/benchmarks.md) between the two.
constexpr std::size_t kFusedTets = 4096;

/// On one thread, add_forces runs a large object's kernels in stages of this many blocks
/// (4,096 tets, 384 KiB of corner forces) and gathers after each stage the vertices whose
/// tets are all done, most of them still in the core's L2 cache. (On more threads the
/// stages' barriers and the other core's cache cost more than they save: all blocks,
/// then all vertices.)
constexpr std::size_t kStageBlocks = 16;

LawParams params_of(const ElasticForces::Segment& s) { return {{s.lambda, s.mu}, s.young, s.beta}; }

/// Object `obj`'s segment fields from its material (begin, end, owned and padded_begin
/// are the caller's).
ElasticForces::Segment segment_for(const Scene& scene, int obj) {
  ElasticForces::Segment s;
  s.object = obj;
  const Material& mat = scene.materials[scene.objects[static_cast<std::size_t>(obj)].material];
  s.model = mat.model;
  s.lambda = mat.lame_lambda();
  s.mu = mat.lame_mu();
  s.young = mat.young;
  s.alpha = mat.damping_mass;
  s.beta = mat.damping_stiffness;
  s.active = !scene.objects[static_cast<std::size_t>(obj)].kinematic();
  return s;
}

/// The rest data of tet t of a structure of arrays from its corners' rest positions X:
/// Dm^-1 (row-major entries) and, with `springs`, the inverse rest lengths of its edges.
/// One function for the constructor and measure()'s objects held elsewhere, so that both
/// round alike.
void rest_data(const double* const X[4], std::size_t t, std::vector<double> (&dm_inv)[9],
               std::vector<double> (&inv_rest_length)[6], bool springs) {
  const Mat3 dm = {X[1][0] - X[0][0], X[2][0] - X[0][0], X[3][0] - X[0][0], X[1][1] - X[0][1], X[2][1] - X[0][1],
                   X[3][1] - X[0][1], X[1][2] - X[0][2], X[2][2] - X[0][2], X[3][2] - X[0][2]};
  // Dm^-1 = cof(Dm)^T / det(Dm); meshes are validated, so det(Dm) = 6 V > 0.
  const Mat3 c = cofactor(dm);
  const double det_dm = det_from_cofactor(dm, c);
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) dm_inv[3 * i + j][t] = c[3 * j + i] / det_dm;
  if (springs)
    for (int e = 0; e < 6; ++e) {
      const double* a = X[kTetEdges[e][0]];
      const double* b = X[kTetEdges[e][1]];
      inv_rest_length[e][t] =
          1 / std::sqrt((b[0] - a[0]) * (b[0] - a[0]) + (b[1] - a[1]) * (b[1] - a[1]) + (b[2] - a[2]) * (b[2] - a[2]));
    }
}

}  // namespace

ElasticForces::ElasticForces(const Scene& scene, const World& w, std::vector<int> held_elsewhere)
    : scene_(&scene), held_elsewhere_(std::move(held_elsewhere)) {
  std::sort(held_elsewhere_.begin(), held_elsewhere_.end());
  held_elsewhere_.erase(std::unique(held_elsewhere_.begin(), held_elsewhere_.end()), held_elsewhere_.end());
  for (int k : held_elsewhere_)
    if (k < 0 || static_cast<std::size_t>(k) >= w.vertex_offset.size() || !w.owns_object(k))
      throw RuntimeFailure("ElasticForces: object " + std::to_string(k) + " is not owned here");
  auto elsewhere = [&](int obj) { return std::binary_search(held_elsewhere_.begin(), held_elsewhere_.end(), obj); };
  // Owned objects only: ghost tets (other ranks' objects within reach) are for contact.
  // src[t]: the World's index of local tet t (the owned tets but those held elsewhere).
  std::vector<std::size_t> src;
  src.reserve(w.m_owned);
  for (std::size_t t = 0; t < w.m_owned; ++t)
    if (!elsewhere(w.tet_object[t])) src.push_back(t);
  const std::size_t m = src.size();
  const std::size_t n = w.n_owned;
  for (auto& c : corner_) c.resize(m);
  for (auto& d : dm_inv_) d.resize(m);
  volume_.resize(m);
  tet_segment_.resize(m);

  // Segments: runs of tets of one object (objects are stored contiguously).
  for (std::size_t t = 0; t < m; ++t) {
    const int obj = w.tet_object[src[t]];
    if (segments_.empty() || segments_.back().object != obj) {
      Segment s = segment_for(scene, obj);
      s.begin = t;
      s.owned = static_cast<int>(std::find(w.owned_objects.begin(), w.owned_objects.end(), obj) - w.owned_objects.begin());
      segments_.push_back(s);
    }
    segments_.back().end = t + 1;
    tet_segment_[t] = static_cast<std::int32_t>(segments_.size() - 1);
  }

  bool any_springs = false;
  for (const Segment& s : segments_) any_springs = any_springs || material_law(s.model).spring_rest_lengths;
  if (any_springs)
    for (auto& l : inv_rest_length_) l.assign(m, 0.0);

  for (std::size_t t = 0; t < m; ++t) {
    const index_t* tet = &w.tets[4 * src[t]];
    for (int c = 0; c < 4; ++c) corner_[c][t] = tet[c];
    const double* X[4] = {&w.x[3 * tet[0]], &w.x[3 * tet[1]], &w.x[3 * tet[2]], &w.x[3 * tet[3]]};
    rest_data(X, t, dm_inv_, inv_rest_length_, material_law(segments_[tet_segment_[t]].model).spring_rest_lengths);
    volume_[t] = w.rest_volume[src[t]];
  }

  // Per-tet force buffer: each segment starts on a whole chunk of kLanes tets, so that the
  // kernels store whole vectors (tet_kernels.hpp); slot(t, c) finds corner c of tet t.
  std::size_t padded = 0;
  for (Segment& s : segments_) {
    s.padded_begin = padded;
    padded += (s.end - s.begin + kLanes - 1) / kLanes * kLanes;
  }
  // Offsets into the buffer are 32-bit (half the memory traffic of the gather's index):
  // enough for 178 million tets on one rank.
  if (12 * padded > static_cast<std::size_t>(std::numeric_limits<std::int32_t>::max()))
    throw RuntimeFailure("ElasticForces: too many tets on one rank (" + std::to_string(m) + "); use more ranks");
  tet_force_.assign(12 * padded, 0.0);
  auto slot = [&](std::size_t t, int c) {
    const Segment& s = segments_[tet_segment_[t]];
    const std::size_t q = s.padded_begin + (t - s.begin);
    return static_cast<std::int32_t>(12 * (q - q % kLanes) + 3 * kLanes * c + q % kLanes);
  };

  for (std::size_t k = 0; k < segments_.size(); ++k) {
    const Segment& s = segments_[k];
    if (!s.active) continue;
    for (std::size_t b = s.begin; b < s.end; b += kBlock)
      blocks_.push_back({b, static_cast<std::int32_t>(std::min(kBlock, s.end - b)), static_cast<std::int32_t>(k)});
  }

  vertex_alpha_.assign(n, 0.0);
  for (std::size_t i = 0; i < n; ++i)
    vertex_alpha_[i] = scene.materials[scene.objects[w.vertex_object[i]].material].damping_mass;

  // Incidence: every (tet, corner) slot under its vertex, sorted by tet global id so that
  // the gather adds a vertex's contributions in an order that does not depend on how
  // tets are distributed over threads or ranks.
  const std::size_t no = w.n_owned;
  inc_offset_.assign(no + 1, 0);
  for (std::size_t t = 0; t < m; ++t)
    for (int c = 0; c < 4; ++c)
      if (static_cast<std::size_t>(corner_[c][t]) < no) ++inc_offset_[corner_[c][t] + 1];
  std::partial_sum(inc_offset_.begin(), inc_offset_.end(), inc_offset_.begin());
  inc_slot_.resize(inc_offset_.back());
  std::vector<std::int64_t> fill(inc_offset_.begin(), inc_offset_.end() - 1);
  for (std::size_t t = 0; t < m; ++t)
    for (int c = 0; c < 4; ++c) {
      const auto v = static_cast<std::size_t>(corner_[c][t]);
      if (v < no) inc_slot_[fill[v]++] = slot(t, c);
    }
  // Tets are stored in increasing global id (objects in order, each object's tets in
  // order), so filling in tet order has already sorted every list.
  for (std::size_t t = 1; t < m; ++t) SC_ASSERT(w.tet_gid[src[t - 1]] < w.tet_gid[src[t]]);

  // add_forces' plan. A small object is evaluated whole when its tets' owned corners span
  // one range of vertices that belong to it alone (then no other tet adds to them);
  // should any range overlap another (never, for objects stored contiguously), nothing is
  // fused.
  std::vector<std::uint8_t> covered(no, 0);
  bool fusable = true;
  std::size_t block = 0;
  for (const Segment& s : segments_) {
    const std::size_t b0 = block;
    while (block < blocks_.size() && &segments_[static_cast<std::size_t>(blocks_[block].segment)] == &s) ++block;
    if (s.end - s.begin > kFusedTets) {
      for (std::size_t k = b0; k < block; ++k) unfused_blocks_.push_back(k);
      continue;
    }
    std::size_t v0 = no, v1 = 0;
    for (std::size_t t = s.begin; t < s.end; ++t)
      for (int c = 0; c < 4; ++c) {
        const auto v = static_cast<std::size_t>(corner_[c][t]);
        if (v < no) {
          v0 = std::min(v0, v);
          v1 = std::max(v1, v + 1);
        }
      }
    bool own = v0 < v1;
    for (std::size_t i = v0; own && i < v1; ++i) own = w.vertex_object[i] == s.object && !covered[i];
    if (!own) {
      fusable = fusable && v0 >= v1;  // an object with no owned corner has nothing to gather
      for (std::size_t k = b0; k < block; ++k) unfused_blocks_.push_back(k);
      continue;
    }
    std::fill(covered.begin() + static_cast<std::ptrdiff_t>(v0), covered.begin() + static_cast<std::ptrdiff_t>(v1), 1);
    fused_.push_back({b0, block, v0, v1});
  }
  if (!fusable) {
    fused_.clear();
    unfused_blocks_.resize(blocks_.size());
    std::iota(unfused_blocks_.begin(), unfused_blocks_.end(), std::size_t{0});
    std::fill(covered.begin(), covered.end(), 0);
  }
  for (std::size_t i = 0; i < no; ++i)
    if (!covered[i]) {
      if (unfused_vertices_.empty() || unfused_vertices_.back().second != i) unfused_vertices_.push_back({i, i});
      ++unfused_vertices_.back().second;
    }
  all_fused_ = fused_;
  all_unfused_blocks_ = unfused_blocks_;
  all_unfused_vertices_ = unfused_vertices_;
  plan_stages();
  // The objects held elsewhere have no tets here; their vertices leave the gather.
  if (!held_elsewhere_.empty()) exclude_objects(w, held_elsewhere_);
}

void ElasticForces::plan_stages() {
  stages_.clear();
  staged_vertices_.clear();
  std::size_t nv = 0;
  for (const auto& range : unfused_vertices_) nv += range.second - range.first;
  if (nv == 0 && unfused_blocks_.empty()) return;
  if (inc_offset_.size() - 1 > std::numeric_limits<std::uint32_t>::max())
    throw RuntimeFailure("ElasticForces: too many vertices on one rank (" + std::to_string(inc_offset_.size() - 1) + ")");
  const std::size_t nstages = std::max<std::size_t>(1, (unfused_blocks_.size() + kStageBlocks - 1) / kStageBlocks);
  // Each vertex's stage: that of its last tet among the unfused blocks (0 for a vertex
  // none of them touches: only inactive tets, or none).
  const std::size_t no = inc_offset_.size() - 1;
  std::vector<std::uint32_t> stage_of(no, 0);
  for (std::size_t k = 0; k < unfused_blocks_.size(); ++k) {
    const Block& b = blocks_[unfused_blocks_[k]];
    const auto stage = static_cast<std::uint32_t>(k / kStageBlocks);
    for (std::size_t t = b.begin; t < b.begin + static_cast<std::size_t>(b.count); ++t)
      for (int c = 0; c < 4; ++c) {
        const auto v = static_cast<std::size_t>(corner_[c][t]);
        if (v < no) stage_of[v] = std::max(stage_of[v], stage);
      }
  }
  // Counting sort: the vertices by stage, ascending within each.
  std::vector<std::size_t> count(nstages + 1, 0);
  for (const auto& range : unfused_vertices_)
    for (std::size_t i = range.first; i < range.second; ++i) ++count[stage_of[i] + 1];
  std::partial_sum(count.begin(), count.end(), count.begin());
  staged_vertices_.resize(nv);
  std::vector<std::size_t> fill(count.begin(), count.end() - 1);
  for (const auto& range : unfused_vertices_)
    for (std::size_t i = range.first; i < range.second; ++i) staged_vertices_[fill[stage_of[i]]++] = static_cast<std::uint32_t>(i);
  for (std::size_t k = 0; k < nstages; ++k)
    stages_.push_back({k * kStageBlocks, std::min(unfused_blocks_.size(), (k + 1) * kStageBlocks), count[k], count[k + 1]});
}

namespace {

TetView make_view(const std::vector<index_t> (&corner)[4], const std::vector<double> (&dm_inv)[9],
                  const std::vector<double>& volume, const std::vector<double> (&inv_rest_length)[6]) {
  TetView v;
  for (int c = 0; c < 4; ++c) v.corner[c] = corner[c].data();
  for (int k = 0; k < 9; ++k) v.dm_inv[k] = dm_inv[k].data();
  v.volume = volume.data();
  for (int e = 0; e < 6; ++e) v.inv_rest_length[e] = inv_rest_length[e].data();
  return v;
}

}  // namespace

namespace {

/// The forces of one block of tets (one segment), by the law's block kernel.
void block_forces(const TetView& T, std::size_t t0, std::size_t t1, const ElasticForces::Segment& s, bool damping,
                  const double* x, const double* v, double* out) {
  material_law(s.model).block_forces(T, t0, t1, params_of(s), damping && s.beta > 0, x, v, out);
}

}  // namespace

void ElasticForces::run_block(const World& w, bool damping, std::size_t k) {
  const TetView T = make_view(corner_, dm_inv_, volume_, inv_rest_length_);
  const Block& b = blocks_[k];
  const Segment& s = segments_[static_cast<std::size_t>(b.segment)];
  block_forces(T, b.begin, b.begin + static_cast<std::size_t>(b.count), s, damping, w.x.data(), w.v.data(),
               tet_force_.data() + 12 * (s.padded_begin + (b.begin - s.begin)));
}

void ElasticForces::compute_tet_forces(const World& w, bool damping) {
  const std::ptrdiff_t nb = static_cast<std::ptrdiff_t>(blocks_.size());
#pragma omp parallel for schedule(static) if (nb > 1)
  for (std::ptrdiff_t k = 0; k < nb; ++k) run_block(w, damping, static_cast<std::size_t>(k));
}

namespace {

/// The sum of vertex i's corner forces in incidence order (ascending tet global id).
inline void fold_corners(const double* tf, const std::int64_t* offset, const std::int32_t* slot, std::size_t i,
                         double acc[3]) {
  acc[0] = acc[1] = acc[2] = 0;
  for (std::int64_t k = offset[i]; k < offset[i + 1]; ++k) {
    const double* c = tf + slot[k];
    acc[0] += c[0];
    acc[1] += c[kLanes];
    acc[2] += c[2 * kLanes];
  }
}

/// f_i += acc and the -alpha m v term.
inline void finish_vertex(const World& w, std::vector<double>& f, bool damping, double alpha, std::size_t i,
                          double acc[3]) {
  double* fi = &f[3 * i];
  if (damping && w.inv_mass[i] != 0 && alpha > 0) {
    const double am = alpha * w.mass[i];
    for (int d = 0; d < 3; ++d) acc[d] -= am * w.v[3 * i + d];
  }
  for (int d = 0; d < 3; ++d) fi[d] += acc[d];
}

/// f_i += the sum of vertex i's corner forces in incidence order (ascending tet global
/// id), and the -alpha m v term.
inline void gather_vertex(const World& w, std::vector<double>& f, bool damping, const double* tf,
                          const std::int64_t* offset, const std::int32_t* slot, const double* alpha, std::size_t i) {
  double acc[3];
  fold_corners(tf, offset, slot, i, acc);
  finish_vertex(w, f, damping, alpha[i], i, acc);
}

}  // namespace

std::size_t ElasticForces::vertex_corner_doubles(std::size_t i, bool fold) const {
  return fold ? 3 : 3 * static_cast<std::size_t>(inc_offset_[i + 1] - inc_offset_[i]);
}

double* ElasticForces::write_vertex_corners(std::size_t i, bool fold, double* out) const {
  if (fold) {
    double acc[3];  // (a local sum: folded into `out` itself, every add waited for the last one's store)
    fold_corners(tet_force_.data(), inc_offset_.data(), inc_slot_.data(), i, acc);
    std::copy(acc, acc + 3, out);
    return out + 3;
  }
  for (std::int64_t k = inc_offset_[i]; k < inc_offset_[i + 1]; ++k) {
    const double* c = tet_force_.data() + inc_slot_[static_cast<std::size_t>(k)];
    *out++ = c[0];
    *out++ = c[kLanes];
    *out++ = c[2 * kLanes];
  }
  return out;
}

void ElasticForces::add_vertex_sums(const World& w, std::vector<double>& f, bool damping, double alpha,
                                    std::size_t first, const double* sums, std::size_t n) {
  for (std::size_t i = 0; i < n; ++i) {
    double acc[3] = {sums[3 * i], sums[3 * i + 1], sums[3 * i + 2]};
    finish_vertex(w, f, damping, alpha, first + i, acc);
  }
}

void ElasticForces::exclude_objects(const World& w, const std::vector<int>& objects) {
  for (int k : held_elsewhere_)
    if (std::find(objects.begin(), objects.end(), k) == objects.end())
      throw RuntimeFailure("ElasticForces: object " + std::to_string(k) +
                           " was built without its rest data here, so its forces must stay elsewhere");
  std::vector<char> skip_segment(segments_.size(), 0);
  for (std::size_t k = 0; k < segments_.size(); ++k)
    skip_segment[k] = std::find(objects.begin(), objects.end(), segments_[k].object) != objects.end() ? 1 : 0;
  fused_.clear();
  for (const FusedObject& o : all_fused_)
    if (o.block_begin == o.block_end || !skip_segment[static_cast<std::size_t>(blocks_[o.block_begin].segment)])
      fused_.push_back(o);
  unfused_blocks_.clear();
  for (std::size_t b : all_unfused_blocks_)
    if (!skip_segment[static_cast<std::size_t>(blocks_[b].segment)]) unfused_blocks_.push_back(b);
  // The excluded objects' owned vertices leave the gather's ranges.
  std::vector<std::pair<std::size_t, std::size_t>> cut;
  for (int k : objects)
    if (w.owns_object(k)) {
      const auto b = static_cast<std::size_t>(w.vertex_offset[static_cast<std::size_t>(k)]);
      cut.push_back({b, b + static_cast<std::size_t>(w.layout[static_cast<std::size_t>(k)].vertex_count)});
    }
  std::sort(cut.begin(), cut.end());
  unfused_vertices_.clear();
  for (auto range : all_unfused_vertices_) {
    for (const auto& c : cut) {
      if (c.second <= range.first || c.first >= range.second) continue;
      if (c.first > range.first) unfused_vertices_.push_back({range.first, c.first});
      range.first = std::min(range.second, c.second);
    }
    if (range.first < range.second) unfused_vertices_.push_back(range);
  }
  plan_stages();
}

void ElasticForces::gather_forces(const World& w, std::vector<double>& f, bool damping) const {
  const std::ptrdiff_t n = static_cast<std::ptrdiff_t>(w.n_owned);
#pragma omp parallel for schedule(static) if (n >= kParallelVertices)
  for (std::ptrdiff_t i = 0; i < n; ++i)
    gather_vertex(w, f, damping, tet_force_.data(), inc_offset_.data(), inc_slot_.data(), vertex_alpha_.data(),
                  static_cast<std::size_t>(i));
}

// add_forces' plan with `per_vertex(i)` for each owned vertex i once all its tets are
// evaluated: the fused objects whole, then the stages (one thread) or all the other
// blocks and then their vertices (more).
template <class PerVertex>
void ElasticForces::run_plan(const World& w, bool damping, const PerVertex& per_vertex) {
  const auto nf = static_cast<std::ptrdiff_t>(fused_.size());
  const auto nb = static_cast<std::ptrdiff_t>(unfused_blocks_.size());
  const bool staged = nf + nb <= 1 || omp_get_max_threads() == 1;  // (then one thread runs it all)
  // Every object and every block writes only its own corner forces, and per_vertex is
  // called once per vertex after all of them, so neither the schedule nor the thread
  // count can change the result.
#pragma omp parallel if (!staged)
  {
#pragma omp for schedule(dynamic, 1) nowait
    for (std::ptrdiff_t k = 0; k < nf; ++k) {
      const FusedObject& o = fused_[static_cast<std::size_t>(k)];
      for (std::size_t b = o.block_begin; b < o.block_end; ++b) run_block(w, damping, b);
      for (std::size_t i = o.vertex_begin; i < o.vertex_end; ++i) per_vertex(i);
    }
    if (staged) {
      // The rest in stages: a stage's blocks, then the vertices whose last tet was in it
      // or before; every tet of theirs is done.
      for (const Stage& st : stages_) {
        for (std::size_t k = st.block_begin; k < st.block_end; ++k) run_block(w, damping, unfused_blocks_[k]);
        for (std::size_t i = st.vertex_begin; i < st.vertex_end; ++i) per_vertex(staged_vertices_[i]);
      }
    } else {
#pragma omp for schedule(static)
      for (std::ptrdiff_t k = 0; k < nb; ++k) run_block(w, damping, unfused_blocks_[static_cast<std::size_t>(k)]);
      // (the loop's barrier: every unfused block is done before its vertices are gathered)
      for (const std::pair<std::size_t, std::size_t>& range : unfused_vertices_) {
        const std::size_t begin = range.first;  // (no structured binding: clang's OpenMP cannot capture one)
        const auto n = static_cast<std::ptrdiff_t>(range.second - begin);
#pragma omp for schedule(static)
        for (std::ptrdiff_t i = 0; i < n; ++i) per_vertex(begin + static_cast<std::size_t>(i));
      }
    }
  }
}

void ElasticForces::add_forces(const World& w, std::vector<double>& f, bool damping) {
  run_plan(w, damping, [&](std::size_t i) {
    gather_vertex(w, f, damping, tet_force_.data(), inc_offset_.data(), inc_slot_.data(), vertex_alpha_.data(), i);
  });
}

void ElasticForces::stream_vertex_corners(const World& w, bool damping, const std::vector<char>& fold,
                                          const std::vector<std::size_t>& offset, double* out) {
  if (fold.size() != w.n_owned || offset.size() != w.n_owned)
    throw RuntimeFailure("ElasticForces: stream_vertex_corners takes a fold flag and an offset per owned vertex");
  run_plan(w, damping, [&](std::size_t i) { write_vertex_corners(i, fold[i] != 0, out + offset[i]); });
}

namespace {

/// Strain energy of one tet and whether it is inverted (det F <= 0).
double tet_energy(const TetView& T, std::size_t t, const ElasticForces::Segment& s, const double* x, bool& inverted) {
  const Mat3 Di = load_dm_inv(T, t);
  const Mat3 F = gradient_at(T, t, x, Di);
  inverted = !(det(F) > 0);
  return material_law(s.model).energy(T, t, params_of(s), x, F);
}

}  // namespace

void ElasticForces::measure(const World& w, ElasticMeasures& out) const {
  out.energy.assign(w.owned_objects.size(), 0.0);
  out.inverted.assign(w.owned_objects.size(), 0);
  const TetView T = make_view(corner_, dm_inv_, volume_, inv_rest_length_);
  const std::ptrdiff_t ns = static_cast<std::ptrdiff_t>(segments_.size());
  // One object per iteration, its tets summed in order: deterministic for any thread count.
#pragma omp parallel for schedule(dynamic) if (ns > 1)
  for (std::ptrdiff_t k = 0; k < ns; ++k) {
    const Segment& s = segments_[k];
    if (!s.active) continue;
    double e = 0;
    std::int64_t inv = 0;
    for (std::size_t t = s.begin; t < s.end; ++t) {
      bool inverted = false;
      e += tet_energy(T, t, s, w.x.data(), inverted);
      inv += inverted ? 1 : 0;
    }
    out.energy[s.owned] += e;
    out.inverted[s.owned] += inv;
  }
  // The objects held elsewhere: their rest data made again from their rest mesh (the
  // positions World::x held when the constructor ran), kChunk tets at a time, by the
  // constructor's rest_data and build_world's signed_tet_volume, and their energy summed
  // in tet order as a segment's above: the same bits as with their rest data held.
  constexpr std::size_t kChunk = 1024;
  for (int k : held_elsewhere_) {
    const Segment s = segment_for(*scene_, k);
    if (!s.active) continue;
    const Scene::MeshView view = scene_->view_mesh(static_cast<std::size_t>(k));
    const TetMesh& mesh = view.get();
    const auto base = w.vertex_offset[static_cast<std::size_t>(k)];
    const bool springs = material_law(s.model).spring_rest_lengths;
    std::vector<index_t> corner[4];
    std::vector<double> dm_inv[9], volume(kChunk), inv_rest_length[6];
    for (auto& c : corner) c.resize(kChunk);
    for (auto& d : dm_inv) d.resize(kChunk);
    if (springs)
      for (auto& l : inv_rest_length) l.resize(kChunk);
    const TetView chunk = make_view(corner, dm_inv, volume, inv_rest_length);
    double e = 0;
    std::int64_t inv = 0;
    for (std::size_t t0 = 0; t0 < mesh.num_tets(); t0 += kChunk) {
      const std::size_t nc = std::min(kChunk, mesh.num_tets() - t0);
      for (std::size_t i = 0; i < nc; ++i) {
        const index_t* tet = &mesh.tets[4 * (t0 + i)];
        for (int c = 0; c < 4; ++c) corner[c][i] = base + tet[c];
        const double* X[4] = {&mesh.points[3 * tet[0]], &mesh.points[3 * tet[1]], &mesh.points[3 * tet[2]],
                              &mesh.points[3 * tet[3]]};
        rest_data(X, i, dm_inv, inv_rest_length, springs);
        volume[i] = signed_tet_volume(X[0], X[1], X[2], X[3]);
      }
      for (std::size_t i = 0; i < nc; ++i) {
        bool inverted = false;
        e += tet_energy(chunk, i, s, w.x.data(), inverted);
        inv += inverted ? 1 : 0;
      }
    }
    const auto owned = static_cast<std::size_t>(std::find(w.owned_objects.begin(), w.owned_objects.end(), k) -
                                                w.owned_objects.begin());
    out.energy[owned] += e;
    out.inverted[owned] += inv;
  }
}

void ElasticForces::tet_forces(std::size_t t, const double* x, double f[12]) const {
  const TetView T = make_view(corner_, dm_inv_, volume_, inv_rest_length_);
  double out[12 * kLanes];
  block_forces(T, t, t + 1, segments_[tet_segment_[t]], false, x, nullptr, out);
  for (int k = 0; k < 12; ++k) f[k] = out[k * kLanes];  // lane 0
}

void ElasticForces::tet_stiffness(std::size_t t, const double* x, StiffnessKind kind, double K[144]) const {
  const TetView T = make_view(corner_, dm_inv_, volume_, inv_rest_length_);
  const Segment& s = segments_[tet_segment_[t]];
  const Mat3 Di = load_dm_inv(T, t);
  const Mat3 F = gradient_at(T, t, x, Di);
  material_law(s.model).stiffness(params_of(s), Di, T.volume[t], F, kind, K);
}

}  // namespace softcontact
