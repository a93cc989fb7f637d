#include "softcontact/primitives.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <numbers>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "softcontact/error.hpp"

namespace softcontact {

namespace {

constexpr double kPi = std::numbers::pi;

// Blend b0 towards the circle/sphere inside the inner block (see primitives.hpp), chosen
// by scanning b0 in steps of 0.05-0.1 for the best worst-tet quality (6 sqrt(2) V /
// l_rms^3) over resolutions up to 64 (disk, cubic cells) and 96 (ball) cells across.
// A flatter inner block pinches the rings/shells at its corners, a rounder one flattens
// its own corner cells; the ball, whose corners stick out further (sqrt(3) against
// sqrt(2)), wants it rounder. Worst quality, tending to as the resolution grows:
//   disk (cylinder): b0 = 0.3: 0.396, 0.4: 0.435, 0.5: 0.379, 0.6: 0.309;
//   ball (sphere):   b0 = 0.4: 0.244, 0.5: 0.269, 0.6: 0.288, 0.65: 0.252.
constexpr double kDiskBlend = 0.4;
constexpr double kBallBlend = 0.6;

// The 6 tets of the Kuhn split of a hex with corners numbered
// 0=(0,0,0) 1=(1,0,0) 2=(1,1,0) 3=(0,1,0) 4=(0,0,1) 5=(1,0,1) 6=(1,1,1) 7=(0,1,1)
// in its local (u,v,w): all share the diagonal 0-6, and each is positive when the local
// frame is right-handed.
constexpr int kKuhn[6][4] = {{0, 1, 2, 6}, {0, 2, 3, 6}, {0, 3, 7, 6},
                             {0, 7, 4, 6}, {0, 4, 5, 6}, {0, 5, 1, 6}};
constexpr int kCorner[8][3] = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0},
                               {0, 0, 1}, {1, 0, 1}, {1, 1, 1}, {0, 1, 1}};

void emit_hex(const std::array<index_t, 8>& c, bool right_handed, std::vector<index_t>& tets) {
  for (const auto& t : kKuhn) {
    // Swapping two vertices turns a negative tet of a left-handed cell positive.
    if (right_handed)
      tets.insert(tets.end(), {c[t[0]], c[t[1]], c[t[2]], c[t[3]]});
    else
      tets.insert(tets.end(), {c[t[0]], c[t[2]], c[t[1]], c[t[3]]});
  }
}

std::string fmt(double x) {
  std::ostringstream s;
  s.precision(17);
  s << x;
  return s.str();
}

bool positive_finite(double x) { return std::isfinite(x) && x > 0; }

// The counts must fit index_t (vertex and tet numbers); computed in double so that huge
// arguments cannot overflow the check itself.
void check_size(const char* what, double vertices, double tets) {
  const double max = static_cast<double>(std::numeric_limits<index_t>::max());
  if (vertices > max || 4.0 * tets > max) {
    std::ostringstream s;
    s << what << ": the requested resolution gives " << vertices << " vertices and " << tets
      << " tets (expected at most " << max << " vertices and " << max / 4 << " tets)";
    throw InputError(s.str());
  }
}

// Layout of a disk or ball: n cells along the side of the inner block, m rings/shells,
// inner block [-s0,s0]^d in the parameter square/cube (equal parameter spacing in the
// block and across the rings).
// Counts are 64-bit so that an absurd `across` cannot overflow before check_size.
struct OGrid {
  std::int64_t n = 1;
  std::int64_t m = 1;
  double s0 = 0.5;
};

OGrid ogrid_for(std::int64_t across) {
  OGrid g;
  g.m = std::max<std::int64_t>(1, (across + 2) / 4);
  g.n = std::max<std::int64_t>(1, across - 2 * g.m);
  g.s0 = static_cast<double>(g.n) / static_cast<double>(g.n + 2 * g.m);
  return g;
}

// s and blend b of ring/shell layer l (0 = the inner block's boundary, m = the circle or
// sphere, exactly 1 there so that boundary points lie on it to rounding) in D dimensions.
// Along the axes |x| = s whatever b, so the layers are evenly spaced there. Towards a
// corner (q = (1,..,1), |q| = sqrt(D)) |x| = s (sqrt(D) - (sqrt(D) - 1) b); b is chosen to
// make that linear in s too, i.e. the layers evenly spaced along the diagonals as well.
// (A b linear in s instead leaves the outermost corner layer about 4 times thinner than
// the innermost one in the ball, and the worst tets' quality kept dropping with
// resolution.)
std::pair<double, double> layer_sb(const OGrid& g, int l, double b0, int D) {
  if (l == g.m) return {1.0, 1.0};
  const double t = static_cast<double>(l) / static_cast<double>(g.m);
  const double s = g.s0 + (1.0 - g.s0) * t;
  const double rd = std::sqrt(static_cast<double>(D));
  const double c0 = g.s0 * (rd - (rd - 1.0) * b0);  // |x| of the inner block's corner
  const double corner = c0 + (1.0 - c0) * t;         // |x| of this layer's corner
  return {s, (rd - corner / s) / (rd - 1.0)};
}

// x = s ((1-b) q + b e(q)) for q on the unit square/cube surface (max |q_i| = 1).
template <std::size_t D>
std::array<double, D> round_map(const std::array<double, D>& q, double s, double b) {
  std::array<double, D> e{};
  double len2 = 0;
  for (std::size_t i = 0; i < D; ++i) {
    e[i] = std::tan(0.25 * kPi * q[i]);
    len2 += e[i] * e[i];
  }
  const double len = std::sqrt(len2);
  std::array<double, D> x{};
  for (std::size_t i = 0; i < D; ++i) x[i] = s * ((1.0 - b) * q[i] + b * e[i] / len);
  return x;
}

// A point of the inner block given as its parameter point p (s = max|p_i| <= s0).
template <std::size_t D>
std::array<double, D> inner_map(const std::array<double, D>& p, double b0) {
  double s = 0;
  for (double v : p) s = std::max(s, std::abs(v));
  if (s == 0) return {};
  std::array<double, D> q{};
  for (std::size_t i = 0; i < D; ++i) q[i] = p[i] / s;
  return round_map<D>(q, s, b0);
}

// Lattice coordinate i in [0,n] -> [-1,1], exact at both ends.
double lattice(int i, int n) { return 2.0 * (static_cast<double>(i) / n) - 1.0; }

// The unit disk as an O-grid of quads. Each quad lists its corners in its local order
// (u0v0, u1v0, u1v1, u0v1): in the inner block u = +x, v = +y; in the rings u runs along
// the positive global axis parallel to the ring's side and v outward. So every shared
// edge is traversed the same way by both quads, which is what keeps the Kuhn split of
// the extruded hexes conforming (see primitives.hpp).
struct Disk {
  std::vector<double> xy;                       // (n,2)
  std::vector<std::array<index_t, 4>> quads;    // local order as above
  std::vector<bool> ccw;                        // local frame (u,v) counter-clockwise
  std::size_t num_vertices() const { return xy.size() / 2; }
};

Disk make_disk(const OGrid& g, double b0) {
  // Fits int: the caller has checked the vertex count against index_t.
  const int n = static_cast<int>(g.n), m = static_cast<int>(g.m), np = 4 * n;  // np: points per ring
  Disk d;
  const auto inner_id = [n](int i, int j) { return static_cast<index_t>(i + (n + 1) * j); };
  // Perimeter point k (counter-clockwise from the corner (-1,-1)) as an inner-block
  // lattice point: side 0 bottom (+x), 1 right (+y), 2 top (-x), 3 left (-y).
  const auto perimeter = [n](int k) -> std::pair<int, int> {
    const int side = k / n, t = k % n;
    switch (side) {
      case 0: return {t, 0};
      case 1: return {n, t};
      case 2: return {n - t, n};
      default: return {0, n - t};
    }
  };
  const auto ring_id = [&](int l, int k) {
    k %= np;
    if (l == 0) {
      const auto [i, j] = perimeter(k);
      return inner_id(i, j);
    }
    return static_cast<index_t>((n + 1) * (n + 1) + (l - 1) * np + k);
  };

  for (int j = 0; j <= n; ++j)
    for (int i = 0; i <= n; ++i) {
      const auto x = inner_map<2>({g.s0 * lattice(i, n), g.s0 * lattice(j, n)}, b0);
      d.xy.insert(d.xy.end(), {x[0], x[1]});
    }
  for (int l = 1; l <= m; ++l) {
    const auto [s, b] = layer_sb(g, l, b0, 2);
    for (int k = 0; k < np; ++k) {
      const auto [i, j] = perimeter(k);
      const auto x = round_map<2>({lattice(i, n), lattice(j, n)}, s, b);
      d.xy.insert(d.xy.end(), {x[0], x[1]});
    }
  }

  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) {
      d.quads.push_back({inner_id(i, j), inner_id(i + 1, j), inner_id(i + 1, j + 1), inner_id(i, j + 1)});
      d.ccw.push_back(true);
    }
  for (int l = 0; l < m; ++l)
    for (int k = 0; k < np; ++k) {
      // Sides 0 and 1 run along +x/+y, with the outward direction on the right
      // (clockwise frame); sides 2 and 3 run along -x/-y, so u is reversed there and the
      // frame is counter-clockwise.
      const bool forward = k / n < 2;
      const int k0 = forward ? k : k + 1, k1 = forward ? k + 1 : k;
      d.quads.push_back({ring_id(l, k0), ring_id(l, k1), ring_id(l + 1, k1), ring_id(l + 1, k0)});
      d.ccw.push_back(!forward);
    }
  return d;
}

}  // namespace

TetMesh make_box(double lx, double ly, double lz, int nx, int ny, int nz) {
  if (!positive_finite(lx) || !positive_finite(ly) || !positive_finite(lz))
    throw InputError("make_box: expected positive finite sizes, got lx=" + fmt(lx) +
                     " ly=" + fmt(ly) + " lz=" + fmt(lz));
  if (nx < 1 || ny < 1 || nz < 1)
    throw InputError("make_box: expected at least 1 cell along each axis, got nx=" + std::to_string(nx) +
                     " ny=" + std::to_string(ny) + " nz=" + std::to_string(nz));
  const double cells = static_cast<double>(nx) * ny * nz;
  check_size("make_box", (nx + 1.0) * (ny + 1.0) * (nz + 1.0), 6.0 * cells);

  TetMesh mesh;
  mesh.points.reserve(3 * static_cast<std::size_t>(nx + 1) * (ny + 1) * (nz + 1));
  // x = l (i/n - 1/2) is exactly +-l/2 at the ends, so opposite faces are flat.
  for (int k = 0; k <= nz; ++k)
    for (int j = 0; j <= ny; ++j)
      for (int i = 0; i <= nx; ++i)
        mesh.points.insert(mesh.points.end(), {lx * (static_cast<double>(i) / nx - 0.5),
                                               ly * (static_cast<double>(j) / ny - 0.5),
                                               lz * (static_cast<double>(k) / nz - 0.5)});
  const auto id = [&](int i, int j, int k) { return static_cast<index_t>(i + (nx + 1) * (j + (ny + 1) * k)); };
  mesh.tets.reserve(24 * static_cast<std::size_t>(cells));
  for (int k = 0; k < nz; ++k)
    for (int j = 0; j < ny; ++j)
      for (int i = 0; i < nx; ++i)
        emit_hex({id(i, j, k), id(i + 1, j, k), id(i + 1, j + 1, k), id(i, j + 1, k), id(i, j, k + 1),
                  id(i + 1, j, k + 1), id(i + 1, j + 1, k + 1), id(i, j + 1, k + 1)},
                 true, mesh.tets);
  return mesh;
}

TetMesh make_cylinder(double r, double h, int radial, int axial) {
  if (!positive_finite(r) || !positive_finite(h))
    throw InputError("make_cylinder: expected a positive finite radius and height, got r=" + fmt(r) +
                     " h=" + fmt(h));
  if (radial < 1 || axial < 1)
    throw InputError("make_cylinder: expected radial >= 1 and axial >= 1 cells, got radial=" +
                     std::to_string(radial) + " axial=" + std::to_string(axial));
  const OGrid g = ogrid_for(2 * static_cast<std::int64_t>(radial));
  const double n = static_cast<double>(g.n), m = static_cast<double>(g.m);
  check_size("make_cylinder", ((n + 1) * (n + 1) + 4 * n * m) * (axial + 1.0), 6 * (n * n + 4 * n * m) * axial);

  const Disk disk = make_disk(g, kDiskBlend);
  const std::size_t nd = disk.num_vertices();
  TetMesh mesh;
  mesh.points.reserve(3 * nd * (axial + 1));
  for (int k = 0; k <= axial; ++k) {
    const double z = h * (static_cast<double>(k) / axial - 0.5);
    for (std::size_t v = 0; v < nd; ++v)
      mesh.points.insert(mesh.points.end(), {r * disk.xy[2 * v], r * disk.xy[2 * v + 1], z});
  }
  mesh.tets.reserve(24 * disk.quads.size() * axial);
  for (int k = 0; k < axial; ++k) {
    const auto lo = static_cast<index_t>(static_cast<std::size_t>(k) * nd), hi = static_cast<index_t>(static_cast<std::size_t>(k + 1) * nd);
    for (std::size_t q = 0; q < disk.quads.size(); ++q) {
      const auto& c = disk.quads[q];
      // w = +z: the hex frame is right-handed when the quad's (u,v) is counter-clockwise.
      emit_hex({c[0] + lo, c[1] + lo, c[2] + lo, c[3] + lo, c[0] + hi, c[1] + hi, c[2] + hi, c[3] + hi},
               disk.ccw[q], mesh.tets);
    }
  }
  return mesh;
}

TetMesh make_sphere(double r, int cells) {
  if (!positive_finite(r)) throw InputError("make_sphere: expected a positive finite radius, got r=" + fmt(r));
  if (cells < 2)
    throw InputError("make_sphere: expected at least 2 cells across the diameter, got cells=" +
                     std::to_string(cells));
  const OGrid g = ogrid_for(cells);
  {
    const double n = static_cast<double>(g.n), m = static_cast<double>(g.m);
    check_size("make_sphere", (n + 1) * (n + 1) * (n + 1) + (6 * n * n + 2) * m, 6 * (n * n * n + 6 * n * n * m));
  }
  const int n = static_cast<int>(g.n), m = static_cast<int>(g.m);

  // Inner block lattice (i,j,k) in [0,n]^3, vertex id = its linear index; the shells
  // reuse the lattice points on the block's surface, numbered in the same order.
  const int n1 = n + 1;
  const std::size_t nb = static_cast<std::size_t>(n1) * n1 * n1;
  std::vector<index_t> surf(nb, -1);
  index_t ns = 0;
  for (int k = 0; k <= n; ++k)
    for (int j = 0; j <= n; ++j)
      for (int i = 0; i <= n; ++i)
        if (i == 0 || i == n || j == 0 || j == n || k == 0 || k == n)
          surf[static_cast<std::size_t>(i + n1 * (j + n1 * k))] = ns++;
  const auto lin = [n1](const std::array<int, 3>& c) { return static_cast<std::size_t>(c[0] + n1 * (c[1] + n1 * c[2])); };
  const auto vid = [&](const std::array<int, 3>& c, int l) {
    const std::size_t L = lin(c);
    return l == 0 ? static_cast<index_t>(L) : static_cast<index_t>(nb + static_cast<std::size_t>(l - 1) * ns + surf[L]);
  };

  TetMesh mesh;
  mesh.points.reserve(3 * (nb + static_cast<std::size_t>(m) * ns));
  for (int k = 0; k <= n; ++k)
    for (int j = 0; j <= n; ++j)
      for (int i = 0; i <= n; ++i) {
        const auto x = inner_map<3>({g.s0 * lattice(i, n), g.s0 * lattice(j, n), g.s0 * lattice(k, n)}, kBallBlend);
        mesh.points.insert(mesh.points.end(), {r * x[0], r * x[1], r * x[2]});
      }
  for (int l = 1; l <= m; ++l) {
    const auto [s, b] = layer_sb(g, l, kBallBlend, 3);
    for (int k = 0; k <= n; ++k)
      for (int j = 0; j <= n; ++j)
        for (int i = 0; i <= n; ++i)
          if (surf[lin({i, j, k})] >= 0) {
            const auto x = round_map<3>({lattice(i, n), lattice(j, n), lattice(k, n)}, s, b);
            mesh.points.insert(mesh.points.end(), {r * x[0], r * x[1], r * x[2]});
          }
  }

  mesh.tets.reserve(24 * (static_cast<std::size_t>(n) * n * n + 6 * static_cast<std::size_t>(n) * n * m));
  for (int k = 0; k < n; ++k)
    for (int j = 0; j < n; ++j)
      for (int i = 0; i < n; ++i) {
        std::array<index_t, 8> c{};
        for (int v = 0; v < 8; ++v) c[v] = vid({i + kCorner[v][0], j + kCorner[v][1], k + kCorner[v][2]}, 0);
        emit_hex(c, true, mesh.tets);
      }
  // Shell hexes over face (axis d, side): local u, v along the other two axes in
  // increasing order, both positive (so shared faces between shells agree, see
  // primitives.hpp), w outward (one layer up).
  for (int d = 0; d < 3; ++d)
    for (int side = 0; side < 2; ++side) {
      const int A = d == 0 ? 1 : 0, B = d == 2 ? 1 : 2;
      // det[e_A, e_B, e_d] is +1 for d = 0, 2 and -1 for d = 1; outward is -e_d on side 0.
      const bool right_handed = (d != 1) == (side == 1);
      for (int l = 0; l < m; ++l)
        for (int bb = 0; bb < n; ++bb)
          for (int aa = 0; aa < n; ++aa) {
            std::array<index_t, 8> c{};
            for (int v = 0; v < 8; ++v) {
              std::array<int, 3> p{};
              p[d] = side ? n : 0;
              p[A] = aa + kCorner[v][0];
              p[B] = bb + kCorner[v][1];
              c[v] = vid(p, l + kCorner[v][2]);
            }
            emit_hex(c, right_handed, mesh.tets);
          }
    }
  return mesh;
}

TetMesh make_torus(double R, double a, int around, int tube) {
  if (!positive_finite(R) || !positive_finite(a) || !(a < R))
    throw InputError("make_torus: expected finite radii with 0 < a < R, got R=" + fmt(R) + " a=" + fmt(a));
  if (around < 3 || tube < 2)
    throw InputError("make_torus: expected around >= 3 and tube >= 2 cells, got around=" + std::to_string(around) +
                     " tube=" + std::to_string(tube));
  const OGrid g = ogrid_for(tube);
  const double n = static_cast<double>(g.n), m = static_cast<double>(g.m);
  check_size("make_torus", ((n + 1) * (n + 1) + 4 * n * m) * around, 6 * (n * n + 4 * n * m) * around);

  const Disk disk = make_disk(g, kDiskBlend);
  const std::size_t nd = disk.num_vertices();
  TetMesh mesh;
  mesh.points.reserve(3 * nd * around);
  // The tube's cross-section: disk x along the radius from the z axis, disk y along z.
  for (int k = 0; k < around; ++k) {
    const double phi = 2.0 * kPi * k / around;
    const double c = std::cos(phi), s = std::sin(phi);
    for (std::size_t v = 0; v < nd; ++v) {
      const double rho = R + a * disk.xy[2 * v];
      mesh.points.insert(mesh.points.end(), {rho * c, rho * s, a * disk.xy[2 * v + 1]});
    }
  }
  mesh.tets.reserve(24 * disk.quads.size() * around);
  for (int k = 0; k < around; ++k) {
    // The last layer of cells closes the ring onto layer 0 (the weld): w = +phi there
    // too, so the seam faces split like every other face between layers.
    const auto lo = static_cast<index_t>(static_cast<std::size_t>(k) * nd), hi = static_cast<index_t>(static_cast<std::size_t>((k + 1) % around) * nd);
    for (std::size_t q = 0; q < disk.quads.size(); ++q) {
      const auto& c = disk.quads[q];
      // (radial, z, phi) is left-handed (e_rho x e_z = -e_phi), so a counter-clockwise
      // quad gives a left-handed hex.
      emit_hex({c[0] + lo, c[1] + lo, c[2] + lo, c[3] + lo, c[0] + hi, c[1] + hi, c[2] + hi, c[3] + hi},
               !disk.ccw[q], mesh.tets);
    }
  }
  return mesh;
}

}  // namespace softcontact
