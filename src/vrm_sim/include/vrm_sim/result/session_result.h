#pragma once
// The session result (issue 34): what a session leaves for the training records and for a replay to check — one
// ROS-free struct with one writer (toJson) and one reader (resultFromJson) on nlohmann-json. The scenario_manager
// writes it next to the bag and publishes it on session_result, the station rewrites it with its session's bag and
// trainee, session_replay prints the replay's, the records store and the console import it, and scripts read the same
// schema through scripts/session_result.py. The schema (every key, type, unit, since when): doc/session_result.md.
//
// Compatibility: keys are never renamed; new keys may be added (readers ignore keys they do not know, so an older
// console reads a newer simulator's result). The text keeps the format the hand-written writer had (", " and ": "
// separators, numbers to 15 significant digits, integral numbers without ".0"), so scripts that grep it, and records
// keyed by its stamps, see the same text.

#include <cstdint>
#include <limits>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

namespace vrm_sim {
namespace result {

constexpr double kUnknown = std::numeric_limits<double>::quiet_NaN();

// One row of the scenario's score table.
struct ScoreItem {
  std::string name;
  double value = kUnknown;   // in `unit`; NaN (written null): the metric had no samples
  std::string unit;          // "1" for counts, "m", "s", ...
  double weight = 0.0;       // weight in the total (0: reported, not scored)
  double points = kUnknown;  // 0..100 earned

  bool operator==(const ScoreItem& other) const;
};

// One factor group (issue 35): the weighted mean of its scored items; the groups' weighted mean is `total`.
struct GroupScore {
  std::string name;          // target_achievement | efficiency | tissue_treatment | instrument_handling | ...
  double points = kUnknown;  // 0..100
  double weight = 0.0;       // the sum of its items' weights

  bool operator==(const GroupScore& other) const;
};

// One penalty (issue 35): why points were lost.
struct PenaltyEvent {
  double time = kUnknown;                               // s of running time since the session started
  std::string kind;                                     // retina_touched, bleeding, ... (doc/session_result.md)
  std::string item;                                     // the score item it raised
  std::string slot;                                     // the instrument's slot ("" unknown)
  std::string instrument;                               // its type ("" unknown)
  double position[3] = {kUnknown, kUnknown, kUnknown};  // m, eye frame: its tip (NaN, written null: unknown)
  double points = kUnknown;                             // the drop of `total` it caused

  bool operator==(const PenaltyEvent& other) const;
};

struct SessionResult {
  std::string scene;       // required: the scene's name
  std::string scene_file;  // the scene file it was loaded from
  // The scenario part: present when the scene has a scenario (scenario.has_value()); without one the text has
  // "scenario", "difficulty", "state" null, "total" null and none of timed_out .. items.
  std::optional<std::string> scenario;    // the scenario type
  std::optional<std::string> difficulty;  // level ("" = the scenario's default)
  std::uint32_t seed = 0;
  std::optional<std::string> state;  // idle | running | paused | finished | failed | interrupted
  bool session_ended = false;        // the scenario finished/failed, or a scene without one was stopped
  bool timed_out = false;
  std::string message;       // why it ended
  double start_stamp = 0.0;  // s, input stamps (0: never started / not ended)
  double end_stamp = 0.0;
  double elapsed = kUnknown;  // s of running input time
  double total = kUnknown;    // 0..100; NaN (null) without a scenario or samples
  std::vector<ScoreItem> items;
  std::vector<GroupScore> groups;    // written with the scenario part (absent in older results: empty)
  std::vector<PenaltyEvent> events;  // at most 200, in time order
  std::uint64_t events_dropped = 0;  // penalty events beyond those
  std::string final_state_hash;      // required: "0x" + 16 hex digits (World::stateHash)
  std::uint64_t frames = 0;          // required: frames assembled
  std::uint64_t simulated_frames = 0;
  std::uint64_t late_inputs = 0;
  std::uint64_t frames_without_source = 0;
  std::uint64_t input_frames = 0;  // input frames published (their last sequence number)
  double last_frame_stamp = 0.0;   // s
  std::string software_version;
  std::optional<std::string> bag;   // the session bag (null: not recorded)
  std::optional<std::string> user;  // the trainee (null: unknown)
  std::string station;              // host name of the simulator
  bool in_progress = false;         // a provisional result, rewritten while the scenario runs
  bool interrupted = false;         // the provisional result of a session whose process died (written only if true)

  bool operator==(const SessionResult& other) const;  // NaN equals NaN: a result equals its own round trip
  bool operator!=(const SessionResult& other) const { return !(*this == other); }
};

// The one writer: a JSON object on one line, ending in "\n". NaN and infinite numbers are written as null.
std::string toJson(const SessionResult& result);

// A malformed result: what() names the source (a file path, "session_result", ...) and the key.
class ResultError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// The one reader. Required: "scene" (a non-empty string), "final_state_hash" (a string), "frames" (a non-negative
// integer). Every other key may be absent or null (its default; null numbers read as NaN); a present key of the wrong
// type is an error, and so is text that is not one JSON object (truncated, "nan" for null, ...). Unknown keys are
// ignored (forward compatibility). Throws ResultError naming `source` and the key.
SessionResult resultFromJson(const std::string& json_text, const std::string& source);

// Reads a result file (ResultError naming the path if it cannot be read or parsed).
SessionResult readResultFile(const std::string& path);

// Writes toJson(result) to path + ".tmp" and renames it to `path`: a crash mid-write leaves the previous version,
// never half a file. Throws ResultError naming the path when the file cannot be written.
void writeResultFile(const std::string& path, const SessionResult& result);

// Crash recovery: the provisional result of a session whose process died, as it is kept — not in progress,
// interrupted, and a "running" state becomes "interrupted".
SessionResult interrupted(SessionResult provisional);

// Where the interrupted provisional result at `path` (<stem>.result.json) is kept: <stem>.interrupted.result.json,
// or .interrupted-2, -3, ... when that exists.
std::string interruptedPath(const std::string& path);

}  // namespace result
}  // namespace vrm_sim
