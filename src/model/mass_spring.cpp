// The mass-spring law's registry entry (mass_spring.hpp, material_registry.hpp): its
// kernel in edge form on the stored inverse rest lengths, the energy of the springs, the
// exact tangent of the law as stiffness, and the springs' own rest stiffness for the
// stability limit (the network is not Hooke's law at rest).
//
// forces.cpp's pragmas, before any include (the headers' inline functions need them too):
// the kernel is cloned per instruction set, and every clone must round alike.
#pragma GCC optimize("fp-contract=off", "no-math-errno")
#pragma GCC diagnostic ignored "-Wpsabi"

#include <cmath>

#include "mass_spring.hpp"
#include "material_registry.hpp"
#include "tet_kernels.hpp"

namespace softcontact::model {

namespace {

/// Mass-spring model in edge form (mass_spring.hpp): k_e = E V / L_e^2 per tet edge. With
/// the stored inverse rest length r = 1/L_e, the force on b is -s u with
/// s = k_e (l - L_e) / l = E V r (r - 1/l): one division and one square root per edge.
template <bool kDamp>
void spring_block(const TetView& T, std::size_t begin, std::size_t end, double young, double beta, const double* x,
                  const double* v, double* out) {
  for (std::size_t t0 = begin; t0 < end; t0 += kLanes, out += 12 * kLanes) {
    const Chunk c(T, t0, static_cast<int>(std::min<std::size_t>(kLanes, end - t0)));
    vdouble p[12], w[12], f[12];
    c.gather(x, p);
    if constexpr (kDamp) c.gather(v, w);
    for (int k = 0; k < 12; ++k) f[k] = broadcast(0.0);
    const vdouble ev = young * c.vol;
    for (int e = 0; e < 6; ++e) {
      const int a = kTetEdges[e][0], b = kTetEdges[e][1];
      vdouble r;
      if (c.n == kLanes) r = load_lanes(T.inv_rest_length[e] + t0);
      else
        for (int l = 0; l < kLanes; ++l) r[l] = T.inv_rest_length[e][t0 + static_cast<std::size_t>(std::min(l, c.n - 1))];
      vdouble u[3];
      for (int d = 0; d < 3; ++d) u[d] = p[3 * b + d] - p[3 * a + d];
      const vdouble inv_len = 1.0 / sqrt_lanes(u[0] * u[0] + u[1] * u[1] + u[2] * u[2]);
      const vdouble evr = ev * r;
      vdouble s = evr * (r - inv_len);  // force on b is -s u
      if constexpr (kDamp) {
        const vdouble du = u[0] * (w[3 * b] - w[3 * a]) + u[1] * (w[3 * b + 1] - w[3 * a + 1]) +
                           u[2] * (w[3 * b + 2] - w[3 * a + 2]);
        s += beta * evr * r * du * inv_len * inv_len;
      }
      for (int d = 0; d < 3; ++d) {
        f[3 * b + d] -= s * u[d];
        f[3 * a + d] += s * u[d];
      }
    }
    c.store(f, out);
  }
}

/// Spring energy of one tet: sum_e k_e/2 (l_e - L_e)^2 = E V/2 sum_e (l_e / L_e - 1)^2.
inline double spring_energy(const TetView& T, std::size_t t, double young, const double* x) {
  double s = 0;
  for (int e = 0; e < 6; ++e) {
    const std::size_t ia = 3 * static_cast<std::size_t>(T.corner[kTetEdges[e][0]][t]);
    const std::size_t ib = 3 * static_cast<std::size_t>(T.corner[kTetEdges[e][1]][t]);
    const double l = std::sqrt((x[ib] - x[ia]) * (x[ib] - x[ia]) + (x[ib + 1] - x[ia + 1]) * (x[ib + 1] - x[ia + 1]) +
                               (x[ib + 2] - x[ia + 2]) * (x[ib + 2] - x[ia + 2]));
    const double q = l * T.inv_rest_length[e][t] - 1;  // strain of the spring
    s += q * q;
  }
  return 0.5 * young * T.volume[t] * s;
}

SOFTCONTACT_BLOCK_KERNEL
void forces(const TetView& T, std::size_t begin, std::size_t end, const LawParams& p, bool damp, const double* x,
            const double* v, double* out) {
  if (damp) spring_block<true>(T, begin, end, p.young, p.beta, x, v, out);
  else spring_block<false>(T, begin, end, p.young, p.beta, x, v, out);
}

double energy(const TetView& T, std::size_t t, const LawParams& p, const double* x, const Mat3&) {
  return spring_energy(T, t, p.young, x);
}

void stiffness(const LawParams& p, const Mat3& Di, double V, const Mat3& F, StiffnessKind, double K[144]) {
  // Rest corners relative to corner 0 from Dm = (Dm^-1)^-1 (columns X1-X0, X2-X0, X3-X0).
  const Mat3 dc = cofactor(Di);
  const double dd = Di[0] * dc[0] + Di[3] * dc[3] + Di[6] * dc[6];
  double X[12] = {0, 0, 0};
  for (int a = 1; a <= 3; ++a)
    for (int i = 0; i < 3; ++i) X[3 * a + i] = dc[3 * (a - 1) + i] / dd;  // Dm_(i,a-1) = cof(Di)_(a-1,i) / det
  element_stiffness(MassSpringLaw::from_rest(p.young, 0, X).stress_derivative(F), Di, V, K);
}

/// Springs k_e = E V / L_e^2 along the rest edges.
void rest_stiffness(const double X[12], const Mat3&, double V, const LawParams& p, double K[144]) {
  for (int k = 0; k < 144; ++k) K[k] = 0;
  for (int e = 0; e < 6; ++e) {
    const int a = kTetEdges[e][0], b = kTetEdges[e][1];
    double d[3], l2 = 0;
    for (int i = 0; i < 3; ++i) {
      d[i] = X[3 * b + i] - X[3 * a + i];
      l2 += d[i] * d[i];
    }
    const double k = p.young * V / (l2 * l2);  // k_e / L^2, times d d^T below (d unnormalised)
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) {
        const double s = k * d[i] * d[j];
        K[12 * (3 * a + i) + 3 * a + j] += s;
        K[12 * (3 * b + i) + 3 * b + j] += s;
        K[12 * (3 * a + i) + 3 * b + j] -= s;
        K[12 * (3 * b + i) + 3 * a + j] -= s;
      }
  }
}

}  // namespace

extern const MaterialLaw mass_spring_law = {.block_forces = forces,
                                            .energy = energy,
                                            .stiffness = stiffness,
                                            .rest_stiffness = rest_stiffness,
                                            .spring_rest_lengths = true};

}  // namespace softcontact::model
