#pragma once
// The script the device twins that play no instrument track (pedals_sim, microscope_sim) load, in one place.

#include <ros/node_handle.h>

#include <cstdint>
#include <memory>
#include <stdexcept>
#include <string>

#include "vrm_scene/package_data.h"
#include "vrm_scene/scene_loader.h"
#include "vrm_tracking/conversions.h"
#include "vrm_tracking/scenario_devices.h"
#include "vrm_tracking/scene_trocars.h"
#include "vrm_tracking/surgeon_script.h"

namespace vrm_tracking {

// The scene's scripted session `name` with the device twins' tracks (scenario_devices.h); the working instrument is
// the scenario's `tool` parameter (default right), as the scenario scores it.
inline SurgeonScript scenarioDeviceScript(const vrm_sim::scene::SceneDescription& scene, const std::string& name) {
  std::string tool = "right";
  if (scene.scenario) {
    const vrm_sim::scene::ScenarioParam* param = scene.scenario->param("tool");
    if (param != nullptr && param->names.size() == 1) tool = param->names.front();
  }
  return withScenarioDeviceTracks(playInScene(scene, vrm_sim::scene::findScript(scene, name)), tool);
}

// ~script (loadSession: empty = the shipped demo, a shipped script's name or a file) played in ~scene, or the default
// scene, as the scripted surgeon plays it; ~loop overrides its playback. `scenario:NAME` (issue 33): the scene's
// scripted session with the device tracks derived from it (withScenarioDeviceTracks: focus on the working plane,
// fixed zoom, pedal travel = the working instrument's suction, no buttons) instead of the demo's sweeps; it needs
// ~scene. Throws ScriptError / SceneError / std::invalid_argument.
inline SurgeonScript loadDeviceScript(const ros::NodeHandle& private_nh) {
  std::string spec, scene_spec;
  private_nh.param<std::string>("script", spec, "");
  private_nh.param<std::string>("scene", scene_spec, "");
  vrm_sim::usePackageData();  // a scene or script name means vrm_sim's shipped one
  if (isScenarioSpec(spec)) {
    if (scene_spec.empty()) throw std::invalid_argument("script '" + spec + "' needs the ~scene parameter");
    return scenarioDeviceScript(vrm_sim::scene::loadScene(scene_spec), spec.substr(9));
  }
  const vrm_sim::scene::SceneDescription scene = vrm_sim::scene::loadScene(sceneOrDefault(scene_spec));
  SurgeonScript script = playInScene(scene, loadSession(spec, scene));
  applyLoopParam(private_nh, &script);
  return script;
}

// A twin playing `scenario:NAME` follows the scene the scene owner announces on running_scene (issue 32), as the
// scripted surgeon does: the device tracks are rebuilt from the new scene's session of that name.
class ScenarioSceneFollower {
 public:
  // spec: the ~script parameter; scene_spec: ~scene. Inactive (follows nothing) unless spec is `scenario:NAME`.
  ScenarioSceneFollower(const std::string& spec, const std::string& scene_spec) {
    if (!isScenarioSpec(spec) || scene_spec.empty()) return;
    name_ = spec.substr(9);
    vrm_sim::usePackageData();
    current_ = sceneIdentity(vrm_sim::scene::loadScene(scene_spec));
    active_ = true;
  }
  bool active() const { return active_; }
  // The script for the announced scene, or nullptr when it is the scene in use. Throws like loadScene /
  // scenarioDeviceScript; the caller keeps its script then.
  std::unique_ptr<SurgeonScript> follow(const std::string& name, const std::string& file, const std::string& difficulty,
                                        std::uint64_t content_hash) {
    if (!active_ || sameScene(SceneIdentity{name, file, difficulty, content_hash}, current_)) return nullptr;
    const vrm_sim::scene::SceneDescription scene = vrm_sim::scene::loadScene(file, difficulty);
    auto script = std::make_unique<SurgeonScript>(scenarioDeviceScript(scene, name_));
    current_ = sceneIdentity(scene);
    return script;
  }
  const std::string& sceneName() const { return current_.name; }

 private:
  bool active_ = false;
  std::string name_;
  SceneIdentity current_;
};

}  // namespace vrm_tracking
