#pragma once
// Bridges vrm_sim's scene descriptions and procedural meshes (ROS-free) to the renderer: mesh conversion, styles
// by object role (thesis §7.4.2: who casts shadows, what is bump mapped, what streams) and the thesis' typical
// scene for benchmarks (§7: 15,000 triangles, 5,000 of them deformable).

#include <string>
#include <vector>

#include "vrm_render/fundus.h"
#include "vrm_render/render_types.h"
#include "vrm_sim/scene/scene_description.h"
#include "vrm_sim/triangle_mesh.h"

namespace vrm_render {

MeshData toMeshData(const vrm_sim::TriangleMesh& mesh);
// The fundus of a scene (issue 16): its eye radius, seeded by `seed` when >= 0, else by a hash of the scene's name
// (scene descriptions carry no seed of their own), so a scene always shows the same fundus.
FundusParams fundusParams(const vrm_sim::scene::SceneDescription& scene, long long seed = -1);
Material toMaterial(const vrm_sim::scene::Material& material);
ObjectStyle objectStyle(const vrm_sim::scene::ObjectDescription& object);
// The light pipe does not cast a shadow (the light leaves its tip); the interacting instruments do.
ObjectStyle instrumentStyle(const vrm_sim::scene::InstrumentDescription& instrument, bool ghost = false);
std::string instrumentObjectId(const vrm_sim::scene::InstrumentDescription& instrument);  // "instrument_<slot>"

// An instrument slot's mesh for a type and jaw opening comes from the instrument model
// (vrm_sim/scene/instrument_model.h: instrumentOfType, jawStepDeg, instrumentMesh), the one the simulation collides
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

// Pose of an instrument inserted through a trocar at `trocar_in_eye`, its tip `depth` metres beyond the trocar,
// aimed at `target_in_eye`.
Eigen::Isometry3f instrumentPoseThroughTrocar(const Eigen::Vector3f& trocar_in_eye,
                                              const Eigen::Vector3f& target_in_eye, float depth);

// Retina (~10k triangles, static), membrane (~5k triangles, deformable), light pipe and forceps in a pose like
// the middle of a membrane peeling: ~15.5k triangles in the eye frame (= world frame, eye at rest).
std::vector<SceneObject> typicalScene(LightPipe* light);

}  // namespace vrm_render
