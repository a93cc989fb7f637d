#pragma once
// Thickness of an object, for the tunnelling diagnostic (method.md, "Collision
// detection": a point that moves more than the thickness of a body within one step can
// cross it without ever being inside it).
//
// Definition: the smallest extent of the object's vertices along six directions, its
// three principal axes (eigenvectors of the covariance of the vertex positions) and the
// three coordinate axes:
//     thickness = min_e ( max_v (x_v . e) - min_v (x_v . e) ).
// Every such extent is at least the body's true minimum width, so the smallest is the
// tightest of these upper bounds. The principal axes make it exact for plates, bars,
// cylinders and tori in any orientation (2a for a torus of minor radius a: the tube's
// diameter), where an axis-aligned box alone would not be (a plate tilted by 45 degrees
// would look thick); the coordinate axes cover bodies whose covariance is isotropic
// (a cube: its principal axes are then arbitrary). Cost O(n). For a bent or hollow object
// it is an upper bound of the local wall thickness (a U-shaped bar is as "thick" as the U
// is wide).
#include <vector>

#include "softcontact/mesh.hpp"

namespace softcontact::collide {

/// `x` (n,3) positions [m], `vertices` the object's vertices. 0 for fewer than 2.
double principal_thickness(const double* x, const std::vector<index_t>& vertices);

}  // namespace softcontact::collide
