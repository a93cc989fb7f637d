#include "coupled_closure.hpp"

#include <Eigen/Dense>
#include <Eigen/Sparse>
#include <Eigen/SparseCholesky>
#include <algorithm>
#include <cmath>
#include <limits>

#include "softcontact/loop_failure.hpp"

namespace softcontact::contact {

namespace {

// One group's matrix: A (unregularised, for the residuals) and the factorisation of
// A + diag(reg) with some rows held at x = 0 (their row and column replaced by the
// identity's). A sparse group keeps its ordering and symbolic factorisation when rows
// are held: the pattern stays (held entries become explicit zeros), only the numeric
// factorisation is repeated.
class GroupSystem {
 public:
  GroupSystem(Eigen::Index n, bool dense) : n_(n), dense_(dense) {
    if (dense_) a0_ = Eigen::MatrixXd::Zero(n, n);
  }
  void add(Eigen::Index i, Eigen::Index j, double v) {
    if (dense_) a0_(i, j) += v;
    else trip_.emplace_back(static_cast<int>(i), static_cast<int>(j), v);
  }
  // Factorises A + diag(reg) with no row held; false when the factorisation fails.
  bool factorize(const Eigen::VectorXd& reg) {
    reg_ = reg;
    if (dense_) {
      Eigen::MatrixXd m = a0_;
      m.diagonal() += reg;
      dense_ldlt_.compute(m);
      return dense_ldlt_.info() == Eigen::Success;
    }
    for (Eigen::Index i = 0; i < n_; ++i) trip_.emplace_back(static_cast<int>(i), static_cast<int>(i), 0.0);
    s0_.resize(n_, n_);
    s0_.setFromTriplets(trip_.begin(), trip_.end());  // every diagonal entry present
    m_ = s0_;
    for (Eigen::Index i = 0; i < n_; ++i) m_.coeffRef(i, i) += reg[i];
    sparse_.analyzePattern(m_);
    sparse_.factorize(m_);
    return sparse_.info() == Eigen::Success;
  }
  // Factorises again with the rows `held` (state != 0) taken out. The held set only grows
  // within a group (solve_closure never releases a row), so entries zeroed in m_ by an
  // earlier call stay right.
  bool refactorize(const std::vector<char>& held) {
    if (dense_) {
      Eigen::MatrixXd m = a0_;
      m.diagonal() += reg_;
      for (Eigen::Index i = 0; i < n_; ++i)
        if (held[static_cast<std::size_t>(i)]) {
          m.row(i).setZero();
          m.col(i).setZero();
          m(i, i) = 1;
        }
      dense_ldlt_.compute(m);
      return dense_ldlt_.info() == Eigen::Success;
    }
    for (Eigen::Index c = 0; c < m_.outerSize(); ++c)
      for (Eigen::SparseMatrix<double>::InnerIterator it(m_, c); it; ++it) {
        const bool hr = held[static_cast<std::size_t>(it.row())] != 0, hc = held[static_cast<std::size_t>(c)] != 0;
        if (it.row() == c) it.valueRef() = hr ? 1.0 : s0_.coeff(c, c) + reg_[c];
        else if (hr || hc) it.valueRef() = 0;
      }
    sparse_.factorize(m_);
    return sparse_.info() == Eigen::Success;
  }
  Eigen::VectorXd solve(const Eigen::VectorXd& b) const {
    return dense_ ? Eigen::VectorXd(dense_ldlt_.solve(b)) : Eigen::VectorXd(sparse_.solve(b));
  }
  Eigen::VectorXd times_a(const Eigen::VectorXd& x) const {
    return dense_ ? Eigen::VectorXd(a0_ * x) : Eigen::VectorXd(s0_ * x);
  }

 private:
  Eigen::Index n_;
  bool dense_;
  Eigen::VectorXd reg_;
  Eigen::MatrixXd a0_;
  Eigen::LDLT<Eigen::MatrixXd> dense_ldlt_;
  std::vector<Eigen::Triplet<double>> trip_;
  Eigen::SparseMatrix<double> s0_, m_;
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> sparse_;
};

}  // namespace

std::vector<double> solve_closure(const std::vector<ClosureRow>& rows, double eps, ClosureStats& stats) {
  stats = ClosureStats{};
  const std::size_t nr = rows.size();
  std::vector<double> x(nr, 0.0);
  if (nr == 0) return x;
  // The movable entries (vertex, row, b), sorted by global vertex id, then row, then
  // entry (a stable sort of the entries taken in row order): each vertex's entries are
  // one run, and every sum below runs in that fixed order wherever the rows were
  // gathered (global ids are >= 0).
  struct Entry {
    gid_t v;
    std::int32_t q, k;
    double b, im;
  };
  std::vector<Entry> ent;
  ent.reserve(5 * nr);
  std::vector<char> active(nr, 0);
  for (std::size_t q = 0; q < nr; ++q) {
    const ClosureRow& r = rows[q];
    if (!(r.depth > 0)) continue;
    for (std::int64_t e = 0; e < r.nv; ++e) {
      if (r.b[e] == 0 || !(r.inv_mass[e] > 0)) continue;
      ent.push_back({r.vertex[e], static_cast<std::int32_t>(q), static_cast<std::int32_t>(e), r.b[e], r.inv_mass[e]});
      active[q] = 1;
    }
  }
  {  // stable LSD radix sort by vertex id (the entries are already in row, entry order)
    gid_t top = 0;
    for (const Entry& e : ent) top = std::max(top, e.v);
    std::vector<Entry> tmp(ent.size());
    constexpr int kBits = 11;
    for (int shift = 0; shift == 0 || (top >> shift) > 0; shift += kBits) {
      std::size_t count[(1 << kBits) + 1] = {};
      for (const Entry& e : ent) ++count[((e.v >> shift) & ((1 << kBits) - 1)) + 1];
      for (int b = 0; b < (1 << kBits); ++b) count[b + 1] += count[b];
      for (const Entry& e : ent) tmp[count[(e.v >> shift) & ((1 << kBits) - 1)]++] = e;
      ent.swap(tmp);
    }
  }
  std::vector<std::size_t> run_begin;  // start of each vertex's run in ent, then ent.size()
  for (std::size_t i = 0; i < ent.size(); ++i)
    if (i == 0 || ent[i].v != ent[i - 1].v) run_begin.push_back(i);
  run_begin.push_back(ent.size());
  const std::size_t nruns = run_begin.size() - 1;
  for (char a : active) stats.rows += a;
  std::vector<double> diag(nr, 0.0);
  for (const Entry& e : ent) diag[static_cast<std::size_t>(e.q)] += e.b * e.b * e.im;

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
  for (std::size_t r = 0; r < nruns; ++r)
    for (std::size_t i = run_begin[r] + 1; i < run_begin[r + 1]; ++i) {
      const std::int32_t ra = find(ent[run_begin[r]].q), rb = find(ent[i].q);
      if (ra != rb) parent[static_cast<std::size_t>(std::max(ra, rb))] = std::min(ra, rb);
    }
  // Group of each row (numbered by its smallest row), its rows and its vertex runs, in
  // ascending order.
  std::vector<std::int32_t> group(nr, -1), root_group(nr, -1);
  std::vector<std::vector<std::int32_t>> group_rows, group_runs;
  for (std::size_t q = 0; q < nr; ++q) {
    if (!active[q]) continue;
    const auto r = static_cast<std::size_t>(find(static_cast<std::int32_t>(q)));
    if (root_group[r] < 0) {
      root_group[r] = static_cast<std::int32_t>(group_rows.size());
      group_rows.emplace_back();
      group_runs.emplace_back();
    }
    group[q] = root_group[r];
    group_rows[static_cast<std::size_t>(group[q])].push_back(static_cast<std::int32_t>(q));
  }
  for (std::size_t r = 0; r < nruns; ++r)
    group_runs[static_cast<std::size_t>(group[static_cast<std::size_t>(ent[run_begin[r]].q)])].push_back(
        static_cast<std::int32_t>(r));

  const double nan = std::numeric_limits<double>::quiet_NaN();
  std::vector<std::int32_t> local(nr, -1);
  // The groups are independent (each writes only its own rows): in parallel, largest
  // first (tori200's largest is more than half of all collisions).
  // An isolated collision (a group of one) takes the closed form itself: A x = |d| exactly.
  std::vector<std::int32_t> by_size;
  for (std::size_t g = 0; g < group_rows.size(); ++g)
    if (group_rows[g].size() > 1) by_size.push_back(static_cast<std::int32_t>(g));
    else x[static_cast<std::size_t>(group_rows[g][0])] = rows[static_cast<std::size_t>(group_rows[g][0])].depth /
                                                          diag[static_cast<std::size_t>(group_rows[g][0])];
  std::stable_sort(by_size.begin(), by_size.end(), [&](std::int32_t a, std::int32_t b) {
    return group_rows[static_cast<std::size_t>(a)].size() > group_rows[static_cast<std::size_t>(b)].size();
  });
  std::int64_t passes = 0, dropped = 0, kept_local = 0;
  int failed = 0;
  const auto ngroups = static_cast<std::ptrdiff_t>(by_size.size());
  LoopFailure failure;  // a group whose system cannot be allocated: rethrown after the loop
#pragma omp parallel for schedule(dynamic, 1) reduction(+ : passes, dropped, kept_local) reduction(max : failed)
  for (std::ptrdiff_t t = 0; t < ngroups; ++t) {
    try {
      const auto g = static_cast<std::size_t>(by_size[static_cast<std::size_t>(t)]);
      const std::vector<std::int32_t>& gr = group_rows[g];
      const auto n = static_cast<Eigen::Index>(gr.size());
      for (std::size_t i = 0; i < gr.size(); ++i) local[static_cast<std::size_t>(gr[i])] = static_cast<std::int32_t>(i);
      // A over the group's rows, summed vertex by vertex in a fixed order.
      GroupSystem sys(n, n <= kDenseRows);
      for (std::int32_t r : group_runs[g]) {
        const std::size_t b0 = run_begin[static_cast<std::size_t>(r)], b1 = run_begin[static_cast<std::size_t>(r) + 1];
        for (std::size_t a = b0; a < b1; ++a) {
          const double* na = rows[static_cast<std::size_t>(ent[a].q)].n;
          const std::int32_t ia = local[static_cast<std::size_t>(ent[a].q)];
          for (std::size_t b = b0; b < b1; ++b) {
            const double* nb = rows[static_cast<std::size_t>(ent[b].q)].n;
            sys.add(ia, local[static_cast<std::size_t>(ent[b].q)],
                    ent[a].b * ent[b].b * (na[0] * nb[0] + na[1] * nb[1] + na[2] * nb[2]) * ent[a].im);
          }
        }
      }
      Eigen::VectorXd rhs(n), reg(n);
      for (Eigen::Index i = 0; i < n; ++i) {
        const auto q = static_cast<std::size_t>(gr[static_cast<std::size_t>(i)]);
        rhs[i] = rows[q].depth;
        reg[i] = eps * diag[q];
      }
      ++passes;
      if (!sys.factorize(reg)) {
        failed = 1;
        for (std::int32_t q : gr) x[static_cast<std::size_t>(q)] = nan;
        continue;
      }
      Eigen::VectorXd sol = sys.solve(rhs);
      std::vector<char> state(static_cast<std::size_t>(n), 0);  // 0 active, 1 dropped, 2 local
      // Solved again without the rows taken out: the same ordering, a new factorisation.
      bool ok = true;
      auto resolve = [&] {
        ++passes;
        ok = sys.refactorize(state);
        if (!ok) return;
        Eigen::VectorXd r = rhs;
        for (Eigen::Index i = 0; i < n; ++i)
          if (state[static_cast<std::size_t>(i)]) r[i] = 0;
        sol = sys.solve(r);
      };
      // Rows that would pull are dropped (first: a contradiction between two depths along
      // one direction shows as one large negative x); rows that the solve cannot close
      // (the system is inconsistent there: the gap left exceeds kResidual of the depth)
      // are left to the caller's closed form. The rest is solved again without them.
      for (int pass = 0; pass < kMaxPasses; ++pass) {
        const bool last = pass + 1 == kMaxPasses;
        bool changed = false;
        for (Eigen::Index i = 0; i < n; ++i)
          if (state[static_cast<std::size_t>(i)] == 0 && sol[i] < 0) {
            ++dropped;
            changed = true;
            state[static_cast<std::size_t>(i)] = 1;  // in the last pass clamped, not solved again
            sol[i] = 0;
          }
        if (changed && !last) {
          resolve();
          if (!ok) break;
          continue;  // the residuals of the others change without them
        }
        const Eigen::VectorXd res = sys.times_a(sol) - rhs;  // the gap each row is left with by A itself
        for (Eigen::Index i = 0; i < n; ++i) {
          if (state[static_cast<std::size_t>(i)] != 0 || std::abs(res[i]) <= kResidual * rhs[i]) continue;
          ++kept_local;
          changed = true;
          state[static_cast<std::size_t>(i)] = 2;
        }
        if (!changed || last) break;
        resolve();
        if (!ok) break;
      }
      if (!ok) {
        failed = 1;
        for (std::int32_t q : gr) x[static_cast<std::size_t>(q)] = nan;
        continue;
      }
      for (Eigen::Index i = 0; i < n; ++i) {
        const auto q = static_cast<std::size_t>(gr[static_cast<std::size_t>(i)]);
        const char st = state[static_cast<std::size_t>(i)];
        x[q] = st == 0 ? sol[i] : (st == 1 ? 0.0 : nan);
      }
    } catch (...) {
      failure.record(static_cast<std::size_t>(t));
    }
  }
  failure.rethrow();
  stats.passes = passes;
  stats.dropped = dropped;
  stats.local = kept_local;
  stats.failed = failed != 0;
  return x;
}

}  // namespace softcontact::contact
