#pragma once
// End-to-end latency of the simulator graph (issue 12) and the thesis' synchronisation patterns (§2.5.2).
//
// Every stage of the graph stamps the frame it handles (vrm_msgs/StageTiming: header.stamp = the input stamp, per
// stage a start and an end on the graph's clock). This file turns those spans into the chain's canonical stages —
//   tracking → collision → simulation → render → image_published, and end_to_end (input stamp → image published)
// — keeps sliding windows of them (p50/p95/p99/max, frame rate), counts frames a stage never used, classifies the
// result against thresholds, and predicts the latency of the patterns of Fig. 2.6 from measured stage times. The
// latency_monitor nodelet and bench_latency share it; it reads no clock (times are arguments).
//
// Times are nanoseconds (std::int64_t) on the graph's clock; summaries are in milliseconds.

#include <cstddef>
#include <cstdint>
#include <deque>
#include <map>
#include <optional>
#include <set>
#include <string>
#include <vector>

namespace vrm_sim {
namespace world {

using Nanoseconds = std::int64_t;

// Nearest-rank percentiles of a sample, in ms.
struct LatencySummary {
  std::size_t count = 0;
  double p50 = 0.0, p95 = 0.0, p99 = 0.0, max = 0.0, mean = 0.0;
};
LatencySummary summarizeLatencies(std::vector<double> values_ms);
// Nearest rank (q in [0, 1]) of an ascending sample; 0 for an empty one.
double nearestRank(const std::vector<double>& sorted, double q);

// The samples of the last `window` (by sample time; older ones are dropped by expire() and add()), at most
// `max_samples` of them.
class SlidingWindow {
 public:
  explicit SlidingWindow(Nanoseconds window = 10'000'000'000, std::size_t max_samples = 4096);
  void add(Nanoseconds time, double value_ms);
  void expire(Nanoseconds now);
  LatencySummary summary() const;
  std::size_t size() const { return samples_.size(); }
  // Samples per second over the window ending at `now` (a stage's frame rate).
  double rate(Nanoseconds now) const;

 private:
  Nanoseconds window_;
  std::size_t max_samples_;
  std::deque<std::pair<Nanoseconds, double>> samples_;
};

// One stage of one frame as a StageTiming carries it.
struct StageSpan {
  std::string stage;
  Nanoseconds start = 0, end = 0;
};

// A frame's measurement at one canonical stage: how long the stage computed (`time_ms`; absent for end_to_end) and
// how long after the frame's input stamp it was done (`latency_ms`).
struct StageSample {
  std::string stage;
  std::optional<double> time_ms;
  double latency_ms = 0.0;
};

// Canonical stage names, in chain order.
extern const char* const kCameraStage;          // the rig twin rendering the camera triple (a real rig: none)
extern const char* const kDetectionStage;       // marker detection, one sample per camera image
extern const char* const kReconstructionStage;  // triangulation and poses (the tracker)
extern const char* const kTrackingStage;        // camera + detection (all cameras) + reconstruction
extern const char* const kCollisionStage;       // sum of the simulation's collision_<object> stages
extern const char* const kSimulationStage;      // the simulation frame: first stage start → last stage end
extern const char* const kRenderStage;          // the stereo frame (all passes, readback)
extern const char* const kImagePublishedStage;  // the images handed to the subscribers
extern const char* const kEndToEndStage;        // input stamp → image published
// Input stamp of the simulation frame the image shows → image published. Equals end_to_end when the render waited
// for the simulation (sequential); one input tick more when it ran ahead with the previous tissue (pipelined).
extern const char* const kEndToEndWorldStage;
// Marker span of render_timing: start = end = the input stamp of the simulation frame the image shows.
extern const char* const kSimulationInputMarker;
std::vector<std::string> canonicalStages();

// Raw spans → canonical samples. Messages of one input stamp arrive in causal order (the rig twin's camera span and
// the detector's spans before the tracker's reconstruction); spans of the tracking chain are kept per stamp for
// `horizon` so the tracking stage can sum them. Raw names: camera, detection_<camera>, reconstruction (tracking);
// collision_<object>, tissue_<object>, bleeding_<object>, scenario (simulation); render, render_<pass>,
// image_published, simulation_input (renderer).
class StageChain {
 public:
  explicit StageChain(Nanoseconds horizon = 2'000'000'000) : horizon_(horizon) {}
  std::vector<StageSample> add(Nanoseconds stamp, const std::vector<StageSpan>& spans);

 private:
  struct TrackingParts {
    double camera_ms = 0.0;
    double detection_ms = 0.0;
  };
  Nanoseconds horizon_;
  std::map<Nanoseconds, TrackingParts> tracking_;
};

// Frames a stage never used: `offer` when a frame reached the upstream stage, `take` when the downstream stage used
// it; a frame offered more than `horizon` before the newest offer and never taken counts as dropped. A frame the
// downstream stage takes before it is offered (a race between topics) is not counted.
class DropCounter {
 public:
  explicit DropCounter(Nanoseconds horizon = 1'000'000'000) : horizon_(horizon) {}
  void offer(Nanoseconds stamp);
  void take(Nanoseconds stamp);
  std::uint64_t dropped() const { return dropped_; }
  std::uint64_t offered() const { return offered_; }

 private:
  void settle();
  Nanoseconds horizon_;
  std::set<Nanoseconds> open_;   // offered, not yet taken
  std::set<Nanoseconds> taken_;  // taken, recently (so a late offer is not counted)
  Nanoseconds newest_ = 0;
  std::uint64_t dropped_ = 0, offered_ = 0;
};

// Diagnostic levels (numerically those of diagnostic_msgs/DiagnosticStatus).
enum class LatencyLevel { kOk = 0, kWarn = 1, kError = 2 };

// Thresholds on one statistic of a stage ("p50" | "p95" | "p99" | "max" of its latency, or of its compute time with
// of_time); a threshold <= 0 is off. min_fps: WARN when the stage's frame rate falls below it (0 = off).
struct LatencyThreshold {
  std::string statistic = "p99";
  bool of_time = false;
  double warn_ms = 0.0, error_ms = 0.0;
  double min_fps = 0.0;
};
double statistic(const LatencySummary& summary, const std::string& name);  // throws std::invalid_argument
// The level and, unless OK, why (e.g. "p99 latency 63.1 ms > 57 ms").
LatencyLevel classify(const LatencySummary& latency, const LatencySummary& time, double fps,
                      const LatencyThreshold& threshold, std::string* why);

// Thesis §2.5.2, modules S (sensor), B (computation), R (render) with times t_s, t_b, t_r (any unit):
double syncLatencyWorst(double rate_hz);                          // eq. 2.1: 1/ν (s)
double syncLatencyMean(double rate_hz);                           // eq. 2.2: 1/(2ν) (s)
double sequentialLatency(double t_s, double t_b, double t_r);     // eq. 2.3
double parallelAsyncLatency(double t_s, double t_b, double t_r);  // eq. 2.4
// eq. 2.5: probability that a result of a producer (time t_producer) is used by its consumer (t_consumer).
double useProbability(double t_producer, double t_consumer);
double pipelinedLatency(const std::vector<double>& stage_times);  // eq. 2.7: n · max T_i

}  // namespace world
}  // namespace vrm_sim
