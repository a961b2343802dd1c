// The scenario_manager's result JSON (written next to each bag and published as session_result) → SessionRecord,
// through the simulator's one reader (vrm_sim/result/session_result.h; schema: doc/session_result.md).
#pragma once

#include <string>

#include "eyesi_gui/records/store.h"

namespace vrm_sim::result {
struct SessionResult;
}

namespace eyesi_gui::records {

// Required: "scene", "final_state_hash", "frames"; other fields may be null or absent (unknown numbers are stored
// as 0). Throws StoreError naming `origin` and the field on malformed JSON or a field of the wrong type. Leaves id,
// recorded_at and result_path empty; user is the file's "user" field ("" when absent or null).
SessionRecord parseResultJson(const std::string& json_text, const std::string& origin);

// A result already read (the console's live result) as a record.
SessionRecord toSessionRecord(const vrm_sim::result::SessionResult& result);

}  // namespace eyesi_gui::records
