#pragma once
// Wall-clock seconds spent in each phase of Algorithm 1 (method.md), per step: what the
// Simulator accumulates, the diagnostics CSV writes and `softcontact bench` reports.
#include <ctime>

namespace softcontact {

/// CPU seconds of the process so far (all its threads): the rebalance's work measure,
/// which a rank sharing a core with others (an oversubscribed node) is not charged for.
/// The phases subtract what their exchanges spend (a wait polls, and would count as work).
inline double process_cpu_seconds() {
  timespec ts{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

struct PhaseTimes {
  double forces = 0, integrate = 0, detect = 0, depth = 0, contact = 0, comm = 0, output = 0;
  /// Process CPU seconds (all threads) of forces, detection and depth: the rebalance's
  /// work measure, not part of total().
  double work_cpu = 0;
  PhaseTimes& operator+=(const PhaseTimes& o) {
    forces += o.forces;
    integrate += o.integrate;
    detect += o.detect;
    depth += o.depth;
    contact += o.contact;
    comm += o.comm;
    output += o.output;
    work_cpu += o.work_cpu;
    return *this;
  }
  PhaseTimes scaled(double s) const {
    return {forces * s, integrate * s, detect * s, depth * s, contact * s, comm * s, output * s, work_cpu * s};
  }
  double total() const { return forces + integrate + detect + depth + contact + comm + output; }
};

}  // namespace softcontact
