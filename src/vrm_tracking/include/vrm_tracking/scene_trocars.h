#pragma once
// The scene file as the single source of truth for the trocars (the fixed insertion holes of the mechanical eye).
// Surgeon scripts (surgeon_script.h) and marker layouts (marker_layout.h) carry their own trocar per slot so they
// work without a scene; when a nodelet is given a scene (~scene), these functions replace those copies by the
// scene's trocars, so the twin surgeon, the tracker and the VR part pivot the instruments at the same points.
// ROS-free; links vrm_sim's scene library (vrm_scene).

#include <Eigen/Core>
#include <string>

#include "vrm_sim/scene/scene_description.h"
#include "vrm_tracking/marker_layout.h"
#include "vrm_tracking/surgeon_script.h"

namespace vrm_tracking {

// What the nodelets' `scene` parameter means, as in vrm_sim's scene_manager: an existing file, else the name of a
// shipped scene (vrm_sim/config/scenes/NAME.yaml). Throws vrm_sim::scene::SceneError.
vrm_sim::scene::SceneDescription loadSceneSpec(const std::string& spec);

// The trocar (eye frame, m) an instrument in tracking slot `slot` ("left" / "right") goes through in `scene`: the
// trocar named by the scene's instrument in that slot, else (no instrument in that slot) the trocar named like the
// slot. Throws std::runtime_error naming the scene file, the slot and the scene's trocars if there is none.
Eigen::Vector3d sceneTrocarForSlot(const vrm_sim::scene::SceneDescription& scene, const std::string& slot);

// Replaces every instrument track's / instrument marker's trocar by the scene's (sceneTrocarForSlot). All slots are
// resolved before anything changes, so on an exception the input is untouched.
void applySceneTrocars(const vrm_sim::scene::SceneDescription& scene, ScriptDefinition* script);
void applySceneTrocars(const vrm_sim::scene::SceneDescription& scene, MarkerLayout* layout);
// The script rebuilt with the scene's trocars (validated again: the tips must still be reachable; ScriptError
// otherwise). The playback mode is kept; the tremor is not (set it afterwards).
SurgeonScript applySceneTrocars(const vrm_sim::scene::SceneDescription& scene, const SurgeonScript& script);

}  // namespace vrm_tracking
