#pragma once
// Headless runs of a scene without ROS (`rosrun vrm_sim tissue_offline`): the instruments follow their scripted
// paths (scene key instruments[].path), sampled into instrument states at `rate` Hz exactly as a device twin would
// publish them, and drive the same World the scenario_manager nodelet wraps. No wall clock enters the result, so the
// same scene, options and seed give the same final state bit for bit — and the same state as the graph given the same
// input sequence (test/graph/core_equivalence). The wall clock only measures the cost.

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "vrm_scene/scene_description.h"
#include "vrm_sim/result/session_result.h"
#include "vrm_sim/world/world.h"

namespace vrm_sim {
namespace world {

struct OfflineOptions {
  double seconds = 1.0;    // simulated time
  double rate = 50.0;      // Hz: input ticks (the scripted surgeon's and the tracker's rate)
  std::string integrator;  // empty: each object's scene integrator
  double dt = 0.0;         // s; 0: each object's scene dt
  std::string detector;    // empty: the scene's collision detectors
  // 0: the scene as written. Otherwise every free node starts displaced by a reproducible pseudo-random offset of at
  // most 1 µm per axis (SplitMix64 of the seed), e.g. to test how sensitive a result is to the initial state.
  std::uint64_t seed = 0;
};

struct OfflineTissueResult {
  std::string object;
  std::uint64_t topology_version = 1;
  std::uint64_t torn_springs = 0;
  std::uint64_t released_adhesions = 0;
  double max_lift = 0.0;
  PeelOutcome outcome = PeelOutcome::kUntouched;
};

struct OfflineResult {
  bool stable = true;  // every node finite, no step the watchdog could not recover
  std::uint64_t frames = 0;
  std::uint64_t steps = 0;    // integration steps, summed over the objects
  double ms_per_step = 0.0;   // wall time of the tissue stages per step (measurement only)
  double ms_per_frame = 0.0;  // mean wall time of a whole frame (collision, tissue, bleeding)
  double ms_per_frame_max = 0.0;
  double max_strain = 0.0;  // max |d|/l over all springs after any frame
  std::size_t max_grasped_nodes = 0;
  double energy_drift = 0.0;    // J: total energy (kinetic + potential) at the end minus at the start
  std::uint64_t fallbacks = 0;  // watchdog rollbacks
  // Per deformable object "<object>: <integrator>" as in use at the end (with "auto" the one it chose).
  std::vector<std::string> integrator_chosen;
  std::size_t retina_contacts = 0;
  double max_injury = 0.0;
  std::vector<OfflineTissueResult> tissues;
  std::uint64_t final_state_hash = 0;

  // One JSON object with the fields above (the hash as a "0x…" hex string: JSON numbers lose 64-bit integers).
  std::string json() const;
};

// The instrument states the scene's scripted paths produce: one per scripted instrument every 1/rate s from t = 0 to
// `seconds` (inclusive), stamps from `start`, poses in the eye frame. Throws std::invalid_argument for a bad rate.
std::vector<InstrumentState> scriptedInputs(const scene::SceneDescription& scene, double rate, double seconds,
                                            Stamp start = 0);

// The scripted instruments' states at path time t, stamped `stamp`.
std::vector<InstrumentState> scriptedInputsAt(const scene::SceneDescription& scene, double t, Stamp stamp);

// Runs `scene` for options.seconds. Throws scene::SceneError for a scene the simulation cannot run (no deformable
// object, an unknown integrator) and std::invalid_argument for bad options.
OfflineResult runOffline(const scene::SceneDescription& scene, const OfflineOptions& options);

// JSON pieces of the tools' output lines and the session result file: a quoted, escaped string, and a 64-bit hash as
// "0x" + 16 hex digits (JSON numbers lose 64-bit integers).
std::string jsonString(const std::string& text);
std::string hashString(std::uint64_t hash);

// ---- scenario sessions (rosrun vrm_sim scenario_offline) ----

struct ScenarioRunOptions {
  std::string script = "expert";                      // a scripted session of the scene's scenario (scenario.scripts)
  std::optional<scene::ScriptedSession> script_file;  // set: this script instead (a script file, loadScript)
  double rate = 50.0;                                 // Hz: input ticks
  double grace = 5.0;      // s after the script's last waypoint (instruments hold still) before the run ends
  std::uint32_t seed = 0;  // recorded with the result (the scenario layer draws no random numbers)
  std::string detector;    // empty: the scene's collision detectors
};

struct ScenarioRunResult {
  std::string scenario, type, difficulty, script;
  std::string state;  // finished | failed | timeout (time limit, or the script ended without an outcome)
  std::string message;
  scenario::Score score;
  std::uint32_t seed = 0;
  std::uint64_t frames = 0;
  std::uint64_t final_state_hash = 0;
  double sim_seconds = 0.0;   // running time of the scenario
  double wall_seconds = 0.0;  // the whole run (measurement only)
  // Mean CPU (wall) ms per frame, in total and by stage; which stages ran at all.
  double ms_per_frame = 0.0, ms_scenario = 0.0, ms_tissue = 0.0, ms_collision = 0.0, ms_bleeding = 0.0;
  double ms_per_frame_max = 0.0;         // the worst frame
  std::vector<std::string> simulations;  // "tissue", "collision", "bleeding", "scenario" (stages that ran)
  // The run's session result, as a live session's scenario_manager writes it (world::sessionResult).
  std::optional<result::SessionResult> session_result;

  // One JSON object (scenario_offline's output line; the hash as a "0x…" string), with the session result under
  // "result" (doc/session_result.md).
  std::string json() const;
};

// Plays the scene's scripted session through the simulation core and its scenario, from START to the end of the
// scenario (finished / failed) or grace seconds after the script's last waypoint. Throws scene::SceneError for a
// scene without a scenario and std::invalid_argument for an unknown script or bad options.
ScenarioRunResult runScenario(const scene::SceneDescription& scene, const ScenarioRunOptions& options);

}  // namespace world
}  // namespace vrm_sim
