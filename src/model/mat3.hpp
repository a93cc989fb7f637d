#pragma once
// 3x3 matrices as plain arrays for the per-tet kernels: row-major, A[3*i + j] = A_ij.
//
// The element type T is a double, or a vector of kLanes doubles (simd.hpp) holding the
// same entry of kLanes different tets: the material laws are written once, as templates,
// and the kernels run them on whole lanes of tets at a time (structure of arrays).
//
// Fourth-order tensors (the derivative dP/dF of a stress) are 9x9 row-major arrays in
// the same flattening: D[9 * (3i + j) + (3k + l)] = dP_ij / dF_kl.
#include <array>
#include <cmath>

namespace softcontact::model {

template <class T>
using M3 = std::array<T, 9>;
using Mat3 = M3<double>;
using Mat9 = std::array<double, 81>;

inline constexpr Mat3 kIdentity3 = {1, 0, 0, 0, 1, 0, 0, 0, 1};

template <class T>
inline M3<T> mul(const M3<T>& a, const M3<T>& b) {
  M3<T> c;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) c[3 * i + j] = a[3 * i] * b[j] + a[3 * i + 1] * b[3 + j] + a[3 * i + 2] * b[6 + j];
  return c;
}

/// a^T b
template <class T>
inline M3<T> mul_tn(const M3<T>& a, const M3<T>& b) {
  M3<T> c;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) c[3 * i + j] = a[i] * b[j] + a[3 + i] * b[3 + j] + a[6 + i] * b[6 + j];
  return c;
}

/// a b^T
template <class T>
inline M3<T> mul_nt(const M3<T>& a, const M3<T>& b) {
  M3<T> c;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      c[3 * i + j] = a[3 * i] * b[3 * j] + a[3 * i + 1] * b[3 * j + 1] + a[3 * i + 2] * b[3 * j + 2];
  return c;
}

template <class T>
inline M3<T> transpose(const M3<T>& a) {
  return {a[0], a[3], a[6], a[1], a[4], a[7], a[2], a[5], a[8]};
}

template <class T>
inline T trace(const M3<T>& a) {
  return a[0] + a[4] + a[8];
}

/// A : B = sum_ij A_ij B_ij
template <class T>
inline T ddot(const M3<T>& a, const M3<T>& b) {
  T s = a[0] * b[0];
  for (int k = 1; k < 9; ++k) s += a[k] * b[k];
  return s;
}

template <class T>
inline T det(const M3<T>& a) {
  return a[0] * (a[4] * a[8] - a[5] * a[7]) - a[1] * (a[3] * a[8] - a[5] * a[6]) + a[2] * (a[3] * a[7] - a[4] * a[6]);
}

/// Cofactor matrix cof(A) = dJ/dA = det(A) A^-T. Column j is the cross product of the
/// other two columns of A (in cyclic order): cof = [a1 x a2, a2 x a0, a0 x a1].
template <class T>
inline M3<T> cofactor(const M3<T>& a) {
  return {a[4] * a[8] - a[5] * a[7], a[5] * a[6] - a[3] * a[8], a[3] * a[7] - a[4] * a[6],
          a[2] * a[7] - a[1] * a[8], a[0] * a[8] - a[2] * a[6], a[1] * a[6] - a[0] * a[7],
          a[1] * a[5] - a[2] * a[4], a[2] * a[3] - a[0] * a[5], a[0] * a[4] - a[1] * a[3]};
}

/// det(A) from A and its cofactor matrix (column 0 of A . column 0 of cof A).
template <class T>
inline T det_from_cofactor(const M3<T>& a, const M3<T>& c) {
  return a[0] * c[0] + a[3] * c[3] + a[6] * c[6];
}

/// Directional derivative of cofactor() at A in the direction dA (cofactor is quadratic,
/// so this is exact): each column d(a_j x a_k) = da_j x a_k + a_j x da_k.
inline Mat3 cofactor_derivative(const Mat3& a, const Mat3& d) {
  Mat3 c;
  const int jk[3][2] = {{1, 2}, {2, 0}, {0, 1}};  // column 0: a1 x a2, 1: a2 x a0, 2: a0 x a1
  for (int col = 0; col < 3; ++col) {
    const int j = jk[col][0], k = jk[col][1];
    const double u[3] = {a[j], a[3 + j], a[6 + j]}, du[3] = {d[j], d[3 + j], d[6 + j]};
    const double v[3] = {a[k], a[3 + k], a[6 + k]}, dv[3] = {d[k], d[3 + k], d[6 + k]};
    c[col] = du[1] * v[2] - du[2] * v[1] + u[1] * dv[2] - u[2] * dv[1];
    c[3 + col] = du[2] * v[0] - du[0] * v[2] + u[2] * dv[0] - u[0] * dv[2];
    c[6 + col] = du[0] * v[1] - du[1] * v[0] + u[0] * dv[1] - u[1] * dv[0];
  }
  return c;
}

template <class T>
inline M3<T> add(const M3<T>& a, const M3<T>& b) {
  M3<T> c;
  for (int k = 0; k < 9; ++k) c[k] = a[k] + b[k];
  return c;
}

template <class T, class S>
inline M3<T> scaled(const M3<T>& a, const S& s) {
  M3<T> c;
  for (int k = 0; k < 9; ++k) c[k] = s * a[k];
  return c;
}

/// sym(A) = (A + A^T) / 2
template <class T>
inline M3<T> sym(const M3<T>& a) {
  M3<T> c;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) c[3 * i + j] = 0.5 * (a[3 * i + j] + a[3 * j + i]);
  return c;
}

/// Builds dP/dF column by column from a directional derivative dP(dF): for a stress
/// whose derivative is known in closed form as a linear map, this is its 9x9 matrix.
template <class Directional>
Mat9 derivative_matrix(Directional&& dP) {
  Mat9 D{};
  for (int kl = 0; kl < 9; ++kl) {
    Mat3 e{};
    e[kl] = 1;
    const Mat3 col = dP(e);
    for (int ij = 0; ij < 9; ++ij) D[9 * ij + kl] = col[ij];
  }
  return D;
}

}  // namespace softcontact::model
