// Session result files (vrm_sim result/session_result.h): arbitrary text through the one reader the records store,
// the console and the station use. It either reads a result or refuses with a ResultError naming the key; a result
// it reads is written back by the one writer, and that text reads back to the same text (the writer's 15 significant
// digits make the second write a fixed point). Anything else escapes as an exception: a finding.
#include <stdexcept>

#include "fuzz_target.h"
#include "vrm_sim/result/session_result.h"

VRM_FUZZ_TARGET(session_result_json) {
  using namespace vrm_sim::result;
  const std::string text(reinterpret_cast<const char*>(data), size);
  SessionResult result;
  try {
    result = resultFromJson(text, "fuzzed.result.json");
  } catch (const ResultError&) {
    return 0;  // a clear rejection is the expected outcome for most inputs
  }
  const std::string written = toJson(result);
  const std::string rewritten = toJson(resultFromJson(written, "rewritten"));  // a ResultError here is a finding too
  if (toJson(resultFromJson(rewritten, "rewritten twice")) != rewritten) {
    throw std::logic_error("the session result text is not a fixed point of read + write: " + rewritten);
  }
  return 0;
}
