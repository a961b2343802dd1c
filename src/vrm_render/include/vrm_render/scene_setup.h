#pragma once
// Bridges vrm_sim's scene descriptions and procedural meshes (ROS-free) to the renderer: mesh conversion, styles
// by object role (thesis §7.4.2: who casts shadows, what is bump mapped, what streams) and the thesis' typical
// scene for benchmarks (§7: 15,000 triangles, 5,000 of them deformable).

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "vrm_render/fundus.h"
#include "vrm_render/render_types.h"
#include "vrm_render/stereo_renderer.h"
#include "vrm_scene/meshes/triangle_mesh.h"
#include "vrm_scene/scene_description.h"
#include "vrm_scene/scene_fundus.h"

namespace vrm_render {

MeshData toMeshData(const vrm_sim::TriangleMesh& mesh);
// The fundus of a scene and its optic disc: vrm_sim's (scene/scene_fundus.h), one for what is drawn and what is scored.
using vrm_sim::scene::fundusParams;
using vrm_sim::scene::kOpticDiscName;
using vrm_sim::scene::opticDisc;
Material toMaterial(const vrm_sim::scene::Material& material);
ObjectStyle objectStyle(const vrm_sim::scene::ObjectDescription& object);
// The light pipe does not cast a shadow (the light leaves its tip); the interacting instruments do.
ObjectStyle instrumentStyle(const vrm_sim::scene::InstrumentDescription& instrument, bool ghost = false);
std::string instrumentObjectId(const vrm_sim::scene::InstrumentDescription& instrument);  // "instrument_<slot>"

// An instrument slot's mesh for a type and jaw opening comes from the instrument model
// (vrm_scene/instrument_model.h: instrumentOfType, jawStepDeg, instrumentMesh), the one the simulation collides
// with; toMeshData() converts it.

// The endoilluminator's light (issue 16): a soft-edged cone (the fibre's light falls off towards the rim rather than
// ending at it) at an intensity that lights the fundus without saturating it. Used by the nodelet and typicalScene.
LightPipe endoilluminator();
// Light pipe spotlight for an instrument pose: tip at the frame origin, shining along the frame's +z.
LightPipe lightPipeAt(const Eigen::Isometry3f& world_from_instrument, const LightPipe& defaults = {});

struct SceneObject {
  std::string id;
  MeshData mesh;
  ObjectStyle style;
  Eigen::Isometry3f pose = Eigen::Isometry3f::Identity();
};

// What the renderer shows of a scene before any input arrives (issue 32: the renderer follows the running scene):
// each object's rest mesh in the frame the object names, styled by role, and the scene's fundus. Built from the scene
// description alone (CPU only, no GL), so a node can prepare the next scene while the current one keeps rendering.
struct SceneContent {
  struct Object {
    SceneObject drawn;         // rest mesh (scene::buildMesh in the parent frame), style by role; pose identity
    bool in_eye_frame = true;  // the mesh moves with the eye (else it is fixed in the world frame)
    // The simulation streams this object's deformed (tissue) or injured (bleeding retina) copy on tissue/<name>.
    bool streamed = false;
  };
  std::string name;
  std::vector<Object> objects;  // in the order of the scene's objects
  std::shared_ptr<const FundusMap> fundus;
};

// Rest meshes get this version: below every published TissueMesh version (they start at 1), so the simulation's
// first streamed copy always replaces them.
constexpr std::uint64_t kRestMeshVersion = 0;

// The content of `scene`; `fundus_seed` as for fundusParams; the optic disc object is left out (see fundusParams).
// Throws vrm_sim::scene::SceneError when a mesh cannot be built (an imported mesh file that vanished since the scene
// was loaded).
SceneContent sceneContent(const vrm_sim::scene::SceneDescription& scene, long long fundus_seed = -1);

// Replaces everything `renderer` draws by `content`: every other object (the previous scene's objects, instruments
// and ghosts included) is removed, the content's objects are styled and uploaded, and its fundus is set. Afterwards
// the renderer holds what a new renderer given only this content holds; the caller adds the scene's instruments.
// Throws RenderError when a mesh is rejected (the renderer then holds part of the content).
void showScene(StereoRenderer* renderer, const SceneContent& content);

// Pose of an instrument inserted through a trocar at `trocar_in_eye`, its tip `depth` metres beyond the trocar,
// aimed at `target_in_eye`.
Eigen::Isometry3f instrumentPoseThroughTrocar(const Eigen::Vector3f& trocar_in_eye,
                                              const Eigen::Vector3f& target_in_eye, float depth);

// Issue 37: the laser probe's aiming beam where it meets the retina (vrm_sim scenario::laserAim): a red, emissive disc
// as wide as the beam's spot there (it widens with the distance, the surgeon's cue), 30 µm in front of the retina,
// facing the eye centre. `eye_from_instrument`: the probe's pose in the eye frame (+z along the shaft to the tip).
// nullopt when the instrument is no laser probe or its beam does not meet the retina (tip outside the eye, bad pose).
struct LaserAimSpot {
  Eigen::Isometry3f eye_from_spot = Eigen::Isometry3f::Identity();
  float diameter = 0.0f;  // m
};
std::optional<LaserAimSpot> laserAimSpot(const vrm_sim::scene::InstrumentDescription& probe,
                                         const Eigen::Isometry3f& eye_from_instrument, double eye_radius);
constexpr const char* kLaserAimId = "laser_aim";
ObjectStyle laserAimStyle();
MeshData laserAimMesh(float diameter);  // a disc in the xy plane

// Retina (~10k triangles, static), membrane (~5k triangles, deformable), light pipe and forceps in a pose like
// the middle of a membrane peeling: ~15.5k triangles in the eye frame (= world frame, eye at rest).
std::vector<SceneObject> typicalScene(LightPipe* light);

}  // namespace vrm_render
