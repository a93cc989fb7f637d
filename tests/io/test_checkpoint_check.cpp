// A checkpoint checked against the scene it continues (checkpoint::check_against_scene):
// which message a user gets when the scene no longer matches.
#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "io/checkpoint_read.hpp"
#include "softcontact/error.hpp"
#include "softcontact/scene.hpp"

using namespace softcontact;

namespace {

const std::string kScene = R"(simulation: {dt: auto, steps: 10}
materials:
  - {name: soft, model: corotational, young: 1.0e5, poisson: 0.3, density: 1000}
objects:
  - {name: cube, material: soft, primitive: {type: box, size: [1, 1, 1], cells: [2, 2, 2]}}
)";

CheckpointInfo info_of(const Scene& s) {
  CheckpointInfo info;
  info.dt = s.sim.dt;
  info.fingerprint = scene_fingerprint(s);
  info.scene_path = "/runs/cube.yaml";
  info.vertices = static_cast<std::int64_t>(s.num_vertices());
  info.partition.assign(s.objects.size(), 0);
  info.boxes.assign(s.objects.size(), Box{{0, 0, 0}, {1, 1, 1}});
  return info;
}

std::string refusal(const CheckpointInfo& info, const Scene& s) {
  try {
    checkpoint::check_against_scene(info, s, "ckpt.h5", s.object_digests());
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

}  // namespace

// The same scene passes. A scene whose only difference is its time step (the checkpoint
// written by a build whose 'dt: auto' came out a few ulps apart) is refused with both
// steps named, not with "a mesh file has changed"; a changed mesh keeps that message.
TEST(CheckpointCheck, ATimeStepThatComesOutDifferentlyIsNamed) {
  const Scene s = load_scene_from_string(kScene, "cube.yaml");
  EXPECT_EQ(refusal(info_of(s), s), "");

  Scene older = s;
  older.sim.dt = std::nextafter(s.sim.dt, 1.0);
  const std::string dt_msg = refusal(info_of(older), s);
  EXPECT_NE(dt_msg.find("ckpt.h5"), std::string::npos) << dt_msg;
  EXPECT_NE(dt_msg.find("is unchanged, but its time step now comes out as dt = "), std::string::npos) << dt_msg;
  EXPECT_EQ(dt_msg.find("mesh file"), std::string::npos) << dt_msg;

  Scene moved = s;
  moved.objects[0].mesh.points[0] += 1e-3;
  const std::string mesh_msg = refusal(info_of(moved), s);
  EXPECT_NE(mesh_msg.find("a mesh file it uses has changed"), std::string::npos) << mesh_msg;

  Scene both = moved;  // a mesh and the step: the mesh is what the user changed
  both.sim.dt = older.sim.dt;
  EXPECT_NE(refusal(info_of(both), s).find("a mesh file it uses has changed"), std::string::npos);
}
