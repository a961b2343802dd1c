// The names a scene gives its physics (tissue model, integrator, collision detector) are checked where the World is
// built (issue 42: the scene floor links no physics), with the loader's file:line:col and typo hints.
#include <gtest/gtest.h>

#include <string>

#include "vrm_scene/scene_loader.h"
#include "vrm_sim/world/tissue_setup.h"
#include "vrm_sim/world/world.h"

namespace {

using vrm_sim::scene::loadSceneFromString;
using vrm_sim::scene::SceneDescription;
using vrm_sim::scene::SceneError;

const std::string kBall = R"(scene: {name: x, kind: abstract}
objects:
  - name: ball
    role: abstract_target
    mesh: {generator: sphere, params: {radius: 0.001}}
    collision: {detector: DETECTOR}
simulations: [collision]
)";

std::string deformable(const std::string& tissue) {
  return "scene: {name: x, kind: surgical}\nobjects:\n  - name: membrane\n    role: membrane\n"
         "    mesh: {generator: membrane}\n    tissue: " +
         tissue + "\nsimulations: [tissue]\n";
}

std::string withDetector(const std::string& detector) {
  std::string yaml = kBall;
  return yaml.replace(yaml.find("DETECTOR"), 8, detector);
}

// The message of checkSimulationNames, "" when it accepts the scene.
std::string namesError(const SceneDescription& scene) {
  try {
    vrm_sim::world::checkSimulationNames(scene);
  } catch (const SceneError& error) {
    return error.what();
  }
  return "";
}

TEST(SimulationNames, TheFloorReadsThemAsText) {
  // The loader no longer knows the registries: an unknown name loads, and keeps where it was written.
  const SceneDescription scene = loadSceneFromString(withDetector("zbuffer"), "inline_scene.yaml");
  EXPECT_EQ(scene.objects[0].collision.detector, "zbuffer");
  EXPECT_EQ(scene.objects[0].collision.detector_location.line, 6);
  EXPECT_EQ(scene.objects[0].collision.detector_location.column, 27);
}

TEST(SimulationNames, UnknownDetectorNamesLineFieldAndChoices) {
  const std::string message = namesError(loadSceneFromString(withDetector("zbuffer"), "inline_scene.yaml"));
  EXPECT_EQ(message,
            "inline_scene.yaml:6:27: objects[0].collision.detector: expected one of zcoll, zcoll_f, zcoll_cpu, "
            "zcoll_f_cpu, zcoll_gl, zcoll_f_gl, myszkowski_cpu, geometric, fcl, fcl_aabb, fcl_obbrss, fcl_kios, none, "
            "got 'zbuffer'");
}

TEST(SimulationNames, TyposGetAHint) {
  EXPECT_NE(namesError(loadSceneFromString(withDetector("zcol_f"), "a.yaml")).find("(did you mean 'zcoll_f'?)"),
            std::string::npos);
  const std::string model = namesError(loadSceneFromString(deformable("{model: mass_sprng}"), "b.yaml"));
  EXPECT_EQ(model.rfind("b.yaml:6:21: objects[0].tissue.model: expected one of none, ", 0), 0u) << model;
  EXPECT_NE(model.find("got 'mass_sprng' (did you mean 'mass_spring'?)"), std::string::npos) << model;
  const std::string integrator =
      namesError(loadSceneFromString(deformable("{model: mass_spring, integrator: symplectc_euler}"), "c.yaml"));
  EXPECT_NE(integrator.find("c.yaml:6:46: objects[0].tissue.integrator: expected one of auto"), std::string::npos)
      << integrator;
  EXPECT_NE(integrator.find("(did you mean 'symplectic_euler'?)"), std::string::npos) << integrator;
}

TEST(SimulationNames, KnownNamesAndDefaultsPass) {
  EXPECT_EQ(namesError(loadSceneFromString(withDetector("geometric"), "a.yaml")), "");
  EXPECT_EQ(namesError(loadSceneFromString(deformable("{model: mass_spring}"), "b.yaml")), "");
  EXPECT_EQ(namesError(loadSceneFromString(deformable("{model: chainmail, integrator: xpbd}"), "c.yaml")), "");
}

TEST(SimulationNames, TheWorldRefusesAnUnknownName) {
  const SceneDescription scene = loadSceneFromString(withDetector("zbuffer"), "inline_scene.yaml");
  try {
    vrm_sim::world::World world(scene);
    FAIL() << "the World was built with an unknown detector";
  } catch (const SceneError& error) {
    EXPECT_NE(std::string(error.what()).find("inline_scene.yaml:6:27: objects[0].collision.detector"),
              std::string::npos)
        << error.what();
  }
}

}  // namespace
