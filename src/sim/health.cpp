// The numerical-failure guard's checks on a simulator (docs/reliability.md): cheap ones
// after every step on this rank's vertices, and collective ones that say where a problem
// is, with the same message on every rank.
#include <cmath>
#include <cstdint>
#include <limits>
#include <sstream>
#include <string>

#include "softcontact/implicit_euler.hpp"
#include "softcontact/motion.hpp"
#include "softcontact/mpi_util.hpp"
#include "softcontact/simulator.hpp"
#include "softcontact/stepper.hpp"

namespace softcontact {

namespace {

constexpr gid_t kNone = std::numeric_limits<gid_t>::max();

bool finite3(const double* p) { return std::isfinite(p[0]) && std::isfinite(p[1]) && std::isfinite(p[2]); }

double speed2(const double* v) { return v[0] * v[0] + v[1] * v[1] + v[2] * v[2]; }

// "vertex 17 of object 'ball[3]' (global vertex 1234), a corner of its element 42 (global
// tet 5678)": `v` is an owned local vertex.
std::string describe_vertex(const Scene& scene, const World& w, std::size_t v) {
  const int k = w.vertex_object[v];
  const ObjectLayout& L = w.layout[static_cast<std::size_t>(k)];
  std::ostringstream s;
  s << "vertex " << w.vertex_gid[v] - L.vertex_begin << " of object '" << scene.objects[static_cast<std::size_t>(k)].name
    << "' (global vertex " << w.vertex_gid[v] << ")";
  std::size_t first = w.m_owned;
  for (std::size_t t = 0; t < w.m_owned; ++t) {
    if (w.tet_object[t] != k) continue;
    if (first == w.m_owned) first = t;
    for (int c = 0; c < 4; ++c)
      if (static_cast<std::size_t>(w.tets[4 * t + static_cast<std::size_t>(c)]) == v) {
        const auto e = static_cast<gid_t>(t - first);
        s << ", a corner of its element " << e << " (global tet " << L.tet_begin + e << ")";
        return s.str();
      }
  }
  return s.str();
}

// The message `text` of rank `owner`, on every rank.
std::string from_rank(MPI_Comm comm, int owner, std::string text) {
  long long n = static_cast<long long>(text.size());
  MPI_Bcast(&n, 1, MPI_LONG_LONG, owner, comm);
  text.resize(static_cast<std::size_t>(n));
  MPI_Bcast(text.data(), static_cast<int>(n), MPI_CHAR, owner, comm);
  return text;
}

// The rank that holds global id `gid` (the lowest rank with `mine` set).
int owner_of(MPI_Comm comm, bool mine) {
  int r = mine ? comm_rank(comm) : comm_size(comm);
  MPI_Allreduce(MPI_IN_PLACE, &r, 1, MPI_INT, MPI_MIN, comm);
  return r;
}

// The owned vertex with the lowest global id among those `pick` accepts, as (gid, local).
template <class Pick>
std::pair<gid_t, std::size_t> lowest(const World& w, Pick&& pick) {
  std::pair<gid_t, std::size_t> best{kNone, 0};
  for (std::size_t i = 0; i < w.n_owned; ++i)
    if (pick(i) && w.vertex_gid[i] < best.first) best = {w.vertex_gid[i], i};
  return best;
}

// The fastest owned movable vertex (ties: lowest global id), as (speed^2, local); -1 when none.
std::pair<double, std::size_t> fastest(const World& w, int object) {
  std::pair<double, std::size_t> best{-1, 0};
  for (std::size_t i = 0; i < w.n_owned; ++i) {
    if (w.inv_mass[i] == 0 || (object >= 0 && w.vertex_object[i] != object)) continue;
    const double s2 = speed2(&w.v[3 * i]);
    if (s2 > best.first || (s2 == best.first && best.first >= 0 && w.vertex_gid[i] < w.vertex_gid[best.second]))
      best = {s2, i};
  }
  return best;
}

// The largest `value` over the ranks (MAXLOC: the lowest rank on ties), as (value, rank).
std::pair<double, int> top_of(MPI_Comm comm, double value) {
  struct {
    double value;
    int rank;
  } mine{value, comm_rank(comm)}, top{};
  MPI_Allreduce(&mine, &top, 1, MPI_DOUBLE_INT, MPI_MAXLOC, comm);
  return {top.value, top.rank};
}

// The owned vertex `pick` names on rank `owner`, described on every rank.
std::string describe_on(MPI_Comm comm, int owner, const Scene& scene, const World& w, std::size_t local,
                        const std::string& prefix) {
  std::string text;
  if (comm_rank(comm) == owner) text = prefix + describe_vertex(scene, w, local);
  return from_rank(comm, owner, text);
}

}  // namespace

int Simulator::local_health(double max_speed) const {
  const World& w = world_;
  if (core_->motion().implicit() && core_->motion().implicit()->failed_object() >= 0) return 3;
  const double limit2 = max_speed * max_speed;
  int code = 0;
  for (std::size_t i = 0; i < w.n_owned; ++i) {
    const double* x = &w.x[3 * i];
    const double* v = &w.v[3 * i];
    if (!finite3(x) || !finite3(v)) return 2;
    if (speed2(v) > limit2) code = 1;
  }
  return code;
}

std::string Simulator::diagnose(int code, double max_speed) {
  const World& w = world_;
  if (code >= 3) {
    // A failed implicit solve: the lowest failed object of all ranks, told by its owner
    // (the same message on any number of ranks).
    int object = core_->motion().implicit() && core_->motion().implicit()->failed_object() >= 0 ? core_->motion().implicit()->failed_object()
                                                              : static_cast<int>(scene_.objects.size());
    const int mine = object;
    MPI_Allreduce(MPI_IN_PLACE, &object, 1, MPI_INT, MPI_MIN, comm_);
    const int owner = owner_of(comm_, mine == object);
    return from_rank(comm_, owner, rank_ == owner ? core_->motion().implicit()->failure() : std::string());
  }
  if (code >= 2) {
    auto [gid, local] = lowest(w, [&](std::size_t i) { return !finite3(&w.x[3 * i]) || !finite3(&w.v[3 * i]); });
    gid_t first = gid;
    MPI_Allreduce(MPI_IN_PLACE, &first, 1, MPI_INT64_T, MPI_MIN, comm_);
    if (first != kNone) {
      const int owner = owner_of(comm_, gid == first);
      return describe_on(comm_, owner, scene_, w, local, "a non-finite position or velocity at ");
    }
  }
  // The fastest vertex of all (MAXLOC keeps the lowest rank on ties).
  const auto [s2, local] = fastest(w, -1);
  const auto [top, top_rank] = top_of(comm_, s2);
  if (top < 0) return "";
  std::ostringstream what;
  what.precision(4);
  what << "a speed of " << std::sqrt(top) << " m/s, above the limit of " << max_speed
       << " m/s (simulation.limits.max_speed), at ";
  return describe_on(comm_, top_rank, scene_, w, local, what.str());
}

std::string Simulator::check_inversions(double max_fraction) {
  const World& w = world_;
  std::int64_t counts[2] = {0, 0};  // inverted, movable tets
  gid_t first = kNone;
  std::size_t first_local = 0;
  std::size_t object_first = 0;
  int current = -1;
  for (std::size_t t = 0; t < w.m_owned; ++t) {
    const int k = w.tet_object[t];
    if (k != current) {
      current = k;
      object_first = t;
    }
    if (scene_.objects[static_cast<std::size_t>(k)].kinematic()) continue;
    ++counts[1];
    const double* p[4];
    for (int c = 0; c < 4; ++c) p[c] = &w.x[3 * static_cast<std::size_t>(w.tets[4 * t + static_cast<std::size_t>(c)])];
    double e[3][3];
    for (int a = 0; a < 3; ++a)
      for (int d = 0; d < 3; ++d) e[a][d] = p[a + 1][d] - p[0][d];
    const double det = e[0][0] * (e[1][1] * e[2][2] - e[1][2] * e[2][1]) -
                       e[0][1] * (e[1][0] * e[2][2] - e[1][2] * e[2][0]) +
                       e[0][2] * (e[1][0] * e[2][1] - e[1][1] * e[2][0]);
    if (det > 0) continue;  // rest tets are positively oriented (mesh validation)
    ++counts[0];
    const gid_t g = w.layout[static_cast<std::size_t>(k)].tet_begin + static_cast<gid_t>(t - object_first);
    if (g < first) {
      first = g;
      first_local = t;
    }
  }
  MPI_Allreduce(MPI_IN_PLACE, counts, 2, MPI_INT64_T, MPI_SUM, comm_);
  if (counts[1] == 0 || !(static_cast<double>(counts[0]) > max_fraction * static_cast<double>(counts[1]))) return "";
  gid_t lowest_gid = first;
  MPI_Allreduce(MPI_IN_PLACE, &lowest_gid, 1, MPI_INT64_T, MPI_MIN, comm_);
  const int owner = owner_of(comm_, first == lowest_gid && first != kNone);
  std::string text;
  if (rank_ == owner) {
    const int k = w.tet_object[first_local];
    const ObjectLayout& L = w.layout[static_cast<std::size_t>(k)];
    std::ostringstream s;
    s.precision(3);
    s << counts[0] << " of " << counts[1] << " movable elements inverted (" << 100.0 * static_cast<double>(counts[0]) / static_cast<double>(counts[1])
      << "%, limit " << 100 * max_fraction << "%, simulation.limits.max_inverted_fraction), the first element "
      << first - L.tet_begin << " of object '" << scene_.objects[static_cast<std::size_t>(k)].name << "' (global tet "
      << first << ")";
    text = s.str();
  }
  return from_rank(comm_, owner, text);
}

std::string Simulator::locate_energy() {
  const World& w = world_;
  // Kinetic energy per owned object; the largest over all ranks.
  double best = -1;
  int best_object = -1;
  for (int k : w.owned_objects) {
    double e = 0;
    for (std::size_t i = 0; i < w.n_owned; ++i)
      if (w.vertex_object[i] == k && w.inv_mass[i] != 0) e += 0.5 * w.mass[i] * speed2(&w.v[3 * i]);
    if (e > best) {
      best = e;
      best_object = k;
    }
  }
  const auto [top, top_rank] = top_of(comm_, best);
  if (top < 0) return "";
  std::string text;
  if (rank_ == top_rank) {
    const auto [s2, local] = fastest(w, best_object);
    std::ostringstream s;
    s.precision(4);
    s << "the most kinetic energy (" << best << " J) in object '" << scene_.objects[static_cast<std::size_t>(best_object)].name
      << "', fastest at " << std::sqrt(s2) << " m/s: " << describe_vertex(scene_, w, local);
    text = s.str();
  }
  return from_rank(comm_, top_rank, text);
}

}  // namespace softcontact
