#pragma once
// Headless runs of a scene's tissue simulation without ROS (issue 3: `rosrun vrm_sim tissue_offline`): every
// deformable object of the scene is simulated with its scene parameters while the instruments follow their scripted
// paths (scene key instruments[].path). No wall clock enters the simulation (every frame runs all its steps), so the
// same scene, options and seed give the same final state bit for bit; the wall clock only measures ms_per_step.

#include <cstdint>
#include <string>

#include "vrm_sim/mge/membrane.h"
#include "vrm_sim/scene/scene_description.h"
#include "vrm_sim/tissue/tissue_simulator.h"

namespace vrm_sim {
namespace tissue {

struct OfflineOptions {
  double seconds = 1.0;    // simulated time
  std::string integrator;  // empty: each object's scene integrator
  double dt = 0.0;         // s; 0: each object's scene dt
  double frame = 1e-3;     // s of simulated time per advance() (the instrument poses update per frame)
  // 0: the scene as written. Otherwise every free node starts displaced by a reproducible pseudo-random offset of at
  // most 1 µm per axis (SplitMix64 of the seed), e.g. to test how sensitive a result is to the initial state.
  std::uint64_t seed = 0;
};

struct OfflineResult {
  bool stable = true;           // every node finite, no step the watchdog could not recover
  std::uint64_t steps = 0;      // integration steps, summed over the objects
  double ms_per_step = 0.0;     // wall time per step (measurement only)
  double max_strain = 0.0;      // max |d|/l over all springs after any frame
  double energy_drift = 0.0;    // J: total energy (kinetic + potential) at the end minus at the start
  std::uint64_t fallbacks = 0;  // watchdog rollbacks
  std::uint64_t final_state_hash = 0;

  // One JSON object with the fields above (the hash as a "0x…" hex string: JSON numbers lose 64-bit integers).
  std::string json() const;
};

// Runs `scene` for options.seconds. Throws scene::SceneError for a scene the simulation cannot run (no deformable
// object, an unknown integrator) and std::invalid_argument for bad options.
OfflineResult runOffline(const scene::SceneDescription& scene, const OfflineOptions& options);

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
