#pragma once
// The script the device twins that play no instrument track (pedals_sim, microscope_sim) load, in one place.

#include <ros/node_handle.h>

#include <string>

#include "vrm_sim/package_data.h"
#include "vrm_sim/scene/scene_loader.h"
#include "vrm_tracking/conversions.h"
#include "vrm_tracking/scene_trocars.h"
#include "vrm_tracking/surgeon_script.h"

namespace vrm_tracking {

// ~script (loadScriptFromParams). Only its instrument tracks (not played here) can need a scene: a file that leaves
// its trocars to the scene gets ~scene's, or the default scene's, so it validates as the scripted surgeon's copy
// does. Throws ScriptError / SceneError.
inline SurgeonScript loadDeviceScript(const ros::NodeHandle& private_nh) {
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
