#include "vrm_sim/world/input_monitor.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <utility>

namespace vrm_sim {
namespace world {

const char* toString(InputHealth health) {
  switch (health) {
    case InputHealth::kOk:
      return "ok";
    case InputHealth::kNoPublisher:
      return "no publisher";
    case InputHealth::kSilent:
      return "silent";
    case InputHealth::kSlow:
      return "slow";
    case InputHealth::kStarting:
      return "starting";
  }
  return "unknown";
}

InputMonitor::InputMonitor(std::vector<ExpectedInput> inputs, InputMonitorOptions options, double start_s)
    : inputs_(std::move(inputs)), options_(options), start_s_(start_s), states_(inputs_.size()) {
  if (!(options_.rate_window_s > 0.0) || !(options_.silence_timeout_s > 0.0)) {
    throw std::invalid_argument("input monitor: rate_window and silence_timeout must be positive");
  }
  for (const ExpectedInput& input : inputs_) {
    if (input.topic.empty()) throw std::invalid_argument("input monitor: an input without a topic");
    if (!(input.expected_rate_hz >= 0.0) || !std::isfinite(input.expected_rate_hz)) {
      throw std::invalid_argument("input monitor: " + input.topic + ": expected rate must be >= 0");
    }
  }
}

void InputMonitor::onMessage(std::size_t index, double now_s) {
  State& state = states_.at(index);
  state.last = now_s;
  ++state.received;
  state.arrivals.push_back(now_s);
  while (!state.arrivals.empty() && state.arrivals.front() < now_s - options_.rate_window_s) {
    state.arrivals.pop_front();
  }
}

namespace {
std::string format(const char* pattern, double a, double b = 0.0) {
  char buffer[128];
  std::snprintf(buffer, sizeof buffer, pattern, a, b);
  return buffer;
}
}  // namespace

std::vector<InputReport> InputMonitor::evaluate(double now_s, const std::vector<int>& publisher_counts) {
  if (publisher_counts.size() != inputs_.size()) {
    throw std::invalid_argument("input monitor: one publisher count per input expected");
  }
  const bool starting = now_s - start_s_ < options_.startup_grace_s;
  std::vector<InputReport> reports;
  reports.reserve(inputs_.size());
  for (std::size_t i = 0; i < inputs_.size(); ++i) {
    const ExpectedInput& input = inputs_[i];
    State& state = states_[i];
    while (!state.arrivals.empty() && state.arrivals.front() < now_s - options_.rate_window_s) {
      state.arrivals.pop_front();
    }
    InputReport report;
    report.topic = input.topic;
    report.publishers = publisher_counts[i];
    report.received = state.received;
    report.seconds_since_last = state.last < 0.0 ? -1.0 : now_s - state.last;
    // The rate over the window, or over the time since start while the window has not filled yet.
    const double span = std::min(options_.rate_window_s, std::max(now_s - start_s_, 1e-9));
    report.rate_hz = static_cast<double>(state.arrivals.size()) / span;
    const std::string hint = input.hint.empty() ? "" : " (expected from " + input.hint + ")";

    if (report.publishers <= 0) {
      report.health = InputHealth::kNoPublisher;
      report.message = "waiting for " + input.topic + ": no publisher" + hint;
    } else if (input.expected_rate_hz <= 0.0) {
      report.health = InputHealth::kOk;  // on-change input: a publisher is all that can be checked
      report.message = input.topic + ": publisher connected";
    } else if (starting) {
      report.health = state.received ? InputHealth::kOk : InputHealth::kStarting;
      report.message = input.topic + (state.received ? ": receiving" : ": publisher connected, waiting for data");
    } else if (state.last < 0.0 || report.seconds_since_last > options_.silence_timeout_s) {
      report.health = InputHealth::kSilent;
      report.message = input.topic + ": " + std::to_string(report.publishers) + " publisher(s) but " +
                       (state.last < 0.0 ? format("no message since the start %.0f s ago", now_s - start_s_)
                                         : format("no message for %.1f s", report.seconds_since_last)) +
                       hint;
    } else if (report.rate_hz < options_.min_rate_fraction * input.expected_rate_hz) {
      report.health = InputHealth::kSlow;
      report.message = input.topic + ": " +
                       format("%.1f Hz, below the expected %.0f Hz", report.rate_hz, input.expected_rate_hz) + hint;
    } else {
      report.health = InputHealth::kOk;
      report.message = input.topic + ": " + format("%.1f Hz", report.rate_hz);
    }
    reports.push_back(std::move(report));
  }
  return reports;
}

}  // namespace world
}  // namespace vrm_sim
