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
}

}  // namespace scenario
}  // namespace vrm_sim
