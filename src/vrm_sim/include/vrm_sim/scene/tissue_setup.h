#pragma once
// A scene's tissue parameters as simulation set-up: the simulator configuration and the mass-spring membrane a
// deformable object is built as. Shared by the simulation core (world/world.h), the scene manager nodelet and the
// benchmarks.

#include <cstddef>

#include "vrm_sim/mge/membrane.h"
#include "vrm_sim/scene/scene_description.h"
#include "vrm_sim/tissue/tissue_simulator.h"

namespace vrm_sim {
namespace scene {

tissue::TissueConfig tissueConfigFor(const TissueParameters& parameters, const CollisionParameters& collision);
// Node mass spread over the object's `node_count` vertices, spring and bending stiffness.
mge::MembraneOptions membraneOptionsFor(const TissueParameters& parameters, std::size_t node_count);

}  // namespace scene
}  // namespace vrm_sim
