#pragma once
// Where ROS messages and the renderer's types meet (one conversions file per package): mesh, pose and microscope
// messages in, tf transforms and CameraInfo out. Used by the stereo_renderer nodelet; tested without a master.

#include <geometry_msgs/Pose.h>
#include <geometry_msgs/Transform.h>
#include <sensor_msgs/CameraInfo.h>
#include <vrm_msgs/AppliedInstrument.h>
#include <vrm_msgs/EyeState.h>
#include <vrm_msgs/InstrumentState.h>
#include <vrm_msgs/MicroscopeSettings.h>
#include <vrm_msgs/SimulationState.h>
#include <vrm_msgs/TissueMesh.h>

#include <Eigen/Geometry>

#include "vrm_render/microscope_camera.h"
#include "vrm_render/render_types.h"

namespace vrm_render {

// A zero quaternion counts as identity; others are normalised.
Eigen::Isometry3f toIsometry(const geometry_msgs::Pose& pose);
geometry_msgs::Transform toTransformMsg(const Eigen::Isometry3f& transform);
// The eye's pose in the world (rotation centre, rotation).
Eigen::Isometry3f worldFromEye(const vrm_msgs::EyeState& eye);
// A raw instrument state as if the World had applied it unchanged (type by name; empty for an unknown constant):
// only for ghosts from a bag recorded before vrm_msgs/InputFrame existed.
vrm_msgs::AppliedInstrument toAppliedInstrument(const vrm_msgs::InstrumentState& state);

// A view of the message's arrays (valid while the message lives). Normals, colours and injury are used only when
// their sizes match the vertex count; the renderer validates the rest (MeshView, StereoRenderer::updateMesh).
MeshView toMeshView(const vrm_msgs::TissueMesh& mesh);
MicroscopeState toMicroscopeState(const vrm_msgs::MicroscopeSettings& settings);
// Issue 37: the simulation state's laser burns as the renderer paints them; burns with non-finite values or no lesion
// are left out.
std::vector<FundusBurn> toFundusBurns(const vrm_msgs::SimulationState& state);

// REP-103 optical frame of a camera in the world: z forward, x right, y down.
Eigen::Isometry3f worldFromOptical(const CameraView& camera);
// The objective in REP-103 body axes: x along the optical axis, z up (the rig's up, made orthogonal), y left.
Eigen::Isometry3f worldFromObjective(const MicroscopeRig& rig);

// Intrinsics of `camera` (plumb_bob without distortion) for a width x height image; P carries the stereo baseline
// as Tx = -fx * |camera - left| (the convention of sensor_msgs/CameraInfo). The header is left empty.
sensor_msgs::CameraInfo toCameraInfo(const CameraView& camera, const CameraView& left, int width, int height);

}  // namespace vrm_render
