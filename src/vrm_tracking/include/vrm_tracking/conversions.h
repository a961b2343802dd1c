#pragma once
// The one place where the ROS-free core types (surgeon_script.h) meet vrm_msgs. Header stamps and frame ids are
// the caller's business: the core has no clock and no frame names.

#include <geometry_msgs/Point.h>
#include <geometry_msgs/Quaternion.h>
#include <geometry_msgs/Vector3.h>
#include <vrm_msgs/EyeState.h>
#include <vrm_msgs/InstrumentState.h>
#include <vrm_msgs/MicroscopeSettings.h>
#include <vrm_msgs/PedalState.h>

#include <cstdint>

#include "vrm_tracking/surgeon_script.h"

namespace vrm_tracking {

geometry_msgs::Quaternion toQuaternionMsg(const Eigen::Quaterniond& q);
geometry_msgs::Point toPointMsg(const Eigen::Vector3d& p);
geometry_msgs::Vector3 toVector3Msg(const Eigen::Vector3d& v);
Eigen::Quaterniond toEigen(const geometry_msgs::Quaternion& q);
Eigen::Vector3d toEigen(const geometry_msgs::Point& p);
Eigen::Vector3d toEigen(const geometry_msgs::Vector3& v);

std::uint8_t toMsgType(InstrumentType type);
// Throws std::invalid_argument for a value that is not one of the InstrumentState constants.
InstrumentType fromMsgType(std::uint8_t type);

// Ground truth: tracking_quality = 1, valid = true. The header is left untouched.
void toMsg(const SurgeonSnapshot& snapshot, vrm_msgs::EyeState* msg);
void toMsg(const InstrumentSample& sample, vrm_msgs::InstrumentState* msg);
void toMsg(const PedalSample& sample, vrm_msgs::PedalState* msg);
void toMsg(const MicroscopeSample& sample, vrm_msgs::MicroscopeSettings* msg);

// The message carries no trocar; it is recovered as tip - insertion_depth * shaft_axis (the trocar constraint).
InstrumentSample fromMsg(const vrm_msgs::InstrumentState& msg);
PedalSample fromMsg(const vrm_msgs::PedalState& msg);
MicroscopeSample fromMsg(const vrm_msgs::MicroscopeSettings& msg);

}  // namespace vrm_tracking
