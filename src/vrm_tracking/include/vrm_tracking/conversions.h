#pragma once
// The one place where the ROS-free core types (surgeon_script.h) meet vrm_msgs. Header stamps and frame ids are
// the caller's business: the core has no clock and no frame names.

#include <diagnostic_msgs/DiagnosticStatus.h>
#include <geometry_msgs/Point.h>
#include <geometry_msgs/Quaternion.h>
#include <geometry_msgs/TransformStamped.h>
#include <geometry_msgs/Vector3.h>
#include <ros/node_handle.h>
#include <ros/time.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>
#include <vrm_msgs/EyeState.h>
#include <vrm_msgs/InstrumentState.h>
#include <vrm_msgs/MarkerObservations.h>
#include <vrm_msgs/MicroscopeSettings.h>
#include <vrm_msgs/PedalState.h>

#include <cstdint>
#include <memory>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "vrm_tracking/camera_rig.h"
#include "vrm_tracking/camera_watchdog.h"
#include "vrm_tracking/pose_tracker.h"
#include "vrm_tracking/surgeon_script.h"
#include "vrm_tracking/tracker_diagnostics.h"

namespace vrm_tracking {

geometry_msgs::Quaternion toQuaternionMsg(const Eigen::Quaterniond& q);
geometry_msgs::Point toPointMsg(const Eigen::Vector3d& p);
geometry_msgs::Vector3 toVector3Msg(const Eigen::Vector3d& v);
Eigen::Quaterniond toEigen(const geometry_msgs::Quaternion& q);
Eigen::Vector3d toEigen(const geometry_msgs::Point& p);
Eigen::Vector3d toEigen(const geometry_msgs::Vector3& v);

// Ground truth: tracking_quality = 1, valid = true. The header is left untouched.
void toMsg(const SurgeonSnapshot& snapshot, vrm_msgs::EyeState* msg);
void toMsg(const InstrumentSample& sample, vrm_msgs::InstrumentState* msg);
void toMsg(const PedalSample& sample, vrm_msgs::PedalState* msg);
void toMsg(const MicroscopeSample& sample, vrm_msgs::MicroscopeSettings* msg);

// The message carries no trocar; it is recovered as tip - insertion_depth * shaft_axis (the trocar constraint).
// Throws std::invalid_argument for a type that is not one of the InstrumentState constants.
InstrumentSample fromMsg(const vrm_msgs::InstrumentState& msg);
PedalSample fromMsg(const vrm_msgs::PedalState& msg);
MicroscopeSample fromMsg(const vrm_msgs::MicroscopeSettings& msg);

// ---- Optical tracking (issue 5) ----

// CameraInfo of a camera model (plumb_bob, no rectification); header left untouched.
void toMsg(const CameraModel& camera, sensor_msgs::CameraInfo* msg);
// Intrinsics from a CameraInfo (the extrinsics stay as they are in *camera). Throws std::invalid_argument for a
// CameraInfo without a usable K (all zero: an uncalibrated driver).
void updateIntrinsics(const sensor_msgs::CameraInfo& msg, CameraModel* camera);

// Blobs of one camera frame <-> MarkerObservations (the FPGA message). camera_name/size/header: the caller's.
void toMsg(const std::vector<Blob>& blobs, vrm_msgs::MarkerObservations* msg);
std::vector<Blob> fromMsg(const vrm_msgs::MarkerObservations& msg);

// Tracking results. The header is left untouched. Roll, jaw and the other non-optical channels come from `sensors`
// (the instrument's own inputs; nullptr: zero / light pipe); the orientation is the shaft frame with that roll.
void toMsg(const EyeEstimate& eye, vrm_msgs::EyeState* msg);
void toMsg(const InstrumentEstimate& estimate, const vrm_msgs::InstrumentState* sensors,
           vrm_msgs::InstrumentState* msg);

// Stamps <-> the core's integer nanoseconds (exact both ways).
StampNs toStampNs(const ros::Time& stamp);
ros::Time toRosTime(StampNs stamp);

// The tracker's health report as a DiagnosticStatus (name and hardware_id are the caller's).
void toMsg(const DiagnosticReport& report, diagnostic_msgs::DiagnosticStatus* msg);

// The static transforms eye_frame -> trocar_<slot> of the layout's instruments (the trocar frame is the eye frame
// shifted to the insertion hole, no rotation); stamps left zero.
std::vector<geometry_msgs::TransformStamped> trocarTransforms(const MarkerLayout& layout, const std::string& eye_frame);

// A BGR8 image message of width x height pixels with its buffer allocated, for a renderer to draw straight into
// (no copy between the renderer and the subscribers in the manager).
sensor_msgs::ImagePtr makeBgr8Image(const std_msgs::Header& header, int width, int height);

// An image message as a BGR8 matrix (a copy, through cv_bridge, as rig_calibrator takes its views): empty when
// cv_bridge cannot convert it (an unknown encoding, a step or data size that does not match the size).
cv::Mat toBgrImage(const sensor_msgs::Image& msg);

// ~loop, when set, overrides the script's playback mode (true: loop, false: once); unset, the script's stays.
void applyLoopParam(const ros::NodeHandle& private_nh, SurgeonScript* script);

}  // namespace vrm_tracking
