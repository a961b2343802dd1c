#pragma once
// The script the device twins that play no instrument track (pedals_sim, microscope_sim) load, in one place.

#include <ros/node_handle.h>

#include <stdexcept>
#include <string>

#include "vrm_sim/package_data.h"
#include "vrm_sim/scene/scene_loader.h"
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
  return withScenarioDeviceTracks(scenarioScript(scene, name), tool);
}

// ~script (loadScriptFromParams). Only its instrument tracks (not played here) can need a scene: a file that leaves
// its trocars to the scene gets ~scene's, or the default scene's, so it validates as the scripted surgeon's copy
// does. `scenario:NAME` (issue 33): the scene's scripted session with the device tracks derived from it
// (withScenarioDeviceTracks: focus on the working plane, fixed zoom, pedal travel = the working instrument's suction,
// no buttons) instead of the built-in demo's sweeps; it needs ~scene. Throws ScriptError / SceneError /
// std::invalid_argument.
inline SurgeonScript loadDeviceScript(const ros::NodeHandle& private_nh) {
  std::string spec;
  private_nh.param<std::string>("script", spec, "");
  if (spec.rfind("scenario:", 0) == 0) {
    std::string scene_spec;
    private_nh.param<std::string>("scene", scene_spec, "");
    if (scene_spec.empty()) throw std::invalid_argument("script '" + spec + "' needs the ~scene parameter");
    vrm_sim::usePackageData();
    return scenarioDeviceScript(vrm_sim::scene::loadScene(scene_spec), spec.substr(9));
  }
  ScriptDefinition definition = loadScriptFromParams(private_nh);
  if (leavesTrocarsToScene(definition)) {
    std::string scene_spec;
    private_nh.param<std::string>("scene", scene_spec, "");
    vrm_sim::usePackageData();  // a scene name means vrm_sim's shipped scene
    applySceneTrocars(vrm_sim::scene::loadScene(sceneOrDefault(scene_spec)), &definition);
  }
  return SurgeonScript(std::move(definition));
}

}  // namespace vrm_tracking
