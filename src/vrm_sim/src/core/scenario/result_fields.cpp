#include "vrm_sim/scenario/result_fields.h"

namespace vrm_sim {
namespace scenario {

void writeResultFields(const Status& status, result::SessionResult* result) {
  result->scenario = status.type;
  result->difficulty = status.difficulty;
  result->state = toString(status.state);
  result->timed_out = status.timed_out;
  result->message = status.message;
  result->start_stamp = status.start_time.value_or(0.0);
  result->end_stamp = status.end_time.value_or(0.0);
  result->elapsed = status.elapsed;
  result->total = status.score.total;
  for (const ScoreItem& item : status.score.items) {
    result->items.push_back({item.name, item.value, item.unit, item.weight, item.points});
  }
  for (const GroupScore& group : status.score.groups)
    result->groups.push_back({group.name, group.points, group.weight});
  for (const PenaltyEvent& event : status.events) {
    result::PenaltyEvent row;
    row.time = event.time;
    row.kind = event.kind;
    row.item = event.item;
    row.slot = event.slot;
    row.instrument = event.instrument;
    for (int axis = 0; axis < 3; ++axis) row.position[axis] = event.position[axis];
    row.points = event.points;
    result->events.push_back(std::move(row));
  }
  result->events_dropped = status.events_dropped;
}

}  // namespace scenario
}  // namespace vrm_sim
