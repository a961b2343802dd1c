#pragma once
// The one place where vrm_sim's core types meet ROS messages (one conversions file per package). Everything else in
// the core is ROS-free.

#include <geometry_msgs/Pose.h>
#include <geometry_msgs/Transform.h>
#include <visualization_msgs/Marker.h>

#include <Eigen/Geometry>
#include <array>
#include <cstdint>
#include <optional>
#include <vector>

#include "vrm_msgs/CollisionReport.h"
#include "vrm_msgs/EyeState.h"
#include "vrm_msgs/InputFrame.h"
#include "vrm_msgs/InstrumentState.h"
#include "vrm_msgs/PedalState.h"
#include "vrm_msgs/ScenarioCommand.h"
#include "vrm_msgs/ScenarioStatus.h"
#include "vrm_msgs/SimulationState.h"
#include "vrm_msgs/TissueMesh.h"
#include "vrm_scene/meshes/triangle_mesh.h"
#include "vrm_sim/collision/collision_detector.h"
#include "vrm_sim/world/world.h"

namespace vrm_sim {

Eigen::Isometry3d toEigen(const geometry_msgs::Pose& pose);
geometry_msgs::Pose toPoseMsg(const Eigen::Isometry3d& pose);
geometry_msgs::Transform toTransformMsg(const Eigen::Isometry3d& transform);

// Packs contiguous positions (what the MGE arrays hold) and triangles into a TissueMesh; computes area-weighted
// vertex normals so renderers and RViz need not.
void fillTissueMesh(const Eigen::Vector3d* positions, std::size_t vertex_count,
                    const std::array<std::uint32_t, 3>* triangles, std::size_t triangle_count,
                    vrm_msgs::TissueMesh& message);
void fillTissueMesh(const TriangleMesh& mesh, vrm_msgs::TissueMesh& message);

// A TRIANGLE_LIST marker of the mesh (RViz has no indexed triangles, so vertices are expanded per triangle).
void fillTriangleListMarker(const vrm_msgs::TissueMesh& mesh, const std::array<float, 4>& rgba,
                            visualization_msgs::Marker& marker);
// A TRIANGLE_LIST marker of the `selected` triangles only (e.g. the colliding ones); header and ns are the caller's.
void fillTriangleListMarker(const Eigen::Vector3d* positions, const std::array<std::uint32_t, 3>* triangles,
                            const std::vector<std::uint32_t>& selected, const std::array<float, 4>& rgba,
                            visualization_msgs::Marker& marker);

// The eye's pose in the world (world <- eye): the mechanical eye rotates about its fixed rotation centre.
Eigen::Isometry3d worldFromEye(const vrm_msgs::EyeState& eye);

// Copies a query's result (colliding, triangles, node deformations, contacts, pixel size, phase times) into a
// CollisionReport; header, detector and object names are the caller's.
void fillCollisionReport(const collision::CollisionResult& result, vrm_msgs::CollisionReport& report);

// Inputs of the simulation core (world/world.h): stamps become integer nanoseconds, so the core's frame assembly
// compares them exactly. A message type outside the known instrument constants keeps the slot's current type.
world::Stamp toStamp(const ros::Time& stamp);
// The one bridge between scene::InstrumentType and the InstrumentTypes.msg constants (every package converts
// here): nullopt for a constant outside the known ones; toMsgType(nullopt) is 255 (no type said).
std::optional<scene::InstrumentType> instrumentTypeFromMsg(std::uint8_t msg_type);
std::uint8_t toMsgType(std::optional<scene::InstrumentType> type);
ros::Time toRosTime(world::Stamp stamp);
world::EyeState toWorld(const vrm_msgs::EyeState& eye);
world::InstrumentState toWorld(const vrm_msgs::InstrumentState& instrument);
// The message a device twin publishes for `instrument` (shaft axis, insertion depth and roll are left zero: the core
// does not read them); toWorld(toMsg(x)) == x number for number.
vrm_msgs::InstrumentState toMsg(const world::InstrumentState& instrument);
world::PedalState toWorld(const vrm_msgs::PedalState& pedals);
// Returns nullopt for an unknown command value.
std::optional<world::ScenarioCommand> toWorld(const vrm_msgs::ScenarioCommand& command);
vrm_msgs::EyeState toMsg(const world::EyeState& eye);
vrm_msgs::PedalState toMsg(const world::PedalState& pedals);
vrm_msgs::ScenarioCommand toMsg(const world::ScenarioCommand& command);
// An input frame as the simulation node publishes and records it, and back (number for number: a replayed frame
// applies the very inputs the live one did). frame_id is the world frame's name. A recorded command of an unknown
// value is dropped.
void fillInputFrame(const world::InputFrame& frame, const std::string& world_frame, const std::string& eye_frame,
                    vrm_msgs::InputFrame& message);
world::InputFrame toWorld(const vrm_msgs::InputFrame& message);
// The frame's report (header, tissues, injuries); header.frame_id stays empty.
void fillSimulationState(const world::FrameResult& frame, const world::WorldStatistics& statistics,
                         vrm_msgs::SimulationState& message);
// The scenario's state, progress message and score (header left to the caller).
void fillScenarioStatus(const scenario::Status& status, vrm_msgs::ScenarioStatus& message);
void fillScore(const scenario::Score& score, vrm_msgs::Score& message);

}  // namespace vrm_sim
