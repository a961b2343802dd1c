#include "rigid_object_params.h"

namespace vrm_sim {
namespace scenario {

RigidBodyOptions bodyOptions(const scene::SceneDescription& scene, Params& params) {
  RigidBodyOptions options;
  options.eye_radius = scene.eye.radius;
  options.grasp_reach = params.number("grasp_reach", 4e-4, 0.0, 3e-3);
  options.grasp_angle = params.number("grasp_angle_deg", 8.0, 0.5, 90.0) * kDegree;
  options.gravity = params.number("gravity", 9.81, 0.0, 100.0);
  options.drag = params.number("drag", 30.0, 0.0, 1e4);
  return options;
}

}  // namespace scenario
}  // namespace vrm_sim
