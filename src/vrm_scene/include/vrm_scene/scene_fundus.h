#pragma once
// The fundus a scene shows and scores (issues 16, 33, 37): the anatomy's parameters from the scene description, so the
// renderer draws and the scenarios score one and the same disc and vessel tree.

#include "vrm_scene/anatomy/fundus_anatomy.h"
#include "vrm_scene/scene_description.h"

namespace vrm_sim {
namespace scene {

// The fundus of a scene: its eye radius, seeded by `seed` when >= 0, else by a hash of the scene's name (scene
// descriptions carry no seed of their own), so a scene always shows the same fundus.
// Issue 33: a scene's optic disc is the object named kOpticDiscName ("optic_disc": membrane_peeling and vitrectomy
// have one, a `disc` decoration on the retina): the fundus puts its disc at that object's position (its fundus
// coordinates; the nasal side from their sign) with the mesh's diameter, and the renderer does not draw the mesh
// (the fundus is the disc). Without one the anatomical default (FundusParams) stays. An `optic_disc` that is not a
// `disc` generator in the eye frame on the retina is a SceneError.
anatomy::FundusParams fundusParams(const SceneDescription& scene, long long seed = -1);
constexpr const char* kOpticDiscName = "optic_disc";
// The scene's optic disc object as described above, nullptr when it has none.
const ObjectDescription* opticDisc(const SceneDescription& scene);

}  // namespace scene
}  // namespace vrm_sim
