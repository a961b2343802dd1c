#include "vrm_sim/scenario/rigid_body.h"

#include <algorithm>
#include <cmath>

namespace vrm_sim {
namespace scenario {

Eigen::Isometry3d restOnSphere(const Eigen::Isometry3d& pose, const Eigen::Vector3d& half_extents,
                               const std::vector<int>& resting_axes, double sphere_radius) {
  Eigen::Vector3d outward = pose.translation();
  if (!(outward.norm() > 1e-12)) outward = -Eigen::Vector3d::UnitZ();  // at the centre: onto the posterior pole
  outward.normalize();
  // The face (local axis, sign) whose outward normal points most towards the wall.
  int axis = resting_axes.empty() ? 2 : resting_axes.front();
  double sign = 1.0, best = -2.0;
  for (int candidate : resting_axes) {
    const double alignment = pose.linear().col(candidate).dot(outward);
    if (std::abs(alignment) > best) {
      best = std::abs(alignment);
      axis = candidate;
      sign = alignment >= 0.0 ? 1.0 : -1.0;
    }
  }
  const Eigen::Vector3d face_normal = sign * pose.linear().col(axis);
  const Eigen::Quaterniond turn = Eigen::Quaterniond::FromTwoVectors(face_normal, outward);
  Eigen::Isometry3d rest = Eigen::Isometry3d::Identity();
  rest.linear() = (turn * Eigen::Quaterniond(pose.linear())).normalized().toRotationMatrix();
  rest.translation() = outward * (sphere_radius - half_extents[axis]);
  return rest;
}

RigidBody::RigidBody(std::string name, const Eigen::Isometry3d& pose, RigidBodyOptions options)
    : name_(std::move(name)), pose_(pose), options_(std::move(options)) {}

bool RigidBody::heldBy(const std::string& slot) const {
  return std::any_of(holders_.begin(), holders_.end(), [&](const Holder& holder) { return holder.slot == slot; });
}

Eigen::Isometry3d RigidBody::instrumentPose(const InstrumentView& tool) {
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.linear() = tool.orientation.normalized().toRotationMatrix();
  pose.translation() = tool.tip;
  return pose;
}

std::vector<std::string> RigidBody::update(const FrameView& frame, const std::vector<std::string>& slots) {
  std::vector<std::string> dropped_by;
  for (const std::string& slot : slots) {
    const InstrumentView* tool = frame.instrument(slot);
    const bool valid = tool != nullptr && tool->valid && tool->tip.allFinite();
    const bool closed = valid && tool->jaw_angle < options_.grasp_angle;
    auto seen = std::find_if(jaws_were_open_.begin(), jaws_were_open_.end(),
                             [&](const auto& entry) { return entry.first == slot; });
    if (seen == jaws_were_open_.end()) seen = jaws_were_open_.insert(jaws_were_open_.end(), {slot, false});
    const bool was_open = seen->second;
    seen->second = valid && !closed;
    auto holder = std::find_if(holders_.begin(), holders_.end(), [&](const Holder& h) { return h.slot == slot; });
    if (holder != holders_.end()) {
      if (!closed) {
        holders_.erase(holder);
        if (holders_.empty()) {
          dropped_by.push_back(slot);
          resting_ = false;
          velocity_.setZero();
        }
      }
      continue;
    }
    if (closed && was_open && (tool->tip - pose_.translation()).norm() <= options_.grasp_reach) {
      holders_.push_back({slot, instrumentPose(*tool).inverse() * pose_});
      velocity_.setZero();
    }
  }
  if (!holders_.empty()) {
    pose_ = instrumentPose(*frame.instrument(holders_.front().slot)) * holders_.front().instrument_from_body;
    resting_ = false;
    // A second pair of jaws on the body slides along it while the first moves it: its grip is re-taken where the body
    // is, so the body does not jump when the first lets go (a hand-over).
    for (std::size_t i = 1; i < holders_.size(); ++i) {
      holders_[i].instrument_from_body = instrumentPose(*frame.instrument(holders_[i].slot)).inverse() * pose_;
    }
  }
  return dropped_by;
}

// Semi-implicit Euler in the eye frame with 1 ms substeps; gravity is the world's -z seen from the (rotating) eye.
bool RigidBody::fall(const FrameView& frame) {
  if (held() || resting_) return false;
  const Eigen::Vector3d gravity = frame.world_from_eye.linear().transpose() * Eigen::Vector3d(0, 0, -options_.gravity);
  const int substeps = std::max(1, static_cast<int>(std::ceil(frame.dt / 1e-3)));
  const double h = frame.dt / substeps;
  const double reach = options_.half_extents.minCoeff();
  for (int i = 0; i < substeps; ++i) {
    velocity_ = (velocity_ + h * gravity) / (1.0 + h * options_.drag);
    pose_.translation() += h * velocity_;
    if (pose_.translation().norm() + reach >= options_.eye_radius) {
      pose_ = restOnSphere(pose_, options_.half_extents, options_.resting_axes, options_.eye_radius);
      velocity_.setZero();
      resting_ = true;
      return true;
    }
  }
  return false;
}

void RigidBody::place(const Eigen::Isometry3d& pose) {
  pose_ = pose;
  holders_.clear();
  velocity_.setZero();
  resting_ = true;
}

void RigidBody::transferState(StateArchive& archive) {
  archive.section("rigid_body").expect(name_, "the body's name");
  archive(pose_)(velocity_)(resting_)(holders_)(jaws_were_open_);
}

void RigidBody::hash(std::uint64_t& state) const {
  hashBytes(state, pose_.matrix().data(), sizeof(double) * 16);
  hashBytes(state, velocity_.data(), sizeof(double) * 3);
  hashValue(state, resting_);
  for (const Holder& holder : holders_) hashBytes(state, holder.slot.data(), holder.slot.size());
}

}  // namespace scenario
}  // namespace vrm_sim
