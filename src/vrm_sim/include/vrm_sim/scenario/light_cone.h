#pragma once
// The one rule for "lit by the light pipe" (issue 33): the scenarios that score illumination (navigation's touches,
// the surgical scenarios' work outside the cone) and the renderer's light pipe cone agree on what the cone is.
// ROS-free, header-only.

#include <Eigen/Core>
#include <cmath>

namespace vrm_sim {
namespace scenario {

// Default half-angle of the light pipe's cone, degrees. The renderer's light pipe (vrm_render LightPipe,
// cone_half_angle_rad 0.6 = 34.4 deg with cone_softness 0.6: smoothstep from the outer edge to 0.24 rad = 13.8 deg)
// has faded to about half its centre intensity at 25 deg (smoothstep 0.58): inside it the work is visibly lit.
constexpr double kLightConeHalfAngleDeg = 25.0;

// cos of a cone half-angle given in degrees (the form litByLightPipe() takes).
inline double lightConeCos(double half_angle_deg) { return std::cos(half_angle_deg * 3.14159265358979323846 / 180.0); }

// True when `point` lies inside the cone of a light pipe whose tip is at `light_tip` and which shines along
// `light_axis` (InstrumentView::axis: from the handle towards the tip, i.e. tip->forward; unit length expected,
// any non-zero length accepted): the angle between the axis and the direction tip->point is within the half-angle
// whose cosine is `cone_cos`. Not lit: a point behind the tip, at the tip itself (no direction), a zero or
// non-finite axis, or non-finite positions — a light pipe whose pose is unknown lights nothing.
inline bool litByLightPipe(const Eigen::Vector3d& light_tip, const Eigen::Vector3d& light_axis,
                           const Eigen::Vector3d& point, double cone_cos) {
  if (!light_tip.allFinite() || !light_axis.allFinite() || !point.allFinite()) return false;
  const double axis_length = light_axis.norm();
  const Eigen::Vector3d to_point = point - light_tip;
  const double distance = to_point.norm();
  if (!(axis_length > 0.0) || !(distance > 0.0)) return false;
  // A unit axis (every InstrumentView's) is used as it is, so navigation scores exactly as before the rule moved here.
  const double scale = axis_length == 1.0 ? distance : distance * axis_length;
  return light_axis.dot(to_point) / scale >= cone_cos;
}

}  // namespace scenario
}  // namespace vrm_sim
