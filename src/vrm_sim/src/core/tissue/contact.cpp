#include "vrm_sim/tissue/contact.h"

#include <Eigen/Geometry>
#include <algorithm>

namespace vrm_sim {
namespace tissue {

void detectCapsuleContacts(const SystemView& system, const Capsule& capsule, const Eigen::Vector3d& velocity,
                           double shell_scale, std::vector<NodeDeformation>& contacts) {
  const Eigen::Vector3d axis = capsule.b - capsule.a;
  const double axis_length2 = axis.squaredNorm();
  const double shell = shell_scale * capsule.radius;
  const double shell2 = shell * shell;
  // A fallback normal for a node exactly on the axis: any direction perpendicular to it.
  Eigen::Vector3d fallback = axis_length2 > 0.0 ? axis.unitOrthogonal() : Eigen::Vector3d::UnitZ();
  for (std::size_t i = 0; i < system.node_count; ++i) {
    if (!system.isFree(i)) continue;
    const Eigen::Vector3d& x = system.positions[i];
    const double t = axis_length2 > 0.0 ? std::clamp((x - capsule.a).dot(axis) / axis_length2, 0.0, 1.0) : 0.0;
    const Eigen::Vector3d p = capsule.a + t * axis;  // P of eq. 5.12: the nearest point inside the tip
    const Eigen::Vector3d offset = x - p;
    const double distance2 = offset.squaredNorm();
    if (distance2 > shell2) continue;
    const double distance = std::sqrt(distance2);
    NodeDeformation contact;
    contact.node = static_cast<std::uint32_t>(i);
    contact.normal = distance > 1e-15 ? Eigen::Vector3d(offset / distance) : fallback;
    // Correction against the unscaled instrument; nodes in the shell only touch.
    contact.deformation = distance < capsule.radius ? Eigen::Vector3d((capsule.radius - distance) * contact.normal)
                                                    : Eigen::Vector3d::Zero();
    contact.instrument_velocity = velocity;
    contacts.push_back(contact);
  }
}

void applyDeformations(const SystemView& system, const std::vector<NodeDeformation>& contacts, double friction) {
  for (const NodeDeformation& contact : contacts) {
    const std::uint32_t i = contact.node;
    if (i >= system.node_count || !system.isFree(i)) continue;
    system.positions[i] += contact.deformation;
    const Eigen::Vector3d& n = contact.normal;
    const Eigen::Vector3d& vp = contact.instrument_velocity;
    const Eigen::Vector3d vp_plane = vp - vp.dot(n) * n;
    Eigen::Vector3d& v = system.velocities[i];
    const double normal_speed = v.dot(n);
    // Eq. 5.12: a node moving away keeps its velocity; one moving into the instrument loses the normal part.
    if (normal_speed > 0.0) {
      v += friction * vp_plane;
    } else {
      v = v - normal_speed * n + friction * vp_plane;
    }
    // The surface moves with the instrument along n: the node must not be slower than the instrument there.
    const double instrument_normal_speed = vp.dot(n);
    if (v.dot(n) < instrument_normal_speed && contact.deformation.squaredNorm() > 0.0) {
      v += (instrument_normal_speed - v.dot(n)) * n;
    }
  }
}

}  // namespace tissue
}  // namespace vrm_sim
