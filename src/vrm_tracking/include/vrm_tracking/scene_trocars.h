#pragma once
// The scene file as the single source of truth for the trocars (the fixed insertion holes of the mechanical eye) and
// for where tissue is. The shipped marker layout and trajectory files name no trocars (trocar_from_scene): the
// nodelets apply their ~scene, or without one the default scene (vrm_sim::scene::kDefaultSceneName), so the twin
// surgeon, the tracker and the VR part pivot the instruments at the same points. (A layout or script may still write
// its own trocars, e.g. the built-in ones for the ROS-free tools; a scene given to a nodelet replaces them.) Keyframes
// written `on` a scene object (SurfaceTarget) are put on that object's surface here, so a script grasps the membrane
// where the scene has it, not where its author once measured it. ROS-free; links vrm_sim's scene library (vrm_scene).

#include <Eigen/Core>
#include <cstdint>
#include <string>
#include <vector>

#include "vrm_sim/scene/scene_description.h"
#include "vrm_sim/triangle_mesh.h"
#include "vrm_tracking/marker_layout.h"
#include "vrm_tracking/surgeon_script.h"

namespace vrm_tracking {

// `spec`, or the simulator's default scene (vrm_sim::scene::kDefaultSceneName, whose trocars the shipped files leave
// out) when it is empty.
std::string sceneOrDefault(const std::string& spec);
// Whether some instrument track leaves its trocar to the scene (InstrumentTrack::trocar_from_scene).
bool leavesTrocarsToScene(const ScriptDefinition& script);

// The trocar (eye frame, m) an instrument in tracking slot `slot` ("left" / "right") goes through in `scene`: the
// trocar named by the scene's instrument in that slot, else (no instrument in that slot) the trocar named like the
// slot. Throws std::runtime_error naming the scene file, the slot and the scene's trocars if there is none.
Eigen::Vector3d sceneTrocarForSlot(const vrm_sim::scene::SceneDescription& scene, const std::string& slot);

// A point of a triangle mesh nearest to a query point, with the normal of the triangle it lies on turned towards the
// eye centre (the origin of the mesh's frame): "above" a retina or membrane is the side the instruments come from.
struct SurfacePoint {
  Eigen::Vector3d position = Eigen::Vector3d::Zero();
  Eigen::Vector3d inward_normal = Eigen::Vector3d::UnitZ();  // unit
  double distance = 0.0;                                     // from the query point, m
};

// Brute force over the triangles (scene objects have a few thousand; this runs once per keyframe at load time).
// Throws std::invalid_argument for a mesh without (non-degenerate) triangles.
SurfacePoint closestSurfacePoint(const vrm_sim::TriangleMesh& surface, const Eigen::Vector3d& point);

// Where a keyframe written `on` an object with this surface lands: closest point to `written_tip` plus `height`
// along the inward normal (negative: below the surface).
Eigen::Vector3d resolveSurfaceTip(const vrm_sim::TriangleMesh& surface, const Eigen::Vector3d& written_tip,
                                  double height);

// What applyScene() did with the keyframes written on scene objects, for the caller's log.
struct SceneTargetReport {
  std::size_t resolved_keyframes = 0;
  // On an object the scene lacks (only where ScriptDefinition::targets_optional): they play their written tips.
  std::size_t kept_keyframes = 0;
  std::vector<std::string> missing_objects;  // unique, in order of first use
};

// Everything the scene decides for a script: the trocars (applySceneTrocars) and the keyframes written on scene
// objects (resolveSurfaceTip on buildMesh(object, kParent)). An object the scene does not have is a ScriptError naming
// the object, the keyframe (field, line, time) and the scene, unless script->targets_optional; an object in the world
// frame is a ScriptError (tips are in the eye frame and the eye moves in the world). Resolution always starts from
// the written tip, so applying a scene twice, or another scene afterwards, gives the same result as once. All of it
// is computed before anything changes, so on an exception the script is untouched. `report` may be null.
void applyScene(const vrm_sim::scene::SceneDescription& scene, ScriptDefinition* script,
                SceneTargetReport* report = nullptr);
// The script rebuilt by applyScene (validated again; ScriptError if a tip left the eye). The playback mode is kept,
// the tremor is not (set it afterwards).
SurgeonScript applyScene(const vrm_sim::scene::SceneDescription& scene, const SurgeonScript& script,
                         SceneTargetReport* report = nullptr);

// The trocars only (keyframes on scene objects keep their tips): replaces every instrument track's / instrument
// marker's trocar by the scene's (sceneTrocarForSlot); a script without an `eye:` block (EyeGeometry::from_scene)
// also takes the scene's eye radius and rotation centre. All slots are resolved before anything changes, so on an
// exception the input is untouched.
void applySceneTrocars(const vrm_sim::scene::SceneDescription& scene, ScriptDefinition* script);
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

// The script rebuilt with the scene's trocars (validated again: the tips must still be reachable; ScriptError
// otherwise). The playback mode is kept; the tremor is not (set it afterwards).
SurgeonScript applySceneTrocars(const vrm_sim::scene::SceneDescription& scene, const SurgeonScript& script);

// The scene's scripted session `name` (scenario.scripts, e.g. "expert") as a surgeon script, so the device twins
// play in the graph what scenario_offline plays offline: one track per scripted instrument through the scene's
// trocar, a keyframe at every waypoint (and every 5 ms along a path with tremor, so the played tip includes it),
// played once; the eye rests about the scene's eye centre. Throws std::invalid_argument naming the scene's scripts for
// an unknown name.
SurgeonScript scenarioScript(const vrm_sim::scene::SceneDescription& scene, const std::string& name);

}  // namespace vrm_tracking
