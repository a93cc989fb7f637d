#pragma once
// A vector of kLanes doubles (GCC/Clang vector extension) for the per-tet kernels: lane l
// holds tet t0 + l. Arithmetic operators act lane-wise, a scalar operand is broadcast,
// comparisons give a lane mask and `mask ? a : b` selects lane-wise. The compiler maps
// it onto whatever the target offers (4 x SSE2, 2 x AVX2 or 1 x AVX-512 registers); the
// kernels are compiled for each of these (forces.cpp), and since add, mul, div and sqrt
// are correctly rounded per lane, all give the same bits.
#include <cmath>
#include <cstring>

// Passing these vectors by value changes the ABI between instruction sets; every
// function taking them is inline and compiled inside one kernel, so this does not matter.
#pragma GCC diagnostic ignored "-Wpsabi"

namespace softcontact::model {

inline constexpr int kLanes = 8;
using vdouble = double __attribute__((vector_size(8 * kLanes)));
using vmask = long long __attribute__((vector_size(8 * kLanes)));

inline vdouble broadcast(double s) { return vdouble{} + s; }

inline vdouble load_lanes(const double* p) {
  vdouble v;
  std::memcpy(&v, p, sizeof v);
  return v;
}

inline vdouble sqrt_lanes(vdouble a) {
  vdouble r;
  for (int l = 0; l < kLanes; ++l) r[l] = std::sqrt(a[l]);
  return r;
}

}  // namespace softcontact::model
