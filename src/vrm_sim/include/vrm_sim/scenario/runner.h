#pragma once
// A scenario session (thesis §2.3): the state machine IDLE -> RUNNING <-> PAUSED -> FINISHED | FAILED around one
// Scenario, its running time (pauses excluded; input stamps only), the time limit, the failure rules (`fail_if`) and
// the score (`scoring`: every item linear between its best and worst value, weighted mean 0..100).
//
// Items every scenario reports besides its own: time (s, running; scores nothing for a failed session), completed (1
// once FINISHED, else 0).

#include <cmath>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "vrm_sim/scenario/factor_groups.h"
#include "vrm_sim/scenario/scenario.h"

namespace vrm_sim {
namespace scenario {

enum class State { kIdle, kRunning, kPaused, kFinished, kFailed };
const char* toString(State state);  // idle, running, paused, finished, failed

struct ScoreItem {
  std::string name;
  double value = 0.0;
  std::string unit;
  double weight = 0.0;  // 0: reported, not scored
  double points = 0.0;  // 0..100 for this item

  void transferState(StateArchive& archive) { archive(name)(value)(unit)(weight)(points); }
};

struct Score {
  double total = 0.0;  // 0..100
  std::vector<ScoreItem> items;
  std::vector<GroupScore> groups;  // factor groups (factor_groups.h): their weighted mean is `total`
  const ScoreItem* item(const std::string& name) const;
  // Saved although refreshScore() could recompute it: the next frame's penalty record compares against these items.
  void transferState(StateArchive& archive) { archive(total)(items)(groups); }
};

// Points of one value under one rule: 100 at best, 0 at worst, linear and clamped in between.
double itemPoints(const scene::ScoringRule& rule, double value);
Score computeScore(const std::vector<scene::ScoringRule>& rules, const std::vector<Measurement>& measurements);

struct Status {
  std::string scenario;    // the scene's name
  std::string type;        // the scenario type
  std::string difficulty;  // level name ("" = none)
  State state = State::kIdle;
  double elapsed = 0.0;  // s running
  bool timed_out = false;
  std::string message;                         // why it ended, or the last refused command
  std::string progress;                        // the scenario's own one-liner
  std::optional<double> start_time, end_time;  // s, input stamps
  Score score;
  std::vector<PenaltyEvent> events;  // why points were lost (factor_groups.h: PenaltyLog), at most kMaxEvents
  std::size_t events_dropped = 0;    // penalty events beyond those
  std::vector<ObjectPlacement>
      placements;                // the objects the scenario moves, after the last frame (Scenario::placements)
  std::vector<LaserBurn> burns;  // the laser burns so far (Scenario::burns)

  // The names come from the scene: a checkpoint of another scene, scenario type or difficulty level is refused.
  void transferState(StateArchive& archive) {
    archive.section("status");
    archive.expect(scenario, "the scene name").expect(type, "the scenario type").expect(difficulty, "the difficulty");
    archive(state)(elapsed)(timed_out)(message)(progress)(start_time)(end_time)(score)(events)(events_dropped);
    archive(placements)(burns);
  }
};

class ScenarioRunner {
 public:
  // Throws scene::SceneError for a scenario that cannot run (see makeScenario) or a scoring / failure rule naming
  // an item the type does not report.
  explicit ScenarioRunner(const scene::SceneDescription& scene);
  ~ScenarioRunner();

  // Commands at input time `time` (s). Each returns "" when applied, else why not (the state is then unchanged).
  // With `time_ns`, the exact input stamp (the World passes it): the running time is counted from it, not from the
  // double `time`, which cannot hold an epoch stamp to the nanosecond (1.8e9 s is 256 ns apart from its neighbours),
  // so sessions at different wall times count the same running time and hash alike.
  std::string start(double time) { return start(time, nanoseconds(time)); }
  std::string start(double time, std::int64_t time_ns);
  std::string pause(double time) { return pause(time, nanoseconds(time)); }
  std::string pause(double time, std::int64_t time_ns);
  std::string resume(double time) { return resume(time, nanoseconds(time)); }
  std::string resume(double time, std::int64_t time_ns);
  // Ends a running or paused session as failed; `reason` is its message ("" = "stopped by the trainee").
  std::string stop(double time, const std::string& reason = "") { return stop(time, nanoseconds(time), reason); }
  std::string stop(double time, std::int64_t time_ns, const std::string& reason);
  static std::int64_t nanoseconds(double time) { return static_cast<std::int64_t>(std::llround(time * 1e9)); }
  void reset();  // back to IDLE with a fresh scenario (the world resets its tissues alongside)
  // A note for the trainee in status().message, e.g. why a command was refused (the state is unchanged).
  void setMessage(const std::string& message) { status_.message = message; }

  // One simulation frame: advances time, measurements, success and failure while RUNNING; nothing otherwise.
  void frame(const FrameView& frame);

  const Status& status() const { return status_; }
  bool running() const { return status_.state == State::kRunning; }
  bool ended() const { return status_.state == State::kFinished || status_.state == State::kFailed; }
  void hash(std::uint64_t& state) const;
  // Saves or loads the session (status, running time, penalty episodes) and the scenario's state (issue 39 §1). Load
  // into a runner built from the same scene; a failed load leaves it half loaded, so load into a fresh one.
  void transferState(StateArchive& archive);
  const scene::ScenarioDescription& description() const { return description_; }

 private:
  void refreshScore();
  void advance(std::int64_t time_ns);
  void finish(State state, const std::string& message, double time);
  const InstrumentView* penaltyInstrument(const FrameView& frame, const std::string& item) const;

  scene::SceneDescription scene_;
  scene::ScenarioDescription description_;
  std::unique_ptr<Scenario> scenario_;
  Status status_;
  std::int64_t last_time_ = 0;   // ns: input time up to which `elapsed` counts
  std::int64_t elapsed_ns_ = 0;  // running time
  PenaltyLog penalties_;         // not hashed: derived from the score items, it never feeds back into the simulation
};

}  // namespace scenario
}  // namespace vrm_sim
