#pragma once
// Input frames as scenario_manager publishes them (vrm_msgs/InputFrame), for the renderer's graph tests, which run
// no simulation: the eye at rest and each instrument as the World applied it, its shaft through its trocar.

#include <ros/time.h>
#include <vrm_msgs/AppliedInstrument.h>
#include <vrm_msgs/InputFrame.h>

#include <Eigen/Geometry>
#include <boost/make_shared.hpp>
#include <string>
#include <vector>

#include "vrm_scene/scene_description.h"

namespace vrm_render::testing {

// The instrument frame (origin at the tip, +z from the trocar to the tip) of `instrument` with its tip at
// `tip_in_eye`, in the eye frame (the scene's rule for scripted paths, vrm_sim::scene::scriptedInstrument).
inline geometry_msgs::Pose poseThroughTrocar(const vrm_sim::scene::SceneDescription& scene,
                                             const vrm_sim::scene::InstrumentDescription& instrument,
                                             const Eigen::Vector3d& tip_in_eye) {
  const vrm_sim::scene::Trocar* trocar = scene.findTrocar(instrument.trocar);
  const Eigen::Vector3d axis =
      trocar ? Eigen::Vector3d(tip_in_eye - trocar->position_in_eye) : -Eigen::Vector3d::UnitZ();
  const Eigen::Quaterniond rotation = Eigen::Quaterniond::FromTwoVectors(Eigen::Vector3d::UnitZ(), axis.normalized());
  geometry_msgs::Pose pose;
  pose.position.x = tip_in_eye.x();
  pose.position.y = tip_in_eye.y();
  pose.position.z = tip_in_eye.z();
  pose.orientation.w = rotation.w();
  pose.orientation.x = rotation.x();
  pose.orientation.y = rotation.y();
  pose.orientation.z = rotation.z();
  return pose;
}

inline vrm_msgs::AppliedInstrument appliedInstrument(const std::string& slot, const std::string& type,
                                                     const geometry_msgs::Pose& pose_in_eye, double jaw_angle,
                                                     bool valid) {
  vrm_msgs::AppliedInstrument applied;
  applied.slot = slot;
  applied.type = type;
  applied.header.frame_id = "eye";
  applied.pose = pose_in_eye;
  applied.jaw_angle = jaw_angle;
  applied.valid = valid;
  applied.delivered = true;
  return applied;
}

// A simulation frame (kind FRAME) with the eye at rest (world <- eye = identity, valid) and `instruments` applied.
inline vrm_msgs::InputFrame::Ptr simulationFrame(const ros::Time& stamp, std::uint64_t sequence,
                                                 const std::vector<vrm_msgs::AppliedInstrument>& instruments) {
  auto frame = boost::make_shared<vrm_msgs::InputFrame>();
  frame->header.stamp = stamp;
  frame->header.frame_id = "world";
  frame->sequence = sequence;
  frame->kind = vrm_msgs::InputFrame::KIND_FRAME;
  frame->eye_pose.orientation.w = 1.0;
  frame->eye_valid = true;
  frame->instruments = instruments;
  for (vrm_msgs::AppliedInstrument& applied : frame->instruments) applied.header.stamp = stamp;
  return frame;
}

}  // namespace vrm_render::testing
