#pragma once
// Collision response from deformation vectors (thesis §5.1, Fig. 5.1, eq. 5.12). The collision library reports,
// per touched node, the vector that moves it out of the instrument; until it lands, an exact capsule / sphere test
// produces the same records. ε-shell: detection against the instrument scaled by ~1.05, correction against the
// unscaled geometry, so nodes in the shell "touch" (get the velocity correction) without being moved — which stops
// the in/out oscillation at the surface.

#include <Eigen/Core>
#include <cstdint>
#include <vector>

#include "vrm_sim/state/state_archive.h"
#include "vrm_sim/tissue/system.h"

namespace vrm_sim {
namespace tissue {

struct NodeDeformation {
  std::uint32_t node = 0;
  Eigen::Vector3d deformation = Eigen::Vector3d::Zero();          // m; zero for a node inside the shell only
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();              // n_i of eq. 5.12: from P inside the tip to the node
  Eigen::Vector3d instrument_velocity = Eigen::Vector3d::Zero();  // v_P, m/s
  void transferState(StateArchive& archive) { archive(node)(deformation)(normal)(instrument_velocity); }
};

// Segment a–b swept by a sphere of `radius` (a == b: a sphere).
struct Capsule {
  Eigen::Vector3d a = Eigen::Vector3d::Zero();
  Eigen::Vector3d b = Eigen::Vector3d::Zero();
  double radius = 0.0;
};

// Appends one record per free node within shell_scale·radius of the capsule.
void detectCapsuleContacts(const SystemView& system, const Capsule& capsule, const Eigen::Vector3d& velocity,
                           double shell_scale, std::vector<NodeDeformation>& contacts);

// Moves each free node by its deformation vector and applies the velocity correction of eq. 5.12 with friction
// f_R in [0, 1]: v = v_i + f_R·v_P,E when the node moves away from the instrument (v_i·n_i > 0), else
// v_i,E + f_R·v_P,E (E = plane through the node perpendicular to n_i).
void applyDeformations(const SystemView& system, const std::vector<NodeDeformation>& contacts, double friction);

}  // namespace tissue
}  // namespace vrm_sim
