#include "vrm_render/conversions.h"

#include "vrm_scene/scene_description.h"
#include "vrm_sim/conversions.h"

namespace vrm_render {

Eigen::Isometry3f toIsometry(const geometry_msgs::Pose& pose) {
  Eigen::Isometry3f t = Eigen::Isometry3f::Identity();
  t.translation() = Eigen::Vector3f(pose.position.x, pose.position.y, pose.position.z);
  Eigen::Quaternionf q(pose.orientation.w, pose.orientation.x, pose.orientation.y, pose.orientation.z);
  if (q.norm() < 1e-6f) q = Eigen::Quaternionf::Identity();
  t.linear() = q.normalized().toRotationMatrix();
  return t;
}

geometry_msgs::Transform toTransformMsg(const Eigen::Isometry3f& t) {
  geometry_msgs::Transform msg;
  msg.translation.x = t.translation().x();
  msg.translation.y = t.translation().y();
  msg.translation.z = t.translation().z();
  const Eigen::Quaternionf q(t.linear());
  msg.rotation.x = q.x();
  msg.rotation.y = q.y();
  msg.rotation.z = q.z();
  msg.rotation.w = q.w();
  return msg;
}

Eigen::Isometry3f worldFromEye(const vrm_msgs::EyeState& eye) {
  geometry_msgs::Pose pose;
  pose.position = eye.rotation_center;
  pose.orientation = eye.rotation;
  return toIsometry(pose);
}

vrm_msgs::AppliedInstrument toAppliedInstrument(const vrm_msgs::InstrumentState& state) {
  vrm_msgs::AppliedInstrument applied;
  applied.slot = state.instrument_id;
  const std::optional<vrm_sim::scene::InstrumentType> type = vrm_sim::instrumentTypeFromMsg(state.type);
  applied.type = type ? vrm_sim::scene::toString(*type) : "";
  applied.header = state.header;
  applied.pose = state.tip_pose;
  applied.jaw_angle = state.jaw_angle;
  applied.suction = state.suction;
  applied.cut_rate = state.cut_rate;
  applied.valid = state.valid;
  applied.delivered = true;
  return applied;
}

MeshView toMeshView(const vrm_msgs::TissueMesh& msg) {
  MeshView view;
  view.positions = msg.positions.data();
  view.vertex_count = msg.positions.size() / 3;
  view.normals = msg.normals.size() == msg.positions.size() ? msg.normals.data() : nullptr;
  view.colors = msg.colors.size() == view.vertex_count * 4 && view.vertex_count ? msg.colors.data() : nullptr;
  view.injury = msg.injury.size() == view.vertex_count && view.vertex_count ? msg.injury.data() : nullptr;
  view.triangles = msg.triangles.data();
  view.triangle_count = msg.triangles.size() / 3;
  return view;
}

MicroscopeState toMicroscopeState(const vrm_msgs::MicroscopeSettings& settings) {
  MicroscopeState knobs;
  knobs.focus_distance = settings.focus_distance;
  knobs.zoom = settings.zoom;
  knobs.ambient_light = settings.ambient_light;
  knobs.disparity_scale = settings.disparity_scale;
  return knobs;
}

// The GL view matrix has x right, y up, z backward in its rows.
Eigen::Isometry3f worldFromOptical(const CameraView& camera) {
  Eigen::Isometry3f t = Eigen::Isometry3f::Identity();
  const Eigen::Matrix3f rows = camera.view.topLeftCorner<3, 3>();
  t.linear().col(0) = rows.row(0).transpose();
  t.linear().col(1) = -rows.row(1).transpose();
  t.linear().col(2) = -rows.row(2).transpose();
  t.translation() = camera.position;
  return t;
}

Eigen::Isometry3f worldFromObjective(const MicroscopeRig& rig) {
  Eigen::Isometry3f t = Eigen::Isometry3f::Identity();
  const Eigen::Vector3f x = rig.view_direction.normalized();
  const Eigen::Vector3f z = (rig.up - rig.up.dot(x) * x).normalized();
  t.linear().col(0) = x;
  t.linear().col(1) = z.cross(x);
  t.linear().col(2) = z;
  t.translation() = rig.objective;
  return t;
}

sensor_msgs::CameraInfo toCameraInfo(const CameraView& camera, const CameraView& left, int width, int height) {
  sensor_msgs::CameraInfo info;
  info.width = width;
  info.height = height;
  info.distortion_model = "plumb_bob";
  info.D.assign(5, 0.0);
  const Eigen::Matrix4f& p = camera.projection;
  const double fx = p(0, 0) * width / 2.0, fy = p(1, 1) * height / 2.0;
  const double cx = (1.0 - p(0, 2)) * width / 2.0, cy = (1.0 + p(1, 2)) * height / 2.0;
  info.K = {fx, 0, cx, 0, fy, cy, 0, 0, 1};
  info.R = {1, 0, 0, 0, 1, 0, 0, 0, 1};
  const double tx = -fx * (camera.position - left.position).norm();
  info.P = {fx, 0, cx, tx, 0, fy, cy, 0, 0, 0, 1, 0};
  return info;
}

std::vector<FundusBurn> toFundusBurns(const vrm_msgs::SimulationState& state) {
  std::vector<FundusBurn> burns;
  burns.reserve(state.burns.size());
  for (const vrm_msgs::LaserBurn& message : state.burns) {
    FundusBurn burn;
    burn.position = Eigen::Vector3d(message.position.x, message.position.y, message.position.z).cast<float>();
    burn.diameter = static_cast<float>(message.diameter);
    burn.whiteness = static_cast<float>(message.whiteness);
    if (!burn.position.allFinite() || !(burn.diameter > 0.0f) || !std::isfinite(burn.whiteness)) continue;
    burns.push_back(burn);
  }
  return burns;
}

}  // namespace vrm_render
