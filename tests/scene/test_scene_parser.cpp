#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>
#include <cmath>
#include <sstream>
#include <string>

#include "softcontact/error.hpp"
#include "softcontact/forces.hpp"
#include "softcontact/scene.hpp"
#include "softcontact/split_forces.hpp"
#include "softcontact/world.hpp"

using namespace softcontact;

namespace {

// E = 1e5, nu = 0.25: lambda = mu = 4e4, lambda + 2 mu = 1.2e5; rho = 1200 -> c = 10 m/s.
const std::string kMaterials = R"(
materials:
  - name: rubber
    model: corotational
    young: 1.0e5
    poisson: 0.25
    density: 1200
  - name: steel
    model: linear
    young: 2.0e11
    poisson: 0.3
    density: 7800
)";

std::string scene_with(const std::string& objects, const std::string& sim = "  dt: auto\n  steps: 10\n") {
  return "simulation:\n" + sim + kMaterials + "objects:\n" + objects;
}

const std::string kBox = R"(  - name: cube
    material: rubber
    primitive: {type: box, size: [1, 1, 1], cells: [2, 2, 2]}
)";

/// Expects load_scene_from_string to throw an InputError whose message contains all of
/// `parts`.
void expect_error(const std::string& yaml, std::initializer_list<std::string> parts) {
  try {
    load_scene_from_string(yaml, "scene.yaml");
    FAIL() << "expected an InputError";
  } catch (const InputError& e) {
    const std::string m = e.what();
    for (const auto& p : parts) EXPECT_NE(m.find(p), std::string::npos) << "message: " << m << "\nmissing: " << p;
  }
}

double point_plane_distance(const double* p, const double* a, const double* b, const double* c) {
  const double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
  const double v[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
  double n[3] = {u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]};
  const double len = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
  return std::abs((p[0] - a[0]) * n[0] + (p[1] - a[1]) * n[1] + (p[2] - a[2]) * n[2]) / len;
}

}  // namespace

TEST(SceneParser, MaterialsAndWaveSpeed) {
  const Scene s = load_scene_from_string(scene_with(kBox), "scene.yaml");
  ASSERT_EQ(s.materials.size(), 2u);
  EXPECT_EQ(s.materials[0].model, ModelKind::corotational);
  EXPECT_NEAR(s.materials[0].lame_lambda(), 4e4, 1e-9);
  EXPECT_NEAR(s.materials[0].lame_mu(), 4e4, 1e-9);
  EXPECT_NEAR(s.materials[0].wave_speed(), 10.0, 1e-12);
  ASSERT_EQ(s.objects.size(), 1u);
  EXPECT_EQ(s.objects[0].mesh.num_tets(), 48u);
  EXPECT_EQ(s.sim.output_dir, "output/scene");
}

/// 2 / omega_max of the assembled, linearised system of object 0 (M^-1/2 K M^-1/2, dense):
/// the true stability limit of Verlet and symplectic Euler at rest.
double true_stable_step(const Scene& s) {
  const World w = build_world(s, block_partition(s, 1), 0);
  const ElasticForces ef(s, w);
  const auto n = static_cast<Eigen::Index>(3 * w.n_owned);
  Eigen::MatrixXd A = Eigen::MatrixXd::Zero(n, n);
  double K[144];
  for (std::size_t t = 0; t < w.tet_gid.size(); ++t) {
    ef.tet_stiffness(t, w.x.data(), StiffnessKind::exact, K);
    const index_t* c = &w.tets[4 * t];
    for (int a = 0; a < 12; ++a)
      for (int b = 0; b < 12; ++b)
        A(3 * c[a / 3] + a % 3, 3 * c[b / 3] + b % 3) +=
            K[12 * a + b] / std::sqrt(w.mass[c[a / 3]] * w.mass[c[b / 3]]);
  }
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(A, Eigen::EigenvaluesOnly);
  return 2 / std::sqrt(es.eigenvalues().maxCoeff());
}

// dt: auto = dt_safety x the guaranteed explicit limit 2 / max_T omega_T, omega_T the
// highest frequency of each tet alone with a quarter of its mass per corner (Irons'
// element eigenvalue bound, docs/models.md). Against the true limit of the assembled cube
// (2 / omega_max, dense eigenvalues): the bound lies below it, as it must, at 0.763 of it
// here; the former estimate h_min / c (smallest altitude over the wave speed) lies above
// it on Kuhn-split boxes (1.070 of it here), so that dt_safety = 1 was unstable.
TEST(SceneParser, AutoTimeStepIsSafetyTimesTheGuaranteedStableLimit) {
  const Scene s = load_scene_from_string(scene_with(kBox, "  dt: auto\n  dt_safety: 0.4\n  steps: 10\n"), "scene.yaml");
  const TetMesh& m = s.objects[0].mesh;
  double wmax = 0, hmin = HUGE_VAL;
  for (std::size_t t = 0; t < m.num_tets(); ++t) {
    double X[12];
    const double* p[4];
    for (int k = 0; k < 4; ++k) {
      p[k] = &m.points[3 * m.tets[4 * t + k]];
      for (int d = 0; d < 3; ++d) X[3 * k + d] = p[k][d];
    }
    wmax = std::max(wmax, tet_max_frequency(X, s.materials[0]));
    for (int k = 0; k < 4; ++k)
      hmin = std::min(hmin, point_plane_distance(p[k], p[(k + 1) % 4], p[(k + 2) % 4], p[(k + 3) % 4]));
  }
  EXPECT_DOUBLE_EQ(stable_time_step(s), 2 / wmax);
  EXPECT_DOUBLE_EQ(s.sim.dt, 0.4 * 2 / wmax);
  EXPECT_TRUE(s.warnings.empty());
  const double limit = true_stable_step(s);
  EXPECT_LE(stable_time_step(s), limit);
  EXPECT_GT(stable_time_step(s), 0.6 * limit);
  EXPECT_GT(hmin / s.materials[0].wave_speed(), limit);
  RecordProperty("bound_over_limit", std::to_string(stable_time_step(s) / limit));
  RecordProperty("former_over_limit", std::to_string(hmin / s.materials[0].wave_speed() / limit));
}

// The mass-spring model's limit follows its springs (k_e = E V / L_e^2), not the Poisson
// ratio of the material (which the model does not use).
TEST(SceneParser, MassSpringLimitIgnoresPoissonRatio) {
  auto limit = [](const char* nu) {
    return stable_time_step(load_scene_from_string(
        std::string("simulation: {dt: auto, steps: 1}\nmaterials:\n  - {name: s, model: mass_spring, young: 1e5, "
                    "poisson: ") + nu + ", density: 1000}\nobjects:\n  - material: s\n"
                    "    primitive: {type: box, size: [1, 1, 1], cells: [2, 2, 2]}\n",
        "scene.yaml"));
  };
  EXPECT_EQ(limit("0.0"), limit("0.45"));
  const Scene s = load_scene_from_string(
      "simulation: {dt: auto, steps: 1}\nmaterials:\n  - {name: s, model: mass_spring, young: 1e5, poisson: 0.3, "
      "density: 1000}\nobjects:\n  - material: s\n    primitive: {type: box, size: [1, 1, 1], cells: [2, 2, 2]}\n",
      "scene.yaml");
  EXPECT_LE(stable_time_step(s), true_stable_step(s));
}

TEST(SceneParser, TimeStepAboveStableLimitWarnsWithTheLimit) {
  const Scene s = load_scene_from_string(scene_with(kBox, "  dt: 0.05\n  end_time: 1.0\n"), "scene.yaml");
  // All 48 Kuhn tets of the box are congruent: the limit is 2 / omega of any one of them
  // (0.0252214 s for cells of 0.5 m at c = 10 m/s).
  const TetMesh& m = s.objects[0].mesh;
  double X[12];
  for (int k = 0; k < 4; ++k)
    for (int d = 0; d < 3; ++d) X[3 * k + d] = m.points[3 * m.tets[k] + d];
  std::ostringstream limit;
  limit << 2 / tet_max_frequency(X, s.materials[0]);
  ASSERT_EQ(s.warnings.size(), 1u);
  EXPECT_NE(s.warnings[0].find("exceeds the stable explicit limit " + limit.str() + " s"), std::string::npos)
      << s.warnings[0];
  EXPECT_EQ(limit.str(), "0.0252214");
  EXPECT_EQ(total_steps(s.sim), 20);
}

// Implicit Euler needs a positive semi-definite stiffness (linear, corotational): other
// models are an input error at the 'integrator' line, naming object, material and model.
TEST(SceneParser, ImplicitEulerRejectsNonLinearModels) {
  std::string yaml = scene_with(kBox, "  dt: 0.001\n  steps: 10\n  integrator: implicit_euler\n");
  yaml.replace(yaml.find("model: corotational"), 19, "model: stvk");
  expect_error(yaml, {"scene.yaml:4:", "'implicit_euler'", "object 'cube'", "material 'rubber'", "model 'stvk'"});
  // Linear and corotational are fine, and so are other models on kinematic objects.
  EXPECT_NO_THROW(load_scene_from_string(scene_with(kBox, "  dt: 0.001\n  steps: 10\n  integrator: implicit_euler\n"),
                                         "scene.yaml"));
}

TEST(SceneParser, StepsAndFramesFromEndTimeAndInterval) {
  const Scene s = load_scene_from_string(
      scene_with(kBox, "  dt: 0.001\n  end_time: 0.5\n  output: {interval: 0.01, directory: out/x}\n"), "scene.yaml");
  EXPECT_EQ(total_steps(s.sim), 500);
  EXPECT_EQ(steps_between_frames(s.sim), 10);
  EXPECT_EQ(s.sim.output_dir, "out/x");
}

TEST(SceneParser, UnknownKeySuggestsNearestWithLine) {
  const std::string yaml = "simulation:\n  dt: auto\n  steps: 10\nmaterials:\n  - name: a\n    young: 1e5\n"
                           "    poisson: 0.3\n    densty: 1000\nobjects:\n" + kBox;
  expect_error(yaml, {"scene.yaml:8:", "unknown key 'densty'", "did you mean 'density'"});
}

TEST(SceneParser, UnknownTopLevelKeyAndEnumSuggestions) {
  expect_error("simulaton:\n  steps: 1\n", {"scene.yaml:1:", "did you mean 'simulation'"});
  expect_error(scene_with(kBox, "  steps: 10\n  integrator: verlett\n"), {"scene.yaml:3:", "did you mean 'verlet'"});
  expect_error(scene_with("  - material: rubbr\n    primitive: {type: sphere, radius: 1}\n"),
               {"unknown material 'rubbr'", "did you mean 'rubber'"});
}

TEST(SceneParser, PhysicalRangesAreChecked) {
  auto mat = [](const std::string& body) {
    return "simulation:\n  steps: 10\nmaterials:\n  - name: a\n" + body + "objects:\n" +
           "  - material: a\n    primitive: {type: box, size: [1, 1, 1]}\n";
  };
  expect_error(mat("    young: 1e5\n    poisson: 0.5\n    density: 1000\n"),
               {"scene.yaml:6:", "'poisson'", "(-1, 0.5)"});
  expect_error(mat("    young: 1e5\n    poisson: -1.0\n    density: 1000\n"), {"scene.yaml:6:", "(-1, 0.5)"});
  expect_error(mat("    young: 1e5\n    poisson: 0.3\n    density: 0\n"), {"scene.yaml:7:", "'density'", "positive"});
  expect_error(mat("    young: 1e5\n    poisson: 0.3\n    density: -5\n"), {"scene.yaml:7:", "positive"});
  expect_error(mat("    young: abc\n    poisson: 0.3\n    density: 5\n"), {"scene.yaml:5:", "expected a number", "'abc'"});
  expect_error(mat("    poisson: 0.3\n    density: 5\n"), {"missing key 'young'"});
}

TEST(SceneParser, MalformedYamlNamesLine) {
  expect_error("simulation:\n  steps: [1, 2\nmaterials: []\n", {"scene.yaml:", "malformed YAML"});
  expect_error("- just\n- a list\n", {"scene.yaml", "mapping"});
}

TEST(SceneParser, EndTimeAndStepsAreExclusive) {
  expect_error(scene_with(kBox, "  steps: 10\n  end_time: 1\n"), {"scene.yaml:2:", "not both"});
  expect_error(scene_with(kBox, "  dt: auto\n"), {"missing key 'end_time'"});
}

TEST(SceneParser, MissingMeshFileIsNamed) {
  expect_error(scene_with("  - material: rubber\n    mesh: nowhere/ball.msh\n"),
               {"scene.yaml:", "nowhere/ball.msh", "does not exist"});
}

// A name the file system refuses (a component over NAME_MAX, 255 bytes on Linux) is an
// InputError at the line of 'mesh', not a std::filesystem_error (found by fuzzing).
TEST(SceneParser, MeshNameTheFileSystemRefusesIsAnInputError) {
  const std::string name(300, 'x');
  expect_error(scene_with("  - material: rubber\n    mesh: " + name + ".msh\n"),
               {"scene.yaml:", "cannot look up mesh file", "File name too long"});
  try {
    load_scene("/tmp/" + name + ".yaml");
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("cannot look up the scene file"), std::string::npos) << e.what();
  }
}

TEST(SceneParser, MissingSceneFile) {
  try {
    load_scene("/nonexistent/scene.yaml");
    FAIL();
  } catch (const InputError& e) {
    EXPECT_EQ(e.file(), "/nonexistent/scene.yaml");
    EXPECT_NE(std::string(e.what()).find("does not exist"), std::string::npos);
  }
}

TEST(SceneParser, GridInstancesAreOffsetExactly) {
  const Scene s = load_scene_from_string(scene_with(R"(  - name: c
    material: rubber
    primitive: {type: box, size: [1, 1, 1], cells: [1, 1, 1]}
    transform: {translate: [10, 0, 0]}
    instances: {grid: {count: [2, 3, 1], spacing: [2, 3, 4]}}
)"),
                                         "scene.yaml");
  ASSERT_EQ(s.objects.size(), 6u);
  EXPECT_EQ(s.objects[5].name, "c[5]");
  // Instance k = ix + 2 iy: its first vertex is the base's first vertex + (2 ix, 3 iy, 0).
  const double* base = s.objects[0].mesh.points.data();
  EXPECT_DOUBLE_EQ(base[0], 10 - 0.5);
  for (int k = 0; k < 6; ++k) {
    const double* p = s.objects[k].mesh.points.data();
    EXPECT_DOUBLE_EQ(p[0], base[0] + 2 * (k % 2));
    EXPECT_DOUBLE_EQ(p[1], base[1] + 3 * (k / 2));
    EXPECT_DOUBLE_EQ(p[2], base[2]);
  }
}

TEST(SceneParser, RandomPlacementIsSeededInsideRegionAndNonOverlapping) {
  auto make = [](int seed) {
    return load_scene_from_string(scene_with("  - name: s\n    material: rubber\n"
                                             "    primitive: {type: sphere, radius: 0.1, resolution: 2}\n"
                                             "    instances: {random: {count: 20, seed: " +
                                             std::to_string(seed) +
                                             ", rotate: true, region: {min: [0, 0, 0], max: [1, 1, 1]}}}\n"),
                                  "scene.yaml");
  };
  const Scene a = make(7), b = make(7), c = make(8);
  ASSERT_EQ(a.objects.size(), 20u);
  std::vector<std::array<double, 3>> centres;
  for (std::size_t k = 0; k < a.objects.size(); ++k) {
    EXPECT_EQ(a.objects[k].mesh.points, b.objects[k].mesh.points);  // same seed: bitwise the same
    std::array<double, 3> c0{0, 0, 0};
    const auto& pts = a.objects[k].mesh.points;
    for (std::size_t i = 0; i < pts.size(); ++i) {
      EXPECT_GE(pts[i], -1e-12);
      EXPECT_LE(pts[i], 1 + 1e-12);
      c0[i % 3] += pts[i] / (pts.size() / 3);
    }
    centres.push_back(c0);
  }
  EXPECT_NE(a.objects[0].mesh.points, c.objects[0].mesh.points);
  // Spheres of radius 0.1: each centre is at least 0.1 from the earlier copies' boxes,
  // which contain their spheres, so centres are at least 0.2 apart (up to the mesh's
  // centroid offset).
  for (std::size_t i = 0; i < centres.size(); ++i)
    for (std::size_t j = 0; j < i; ++j)
      EXPECT_GT(std::hypot(centres[i][0] - centres[j][0], centres[i][1] - centres[j][1], centres[i][2] - centres[j][2]),
                0.2 - 1e-6);
}

TEST(SceneParser, RandomPlacementFailsClearlyWhenRegionIsTooSmall) {
  expect_error(scene_with("  - name: s\n    material: rubber\n    primitive: {type: sphere, radius: 0.4}\n"
                          "    instances: {random: {count: 50, region: {min: [0, 0, 0], max: [1, 1, 1]}}}\n"),
               {"scene.yaml:", "non-overlapping", "enlarge the region"});
}

TEST(SceneParser, TransformRotatesScalesThenTranslates) {
  const Scene s = load_scene_from_string(scene_with(R"(  - material: rubber
    primitive: {type: box, size: [2, 2, 2], cells: [1, 1, 1]}
    transform: {scale: [2, 1, 1], rotate: {axis: [0, 0, 1], angle: 90}, translate: [0, 0, 5]}
)"),
                                         "scene.yaml");
  // Box [-1,1]^3 scaled to x in [-2,2], rotated 90 deg about z: x -> y. Bounds then
  // x in [-1,1], y in [-2,2], z in [4,6].
  double lo[3] = {HUGE_VAL, HUGE_VAL, HUGE_VAL}, hi[3] = {-HUGE_VAL, -HUGE_VAL, -HUGE_VAL};
  const auto& p = s.objects[0].mesh.points;
  for (std::size_t i = 0; i < p.size(); ++i) {
    lo[i % 3] = std::min(lo[i % 3], p[i]);
    hi[i % 3] = std::max(hi[i % 3], p[i]);
  }
  EXPECT_NEAR(lo[0], -1, 1e-14);
  EXPECT_NEAR(hi[0], 1, 1e-14);
  EXPECT_NEAR(lo[1], -2, 1e-14);
  EXPECT_NEAR(hi[1], 2, 1e-14);
  EXPECT_NEAR(lo[2], 4, 1e-14);
  EXPECT_NEAR(hi[2], 6, 1e-14);
  // Volume preserved up to the scale: 8 * 2.
  double vol = 0;
  const TetMesh& m = s.objects[0].mesh;
  for (std::size_t t = 0; t < m.num_tets(); ++t)
    vol += signed_tet_volume(&m.points[3 * m.tets[4 * t]], &m.points[3 * m.tets[4 * t + 1]],
                             &m.points[3 * m.tets[4 * t + 2]], &m.points[3 * m.tets[4 * t + 3]]);
  EXPECT_NEAR(vol, 16.0, 1e-12);
}

TEST(SceneParser, FrictionPairsAreSymmetricAndChecked) {
  const Scene s = load_scene_from_string(scene_with(kBox) + R"(friction:
  default: {static: 0.3, kinetic: 0.2}
  pairs:
    - materials: [rubber, steel]
      static: 0.95
      kinetic: 0.8
)",
                                         "scene.yaml");
  EXPECT_DOUBLE_EQ(s.friction[0][1].mu_static, 0.95);
  EXPECT_DOUBLE_EQ(s.friction[1][0].mu_kinetic, 0.8);
  EXPECT_DOUBLE_EQ(s.friction[0][0].mu_static, 0.3);
  EXPECT_DOUBLE_EQ(s.friction[1][1].mu_kinetic, 0.2);
  expect_error(scene_with(kBox) + "friction:\n  default: {static: 0.3, kinetic: 0.5}\n", {"exceeds 'static'"});
}

TEST(SceneParser, KinematicAndFixedBoxesGiveZeroInverseMass) {
  const Scene s = load_scene_from_string(scene_with(R"(  - name: floor
    material: steel
    primitive: {type: plate, size: [4, 4], thickness: 0.2, cells: [4, 4]}
    kinematic: true
  - name: bar
    material: rubber
    primitive: {type: box, size: [2, 1, 1], cells: [2, 1, 1]}
    fixed: {min: [-1.1, -1, -1], max: [-0.9, 1, 1]}
)"),
                                         "scene.yaml");
  const World w = build_world(s, block_partition(s, 1), 0);
  std::size_t fixed_floor = 0, fixed_bar = 0;
  double bar_mass = 0;
  for (std::size_t i = 0; i < w.n_owned; ++i) {
    if (w.vertex_object[i] == 0) fixed_floor += w.inv_mass[i] == 0;
    if (w.vertex_object[i] == 1) {
      fixed_bar += w.inv_mass[i] == 0;
      bar_mass += w.mass[i];
    }
  }
  EXPECT_EQ(fixed_floor, s.objects[0].mesh.num_vertices());
  EXPECT_EQ(fixed_bar, 4u);  // the end face x = -1 of a 2x1x1-cell box
  EXPECT_NEAR(bar_mass, 1200.0 * 2.0, 1e-9);  // lumped masses sum to rho V
  // dt auto ignores the kinematic (stiff steel) floor: limited by rubber's c = 10 m/s.
  EXPECT_GT(stable_time_step(s), 1e-3);
}

TEST(SceneParser, PrimitiveArgumentsAreChecked) {
  expect_error(scene_with("  - material: rubber\n    primitive: {type: torus, major_radius: 1, minor_radius: 2}\n"),
               {"scene.yaml:", "smaller than 'major_radius'"});
  expect_error(scene_with("  - material: rubber\n    primitive: {type: cube, size: [1, 1, 1]}\n"),
               {"unknown primitive type 'cube'"});
  expect_error(scene_with("  - material: rubber\n    primitive: {type: box, size: [1, 0, 1]}\n"), {"positive"});
  expect_error(scene_with("  - material: rubber\n"), {"needs a 'mesh' file or a 'primitive'"});
}

// Sizes are bounded before anything is built (found while fuzzing, tests/fuzz): a grid of
// 10^15 copies, cell counts derived from extreme length ratios, step counts beyond int64.
TEST(SceneParser, HugeScenesAreRejectedBeforeTheyAreBuilt) {
  expect_error(scene_with("  - name: c\n    material: rubber\n    primitive: {type: box, size: [1, 1, 1], cells: [1, 1, 1]}\n"
                          "    instances: {grid: {count: [100000, 100000, 100000], spacing: [2, 2, 2]}}\n"),
               {"scene.yaml:", "object 'c' makes 1e+15 objects", "a scene can hold"});
  expect_error(scene_with("  - name: t\n    material: rubber\n    primitive: {type: torus, major_radius: 1e300, minor_radius: 1e-300}\n"),
               {"scene.yaml:", "cells for 'around'", "give 'around' explicitly"});
  expect_error(scene_with("  - name: n\n    material: rubber\n    primitive: {type: cylinder, radius: 1e-300, height: 1e300}\n"),
               {"scene.yaml:", "cells for 'axial'"});
  expect_error(scene_with(kBox, "  dt: 1e-300\n  end_time: 1e300\n"), {"scene.yaml:", "steps (expected at most 2^40"});
  SceneLimits small;
  small.max_tets = 100;
  try {
    load_scene_from_string(scene_with("  - name: b\n    material: rubber\n    primitive: {type: box, size: [1, 1, 1], cells: [10, 10, 10]}\n"),
                           "scene.yaml", small);
    FAIL() << "expected an InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("6000 tets"), std::string::npos) << e.what();
  }
}

TEST(SceneParser, ObjectsWithoutAStableTimeStepAreRejected) {
  expect_error(scene_with("  - name: flat\n    material: rubber\n    primitive: {type: box, size: [1e-320, 1, 1e300]}\n"),
               {"scene.yaml:", "object 'flat'", "no time step is stable"});
}

// The switches of the contact pipeline: off by default, on when asked, a bad value named
// with its line.
TEST(SceneParser, ContactSwitchesDefaultOffAndAreChecked) {
  const Scene off = load_scene_from_string(scene_with(kBox), "scene.yaml");
  EXPECT_FALSE(off.sim.mutual_pairs);
  EXPECT_FALSE(off.sim.edge_contacts);
  EXPECT_FALSE(off.sim.self_collisions);
  const Scene on = load_scene_from_string(scene_with(kBox, "  dt: auto\n  steps: 10\n  mutual_pairs: true\n"), "scene.yaml");
  EXPECT_TRUE(on.sim.mutual_pairs);
  expect_error(scene_with(kBox, "  dt: auto\n  steps: 10\n  mutual_pairs: maybe\n"), {"scene.yaml:4:", "'mutual_pairs'"});
}

// Objects split for their forces (split_forces.hpp): on by default, off when asked, a bad
// value named with its line; split_candidate follows it.
TEST(SceneParser, SplitObjectsDefaultsOnAndIsChecked) {
  const Scene on = load_scene_from_string(scene_with(kBox), "scene.yaml");
  EXPECT_TRUE(on.sim.split_objects);
  const Scene off = load_scene_from_string(scene_with(kBox, "  dt: auto\n  steps: 10\n  split_objects: false\n"), "scene.yaml");
  EXPECT_FALSE(off.sim.split_objects);
  // The one object is all of the scene's tets: more than a share on 2 ranks, not on 1.
  EXPECT_TRUE(split_candidate(on, 0, 2));
  EXPECT_FALSE(split_candidate(on, 0, 1));
  EXPECT_FALSE(split_candidate(off, 0, 2));
  expect_error(scene_with(kBox, "  dt: auto\n  steps: 10\n  split_objects: sometimes\n"), {"scene.yaml:4:", "'split_objects'"});
  // Their points' detection by the bodies' owners: the same.
  EXPECT_TRUE(on.sim.split_detection);
  EXPECT_FALSE(load_scene_from_string(scene_with(kBox, "  dt: auto\n  steps: 10\n  split_detection: false\n"), "scene.yaml")
                   .sim.split_detection);
  expect_error(scene_with(kBox, "  dt: auto\n  steps: 10\n  split_detection: 2\n"), {"scene.yaml:4:", "'split_detection'"});
}

TEST(SceneParser, ContactClosureIsLocalOrCoupled) {
  EXPECT_EQ(load_scene_from_string(scene_with(kBox), "scene.yaml").sim.split_parts, SplitParts::automatic);
  EXPECT_EQ(load_scene_from_string(scene_with(kBox, "  dt: auto\n  steps: 10\n  split_parts: bisection\n"), "scene.yaml")
                .sim.split_parts,
            SplitParts::bisection);
  EXPECT_EQ(load_scene_from_string(scene_with(kBox, "  dt: auto\n  steps: 10\n  split_parts: metis\n"), "scene.yaml")
                .sim.split_parts,
            SplitParts::metis);
  expect_error(scene_with(kBox, "  dt: auto\n  steps: 10\n  split_parts: rcb\n"),
               {"scene.yaml:4:", "split_parts", "auto", "metis", "bisection"});
  EXPECT_EQ(load_scene_from_string(scene_with(kBox), "scene.yaml").sim.contact_closure, ContactClosure::local);
  const Scene c = load_scene_from_string(scene_with(kBox, "  dt: auto\n  steps: 10\n  contact_closure: coupled\n"), "scene.yaml");
  EXPECT_EQ(c.sim.contact_closure, ContactClosure::coupled);
  expect_error(scene_with(kBox, "  dt: auto\n  steps: 10\n  contact_closure: global\n"),
               {"scene.yaml:4:", "contact_closure", "local", "coupled"});
}

// 'dt_bound' picks the bound on each object's highest frequency: 'element' (the default,
// Irons' bound) or 'mesh' (the assembled mesh's, certified; tests/sim/test_mesh_bound.cpp).
// A fixed dt between the two (the cube's element limit is 0.0252 s, its true limit 0.033
// s) warns under the element bound only; anything else is an input error at the key.
TEST(SceneParser, DtBoundIsElementOrMesh) {
  const Scene e = load_scene_from_string(scene_with(kBox, "  dt: 0.03\n  steps: 10\n"), "scene.yaml");
  EXPECT_EQ(e.sim.dt_bound, DtBound::element);
  EXPECT_EQ(e.warnings.size(), 1u);
  const Scene m = load_scene_from_string(scene_with(kBox, "  dt: 0.03\n  steps: 10\n  dt_bound: mesh\n"), "scene.yaml");
  EXPECT_EQ(m.sim.dt_bound, DtBound::mesh);
  EXPECT_TRUE(m.warnings.empty()) << m.warnings[0];
  EXPECT_LT(stable_step(m).dt, true_stable_step(m));
  EXPECT_GT(stable_step(m).dt, 0.999 * true_stable_step(m));
  expect_error(scene_with(kBox, "  dt: auto\n  steps: 10\n  dt_bound: meshes\n"),
               {"scene.yaml:4:", "unknown dt_bound 'meshes'", "expected one of: element mesh"});
}

// 'rebalance' sets the repartition policy (docs/formats.md): defaults every 200 steps,
// 1.25, 0.5, measured weights; each key is read, and out-of-range values are input errors
// at their line.
TEST(SceneParser, RebalanceKeys) {
  const Scene d = load_scene_from_string(scene_with(kBox, "  dt: auto\n  steps: 10\n"), "scene.yaml");
  EXPECT_EQ(d.sim.rebalance_every, 200);
  EXPECT_EQ(d.sim.rebalance_max_imbalance, 1.25);
  EXPECT_EQ(d.sim.rebalance_max_cross_fraction, 0.5);
  EXPECT_EQ(d.sim.rebalance_weights, RebalanceWeights::measured);
  const Scene s = load_scene_from_string(
      scene_with(kBox, "  dt: auto\n  steps: 10\n  rebalance: {every: 50, max_imbalance: 1.1, max_cross_fraction: 0.3, weights: tets}\n"),
      "scene.yaml");
  EXPECT_EQ(s.sim.rebalance_every, 50);
  EXPECT_EQ(s.sim.rebalance_max_imbalance, 1.1);
  EXPECT_EQ(s.sim.rebalance_max_cross_fraction, 0.3);
  EXPECT_EQ(s.sim.rebalance_weights, RebalanceWeights::tets);
  EXPECT_EQ(load_scene_from_string(scene_with(kBox, "  dt: auto\n  steps: 10\n  rebalance: {every: 0}\n"), "scene.yaml")
                .sim.rebalance_every,
            0);
  expect_error(scene_with(kBox, "  dt: auto\n  steps: 10\n  rebalance: {weights: time}\n"),
               {"scene.yaml:4:", "unknown rebalance.weights 'time'", "measured tets"});
  expect_error(scene_with(kBox, "  dt: auto\n  steps: 10\n  rebalance: {max_imbalance: 0.9}\n"),
               {"scene.yaml:4:", "'rebalance.max_imbalance' must be at least 1"});
  expect_error(scene_with(kBox, "  dt: auto\n  steps: 10\n  rebalance: {max_cross_fraction: 2}\n"),
               {"scene.yaml:4:", "'rebalance.max_cross_fraction' must be in (0, 1]"});
  expect_error(scene_with(kBox, "  dt: auto\n  steps: 10\n  rebalance: {every: -1}\n"), {"scene.yaml:4:", "rebalance.every"});
  expect_error(scene_with(kBox, "  dt: auto\n  steps: 10\n  rebalance: {often: 3}\n"), {"scene.yaml:4:", "often"});
}
