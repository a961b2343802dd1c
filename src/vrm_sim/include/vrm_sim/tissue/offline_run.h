#pragma once
// Scene -> tissue simulation helpers shared by the simulation core (world/world.h), its offline driver
// (world/offline.h) and the benchmarks: simulator configuration and membrane options from the scene's parameters,
// the instruments' tissue-side shapes, scripted instrument paths and the state hash.

#include <cstdint>
#include <string>

#include "vrm_sim/mge/membrane.h"
#include "vrm_sim/scene/scene_description.h"
#include "vrm_sim/tissue/tissue_simulator.h"

namespace vrm_sim {
namespace tissue {

// FNV-1a (64 bit) over `bytes` bytes, continuing from `hash`.
std::uint64_t hashBytes(std::uint64_t hash, const void* data, std::size_t bytes);
// FNV-1a (64 bit) over the bit patterns of all node positions and velocities, in slot order; continues from `hash`
// so several membranes chain into one value.
std::uint64_t stateHash(mge::Membrane& membrane, std::uint64_t hash = 14695981039346656037ull);

// The scene's tissue parameters as simulator configuration (shared by the offline driver and the tissue_sim
// nodelet's needs).
TissueConfig tissueConfigFor(const scene::TissueParameters& parameters, const scene::CollisionParameters& collision);
// The mass-spring membrane a deformable scene object is built as (node mass spread over its `node_count` vertices,
// spring and bending stiffness); shared by the scene manager, the tissue nodelet and the offline driver.
mge::MembraneOptions membraneOptionsFor(const scene::TissueParameters& parameters, std::size_t node_count);
// The instrument's tissue-side shape: a capsule along the shaft; the forceps grasp with their jaws instead.
InstrumentInput instrumentInputFor(const scene::InstrumentDescription& description);
// The scripted pose (tip and shaft direction from the trocar, in the eye frame) and jaw angle [rad] at time t; the
// path is held at its ends. Requires a non-empty path.
InstrumentInput scriptedInstrument(const scene::SceneDescription& scene,
                                   const scene::InstrumentDescription& description, double t);

}  // namespace tissue
}  // namespace vrm_sim
