#pragma once
// Scripts for the unit tests: a scene built in code (no file) and a session written in the scripts' YAML format,
// played in it as the device twins play a script (playInScene).

#include <Eigen/Core>
#include <string>

#include "vrm_scene/scene_loader.h"
#include "vrm_tracking/scene_trocars.h"
#include "vrm_tracking/surgeon_script.h"

namespace vrm_tracking {
namespace testing {

// A 12 mm eye whose centre is at `centre` in the world, the default trocars (left at azimuth 150, right at 30, 45
// degrees off the optical axis: [-+0.0073485, 0.0042426, 0.0084853]), a light pipe left and a forceps right.
inline vrm_sim::scene::SceneDescription testScene(const Eigen::Vector3d& centre = Eigen::Vector3d::Zero()) {
  namespace scene = vrm_sim::scene;
  scene::SceneDescription made;
  made.name = "test_scene";
  made.eye.centre_in_world = centre;
  made.eye.trocars = scene::defaultTrocars(made.eye.radius);
  scene::InstrumentDescription light;
  light.slot = scene::InstrumentSlot::kLeft;
  light.type = scene::InstrumentType::kLightPipe;
  light.trocar = "left";
  scene::InstrumentDescription forceps;
  forceps.slot = scene::InstrumentSlot::kRight;
  forceps.type = scene::InstrumentType::kForceps;
  forceps.trocar = "right";
  made.instruments = {light, forceps};
  return made;
}

inline SurgeonScript playYaml(const std::string& yaml, const vrm_sim::scene::SceneDescription& scene = testScene(),
                              const std::string& name = "test.yaml") {
  return playInScene(scene, vrm_sim::scene::loadScriptFromString(yaml, name));
}

}  // namespace testing
}  // namespace vrm_tracking
