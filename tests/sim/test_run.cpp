// The run loop (src/sim/run.cpp) with the deformation models: the diagnostics CSV carries
// the models' strain energy and the inverted-element count, and a free vibrating body
// conserves its total energy.
#include <gtest/gtest.h>
#include <mpi.h>

#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include "softcontact/run.hpp"
#include "softcontact/scene.hpp"

using namespace softcontact;

namespace {

/// Rows of a CSV file as column name -> values.
std::map<std::string, std::vector<double>> read_csv(const std::string& path) {
  std::ifstream in(path);
  std::string line;
  std::getline(in, line);
  std::vector<std::string> names;
  std::stringstream hs(line);
  for (std::string c; std::getline(hs, c, ',');) names.push_back(c);
  std::map<std::string, std::vector<double>> cols;
  while (std::getline(in, line)) {
    std::stringstream ls(line);
    std::size_t k = 0;
    for (std::string c; std::getline(ls, c, ',') && k < names.size(); ++k) cols[names[k]].push_back(std::stod(c));
  }
  return cols;
}

}  // namespace

std::string scene_yaml(const std::filesystem::path& dir, const std::string& sim, const std::string& model,
                       const std::string& extra) {
  return "simulation: {dt: auto, " + sim + ", output: {every: 20, directory: " + dir.string() +
         "}}\nmaterials:\n  - {name: m, model: " + model +
         ", young: 1e5, poisson: 0.3, density: 1000}\nobjects:\n  - material: m\n"
         "    primitive: {type: box, size: [1, 1, 1], cells: [3, 3, 3]}\n" + extra;
}

// 1. A cube in free fall keeps its rest shape: the CSV has the columns elastic_energy and
//    inverted_elements, both 0 on every row.
// 2. A cube clamped at its top face and released under a heavy load (g = 50 m/s^2)
//    vibrates about its sagged equilibrium: strain energy appears, no tet inverts, and
//    kinetic + strain + potential energy stays within 3 % of the largest strain energy
//    of its initial value (measured 1.3 %: Verlet's backward-difference velocities make
//    the kinetic energy in the CSV only O(dt) accurate).
TEST(RunLoop, DiagnosticsCarryStrainEnergyAndInvertedElements) {
  const std::filesystem::path dir = std::filesystem::temp_directory_path() / "softcontact_test_run";
  std::filesystem::remove_all(dir);
  std::ostringstream log;
  RunOptions opt;
  opt.quiet = true;
  opt.overwrite = true;
  const Scene fall = load_scene_from_string(scene_yaml(dir, "steps: 200", "corotational", "    velocity: [0, 0, -1]\n"),
                                            (dir / "scene.yaml").string());
  auto cols = read_csv(run_scene(MPI_COMM_WORLD, fall, opt, log).csv);
  ASSERT_TRUE(cols.count("inverted_elements"));
  ASSERT_TRUE(cols.count("elastic_energy"));
  ASSERT_EQ(cols["step"].size(), 11u);
  for (double v : cols["inverted_elements"]) EXPECT_EQ(v, 0.0);
  for (double v : cols["elastic_energy"]) EXPECT_NEAR(v, 0.0, 1e-9);

  const Scene clamped =
      load_scene_from_string(scene_yaml(dir, "steps: 600, gravity: [0, 0, -50]", "neohookean",
                                        "    fixed: {min: [-1, -1, 0.49], max: [1, 1, 1]}\n"),
                             (dir / "scene.yaml").string());
  cols = read_csv(run_scene(MPI_COMM_WORLD, clamped, opt, log).csv);
  double emax = 0, worst = 0;
  for (double e : cols["elastic_energy"]) emax = std::max(emax, e);
  EXPECT_GT(emax, 0.0);
  const double e0 = cols["kinetic_energy"][0] + cols["elastic_energy"][0] + cols["potential_energy"][0];
  for (std::size_t k = 0; k < cols["step"].size(); ++k) {
    EXPECT_EQ(cols["inverted_elements"][k], 0.0);
    const double e = cols["kinetic_energy"][k] + cols["elastic_energy"][k] + cols["potential_energy"][k];
    worst = std::max(worst, std::abs(e - e0) / emax);
  }
  EXPECT_LT(worst, 0.03);
  RecordProperty("energy_error", std::to_string(worst));
  std::filesystem::remove_all(dir);
}
