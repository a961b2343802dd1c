#pragma once
// Offline replay of a recorded session (rosrun vrm_sim session_replay): the bag's input frames (the frames the live
// session's mediator closed, in sequence; a bag recorded before them: its device inputs in stamp order through the
// mediator, with a warning) through the simulation core the scenario_manager nodelet wraps (world::Session), as fast
// as the CPU allows — cartographer_ros'
// offline node pattern: one handler path for live and recorded input, so the replay ends in the live session's
// final state hash bit for bit.

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "vrm_sim/bag/session_bag.h"
#include "vrm_sim/result/session_result.h"

namespace vrm_sim {
namespace bag {

// How the VR part is set up for a bag: from its session_info, unless overridden.
struct SessionSetup {
  std::string scene;       // what scene::loadScene takes (the recorded file if it exists, else the name)
  std::string scene_name;  // as recorded (or the override)
  std::string difficulty;
  std::string collision_detector;
  bool auto_start = true;
  std::uint32_t seed = 0;
  std::vector<std::string> warnings;  // different scene or software version, no session_info, ...
};

// Throws BagError when the bag has no session_info and no override is given.
SessionSetup resolveSession(const PreparedBag& bag, const std::string& scene_override = "");

struct ReplayResult {
  SessionSetup setup;
  std::uint64_t frames = 0;            // frames assembled
  std::uint64_t simulated_frames = 0;  // frames in which the world advanced
  std::uint64_t inputs = 0;            // input messages fed
  std::uint64_t late_inputs = 0;
  std::uint64_t rejected_inputs = 0;
  std::uint64_t frames_without_source = 0;  // frames closed while a source was silent
  std::string input;                        // "input_frame" (recorded frames) or "devices" (an older bag)
  std::uint64_t final_state_hash = 0;
  std::optional<double> score_total;  // nullopt: the scene has no scenario
  std::string scenario_state;         // idle | running | paused | finished | failed ("" without a scenario)
  double input_seconds = 0.0;         // input stamps, first to last
  double wall_seconds = 0.0;
  double speedup = 0.0;  // input_seconds / wall_seconds
  // The replay's session result, as the live session's scenario_manager writes it (world::sessionResult; bag = the
  // original bag, no user or station): a replay can be compared with, or imported like, the live result.
  std::optional<result::SessionResult> session_result;

  // One JSON object: frames, simulated_frames, final_state_hash ("0x…"), score_total (null without a scenario),
  // state, scene, difficulty, seed, inputs, late_inputs, wall_seconds, speedup, recovered_messages,
  // recovered_seconds, warnings, and the session result under "result" (doc/session_result.md).
  std::string json(const PreparedBag& bag) const;
};

// Which inputs a replay feeds: the bag's input frames when it has them (else its device topics), or its device topics
// through the mediator even when it has frames (session_replay --input devices: how a bag replayed before input
// frames existed, to compare against).
enum class ReplayInput { kAsRecorded, kDevices };

// Replays `bag`. Throws scene::SceneError for a scene that does not load, and BagError for recorded input frames with
// a gap in their sequence (a lost frame: which, and where) or for a message whose bytes do not hold its type (its
// topic and bag time).
ReplayResult replaySession(const PreparedBag& bag, const SessionSetup& setup,
                           ReplayInput input = ReplayInput::kAsRecorded);

}  // namespace bag
}  // namespace vrm_sim
