#pragma once
// The scene file as the single source of truth for the trocars (the fixed insertion holes of the mechanical eye), for
// the eye the scripts play in and for where tissue is. The shipped marker layouts name no trocars (trocar_from_scene):
// the nodelets apply their ~scene, or without one the default scene (vrm_sim::scene::kDefaultSceneName), so the twin
// surgeon, the tracker and the VR part pivot the instruments at the same points. A script (the scene's format,
// vrm_sim::scene::ScriptedSession) is played in a scene (playInScene): its waypoints written `on` scene objects are
// put on that object's surface (vrm_scene/surface_target.h), every shaft pivots at the scene's trocar of its slot.
// ROS-free; links vrm_sim's scene library (vrm_scene).

#include <Eigen/Core>
#include <cstdint>
#include <string>
#include <vector>

#include "vrm_scene/meshes/triangle_mesh.h"
#include "vrm_scene/scene_description.h"
#include "vrm_scene/surface_target.h"
#include "vrm_tracking/marker_layout.h"
#include "vrm_tracking/surgeon_script.h"

namespace vrm_tracking {

// `spec`, or the simulator's default scene (vrm_sim::scene::kDefaultSceneName, whose trocars the shipped files leave
// out) when it is empty.
std::string sceneOrDefault(const std::string& spec);
// The trocar (eye frame, m) an instrument in tracking slot `slot` ("left" / "right") goes through in `scene`: the
// trocar named by the scene's instrument in that slot, else (no instrument in that slot) the trocar named like the
// slot. Throws std::runtime_error naming the scene file, the slot and the scene's trocars if there is none.
Eigen::Vector3d sceneTrocarForSlot(const vrm_sim::scene::SceneDescription& scene, const std::string& slot);

// The script that plays `session` in `scene`: waypoints on scene objects resolved (resolveSurfaceTargets: an object
// the scene lacks is a ScriptError unless the session keeps its tips), every scripted slot's trocar and (unless the
// session names one) instrument type from the scene, the eye's radius and rotation centre from the scene. Throws
// ScriptError (a tip outside the eye, an unresolvable waypoint) or std::runtime_error (a slot without a trocar, or
// without an instrument and no `type`). The playback mode is the session's. `report` may be null.
SurgeonScript playInScene(const vrm_sim::scene::SceneDescription& scene, const vrm_sim::scene::ScriptedSession& session,
                          vrm_sim::scene::SurfaceTargetReport* report = nullptr);

// The script the device twins play without a ~script (a shipped script, config/scripts/demo.yaml of vrm_sim).
extern const char* const kDefaultScriptName;
// What the nodelets' and tools' `script` means: "" -> kDefaultScriptName; "scenario:NAME" -> the scene's scripted
// session NAME (scenario.scripts); anything else -> vrm_sim::scene::loadScript (a file, or a shipped script's name).
// Throws SceneError / std::invalid_argument (an unknown session name, naming the scene's).
vrm_sim::scene::ScriptedSession loadSession(const std::string& spec, const vrm_sim::scene::SceneDescription& scene);
bool isScenarioSpec(const std::string& spec);

// Replaces every instrument marker's trocar by the scene's (sceneTrocarForSlot). All slots are resolved before anything
// changes, so on an exception the layout is untouched.
void applySceneTrocars(const vrm_sim::scene::SceneDescription& scene, MarkerLayout* layout);
// Everything the scene decides for a marker layout: the trocars (applySceneTrocars) and the eye's rotation centre
// (the layout's rotation_center and the scene's eye.centre are the same point: the world position the eye turns
// about, which the scripted surgeon also takes from the scene). EyeDescription has no "unset" centre: the loader puts
// a scene that writes none at the world origin, where the simulation and the surgeon put the eye too, so a loaded
// scene always decides it. Returns the layout's own centre before the change, for the caller's log. On an exception
// (a slot without a trocar) the layout is untouched.
Eigen::Vector3d applyScene(const vrm_sim::scene::SceneDescription& scene, MarkerLayout* layout);

// What identifies the scene a node runs, as vrm_msgs/RunningScene announces it: a node follows an announcement only
// when (file, difficulty, content_hash) differ from what it runs; the name is for the log.
struct SceneIdentity {
  std::string name;
  std::string file;                // absolute path of the YAML (empty for a scene built in code)
  std::string difficulty;          // the level the scene was loaded with ("" = none)
  std::uint64_t content_hash = 0;  // vrm_sim::scene::sceneContentHash(file, difficulty)
};
// The identity of a loaded scene: its file, the level it was loaded with and the hash of the file as it is now.
SceneIdentity sceneIdentity(const vrm_sim::scene::SceneDescription& scene);
bool sameScene(const SceneIdentity& a, const SceneIdentity& b);

}  // namespace vrm_tracking
