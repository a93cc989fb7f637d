// The serial core (SerialStepper, stepper.hpp) on its own, without a communicator: it is
// the step the Simulator takes. Reference: the Simulator on one rank (MPI_COMM_SELF),
// whose step adds only timing and the parallel layer's ghost refreshes (none on one
// rank). Positions, velocities and contact forces must be bitwise equal after every
// step, on a pile whose balls land on boxes (contact and friction in most steps).
#include <gtest/gtest.h>
#include <mpi.h>

#include <string>

#include "softcontact/scene.hpp"
#include "softcontact/simulator.hpp"
#include "softcontact/stepper.hpp"
#include "softcontact/world.hpp"

using namespace softcontact;

TEST(SerialStepper, StepsAsTheSimulatorDoesOnOneRank) {
  const Scene scene = load_scene(std::string(SOFTCONTACT_TEST_DATA) + "/scenes/pile.yaml");
  World w = build_world(scene, std::vector<int>(scene.objects.size(), 0), 0);
  SerialStepper core(scene, w, collision_settings_for(scene));
  core.make_detector();
  core.resize();
  core.start();

  Simulator sim(MPI_COMM_SELF, scene);
  const World& ref = sim.world();
  ASSERT_EQ(ref.n_local(), w.n_local());
  std::int64_t contact_steps = 0;
  for (int s = 0; s < 120; ++s) {
    core.step(static_cast<double>(s) * scene.sim.dt);
    sim.step();
    contact_steps += core.collisions().empty() ? 0 : 1;
    ASSERT_EQ(core.collisions().size(), sim.collisions().size()) << "step " << s;
    ASSERT_EQ(w.x, ref.x) << "step " << s;
    ASSERT_EQ(w.v, ref.v) << "step " << s;
    ASSERT_EQ(core.response().force(), sim.contact_force()) << "step " << s;
  }
  // The comparison covers contact: 48 of the 120 steps have collisions (measured).
  EXPECT_GE(contact_steps, 40);
}
