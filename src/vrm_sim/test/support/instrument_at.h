#pragma once
// A test input: an instrument state of `slot` with its tip at `tip` (eye frame), its shaft through its trocar as the
// scripted instruments hold it (x any normal of the shaft: the tests need no roll).
#include <Eigen/Geometry>
#include <string>

#include "vrm_scene/scene_description.h"
#include "vrm_sim/world/inputs.h"

namespace vrm_sim {
namespace testing_support {

inline world::InstrumentState instrumentAt(const scene::SceneDescription& scene, const std::string& slot,
                                           const Eigen::Vector3d& tip, double jaw_angle, world::Stamp stamp) {
  const scene::Trocar* trocar = scene.findTrocar(slot);
  const Eigen::Vector3d z = (tip - trocar->position_in_eye).normalized();
  const Eigen::Vector3d x = z.unitOrthogonal();
  world::InstrumentState state;
  state.stamp = stamp;
  state.slot = slot;
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.linear().col(0) = x;
  pose.linear().col(1) = z.cross(x);
  pose.linear().col(2) = z;
  pose.translation() = tip;
  state.setPose(pose);
  state.jaw_angle = jaw_angle;
  return state;
}

}  // namespace testing_support
}  // namespace vrm_sim
