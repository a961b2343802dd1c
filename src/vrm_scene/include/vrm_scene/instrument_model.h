#pragma once
// The instrument model: one definition of what an instrument slot is for every package — which types it may take,
// its surface mesh for a type and jaw opening, and its scripted pose. The simulation core builds the tissue's and the
// collision detectors' shapes from the same description (vrm_sim/world/instrument_shapes.h) and the renderer draws
// this mesh (vrm_render/scene_setup.h), so the drawn instrument is the one that collides.

#include <Eigen/Geometry>
#include <optional>
#include <vector>

#include "vrm_scene/instrument_limits.h"
#include "vrm_scene/meshes/triangle_mesh.h"
#include "vrm_scene/scene_description.h"

namespace vrm_sim {
namespace scene {

// The slot's instrument when it holds `type`: the scene's parameters for its declared type, the generator defaults
// for another type (instrument switching).
InstrumentDescription instrumentOfType(const InstrumentDescription& configured, InstrumentType type);
// Whether the slot may hold `type`: its declared type or one of the scene's `alternatives` (thesis §7: the trainee
// changes instruments in a trocar; any other type keeps the one in use).
bool allowsType(const InstrumentDescription& configured, InstrumentType type);
// The type a slot holds after a request for `requested` (nullopt: no type said) while holding `current`.
InstrumentType typeAfterRequest(const InstrumentDescription& configured, InstrumentType current,
                                std::optional<InstrumentType> requested);

// The jaw opening the meshes are built at, in whole degrees (so tracking noise does not rebuild meshes or invalidate
// the detectors' cached depth images every frame): forceps only, clamped to [0, kMaxJawOpening], non-finite =
// closed; 0 for the other types.
int jawStepDeg(InstrumentType type, double jaw_angle_rad);

// Issue 37: an instrument's console settings as a ScenarioCommand SELECT_INSTRUMENT carries them after the type,
// "key=value,key=value" (the laser probe's power_mw, duration_ms, interval_ms). Sets them on `instrument` and returns
// "" — or, changing nothing, why not (an instrument without settings, an unknown key, a value out of the scene file's
// range).
std::string applyInstrumentSettings(InstrumentDescription& instrument, const std::string& settings);
// The instrument's surface mesh (instrument frame: tip at the origin, +z from the handle to the tip) with the jaws
// at `jaw_deg` (a jawStepDeg value). SceneError with the instrument's location for bad generator parameters.
TriangleMesh instrumentMesh(const InstrumentDescription& instrument, int jaw_deg);

// Orientation of an instrument whose shaft runs through `trocar` along `shaft_axis` (eye frame). Roll 0 puts the tip
// frame's x axis as close as possible to the circumferential tangent of the eye sphere at the trocar: a shaft through
// a point on the sphere with its tip inside can never be tangent, so this reference never degenerates (a world or
// eye axis would, e.g. for a shaft pointing straight down to the posterior pole). The scripted surgeon (vrm_tracking)
// and scriptedInstrument() use it, so a scripted roll means the same offline and in the graph.
Eigen::Quaterniond shaftOrientation(const Eigen::Vector3d& trocar, const Eigen::Vector3d& shaft_axis, double roll);

// A scripted instrument at time t: its pose (tip and shaft direction from the trocar, in the eye frame; roll by
// shaftOrientation) and jaw angle [rad]; the path is held at its ends. Requires a non-empty path
// (std::invalid_argument).
struct ScriptedPose {
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  double jaw_angle = 0.0;
};
ScriptedPose scriptedPose(const SceneDescription& scene, const InstrumentDescription& instrument, double t);

}  // namespace scene
}  // namespace vrm_sim
