#pragma once
// The session result of a World (result/session_result.h): built here once, for the scenario_manager (its result
// files and session_result topic) and session_replay (the replay's result), so both report a session alike.

#include <cstdint>
#include <optional>
#include <string>

#include "vrm_sim/result/session_result.h"
#include "vrm_sim/world/world.h"

namespace vrm_sim {
namespace world {

// What the World does not know about its session.
struct ResultContext {
  std::uint32_t seed = 0;           // the session's seed (of its last LOAD, else the configured one)
  std::optional<std::string> bag;   // the session bag's path
  std::optional<std::string> user;  // the trainee
  std::string station;              // the simulator's host name
  bool in_progress = false;         // a provisional result while the scenario runs
};

result::SessionResult sessionResult(const World& world, const ResultContext& context);

}  // namespace world
}  // namespace vrm_sim
