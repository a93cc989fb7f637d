#pragma once
// Per-step diagnostics: conserved and monitored quantities, reduced over ranks in an
// order fixed by object index (so the numbers do not depend on the rank count), and the
// diagnostics CSV that rank 0 writes (columns documented in docs/output-format.md).
#include <mpi.h>

#include <array>
#include <cstdint>
#include <fstream>
#include <string>

#include "softcontact/forces.hpp"
#include "softcontact/phase_times.hpp"
#include "softcontact/scene.hpp"
#include "softcontact/world.hpp"

namespace softcontact {

struct StepDiagnostics {
  std::int64_t step = 0;
  double time = 0;
  double kinetic_energy = 0;     ///< sum 1/2 m |v|^2 over movable vertices [J]
  double elastic_energy = 0;     ///< sum of the models' strain energies [J]
  std::int64_t inverted_elements = 0;  ///< tets with det F <= 0 (inverted or flat)
  double potential_energy = 0;   ///< - sum m g . x over movable vertices [J]
  Vec3 momentum{};               ///< sum m v over movable vertices [kg m/s]
  std::int64_t contacts = 0;     ///< colliding points this step
  std::int64_t edge_contacts = 0;///< edge-edge contact records this step (docs/collision.md, "Edge contacts")
  double residual_penetration = 0;  ///< largest remaining depth / median edge length
  double contact_force_balance = 0; ///< |sum F| / sum |F| over contact forces
  PhaseTimes seconds;            ///< mean seconds per step since the previous row
};

/// Kinetic and potential energy and momentum of the owned vertices, summed per object in
/// vertex order, and (when given) the per-object strain energy and inverted-tet count of
/// ElasticForces::measure, then summed over objects in object order on rank 0 and
/// broadcast. With `contact_force` (3 per local vertex, ContactResponse::force) also the
/// contact force balance |sum F| / sum |F|, summed the same way over every owned vertex,
/// kinematic ones included, so that it too is bitwise the same on any number of ranks.
/// Collective.
void reduce_mechanics(MPI_Comm comm, const Scene& scene, const World& world, StepDiagnostics& d,
                      const ElasticMeasures* elastic = nullptr, const double* contact_force = nullptr);

/// The diagnostics CSV (rank 0 only; other ranks hold a closed writer).
class DiagnosticsCsv {
public:
  DiagnosticsCsv() = default;
  void open(const std::string& path);
  /// Continues an earlier run's file (restart): keeps the header and the complete rows up
  /// to step `last_step`, drops later or torn ones, then appends. A missing file starts anew.
  void resume(const std::string& path, std::int64_t last_step);
  void write(const StepDiagnostics& d);
  static const char* header();

private:
  std::ofstream out_;
};

}  // namespace softcontact
