#pragma once
// Rigid objects the forceps move in the abstract manipulation scenarios (thesis §7.4.1: spheres, boxes, rings,
// key-and-lock; issue 36): a body is grasped by closing the jaws at it, follows the holding jaws rigidly (position
// and orientation, the offset fixed at the grasp), can be held by two forceps at once and passed from one to the
// other, and when let go falls through the vitreous under gravity with viscous drag and comes to rest lying flat on
// the retina (the eye sphere). ROS-free, eye frame, SI units; exact references in test/unit/test_rigid_body.cpp.
//
// Why not a rigid-body solver: inside the eye nothing bounces or tumbles at these speeds (drag 30 1/s: a body reaches
// its terminal speed within 0.1 s), so "falls along gravity, then lies on its flattest face" is the observable
// behaviour, and it keeps a frame's cost at a few hundred flops.

#include <Eigen/Geometry>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "vrm_sim/scenario/scenario.h"
#include "vrm_sim/state/state_archive.h"

namespace vrm_sim {
namespace scenario {

// The pose of a body lying on the inside of a sphere of `sphere_radius` (centred at the origin) below `pose`: of the
// body's local axes listed in `resting_axes` (0 = x, 1 = y, 2 = z; each axis with both signs), the face whose normal
// points most towards the wall is turned onto it with the smallest rotation (the body keeps its yaw about the wall
// normal) and the body is moved along the wall normal through its position until that face touches the wall
// (`half_extents` along each local axis).
Eigen::Isometry3d restOnSphere(const Eigen::Isometry3d& pose, const Eigen::Vector3d& half_extents,
                               const std::vector<int>& resting_axes, double sphere_radius);

struct RigidBodyOptions {
  Eigen::Vector3d half_extents = Eigen::Vector3d::Constant(2e-4);  // m, along the body's local axes
  std::vector<int> resting_axes = {0, 1, 2};                       // faces it can lie on (a ring: only z)
  double grasp_reach = 3e-4;  // m: the jaws grasp with the tip within this distance of the body's centre
  double grasp_angle = 0.14;  // rad: jaws below this are closed
  double gravity = 9.81;      // m/s^2 (world -z)
  double drag = 30.0;         // 1/s
  double eye_radius = 0.012;  // m: the retina the body falls onto
};

class RigidBody {
 public:
  RigidBody(std::string name, const Eigen::Isometry3d& pose, RigidBodyOptions options);

  // One frame of the forceps in `slots` (each: grasp, hold or release). Returns the slots that let go of the body this
  // frame while no other forceps held it (it falls from there). A grasp needs the jaws open in the slot's previous
  // frame and closing now, with the tip within grasp_reach of the centre; an instrument that is not valid lets go.
  std::vector<std::string> update(const FrameView& frame, const std::vector<std::string>& slots);
  // Falls (not held, not resting) for the frame's dt; returns true when it lands on the retina in this frame.
  bool fall(const FrameView& frame);

  // The scenario puts the body somewhere (placed on a target, slid down a post): held by nobody, at rest there.
  void place(const Eigen::Isometry3d& pose);

  const std::string& name() const { return name_; }
  const Eigen::Isometry3d& pose() const { return pose_; }
  Eigen::Vector3d centre() const { return pose_.translation(); }
  bool held() const { return !holders_.empty(); }
  bool heldBy(const std::string& slot) const;
  // The forceps that moves the body (the first that still holds it); "" when not held.
  std::string holder() const { return holders_.empty() ? "" : holders_.front().slot; }
  std::size_t holderCount() const { return holders_.size(); }
  bool resting() const { return resting_; }
  const RigidBodyOptions& options() const { return options_; }
  ObjectPlacement placement() const { return {name_, pose_}; }
  void hash(std::uint64_t& state) const;
  // The grasp offsets and the jaws' last opening are not hashed but decide the next frames (where a held body goes,
  // whether closing jaws grasp). The name and options are the scene's.
  void transferState(StateArchive& archive);

 private:
  struct Holder {
    std::string slot;
    Eigen::Isometry3d instrument_from_body;  // fixed at the grasp
    void transferState(StateArchive& archive) { archive(slot)(instrument_from_body); }
  };
  static Eigen::Isometry3d instrumentPose(const InstrumentView& tool);

  std::string name_;
  Eigen::Isometry3d pose_;
  RigidBodyOptions options_;
  Eigen::Vector3d velocity_ = Eigen::Vector3d::Zero();
  bool resting_ = true;
  std::vector<Holder> holders_;
  std::vector<std::pair<std::string, bool>> jaws_were_open_;  // per slot seen
};

}  // namespace scenario
}  // namespace vrm_sim
