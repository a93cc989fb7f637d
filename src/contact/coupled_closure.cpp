#include "coupled_closure.hpp"

#include <Eigen/Dense>
#include <Eigen/Sparse>
#include <Eigen/SparseCholesky>
#include <algorithm>
#include <cmath>
#include <limits>
#include <unordered_map>

namespace softcontact::contact {

std::vector<double> solve_closure(const std::vector<ClosureRow>& rows, double eps, ClosureStats& stats) {
  stats = ClosureStats{};
  const std::size_t nr = rows.size();
  std::vector<double> x(nr, 0.0);
  if (nr == 0) return x;
  // Vertices in order of first appearance in the rows (a fixed order), each with its
  // (row, b) entries in row order: the matrix and every sum in it come out the same
  // wherever the rows were gathered.
  std::unordered_map<gid_t, std::int32_t> index;
  std::vector<double> inv_mass;
  std::vector<std::vector<std::pair<std::int32_t, double>>> entries;
  std::vector<char> active(nr, 0);
  for (std::size_t q = 0; q < nr; ++q) {
    const ClosureRow& r = rows[q];
    if (!(r.depth > 0)) continue;
    for (std::int64_t e = 0; e < r.nv; ++e) {
      if (r.b[e] == 0 || !(r.inv_mass[e] > 0)) continue;
      const auto [it, fresh] = index.emplace(r.vertex[e], static_cast<std::int32_t>(entries.size()));
      if (fresh) {
        entries.emplace_back();
        inv_mass.push_back(r.inv_mass[e]);
      }
      entries[static_cast<std::size_t>(it->second)].emplace_back(static_cast<std::int32_t>(q), r.b[e]);
      active[q] = 1;
    }
  }
  for (char a : active) stats.rows += a;
  std::vector<double> diag(nr, 0.0);
  for (std::size_t v = 0; v < entries.size(); ++v)
    for (const auto& [q, b] : entries[v]) diag[static_cast<std::size_t>(q)] += b * b * inv_mass[v];

  // Connected groups: rows that share a movable vertex, transitively. Each group is its
  // own system (A is block diagonal over them); most are one to a few collisions.
  std::vector<std::int32_t> parent(nr);
  for (std::size_t q = 0; q < nr; ++q) parent[q] = static_cast<std::int32_t>(q);
  auto find = [&](std::int32_t q) {
    while (parent[static_cast<std::size_t>(q)] != q) {
      parent[static_cast<std::size_t>(q)] = parent[static_cast<std::size_t>(parent[static_cast<std::size_t>(q)])];
      q = parent[static_cast<std::size_t>(q)];
    }
    return q;
  };
  for (const auto& e : entries)
    for (const auto& [q, b] : e) {
      const std::int32_t ra = find(e.front().first), rb = find(q);
      if (ra != rb) parent[static_cast<std::size_t>(std::max(ra, rb))] = std::min(ra, rb);
    }
  // Group of each row (by its smallest row), its rows and its vertices, in ascending order.
  std::vector<std::int32_t> group(nr, -1), root_group(nr, -1);
  std::vector<std::vector<std::int32_t>> group_rows, group_vertices;
  for (std::size_t q = 0; q < nr; ++q) {
    if (!active[q]) continue;
    const auto r = static_cast<std::size_t>(find(static_cast<std::int32_t>(q)));
    if (root_group[r] < 0) {
      root_group[r] = static_cast<std::int32_t>(group_rows.size());
      group_rows.emplace_back();
      group_vertices.emplace_back();
    }
    group[q] = root_group[r];
    group_rows[static_cast<std::size_t>(group[q])].push_back(static_cast<std::int32_t>(q));
  }
  for (std::size_t v = 0; v < entries.size(); ++v)
    group_vertices[static_cast<std::size_t>(group[static_cast<std::size_t>(entries[v].front().first)])].push_back(
        static_cast<std::int32_t>(v));

  std::vector<std::int32_t> local(nr, -1);
  for (std::size_t g = 0; g < group_rows.size(); ++g) {
    const std::vector<std::int32_t>& gr = group_rows[g];
    const auto n = static_cast<Eigen::Index>(gr.size());
    for (std::size_t i = 0; i < gr.size(); ++i) local[static_cast<std::size_t>(gr[i])] = static_cast<std::int32_t>(i);
    for (int pass = 0; pass < kMaxPasses; ++pass) {
      // A over the group's rows (inactive ones: identity, x = 0), summed vertex by vertex
      // in a fixed order: dense for small groups, triplets for large ones.
      const bool dense = n <= kDenseRows;
      Eigen::MatrixXd D0;
      std::vector<Eigen::Triplet<double>> trip;
      if (dense) D0 = Eigen::MatrixXd::Zero(n, n);
      for (std::int32_t v : group_vertices[g]) {
        const auto& ev = entries[static_cast<std::size_t>(v)];
        const double im = inv_mass[static_cast<std::size_t>(v)];
        for (const auto& [qa, ba] : ev) {
          if (!active[static_cast<std::size_t>(qa)]) continue;
          const double* na = rows[static_cast<std::size_t>(qa)].n;
          const std::int32_t ia = local[static_cast<std::size_t>(qa)];
          for (const auto& [qb, bb] : ev) {
            if (!active[static_cast<std::size_t>(qb)]) continue;
            const double* nb = rows[static_cast<std::size_t>(qb)].n;
            const double val = ba * bb * (na[0] * nb[0] + na[1] * nb[1] + na[2] * nb[2]) * im;
            if (dense) D0(ia, local[static_cast<std::size_t>(qb)]) += val;
            else trip.emplace_back(ia, local[static_cast<std::size_t>(qb)], val);
          }
        }
      }
      Eigen::VectorXd rhs = Eigen::VectorXd::Zero(n), reg = Eigen::VectorXd::Zero(n);
      for (Eigen::Index i = 0; i < n; ++i) {
        const auto q = static_cast<std::size_t>(gr[static_cast<std::size_t>(i)]);
        if (active[q]) {
          reg[i] = eps * diag[q];
          rhs[i] = rows[q].depth;
        } else {
          reg[i] = 1.0;  // no unknown: x = 0
        }
      }
      ++stats.passes;
      Eigen::VectorXd sol, res;
      if (dense) {
        Eigen::MatrixXd M = D0;
        M.diagonal() += reg;
        sol = M.ldlt().solve(rhs);
        res = D0 * sol - rhs;  // the gap each row is left with by A itself
      } else {
        Eigen::SparseMatrix<double> S0(n, n);
        S0.setFromTriplets(trip.begin(), trip.end());
        Eigen::SparseMatrix<double> S = S0;
        for (Eigen::Index i = 0; i < n; ++i) S.coeffRef(i, i) += reg[i];
        Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> ldlt(S);
        if (ldlt.info() != Eigen::Success) {
          stats.failed = true;
          for (std::int32_t q : gr) x[static_cast<std::size_t>(q)] = std::numeric_limits<double>::quiet_NaN();
          break;
        }
        sol = ldlt.solve(rhs);
        res = S0 * sol - rhs;
      }
      // Rows that would pull are dropped (first: a contradiction between two depths along
      // one direction shows as one large negative x); rows that the solve cannot close
      // (the system is inconsistent there: the gap left exceeds kResidual of the depth)
      // are left to the caller's closed form. The rest is solved again without them.
      const bool last = pass + 1 == kMaxPasses;
      bool changed = false;
      for (Eigen::Index i = 0; i < n; ++i) {
        const auto q = static_cast<std::size_t>(gr[static_cast<std::size_t>(i)]);
        if (!active[q]) continue;
        x[q] = sol[i];
        if (x[q] < 0) {
          x[q] = 0;
          active[q] = 0;
          ++stats.dropped;
          changed = true;
        }
      }
      if (changed && !last) continue;  // the residuals of the others change without them
      for (Eigen::Index i = 0; i < n; ++i) {
        const auto q = static_cast<std::size_t>(gr[static_cast<std::size_t>(i)]);
        if (!active[q] || std::abs(res[i]) <= kResidual * rows[q].depth) continue;
        x[q] = std::numeric_limits<double>::quiet_NaN();
        active[q] = 0;
        ++stats.local;
        changed = true;
      }
      if (!changed || last) break;
    }
  }
  return x;
}

}  // namespace softcontact::contact
