// The vrm_msgs constants the console uses, by name and number, in one list per message. The console links no message
// headers (its windows run against a fake link without ROS), so it mirrors the numbers; these lists are what keeps
// the mirror honest: ros_link.cpp static_asserts every entry against the generated message header, and
// test_message_constants compares each list with the .msg file itself, so a constant added to, removed from or
// renumbered in a message fails the build or the tests instead of silently shifting the console.
#pragma once

#include <cstddef>

#include "eyesi_gui/console/simulator_link.h"

namespace eyesi_gui {

struct MessageConstant {
  const char* name;  // as in the .msg file
  int value;
  const char* label;  // what the console shows (lower case), "" for commands
};

// vrm_msgs/ScenarioCommand: SimulatorLink::Command.
constexpr MessageConstant kScenarioCommandConstants[] = {{"LOAD", SimulatorLink::kLoad, ""},
                                                         {"START", SimulatorLink::kStart, ""},
                                                         {"PAUSE", SimulatorLink::kPause, ""},
                                                         {"RESUME", SimulatorLink::kResume, ""},
                                                         {"STOP", SimulatorLink::kStop, ""},
                                                         {"RESET", SimulatorLink::kReset, ""},
                                                         {"SELECT_INSTRUMENT", SimulatorLink::kSelectInstrument, ""}};

// vrm_msgs/StationStatus: StationState::State.
constexpr MessageConstant kStationStatusConstants[] = {
    {"IDLE", StationState::kIdle, "idle"},    {"LOADING", StationState::kLoading, "loading"},
    {"READY", StationState::kReady, "ready"}, {"RUNNING", StationState::kRunning, "running"},
    {"ENDED", StationState::kEnded, "ended"}, {"FAILED", StationState::kFailed, "failed"}};

// vrm_msgs/ScenarioStatus: ScenarioState::State.
constexpr MessageConstant kScenarioStatusConstants[] = {{"IDLE", ScenarioState::kIdle, "idle"},
                                                        {"RUNNING", ScenarioState::kRunning, "running"},
                                                        {"PAUSED", ScenarioState::kPaused, "paused"},
                                                        {"FINISHED", ScenarioState::kFinished, "finished"},
                                                        {"FAILED", ScenarioState::kFailed, "failed"}};

// The label of a value in one of the lists above; "unknown" for a value it does not have.
template <std::size_t N>
const char* constantLabel(const MessageConstant (&constants)[N], int value) {
  for (const MessageConstant& constant : constants) {
    if (constant.value == value) return constant.label;
  }
  return "unknown";
}

}  // namespace eyesi_gui
