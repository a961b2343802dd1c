#pragma once
// The scenario's part of the session result (result/session_result.h): state, times, total and score items. Kept in
// the training layer so that what a scenario adds to its result (issue 35: factor groups, penalty events) is written
// where it is computed; world::sessionResult adds the simulation's part.

#include "vrm_sim/result/session_result.h"
#include "vrm_sim/scenario/runner.h"

namespace vrm_sim {
namespace scenario {

void writeResultFields(const Status& status, result::SessionResult* result);

}  // namespace scenario
}  // namespace vrm_sim
