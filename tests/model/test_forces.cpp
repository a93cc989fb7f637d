// ElasticForces (src/model/forces.cpp): the assembled forces are minus the gradient of
// the measured energy, the element stiffness the derivative of the element forces (also
// on near-flat and inverted tets), rigid motions give no force, the vectorised kernels
// agree with the scalar laws, and the sum does not depend on the thread count.
#include <gtest/gtest.h>
#include <omp.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <random>
#include <string>

#include "model/corotational.hpp"
#include "model/linear.hpp"
#include "model/neohookean.hpp"
#include "model/stvk.hpp"
#include "model/mass_spring.hpp"
#include "softcontact/error.hpp"
#include "softcontact/forces.hpp"
#include "softcontact/scene.hpp"
#include "softcontact/world.hpp"

using namespace softcontact;

namespace {

/// Scientific notation for RecordProperty (std::to_string rounds small numbers to 0).
std::string sci(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.2e", v);
  return buf;
}

const char* const kModels[] = {"linear", "corotational", "stvk", "neohookean", "mass_spring"};

/// One object of the given model: a box of 1 x 0.8 x 0.6 m, by default 2x2x2 cells (48
/// tets), no gravity.
Scene box(const std::string& model, const std::string& cells = "[2, 2, 2]") {
  return load_scene_from_string("simulation: {dt: 1e-4, steps: 1, gravity: [0, 0, 0]}\n"
                                "materials:\n  - {name: m, model: " + model +
                                    ", young: 1e5, poisson: 0.3, density: 1000}\n"
                                    "objects:\n  - material: m\n"
                                    "    primitive: {type: box, size: [1, 0.8, 0.6], cells: " + cells + "}\n",
                                "test.yaml");
}

void perturb(std::vector<double>& x, double s, std::uint64_t seed) {
  std::mt19937_64 g(seed);
  std::uniform_real_distribution<double> u(-s, s);
  for (double& v : x) v += u(g);
}

double energy(const ElasticForces& ef, const World& w) {
  ElasticMeasures m;
  ef.measure(w, m);
  return m.energy[0];
}

std::vector<double> forces(ElasticForces& ef, const World& w) {
  std::vector<double> f(w.x.size(), 0.0);
  ef.add_forces(w, f, false);
  return f;
}

}  // namespace

TEST(ElasticForces, ForcesAreMinusTheEnergyGradient) {
  for (const char* model : kModels) {
    const Scene s = box(model);
    World w = build_world(s, block_partition(s, 1), 0);
    ElasticForces ef(s, w);
    perturb(w.x, 0.08, 7);  // strains of ~20 %
    const std::vector<double> f = forces(ef, w);
    double fmax = 0;
    for (double v : f) fmax = std::max(fmax, std::abs(v));
    const double h = 1e-7;
    double worst = 0;
    for (std::size_t k = 0; k < w.x.size(); ++k) {
      const double x0 = w.x[k];
      w.x[k] = x0 + h;
      const double ep = energy(ef, w);
      w.x[k] = x0 - h;
      const double em = energy(ef, w);
      w.x[k] = x0;
      EXPECT_NEAR(f[k], -(ep - em) / (2 * h), 1e-6 * fmax) << model << " dof " << k;
      worst = std::max(worst, std::abs(f[k] + (ep - em) / (2 * h)) / fmax);
    }
    RecordProperty(std::string("worst_") + model, sci(worst));
  }
}

// K = -df/dx of one tet against central differences of its corner forces, on a regular
// strained tet, a near-flat one (height 1e-3 of its size) and an inverted one. The
// corotational model's implicit (warped) stiffness equals the exact one at rotated rest
// states; the linear model's equals it everywhere.
TEST(ElasticForces, StiffnessIsTheDerivativeOfTheForces) {
  for (const char* model : kModels) {
    const Scene s = box(model);
    World w = build_world(s, block_partition(s, 1), 0);
    ElasticForces ef(s, w);
    const std::size_t t = 5;
    const index_t* tet = &w.tets[4 * t];
    const std::vector<double> rest = w.x;
    // Configurations of tet t's corners: strained, nearly flat (corner 3 moved almost
    // into the plane of the others), inverted (corner 3 through that plane).
    for (int config = 0; config < 3; ++config) {
      w.x = rest;
      perturb(w.x, 0.05, 11 + config);
      if (config > 0) {
        const double* a = &w.x[3 * tet[0]];
        const double* b = &w.x[3 * tet[1]];
        const double* c = &w.x[3 * tet[2]];
        double* d = &w.x[3 * tet[3]];
        const double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, v[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
        double n[3] = {u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]};
        const double nn = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
        const double dist = (d[0] - a[0]) * n[0] / nn + (d[1] - a[1]) * n[1] / nn + (d[2] - a[2]) * n[2] / nn;
        const double target = config == 1 ? 1e-3 * 0.5 : -0.1;  // signed height over the face plane
        for (int k = 0; k < 3; ++k) d[k] += (target - dist) * n[k] / nn;
      }
      double K[144];
      ef.tet_stiffness(t, w.x.data(), StiffnessKind::exact, K);
      double worst = 0;
      double kmax = 0;
      for (double v : K) kmax = std::max(kmax, std::abs(v));
      const double h = config == 1 ? 1e-9 : 1e-7;
      for (int col = 0; col < 12; ++col) {
        double* xc = &w.x[3 * tet[col / 3] + col % 3];
        const double x0 = *xc;
        double fp[12], fm[12];
        *xc = x0 + h;
        ef.tet_forces(t, w.x.data(), fp);
        *xc = x0 - h;
        ef.tet_forces(t, w.x.data(), fm);
        *xc = x0;
        for (int row = 0; row < 12; ++row) {
          const double fd = -(fp[row] - fm[row]) / (2 * h);
          EXPECT_NEAR(K[12 * row + col], fd, 2e-6 * kmax)
              << model << " config " << config << " K(" << row << "," << col << ")";
          worst = std::max(worst, std::abs(K[12 * row + col] - fd) / kmax);
        }
      }
      RecordProperty(std::string("worst_") + model + "_" + std::to_string(config), sci(worst));
    }
  }
  // Warped = exact at a rotated rest state (corotational); implicit = exact (linear).
  for (const char* model : {"linear", "corotational"}) {
    const Scene s = box(model);
    World w = build_world(s, block_partition(s, 1), 0);
    ElasticForces ef(s, w);
    if (std::string(model) == "corotational")
      for (std::size_t i = 0; i < w.n_local(); ++i) {  // 90 degrees about z
        const double x = w.x[3 * i], y = w.x[3 * i + 1];
        w.x[3 * i] = -y;
        w.x[3 * i + 1] = x;
      }
    else
      perturb(w.x, 0.05, 3);
    double Ke[144], Ki[144];
    ef.tet_stiffness(7, w.x.data(), StiffnessKind::exact, Ke);
    ef.tet_stiffness(7, w.x.data(), StiffnessKind::implicit, Ki);
    for (int k = 0; k < 144; ++k) EXPECT_NEAR(Ki[k], Ke[k], 1e-9 * 1e5) << model << " entry " << k;
  }
}

// Translation and any rotation give zero force for every model but the linear one, which
// is only invariant under translations and infinitesimal rotations.
TEST(ElasticForces, RigidMotionsGiveNoForce) {
  const double th = 1.2, c = std::cos(th), sn = std::sin(th);
  for (const char* model : kModels) {
    const Scene s = box(model);
    World w = build_world(s, block_partition(s, 1), 0);
    ElasticForces ef(s, w);
    const bool linear = std::string(model) == "linear";
    const double eps = linear ? 1e-7 : 1.0;  // rotation angle scale
    for (std::size_t i = 0; i < w.n_local(); ++i) {
      double* p = &w.x[3 * i];
      const double x = p[0], y = p[1], z = p[2];
      if (linear) {  // u = w x X, w = eps (1, 2, 3): an infinitesimal rotation
        p[0] = x + eps * (2 * z - 3 * y) + 5;
        p[1] = y + eps * (3 * x - 1 * z) - 2;
        p[2] = z + eps * (1 * y - 2 * x) + 1;
      } else {  // rotation by 1.2 rad about z, then about x, plus a translation
        const double x1 = c * x - sn * y, y1 = sn * x + c * y;
        p[0] = x1 + 5;
        p[1] = c * y1 - sn * z - 2;
        p[2] = sn * y1 + c * z + 1;
      }
    }
    const std::vector<double> f = forces(ef, w);
    // Scale: a force of 1e-9 of what a 1 % strain of one cell gives (E h^2 0.01 ~ 250 N).
    double worst = 0;
    for (std::size_t k = 0; k < f.size(); ++k) {
      EXPECT_NEAR(f[k], 0.0, 1e-9 * 250) << model << " dof " << k;
      worst = std::max(worst, std::abs(f[k]));
    }
    RecordProperty(std::string("max_force_") + model, sci(worst));
    EXPECT_NEAR(energy(ef, w), 0.0, 1e-12 * 1e5) << model;
  }
}

// The vectorised kernels (lanes of tets, all instruction-set variants) compute what the
// scalar laws compute, tet by tet (the mass-spring kernel, in edge form, against the F
// form of its energy), including a partial chunk at the end and an inverted tet (SVD).
TEST(ElasticForces, KernelsAgreeWithTheScalarLaws) {
  using namespace softcontact::model;
  for (const char* model : kModels) {
    const Scene s = box(model, "[3, 2, 1]");  // 36 tets: two pairs of chunks, then 4 tets
    World w = build_world(s, block_partition(s, 1), 0);
    ElasticForces ef(s, w);
    const World rest = build_world(s, block_partition(s, 1), 0);
    perturb(w.x, 0.1, 5);
    // Invert tet 3 (corner 3 reflected through the centroid of the others).
    const index_t* tet = &w.tets[12];
    for (int d = 0; d < 3; ++d) {
      const double cen = (w.x[3 * tet[0] + d] + w.x[3 * tet[1] + d] + w.x[3 * tet[2] + d]) / 3;
      w.x[3 * tet[3] + d] = 2 * cen - w.x[3 * tet[3] + d];
    }
    const std::vector<double> f = forces(ef, w);
    std::vector<double> ref(w.x.size(), 0.0);
    const ElasticForces::Segment& seg = ef.segments()[0];
    const Lame l{seg.lambda, seg.mu};
    for (std::size_t t = 0; t < w.tet_gid.size(); ++t) {
      const index_t* c = &w.tets[4 * t];
      // Rest Dm^-1 from the rest positions.
      const double* X[4] = {&rest.x[3 * c[0]], &rest.x[3 * c[1]], &rest.x[3 * c[2]], &rest.x[3 * c[3]]};
      const Mat3 dm = {X[1][0] - X[0][0], X[2][0] - X[0][0], X[3][0] - X[0][0], X[1][1] - X[0][1], X[2][1] - X[0][1],
                       X[3][1] - X[0][1], X[1][2] - X[0][2], X[2][2] - X[0][2], X[3][2] - X[0][2]};
      const Mat3 cof = cofactor(dm);
      Mat3 di;
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) di[3 * i + j] = cof[3 * j + i] / det(dm);
      const Mat3 F = deformation_gradient(&w.x[3 * c[0]], &w.x[3 * c[1]], &w.x[3 * c[2]], &w.x[3 * c[3]], di);
      Mat3 P;
      const std::string m = model;
      if (m == "linear") P = LinearLaw{l, 0}.stress(F);
      else if (m == "corotational") P = CorotationalLaw{l, 0}.stress(F);
      else if (m == "stvk") P = StvkLaw{l, 0}.stress(F);
      else if (m == "neohookean") P = NeoHookeanLaw(l, 0).stress(F);
      else {  // the edge-form kernel against the F form of the same energy
        double Xr[12];
        for (int a = 0; a < 4; ++a)
          for (int d = 0; d < 3; ++d) Xr[3 * a + d] = X[a][d];
        P = MassSpringLaw::from_rest(seg.young, 0, Xr).stress(F);
      }
      double fc[12];
      corner_forces(P, di, ef.rest_volume(t), fc);
      for (int a = 0; a < 4; ++a)
        for (int d = 0; d < 3; ++d) ref[3 * c[a] + d] += fc[3 * a + d];
    }
    double fmax = 0;
    for (double v : ref) fmax = std::max(fmax, std::abs(v));
    for (std::size_t k = 0; k < f.size(); ++k) EXPECT_NEAR(f[k], ref[k], 1e-12 * fmax) << model << " dof " << k;
  }
}

TEST(ElasticForces, SumDoesNotDependOnThreadCount) {
  for (const char* model : kModels) {
    const Scene s = load_scene_from_string(
        std::string("simulation: {dt: 1e-4, steps: 1, gravity: [0, 0, 0]}\nmaterials:\n  - {name: m, model: ") + model +
            ", young: 1e5, poisson: 0.3, density: 1000, damping: {mass: 0.5, stiffness: 0.01}}\n"
            "objects:\n  - material: m\n    primitive: {type: sphere, radius: 0.5, resolution: 8}\n",
        "test.yaml");
    World w = build_world(s, block_partition(s, 1), 0);
    ElasticForces ef(s, w);
    perturb(w.x, 0.02, 9);
    perturb(w.v, 1.0, 10);
    const int before = omp_get_max_threads();
    std::vector<std::vector<double>> results;
    for (int threads : {1, 2, 3}) {
      omp_set_num_threads(threads);
      std::vector<double> f(w.x.size(), 0.0);
      ef.add_forces(w, f, true);
      results.push_back(f);
    }
    omp_set_num_threads(before);
    for (std::size_t r = 1; r < results.size(); ++r)
      for (std::size_t k = 0; k < results[0].size(); ++k)
        ASSERT_EQ(results[r][k], results[0][k]) << model << " dof " << k << " with " << r + 1 << " threads";
  }
}

// add_forces evaluates small objects whole (kernels, then the gather of their vertices)
// and larger ones, on one thread, in stages of 4,096 tets, each vertex gathered after the
// stage of its last tet (on more, all kernels and then all vertices). Reference: every
// tet's corner forces (tet_forces, one tet at a time) added to its corners in ascending
// tet order, the order the gather promises, so the result must be bitwise the same for
// any thread count. The scene mixes an object above the fused size and the stage (box of
// 12 x 12 x 6 cells: 5,184 tets > 4,096, so two stages, with vertices whose tets lie in
// both), small ones before and after it, and a kinematic one (no forces at all). Each
// evaluation follows one at other positions, so a vertex gathered before all its tets
// are done would read their stale corner forces. The corner forces streamed in the same
// stages (stream_vertex_corners, a split object's part) are those written after the two
// phases.
TEST(ElasticForces, ObjectsEvaluatedWholeAddInTetOrder) {
  const Scene s = load_scene_from_string(
      "simulation: {dt: 1e-4, steps: 1, gravity: [0, 0, 0]}\n"
      "materials:\n  - {name: m, model: neohookean, young: 1e5, poisson: 0.3, density: 1000}\n"
      "  - {name: c, model: corotational, young: 1e5, poisson: 0.3, density: 1000}\n"
      "objects:\n"
      "  - {material: m, primitive: {type: sphere, radius: 0.2, resolution: 4}}\n"
      "  - {material: c, primitive: {type: box, size: [1, 1, 0.5], cells: [12, 12, 6]}, transform: {translate: [0, 0, 1]}}\n"
      "  - {material: m, primitive: {type: box, size: [0.3, 0.3, 0.3], cells: [2, 2, 2]}, kinematic: true,\n"
      "     transform: {translate: [1, 0, 0]}}\n"
      "  - {material: c, primitive: {type: sphere, radius: 0.2, resolution: 5}, transform: {translate: [0, 1, 0]}}\n",
      "test.yaml");
  World w = build_world(s, block_partition(s, 1), 0);
  ASSERT_GT(w.m_owned, std::size_t{4096});
  ElasticForces ef(s, w);
  perturb(w.x, 0.01, 21);

  std::vector<double> ref(w.x.size(), 0.0);
  for (std::size_t t = 0; t < w.m_owned; ++t) {
    if (s.objects[static_cast<std::size_t>(w.tet_object[t])].kinematic()) continue;
    double c[12];
    ef.tet_forces(t, w.x.data(), c);
    for (int k = 0; k < 4; ++k)
      for (int d = 0; d < 3; ++d) ref[3 * static_cast<std::size_t>(w.tets[4 * t + k]) + d] += c[3 * k + d];
  }
  double fmax = 0;
  for (double v : ref) fmax = std::max(fmax, std::abs(v));
  ASSERT_GT(fmax, 0);
  const int before = omp_get_max_threads();
  const std::vector<double> x = w.x;
  std::vector<double> elsewhere = x;
  perturb(elsewhere, 0.02, 22);
  for (int threads : {1, 2, 3}) {
    omp_set_num_threads(threads);
    std::vector<double> f(w.x.size(), 0.0);
    w.x = elsewhere;
    ef.add_forces(w, f, false);
    w.x = x;
    std::fill(f.begin(), f.end(), 0.0);
    ef.add_forces(w, f, false);
    for (std::size_t k = 0; k < f.size(); ++k) ASSERT_EQ(f[k], ref[k]) << "dof " << k << ", " << threads << " threads";
    std::vector<double> g(w.x.size(), 0.0);
    ef.compute_tet_forces(w, false);
    ef.gather_forces(w, g, false);
    for (std::size_t k = 0; k < g.size(); ++k) ASSERT_EQ(g[k], ref[k]) << "dof " << k << " (two phases)";
    for (const bool folded : {false, true}) {
      std::vector<char> fold(w.n_owned);
      std::vector<std::size_t> offset(w.n_owned);
      std::size_t doubles = 0;
      for (std::size_t i = 0; i < w.n_owned; ++i) {
        fold[i] = folded == (i % 3 != 0) ? 1 : 0;  // both kinds in each run
        offset[i] = doubles;
        doubles += ef.vertex_corner_doubles(i, fold[i] != 0);
      }
      std::vector<double> two_phases(doubles, -1.0), streamed(doubles, -2.0);
      double* out = two_phases.data();
      for (std::size_t i = 0; i < w.n_owned; ++i) out = ef.write_vertex_corners(i, fold[i] != 0, out);
      ASSERT_EQ(out, two_phases.data() + doubles);
      w.x = elsewhere;
      ef.compute_tet_forces(w, false);
      w.x = x;
      ef.stream_vertex_corners(w, false, fold, offset, streamed.data());
      for (std::size_t k = 0; k < doubles; ++k)
        ASSERT_EQ(streamed[k], two_phases[k]) << "stream entry " << k << ", " << threads << " threads";
    }
  }
  omp_set_num_threads(before);
}

// Objects split over ranks (split_forces.hpp): exclude_objects drops an object's tets and
// vertices from add_forces, whether it is evaluated whole (a small one) or in two phases
// (a large one), and leaves every other vertex's force bitwise as it was. The excluded
// vertices' forces rebuilt from their corner forces (write_vertex_corners, each entry or
// the fold, folded from zero in order) by add_vertex_sums are bitwise add_forces' own,
// with both kinds of damping; an empty list restores the whole plan.
TEST(ElasticForces, ExcludedObjectsRebuildFromTheirCornerForcesBitwise) {
  const Scene s = load_scene_from_string(
      "simulation: {dt: 1e-4, steps: 1, gravity: [0, 0, 0]}\n"
      "materials:\n  - {name: m, model: neohookean, young: 1e5, poisson: 0.3, density: 1000, damping: {mass: 0.7, stiffness: 0.01}}\n"
      "  - {name: c, model: corotational, young: 1e5, poisson: 0.3, density: 1000, damping: {mass: 0.3, stiffness: 0.02}}\n"
      "objects:\n"
      "  - {material: m, primitive: {type: sphere, radius: 0.2, resolution: 4}}\n"
      "  - {material: c, primitive: {type: box, size: [1, 1, 0.5], cells: [12, 12, 6]}, transform: {translate: [0, 0, 1]}}\n"
      "  - {material: m, primitive: {type: box, size: [0.3, 0.3, 0.3], cells: [2, 2, 2]}, transform: {translate: [1, 0, 0]}}\n"
      "  - {material: c, primitive: {type: sphere, radius: 0.2, resolution: 5}, transform: {translate: [0, 1, 0]}}\n",
      "test.yaml");
  World w = build_world(s, block_partition(s, 1), 0);
  ElasticForces ef(s, w);
  perturb(w.x, 0.01, 31);
  perturb(w.v, 0.5, 32);
  std::vector<double> full(w.x.size(), 0.0);
  ef.add_forces(w, full, true);

  const std::vector<int> excluded = {1, 3};  // the large object and a small one
  auto is_excluded = [&](std::size_t i) {
    return std::find(excluded.begin(), excluded.end(), w.vertex_object[i]) != excluded.end();
  };
  ef.exclude_objects(w, excluded);
  std::vector<double> part(w.x.size(), 0.0);
  ef.add_forces(w, part, true);
  std::size_t checked = 0;
  for (std::size_t i = 0; i < w.n_owned; ++i)
    for (std::size_t d = 0; d < 3; ++d) {
      if (is_excluded(i)) ASSERT_EQ(part[3 * i + d], 0.0) << "excluded vertex " << i << " got a force";
      else ASSERT_EQ(part[3 * i + d], full[3 * i + d]) << "vertex " << i;
      checked += is_excluded(i) ? 1 : 0;
    }
  ASSERT_GT(checked, std::size_t{3 * 1000});

  // The excluded vertices from their corner forces (the tet buffer holds every tet's).
  ef.compute_tet_forces(w, true);
  for (const bool fold : {false, true}) {
    std::vector<double> rebuilt = part;
    for (std::size_t i = 0; i < w.n_owned; ++i) {
      if (!is_excluded(i)) continue;
      std::vector<double> c(ef.vertex_corner_doubles(i, fold), -1.0);
      ASSERT_EQ(ef.write_vertex_corners(i, fold, c.data()), c.data() + c.size()) << "vertex " << i;
      ASSERT_EQ(c.size() % 3, 0u);
      if (fold) ASSERT_EQ(c.size(), 3u);
      double sum[3] = {0, 0, 0};  // the entries folded from zero in their order
      for (std::size_t k = 0; k < c.size(); k += 3)
        for (std::size_t d = 0; d < 3; ++d) sum[d] += c[k + d];
      const double alpha = s.materials[s.objects[static_cast<std::size_t>(w.vertex_object[i])].material].damping_mass;
      ElasticForces::add_vertex_sums(w, rebuilt, true, alpha, i, sum, 1);
    }
    for (std::size_t k = 0; k < full.size(); ++k) ASSERT_EQ(rebuilt[k], full[k]) << "dof " << k << (fold ? " (fold)" : "");
  }

  ef.exclude_objects(w, {});
  std::vector<double> again(w.x.size(), 0.0);
  ef.add_forces(w, again, true);
  for (std::size_t k = 0; k < full.size(); ++k) ASSERT_EQ(again[k], full[k]) << "dof " << k << " after restoring";
}

TEST(ElasticForces, MeasureCountsInvertedTets) {
  const Scene s = box("neohookean");
  World w = build_world(s, block_partition(s, 1), 0);
  ElasticForces ef(s, w);
  ElasticMeasures m;
  ef.measure(w, m);
  ASSERT_EQ(m.energy.size(), 1u);
  EXPECT_EQ(m.energy[0], 0.0);
  EXPECT_EQ(m.inverted[0], 0);
  // Flatten the box completely in z: every tet has det F = 0 (counted as inverted).
  for (std::size_t i = 0; i < w.n_local(); ++i) w.x[3 * i + 2] = 0;
  ef.measure(w, m);
  EXPECT_EQ(m.inverted[0], 48);
  EXPECT_GT(m.energy[0], 0.0);
}

// Objects whose forces are computed elsewhere from the start (held_elsewhere: an owned
// object split over ranks): no rest data of theirs is held, add_forces gives every other
// vertex bitwise the force of the full plan with those objects excluded and leaves theirs
// at zero, and measure() gives every object's energy and inverted count bitwise the full
// one's, theirs from rest data made again from the scene's mesh. The reference is an
// ElasticForces holding every tet. A list that leaves such an object out is refused.
TEST(ElasticForces, ObjectsHeldElsewhereKeepNoRestDataAndMeasureBitwise) {
  const Scene s = load_scene_from_string(
      "simulation: {dt: 1e-4, steps: 1, gravity: [0, 0, 0]}\n"
      "materials:\n  - {name: m, model: neohookean, young: 1e5, poisson: 0.3, density: 1000, damping: {mass: 0.7, stiffness: 0.01}}\n"
      "  - {name: c, model: corotational, young: 1e5, poisson: 0.3, density: 1000, damping: {mass: 0.3, stiffness: 0.02}}\n"
      "  - {name: s, model: mass_spring, young: 1e5, poisson: 0.3, density: 1000}\n"
      "objects:\n"
      "  - {material: m, primitive: {type: sphere, radius: 0.2, resolution: 4}}\n"
      "  - {material: c, primitive: {type: box, size: [1, 1, 0.5], cells: [12, 12, 6]}, transform: {translate: [0, 0, 1]}}\n"
      "  - {material: m, primitive: {type: box, size: [0.3, 0.3, 0.3], cells: [2, 2, 2]}, transform: {translate: [1, 0, 0]}}\n"
      "  - {material: s, primitive: {type: sphere, radius: 0.2, resolution: 5}, transform: {translate: [0, 1, 0]}}\n",
      "test.yaml");
  World w = build_world(s, block_partition(s, 1), 0);
  const std::vector<int> elsewhere = {1, 3};  // a large object (more than a chunk of 1,024 tets) and a spring one
  ElasticForces full(s, w);
  ElasticForces held(s, w, elsewhere);
  EXPECT_EQ(held.held_tets(), full.held_tets() - s.shape(1).tets - s.shape(3).tets);
  ASSERT_GT(s.shape(1).tets, std::size_t{1024});
  perturb(w.x, 0.02, 41);
  perturb(w.v, 0.5, 42);

  full.exclude_objects(w, elsewhere);
  std::vector<double> want(w.x.size(), 0.0), got(w.x.size(), 0.0);
  full.add_forces(w, want, true);
  held.add_forces(w, got, true);
  for (std::size_t k = 0; k < want.size(); ++k) ASSERT_EQ(got[k], want[k]) << "dof " << k;

  ElasticMeasures a, b;
  full.measure(w, a);
  held.measure(w, b);
  ASSERT_EQ(b.energy.size(), a.energy.size());
  for (std::size_t k = 0; k < a.energy.size(); ++k) {
    EXPECT_EQ(std::memcmp(&b.energy[k], &a.energy[k], sizeof(double)), 0)
        << "object " << k << ": " << b.energy[k] << " against " << a.energy[k];
    EXPECT_EQ(b.inverted[k], a.inverted[k]) << "object " << k;
    EXPECT_GT(a.energy[k], 0.0) << "object " << k << " is not deformed: the test proves nothing";
  }
  // Inverted tets count alike: squash the large object flat through itself.
  for (std::size_t i = 0; i < w.n_owned; ++i)
    if (w.vertex_object[i] == 1) w.x[3 * i + 2] = 1.0 - (w.x[3 * i + 2] - 1.0);
  full.measure(w, a);
  held.measure(w, b);
  EXPECT_GT(a.inverted[1], 0);
  EXPECT_EQ(b.inverted[1], a.inverted[1]);
  EXPECT_EQ(std::memcmp(&b.energy[1], &a.energy[1], sizeof(double)), 0);

  EXPECT_NO_THROW(held.exclude_objects(w, {0, 1, 3}));
  EXPECT_THROW(held.exclude_objects(w, {1}), RuntimeFailure);
  EXPECT_THROW(held.exclude_objects(w, {}), RuntimeFailure);
}
