// The measures of tests/scenes/validation_test_archway.cpp and long_test_archway.cpp:
// the voussoirs' poses (mass-weighted centroid, best-fitting rotation) and a standing run
// of inputs/archway.yaml over a given simulated time. Criteria and their reasons are in
// validation_test_archway.cpp's header comment.
#pragma once

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <mpi.h>

#include "softcontact/diagnostics.hpp"
#include "softcontact/scene.hpp"
#include "softcontact/simulator.hpp"
#include "softcontact/verify.hpp"

namespace softcontact::archway_test {

using Mat = std::array<double, 9>;  // row-major 3x3

inline double det(const Mat& a) {
  return a[0] * (a[4] * a[8] - a[5] * a[7]) - a[1] * (a[3] * a[8] - a[5] * a[6]) + a[2] * (a[3] * a[7] - a[4] * a[6]);
}

/// Rotation factor of the polar decomposition of a (det a > 0), by Newton's iteration
/// X <- (X + X^-T) / 2; the angle of that rotation in degrees. Returns 180 when det a <= 0
/// (a stone turned inside out or crushed flat: certainly not standing).
inline double rotation_angle_deg(Mat x) {
  if (det(x) <= 0) return 180.0;
  for (int it = 0; it < 50; ++it) {
    const double d = det(x);
    // X^-T = cof(X) / det X
    const Mat cof = {x[4] * x[8] - x[5] * x[7], x[5] * x[6] - x[3] * x[8], x[3] * x[7] - x[4] * x[6],
                     x[2] * x[7] - x[1] * x[8], x[0] * x[8] - x[2] * x[6], x[1] * x[6] - x[0] * x[7],
                     x[1] * x[5] - x[2] * x[4], x[2] * x[3] - x[0] * x[5], x[0] * x[4] - x[1] * x[3]};
    double change = 0;
    for (int k = 0; k < 9; ++k) {
      const double n = 0.5 * (x[k] + cof[k] / d);
      change += (n - x[k]) * (n - x[k]);
      x[k] = n;
    }
    if (change < 1e-24) break;
  }
  const double c = std::clamp((x[0] + x[4] + x[8] - 1) / 2, -1.0, 1.0);
  return std::acos(c) * 180.0 / M_PI;
}

struct Pose {
  std::array<double, 3> centroid{};
  double angle_deg = 0;
};

/// The voussoirs of an archway scene (objects named voussoir_* and keystone), their rest
/// positions, and their pose now.
class Arch {
public:
  explicit Arch(const Simulator& s) {
    const auto& objects = s.scene().objects;
    for (std::size_t k = 0; k < objects.size(); ++k) {
      const std::string& n = objects[k].name;
      if (n.rfind("voussoir_", 0) == 0 || n == "keystone") {
        if (n == "keystone") keystone_ = static_cast<int>(stones_.size());
        if (n == "voussoir_0") springer_ = static_cast<int>(stones_.size());
        stones_.push_back(static_cast<int>(k));
      }
    }
    const World& w = s.world();
    members_.resize(stones_.size());
    for (std::size_t i = 0; i < w.n_owned; ++i)
      for (std::size_t j = 0; j < stones_.size(); ++j)
        if (w.vertex_object[i] == stones_[j]) members_[j].push_back(i);
    rest_x_ = w.x;
    rest_ = poses(s);
    double top = -1e300, bottom = 1e300;
    for (std::size_t i : members_[keystone_]) top = std::max(top, w.x[3 * i + 2]);
    for (std::size_t i : members_[springer_]) bottom = std::min(bottom, w.x[3 * i + 2]);
    rise_ = top - bottom;
  }

  std::size_t size() const { return stones_.size(); }
  int keystone() const { return keystone_; }
  double rise() const { return rise_; }
  const std::vector<Pose>& rest() const { return rest_; }

  std::vector<Pose> poses(const Simulator& s) const {
    const World& w = s.world();
    std::vector<Pose> p(stones_.size());
    for (std::size_t j = 0; j < stones_.size(); ++j) {
      double m = 0;
      std::array<double, 3> c{}, c0{};
      for (std::size_t i : members_[j]) {
        m += w.mass[i];
        for (int d = 0; d < 3; ++d) {
          c[d] += w.mass[i] * w.x[3 * i + d];
          c0[d] += w.mass[i] * rest_x_[3 * i + d];
        }
      }
      for (int d = 0; d < 3; ++d) c[d] /= m, c0[d] /= m;
      Mat a{};
      for (std::size_t i : members_[j])
        for (int r = 0; r < 3; ++r)
          for (int q = 0; q < 3; ++q)
            a[3 * r + q] += w.mass[i] * (w.x[3 * i + r] - c[r]) * (rest_x_[3 * i + q] - c0[q]);
      p[j].centroid = c;
      p[j].angle_deg = rotation_angle_deg(a);
    }
    return p;
  }

private:
  std::vector<int> stones_;                      // object index of each stone
  std::vector<std::vector<std::size_t>> members_;
  std::vector<double> rest_x_;
  std::vector<Pose> rest_;
  int keystone_ = -1, springer_ = -1;
  double rise_ = 0;
};

inline double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

/// What a standing run of the mu_s = 0.95 arch measured.
struct StandingRun {
  double end = 0;                   // simulated time run [s]
  std::int64_t steps = 0;
  double wall = 0;                  // [s]
  double rise = 0;                  // h [m]
  double worst_drop = 0;            // the keystone centroid's largest drop below rest [m]
  double worst_angle = 0;           // the largest rotation of any stone from rest [deg]
  int worst_angle_stone = -1;
  double worst_drift = INFINITY;    // the largest distance between a stone's mean centroid
                                    // over [1, 2) s and over the last second [m]
  double drift_span = 0;            // the time between those two windows' middles [s]
  double contacts = 0;              // contacts, averaged over every 0.1 s
  double worst_residual = 0;        // residual penetration, worst of every 0.1 s [median edges]
  double collapsed_at = -1;         // when the keystone fell past half the rise [s], or -1
  std::size_t stones = 0;
  bool found_keystone = false;
  // With a check every N steps (run_standing's verify_every > 0): the check of
  // `softcontact verify` (Simulator::verify, as `softcontact run --verify-every N`) at
  // step 0, every N-th step and the last one; its maxima, and the last check's inverted
  // tets (-1: no check).
  VerifyMaxima checks;
  std::int64_t last_inverted = -1;
};

/// Runs the scene at `path` (the arch of inputs/archway.yaml) from rest for `seconds` of
/// simulated time (all of its end_time when infinite), sampling the stones' poses 100
/// times per second; stops early once the keystone has fallen past half the rise. With
/// `verify_every` > 0, also the check of `softcontact verify` at step 0, every
/// `verify_every` steps and the last step (StandingRun::checks).
inline StandingRun run_standing(const std::string& path, double seconds, std::int64_t verify_every = 0) {
  const auto t0 = std::chrono::steady_clock::now();
  const Scene scene = load_scene(path);
  Simulator s(MPI_COMM_WORLD, scene);
  const Arch arch(s);
  StandingRun r;
  r.stones = arch.size();
  r.found_keystone = arch.keystone() >= 0;
  if (r.stones != 9 || !r.found_keystone) return r;
  const double dt = scene.sim.dt, h = arch.rise();
  const std::int64_t whole = total_steps(scene.sim);
  const std::int64_t steps = std::isfinite(seconds) ? std::min<std::int64_t>(whole, std::llround(seconds / dt)) : whole;
  const std::int64_t sample = std::max<std::int64_t>(1, std::llround(0.01 / dt));   // 100 samples/s
  const std::int64_t measure_every = std::max<std::int64_t>(1, std::llround(0.1 / dt));
  r.end = static_cast<double>(steps) * dt;
  r.steps = steps;
  r.rise = h;

  int measured = 0;
  std::vector<std::array<double, 3>> early(arch.size()), late(arch.size());
  int n_early = 0, n_late = 0;
  VerifyFrame checked;
  std::int64_t checked_step = -1;
  auto check = [&](std::int64_t k) {
    checked = s.verify(true);
    checked_step = k;
    r.checks.add(checked);
    r.last_inverted = checked.inverted;
  };
  if (verify_every > 0) check(0);
  for (std::int64_t k = 1; k <= steps; ++k) {
    s.step();
    if (verify_every > 0 && k % verify_every == 0) check(k);
    if (k % measure_every == 0) {
      StepDiagnostics d;
      s.measure(d, checked_step == k ? &checked : nullptr);
      r.worst_residual = std::max(r.worst_residual, d.residual_penetration);
      r.contacts += static_cast<double>(d.contacts);
      ++measured;
    }
    if (k % sample != 0 && k != steps) continue;
    const double t = s.time();
    const std::vector<Pose> p = arch.poses(s);
    r.worst_drop = std::max(r.worst_drop, arch.rest()[arch.keystone()].centroid[2] - p[arch.keystone()].centroid[2]);
    for (std::size_t j = 0; j < p.size(); ++j)
      if (p[j].angle_deg > r.worst_angle) r.worst_angle = p[j].angle_deg, r.worst_angle_stone = static_cast<int>(j);
    const bool in_early = t >= 1.0 && t < 2.0, in_late = t >= r.end - 1.0 && t >= 2.0;
    for (std::size_t j = 0; j < p.size(); ++j)
      for (int d = 0; d < 3; ++d) {
        if (in_early) early[j][d] += p[j].centroid[d];
        if (in_late) late[j][d] += p[j].centroid[d];
      }
    n_early += in_early;
    n_late += in_late;
    if (r.worst_drop > 0.5 * h) {  // collapsed: no point in running on
      r.collapsed_at = t;
      if (verify_every > 0 && checked_step != k) check(k);
      break;
    }
    if (verify_every > 0 && k == steps && checked_step != k) check(k);
  }
  if (n_early && n_late) {
    r.worst_drift = 0;
    for (std::size_t j = 0; j < arch.size(); ++j) {
      double d2 = 0;
      for (int d = 0; d < 3; ++d) {
        const double diff = late[j][d] / n_late - early[j][d] / n_early;
        d2 += diff * diff;
      }
      r.worst_drift = std::max(r.worst_drift, std::sqrt(d2));
    }
    r.drift_span = (r.end - 0.5) - 1.5;
  }
  if (measured) r.contacts /= measured;
  r.wall = seconds_since(t0);
  return r;
}

/// Prints the run as a [measured] line (recorded in docs/validation.md) and checks the
/// standing criteria of validation_test_archway.cpp's header comment: the drift bound is
/// a creep rate, 0.25 mm/s between the two windows (2 mm over the 10 s scene's 8 s).
inline void expect_stands(const StandingRun& r) {
  ASSERT_EQ(r.stones, 9u);
  ASSERT_TRUE(r.found_keystone);
  std::printf("[measured] archway mu_s = 0.95, %.1f s simulated (%lld steps) in %.0f s wall: rise %.4f m; "
              "largest keystone drop %.4f m (%.3f of the rise); largest stone rotation %.2f deg (stone %d); "
              "largest drift of a mean centroid from [1, 2] s to the last second %.3g m over %.1f s; "
              "contacts %.0f on average; worst residual penetration %.3g median edges; collapsed at t = %.3f s (-1: "
              "never)\n",
              r.end, static_cast<long long>(r.steps), r.wall, r.rise, r.worst_drop, r.worst_drop / r.rise, r.worst_angle,
              r.worst_angle_stone, r.worst_drift, r.drift_span, r.contacts, r.worst_residual, r.collapsed_at);
  EXPECT_LT(r.collapsed_at, 0.0) << "the arch collapsed";
  EXPECT_LT(r.worst_drop, 0.15 * r.rise);
  EXPECT_LT(r.worst_angle, 10.0);
  EXPECT_GE(r.drift_span, 0.99) << "the run is too short to measure a creep";
  EXPECT_LT(r.worst_drift, 0.25e-3 * r.drift_span);
}

/// Prints the in-run checks of a run with verify_every > 0 and holds them to the bounds
/// of a `softcontact verify` run: the deepest surface vertex inside another body
/// (`max_depth` median edges) and the fastest vertex (`max_speed_ratio` x v_ff) at every
/// check, `max_inverted` inverted tets at the last one.
inline void expect_contact_within(const StandingRun& r, double max_depth, double max_speed_ratio,
                                  std::int64_t max_inverted) {
  ASSERT_GT(r.checks.checks, 0) << "no in-run check";
  std::printf("[measured] in-run checks: %lld; deepest surface vertex %.3g median edges (step %lld); fastest "
              "vertex %.3g x v_ff (step %lld); inverted tets at most %.0f, at the last check %lld\n",
              static_cast<long long>(r.checks.checks), r.checks.surface_depth.value,
              static_cast<long long>(r.checks.surface_depth.step), r.checks.speed_ratio.value,
              static_cast<long long>(r.checks.speed_ratio.step), r.checks.inverted.value,
              static_cast<long long>(r.last_inverted));
  EXPECT_LE(r.checks.surface_depth.value, max_depth);
  EXPECT_LE(r.checks.speed_ratio.value, max_speed_ratio);
  EXPECT_LE(r.last_inverted, max_inverted);
}

}  // namespace softcontact::archway_test
