#include "eyesi_gui/records/result_json.h"

#include <cmath>

#include "vrm_sim/result/session_result.h"

namespace eyesi_gui::records {
namespace {

// The store keeps 0 for a number the result does not know (null: a metric without samples): its columns are REAL
// NOT NULL, and SQLite would store a NaN as NULL.
double known(double value) { return std::isfinite(value) ? value : 0.0; }

}  // namespace

SessionRecord toSessionRecord(const vrm_sim::result::SessionResult& result) {
  SessionRecord s;
  s.scene = result.scene;
  s.scenario = result.scenario.value_or("");
  s.difficulty = result.difficulty.value_or("");
  s.seed = result.seed;
  s.state = result.state.value_or("");
  s.passed = s.state == "finished";
  s.message = result.message;
  s.start_stamp = known(result.start_stamp);
  s.end_stamp = known(result.end_stamp);
  s.elapsed = known(result.elapsed);
  s.total = known(result.total);
  s.final_state_hash = result.final_state_hash;
  s.frames = result.frames;
  s.software_version = result.software_version;
  s.bag_path = result.bag.value_or("");
  s.user = result.user.value_or("");
  s.station = result.station;
  for (const vrm_sim::result::ScoreItem& item : result.items) {
    s.items.push_back({item.name, known(item.value), item.unit, known(item.weight), known(item.points)});
  }
  for (const vrm_sim::result::GroupScore& group : result.groups) {
    s.groups.push_back({group.name, known(group.points), known(group.weight)});
  }
  for (const vrm_sim::result::PenaltyEvent& event : result.events) {
    PenaltyEventRecord e;
    e.time = known(event.time);
    e.kind = event.kind;
    e.item = event.item;
    e.slot = event.slot;
    e.instrument = event.instrument;
    for (int axis = 0; axis < 3; ++axis) e.position[axis] = event.position[axis];  // NaN kept: stored as NULL
    e.points = known(event.points);
    s.events.push_back(std::move(e));
  }
  s.events_dropped = result.events_dropped;
  return s;
}

SessionRecord parseResultJson(const std::string& json_text, const std::string& origin) {
  try {
    return toSessionRecord(vrm_sim::result::resultFromJson(json_text, origin));
  } catch (const vrm_sim::result::ResultError& error) {
    throw StoreError(error.what());
  }
}

}  // namespace eyesi_gui::records
