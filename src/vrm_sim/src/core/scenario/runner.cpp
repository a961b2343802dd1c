#include "vrm_sim/scenario/runner.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "vrm_scene/scene_loader.h"

namespace vrm_sim {
namespace scenario {

const char* toString(State state) {
  switch (state) {
    case State::kIdle:
      return "idle";
    case State::kRunning:
      return "running";
    case State::kPaused:
      return "paused";
    case State::kFinished:
      return "finished";
    case State::kFailed:
      return "failed";
  }
  return "?";
}

const ScoreItem* Score::item(const std::string& name) const {
  for (const ScoreItem& entry : items) {
    if (entry.name == name) return &entry;
  }
  return nullptr;
}

double itemPoints(const scene::ScoringRule& rule, double value) {
  if (!std::isfinite(value)) return 0.0;
  const double fraction = (value - rule.worst) / (rule.best - rule.worst);
  return 100.0 * std::clamp(fraction, 0.0, 1.0);
}

namespace {

double weightedTotal(const std::vector<ScoreItem>& items) {
  double weighted = 0.0, weights = 0.0;
  for (const ScoreItem& item : items) {
    weighted += item.weight * item.points;
    weights += item.weight;
  }
  return weights > 0.0 ? weighted / weights : 0.0;
}

}  // namespace

Score computeScore(const std::vector<scene::ScoringRule>& rules, const std::vector<Measurement>& measurements) {
  Score score;
  for (const Measurement& measurement : measurements) {
    ScoreItem item{measurement.name, measurement.value, measurement.unit, 0.0, 0.0};
    for (const scene::ScoringRule& rule : rules) {
      if (rule.item != measurement.name) continue;
      item.weight = rule.weight;
      item.points = itemPoints(rule, measurement.value);
    }
    score.items.push_back(item);
  }
  score.total = weightedTotal(score.items);
  score.groups = groupScores(score.items);
  return score;
}

namespace {

// Running time is summed in integer nanoseconds of the input stamps, so it does not depend on where the stamps start
// (a session at t = 0 offline and at t = 1.7e9 live give the same elapsed time, bit for bit, when the caller passes
// the exact stamps; ScenarioRunner::nanoseconds rounds a double).

std::string seconds(double value) {
  char text[32];
  std::snprintf(text, sizeof(text), "%.1f s", value);
  return text;
}

}  // namespace

ScenarioRunner::ScenarioRunner(const scene::SceneDescription& scene) : scene_(scene) {
  if (!scene.scenario) {
    scene::SourceLocation where;
    where.file = scene.source_file;
    throw scene::SceneError(where, "the scene has no scenario section");
  }
  description_ = *scene.scenario;
  scenario_ = makeScenario(scene_);
  std::vector<Measurement> items = scenario_->items();
  items.push_back({"time", 0.0, "s"});
  items.push_back({"completed", 0.0, "1"});
  auto known = [&items](const std::string& name) {
    return std::any_of(items.begin(), items.end(), [&name](const Measurement& item) { return item.name == name; });
  };
  std::string names;
  for (const Measurement& item : items) names += (names.empty() ? "" : ", ") + item.name;
  auto check = [&](const std::string& item, const scene::SourceLocation& location) {
    if (!known(item)) {
      throw scene::SceneError(
          location, "scenario type '" + description_.type + "' has no score item '" + item + "'; its items: " + names);
    }
  };
  for (const scene::ScoringRule& rule : description_.scoring) check(rule.item, rule.location);
  for (const Measurement& item : items) {
    if (itemRole(item.name) == nullptr) {
      throw scene::SceneError(description_.type_location,
                              "scenario type '" + description_.type + "' reports item '" + item.name +
                                  "', which has no factor group (add it to itemRoles() in scenario/factor_groups.cpp)");
    }
  }
  for (const scene::FailureRule& rule : description_.fail_if) check(rule.item, rule.location);
  status_.scenario = scene.name;
  status_.type = description_.type;
  status_.difficulty = description_.difficulty;
  status_.placements = scenario_->placements();
  status_.burns = scenario_->burns();
  refreshScore();
}

ScenarioRunner::~ScenarioRunner() = default;

std::string ScenarioRunner::start(double time, std::int64_t time_ns) {
  if (status_.state == State::kRunning || status_.state == State::kPaused) {
    return "START refused: the scenario is already " + std::string(toString(status_.state)) + " (STOP or RESET first)";
  }
  if (ended()) return "START refused: the session has ended; RESET starts a new one";
  status_.state = State::kRunning;
  status_.start_time = time;
  status_.message = "started";
  last_time_ = time_ns;
  return "";
}

std::string ScenarioRunner::pause(double time, std::int64_t time_ns) {
  (void)time;
  if (status_.state != State::kRunning) {
    return "PAUSE refused: the scenario is " + std::string(toString(status_.state));
  }
  advance(time_ns);
  status_.state = State::kPaused;
  status_.message = "paused";
  refreshScore();
  return "";
}

std::string ScenarioRunner::resume(double time, std::int64_t time_ns) {
  (void)time;
  if (status_.state != State::kPaused) return "RESUME refused: the scenario is " + std::string(toString(status_.state));
  status_.state = State::kRunning;
  status_.message = "resumed";
  last_time_ = time_ns;
  return "";
}

std::string ScenarioRunner::stop(double time, std::int64_t time_ns, const std::string& reason) {
  if (status_.state != State::kRunning && status_.state != State::kPaused) {
    return "STOP refused: the scenario is " + std::string(toString(status_.state));
  }
  if (status_.state == State::kRunning) advance(time_ns);
  finish(State::kFailed, reason.empty() ? "stopped by the trainee" : reason, time);
  return "";
}

void ScenarioRunner::reset() {
  scenario_ = makeScenario(scene_);
  status_ = Status{};
  status_.scenario = scene_.name;
  status_.type = description_.type;
  status_.difficulty = description_.difficulty;
  status_.message = "reset";
  last_time_ = 0;
  elapsed_ns_ = 0;
  penalties_.reset();
  status_.placements = scenario_->placements();
  status_.burns = scenario_->burns();
  refreshScore();
}

void ScenarioRunner::finish(State state, const std::string& message, double time) {
  status_.state = state;
  status_.message = message;
  status_.end_time = time;
  refreshScore();
}

void ScenarioRunner::advance(std::int64_t now) {
  elapsed_ns_ += std::max<std::int64_t>(0, now - last_time_);
  last_time_ = std::max(last_time_, now);
  status_.elapsed = 1e-9 * static_cast<double>(elapsed_ns_);
}

void ScenarioRunner::frame(const FrameView& frame) {
  if (status_.state != State::kRunning) return;
  advance(frame.stamp_ns ? *frame.stamp_ns : nanoseconds(frame.time));
  scenario_->update(frame, status_.elapsed);
  status_.progress = scenario_->progress();
  status_.placements = scenario_->placements();
  status_.burns = scenario_->burns();
  const std::vector<ScoreItem> before = std::move(status_.score.items);
  refreshScore();
  const std::size_t events_before = status_.events.size();
  penalties_.record(
      before, status_.score.items, status_.elapsed,
      [&](const std::string& item) { return penaltyInstrument(frame, item); }, status_.events, status_.events_dropped);
  for (std::size_t i = events_before; i < status_.events.size(); ++i) {
    if (auto position = scenario_->penaltyPosition(status_.events[i].item)) status_.events[i].position = *position;
  }
  // Failure first: a frame that completes the task and crosses a failure threshold is a failed session.
  for (const scene::FailureRule& rule : description_.fail_if) {
    const ScoreItem* item = status_.score.item(rule.item);
    if (item != nullptr && item->value >= rule.at_least) {
      char value[64];
      std::snprintf(value, sizeof(value), "%g", item->value);
      finish(State::kFailed, "failed: " + rule.item + " reached " + value, frame.time);
      return;
    }
  }
  if (scenario_->succeeded()) {
    finish(State::kFinished, "task completed in " + seconds(status_.elapsed), frame.time);
    return;
  }
  if (description_.time_limit > 0.0 && status_.elapsed >= description_.time_limit) {
    status_.timed_out = true;
    finish(State::kFailed, "time limit of " + seconds(description_.time_limit) + " reached", frame.time);
  }
}

void ScenarioRunner::refreshScore() {
  std::vector<Measurement> measurements = scenario_->measurements(status_.elapsed);
  measurements.push_back({"time", status_.elapsed, "s"});
  measurements.push_back({"completed", status_.state == State::kFinished ? 1.0 : 0.0, "1"});
  status_.score = computeScore(description_.scoring, measurements);
  // A failed session earns no points for being quick: `time` only scores a completed task.
  if (status_.state == State::kFailed) {
    for (ScoreItem& item : status_.score.items) {
      if (item.name == "time") item.points = 0.0;
    }
    status_.score.total = weightedTotal(status_.score.items);
    status_.score.groups = groupScores(status_.score.items);
  }
}

// The scenario's own instrument for its instrument items (a wrong touch is the tool's); otherwise — an injury of the
// retina, which any instrument may cause — the tracked instrument whose tip is nearest the retina (the eye sphere).
const InstrumentView* ScenarioRunner::penaltyInstrument(const FrameView& frame, const std::string& item) const {
  const std::string slot = scenario_->penaltySlot(item);
  if (!slot.empty()) return frame.instrument(slot);
  const InstrumentView* nearest = nullptr;
  double clearance = 0.0;
  for (const InstrumentView& instrument : frame.instruments) {
    if (!instrument.valid || !instrument.tip.allFinite()) continue;
    const double gap = scene_.eye.radius - instrument.tip.norm();
    if (nearest == nullptr || gap < clearance) {
      nearest = &instrument;
      clearance = gap;
    }
  }
  return nearest;
}

// scene_ and description_ are the configuration the runner was built from, not state.
void ScenarioRunner::transferState(StateArchive& archive) {
  archive.section("scenario_runner");
  archive(status_)(last_time_)(elapsed_ns_)(penalties_);
  scenario_->transferState(archive);
}

void ScenarioRunner::hash(std::uint64_t& state) const {
  hashValue(state, static_cast<int>(status_.state));
  hashValue(state, elapsed_ns_);
  scenario_->hash(state);
}

}  // namespace scenario
}  // namespace vrm_sim
