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

// vrm_msgs/InstrumentTypes (issue 37: every instrument type; a type's name in the scene files is its constant's name in
// lower case, e.g. LASER_PROBE <-> laser_probe).
constexpr MessageConstant kInstrumentTypeConstants[] = {
    {"LIGHT_PIPE", 0, "light pipe"}, {"FORCEPS", 1, "forceps"}, {"VITRECTOR", 2, "vitrector"},
    {"NEEDLE", 3, "needle"},         {"HOOK", 4, "hook"},       {"LASER_PROBE", 5, "laser probe"}};

// The label of an instrument type by its scene name ("laser_probe" -> "laser probe"); nullptr for a name the list
// does not have.
inline const char* instrumentTypeLabel(const char* type_name) {
  for (const MessageConstant& constant : kInstrumentTypeConstants) {
    const char* a = constant.name;
    const char* b = type_name;
    while (*a != '\0' && *b != '\0' && (*a >= 'A' && *a <= 'Z' ? *a - 'A' + 'a' : *a) == *b) ++a, ++b;
    if (*a == '\0' && *b == '\0') return constant.label;
  }
  return nullptr;
}

// The label of a value in one of the lists above; "unknown" for a value it does not have.
template <std::size_t N>
const char* constantLabel(const MessageConstant (&constants)[N], int value) {
  for (const MessageConstant& constant : constants) {
    if (constant.value == value) return constant.label;
  }
  return "unknown";
}

}  // namespace eyesi_gui
