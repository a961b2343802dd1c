#pragma once
// Liveness of the VR part's inputs (issue 20): tells a user what the simulator is waiting for.
//
// The VR part advances only on input stamps (world.h), so without devices it waits silently — nothing is wrong in
// the simulation, but a user sees a graph that does nothing. The monitor classifies each expected input (eye_state,
// instrument_state, pedals, microscope) as
//   no publisher      — nobody publishes the topic (a driver or the tracking is not running),
//   silent            — a publisher exists but no message came for `silence_timeout` (a device that stopped),
//   slow              — messages arrive below `min_rate_fraction` × the expected rate over `rate_window`,
//   ok,
// with a message naming the topic and a hint where its data should come from. It reads no clock: times (s, any
// monotonic clock — the nodelet uses the wall clock, since device liveness is a wall-clock matter) are arguments.

#include <cstddef>
#include <deque>
#include <string>
#include <vector>

namespace vrm_sim {
namespace world {

struct ExpectedInput {
  std::string topic;
  double expected_rate_hz = 0.0;  // 0: on change (e.g. a console's commands): only publisher presence is checked
  std::string hint;               // where the data should come from, e.g. "the tracker (tracking:=true)"
};

struct InputMonitorOptions {
  double silence_timeout_s = 1.0;  // no message for this long with a publisher present: silent
  double rate_window_s = 2.0;      // the rate is counted over this window
  double min_rate_fraction = 0.5;  // below this fraction of the expected rate: slow
  double startup_grace_s = 2.0;    // after start: silent/slow are not reported yet (publishers connect)
};

enum class InputHealth { kOk, kNoPublisher, kSilent, kSlow, kStarting };
const char* toString(InputHealth health);

struct InputReport {
  std::string topic;
  InputHealth health = InputHealth::kStarting;
  int publishers = 0;
  double rate_hz = 0.0;            // over the rate window
  double seconds_since_last = -1;  // -1: never received
  std::size_t received = 0;
  std::string message;  // one line for the console and the diagnostics status
};

class InputMonitor {
 public:
  InputMonitor(std::vector<ExpectedInput> inputs, InputMonitorOptions options, double start_s);

  // A message on input `index` arrived at `now_s`.
  void onMessage(std::size_t index, double now_s);
  // The state of every input at `now_s`, given the current publisher count per input (same order as the inputs).
  std::vector<InputReport> evaluate(double now_s, const std::vector<int>& publisher_counts);

  const std::vector<ExpectedInput>& inputs() const { return inputs_; }

 private:
  struct State {
    std::deque<double> arrivals;  // within the rate window
    double last = -1.0;
    std::size_t received = 0;
  };
  std::vector<ExpectedInput> inputs_;
  InputMonitorOptions options_;
  double start_s_;
  std::vector<State> states_;
};

}  // namespace world
}  // namespace vrm_sim
