#pragma once
// The state the next step needs from this one, for one rank's owned vertices: what a
// checkpoint saves and restores, and what migration carries to an object's new rank
// (Simulator::snapshot and Simulator::restore; docs/architecture.md, "Data").
#include <cstdint>
#include <vector>

#include "softcontact/contact.hpp"

namespace softcontact {

struct StepState {
  std::int64_t step = 0;              ///< steps done
  std::int64_t anchor_step = 0;       ///< the contact response's step counter (friction anchors)
  std::vector<double> x, x_prev, v;   ///< owned rows (n_owned, 3), in the World's local order
  std::vector<StictionAnchor> anchors;///< (n_owned)
};

}  // namespace softcontact
