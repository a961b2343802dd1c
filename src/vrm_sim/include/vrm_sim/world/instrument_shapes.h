#pragma once
// What an instrument of the scene (vrm_scene/instrument_model.h) is to the physics: its tissue-side shape and its
// collision model. Here, above the scene floor, because they are the tissue's and the collision detectors' types;
// the floor keeps the description, the mesh and the scripted pose.

#include "vrm_scene/instrument_model.h"
#include "vrm_scene/scene_description.h"
#include "vrm_sim/collision/collision_detector.h"
#include "vrm_sim/tissue/tissue_simulator.h"

namespace vrm_sim {
namespace world {

// The instrument's tissue-side shape: a capsule along the shaft; the forceps grasp with their jaws; the vitrector
// cuts what its port aspirates. Pose and jaw angle are the caller's.
tissue::InstrumentInput tissueShape(const scene::InstrumentDescription& instrument);
// The collision model at `jaw_deg` (a scene::jawStepDeg value): the surface mesh for the image-space and mesh
// detectors and, for the exact (geometric) detector, the tissue-side capsules at the same opening.
collision::InstrumentModel collisionModel(const scene::InstrumentDescription& instrument, int jaw_deg);
// The tissue-side shape at the scripted pose and jaw angle of time t (scene::scriptedPose).
tissue::InstrumentInput scriptedInstrument(const scene::SceneDescription& scene,
                                           const scene::InstrumentDescription& instrument, double t);

}  // namespace world
}  // namespace vrm_sim
