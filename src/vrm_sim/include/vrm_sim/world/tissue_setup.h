#pragma once
// A scene's tissue parameters as simulation set-up: the names it chose checked against the physics' registries, the
// simulator configuration and the mass-spring membrane a deformable object is built as. Shared by the simulation core
// (world/world.h), the scene manager nodelet and the benchmarks.

#include <cstddef>

#include "vrm_scene/scene_description.h"
#include "vrm_sim/mge/membrane.h"
#include "vrm_sim/tissue/tissue_simulator.h"

namespace vrm_sim {
namespace world {

// Every object's tissue model, integrator and collision detector is one its registry knows (tissue::
// tissueModelRegistry, tissue::integratorRegistry, collision::detectorRegistry). The scene loader reads them as text
// (the floor links no physics); this check, run where the World is built, throws scene::SceneError at the name's
// file:line:col, "expected one of ..., got 'x' (did you mean 'y'?)", as the loader does for its own choices.
void checkSimulationNames(const scene::SceneDescription& scene);

tissue::TissueConfig tissueConfigFor(const scene::TissueParameters& parameters,
                                     const scene::CollisionParameters& collision);
// Node mass spread over the object's `node_count` vertices, spring and bending stiffness.
mge::MembraneOptions membraneOptionsFor(const scene::TissueParameters& parameters, std::size_t node_count);

}  // namespace world
}  // namespace vrm_sim
