// The scenario_manager's result JSON (written next to each bag and published as session_result) → SessionRecord.
#pragma once

#include <string>

#include "eyesi_gui/records/store.h"

namespace eyesi_gui::records {

// Fields may be null or absent except "scene" (a non-empty string). Throws StoreError naming `origin` and the field
// on malformed JSON or a field of the wrong type. Leaves id, recorded_at and result_path empty; user is the file's
// "user" field ("" when absent or null).
SessionRecord parseResultJson(const std::string& json_text, const std::string& origin);

}  // namespace eyesi_gui::records
