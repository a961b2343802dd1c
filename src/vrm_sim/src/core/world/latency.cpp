#include "vrm_sim/world/latency.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numeric>
#include <stdexcept>

namespace vrm_sim {
namespace world {

const char* const kCameraStage = "camera";
const char* const kDetectionStage = "detection";
const char* const kReconstructionStage = "reconstruction";
const char* const kTrackingStage = "tracking";
const char* const kCollisionStage = "collision";
const char* const kSimulationStage = "simulation";
const char* const kRenderStage = "render";
const char* const kImagePublishedStage = "image_published";
const char* const kEndToEndStage = "end_to_end";
const char* const kEndToEndWorldStage = "end_to_end_world";
const char* const kSimulationInputMarker = "simulation_input";

namespace {

double toMs(Nanoseconds ns) { return 1e-6 * static_cast<double>(ns); }

bool startsWith(const std::string& text, const char* prefix) { return text.rfind(prefix, 0) == 0; }

bool isSimulationSpan(const std::string& stage) {
  return startsWith(stage, "collision_") || startsWith(stage, "tissue_") || startsWith(stage, "bleeding_") ||
         stage == "scenario";
}

}  // namespace

double nearestRank(const std::vector<double>& sorted, double q) {
  if (sorted.empty()) return 0.0;
  const double rank = std::ceil(q * static_cast<double>(sorted.size()));
  const std::size_t index = static_cast<std::size_t>(std::max(1.0, rank)) - 1;
  return sorted[std::min(index, sorted.size() - 1)];
}

LatencySummary summarizeLatencies(std::vector<double> values_ms) {
  LatencySummary summary;
  summary.count = values_ms.size();
  if (values_ms.empty()) return summary;
  std::sort(values_ms.begin(), values_ms.end());
  summary.p50 = nearestRank(values_ms, 0.50);
  summary.p95 = nearestRank(values_ms, 0.95);
  summary.p99 = nearestRank(values_ms, 0.99);
  summary.max = values_ms.back();
  summary.mean = std::accumulate(values_ms.begin(), values_ms.end(), 0.0) / static_cast<double>(values_ms.size());
  return summary;
}

SlidingWindow::SlidingWindow(Nanoseconds window, std::size_t max_samples)
    : window_(window), max_samples_(std::max<std::size_t>(1, max_samples)) {}

void SlidingWindow::add(Nanoseconds time, double value_ms) {
  samples_.emplace_back(time, value_ms);
  while (samples_.size() > max_samples_) samples_.pop_front();
  expire(time);
}

void SlidingWindow::expire(Nanoseconds now) {
  while (!samples_.empty() && samples_.front().first < now - window_) samples_.pop_front();
}

LatencySummary SlidingWindow::summary() const {
  std::vector<double> values;
  values.reserve(samples_.size());
  for (const auto& sample : samples_) values.push_back(sample.second);
  return summarizeLatencies(std::move(values));
}

double SlidingWindow::rate(Nanoseconds now) const {
  if (samples_.empty()) return 0.0;
  // A full window counts over its length; a young one (start-up, or capped by max_samples) over what it spans.
  const Nanoseconds span = std::min(window_, now - samples_.front().first);
  if (span <= 0) return 0.0;
  return static_cast<double>(samples_.size()) / (1e-9 * static_cast<double>(span));
}

std::vector<std::string> canonicalStages() {
  return {kCameraStage,     kDetectionStage, kReconstructionStage, kTrackingStage, kCollisionStage,
          kSimulationStage, kRenderStage,    kImagePublishedStage, kEndToEndStage, kEndToEndWorldStage};
}

std::vector<StageSample> StageChain::add(Nanoseconds stamp, const std::vector<StageSpan>& spans) {
  std::vector<StageSample> samples;
  auto sample = [&](const char* stage, std::optional<double> time_ms, Nanoseconds done) {
    samples.push_back(StageSample{stage, time_ms, toMs(done - stamp)});
  };
  bool simulation = false;
  Nanoseconds simulation_start = 0, simulation_end = 0, collision_end = 0;
  double collision_ms = 0.0;
  bool collision = false;
  const StageSpan* published = nullptr;
  const StageSpan* simulation_input = nullptr;
  for (const StageSpan& span : spans) {
    const double duration_ms = toMs(span.end - span.start);
    if (span.stage == kCameraStage) {
      tracking_[stamp].camera_ms += duration_ms;
      sample(kCameraStage, duration_ms, span.end);
    } else if (startsWith(span.stage, "detection_")) {
      tracking_[stamp].detection_ms += duration_ms;
      sample(kDetectionStage, duration_ms, span.end);
    } else if (span.stage == kReconstructionStage) {
      const TrackingParts parts = tracking_.count(stamp) ? tracking_[stamp] : TrackingParts{};
      sample(kReconstructionStage, duration_ms, span.end);
      sample(kTrackingStage, parts.camera_ms + parts.detection_ms + duration_ms, span.end);
      tracking_.erase(stamp);
    } else if (isSimulationSpan(span.stage)) {
      if (!simulation) simulation_start = span.start, simulation_end = span.end;
      simulation = true;
      simulation_start = std::min(simulation_start, span.start);
      simulation_end = std::max(simulation_end, span.end);
      if (startsWith(span.stage, "collision_")) {
        collision_end = collision ? std::max(collision_end, span.end) : span.end;
        collision = true;
        collision_ms += duration_ms;
      }
    } else if (span.stage == kRenderStage) {
      sample(kRenderStage, duration_ms, span.end);
    } else if (span.stage == kImagePublishedStage) {
      published = &span;
    } else if (span.stage == kSimulationInputMarker) {
      simulation_input = &span;
    }
  }
  if (collision) sample(kCollisionStage, collision_ms, collision_end);
  if (simulation) sample(kSimulationStage, toMs(simulation_end - simulation_start), simulation_end);
  if (published) {
    sample(kImagePublishedStage, toMs(published->end - published->start), published->end);
    sample(kEndToEndStage, std::nullopt, published->end);
    if (simulation_input) {
      samples.push_back(StageSample{kEndToEndWorldStage, std::nullopt, toMs(published->end - simulation_input->start)});
    }
  }
  // Tracking parts of frames the tracker never reconstructed (a camera that stopped) must not pile up.
  while (!tracking_.empty() && tracking_.begin()->first < stamp - horizon_) tracking_.erase(tracking_.begin());
  return samples;
}

void DropCounter::offer(Nanoseconds stamp) {
  newest_ = std::max(newest_, stamp);
  if (taken_.count(stamp) ? true : open_.insert(stamp).second) ++offered_;
  settle();
}

void DropCounter::take(Nanoseconds stamp) {
  if (open_.erase(stamp) == 0) taken_.insert(stamp);
  settle();
}

void DropCounter::settle() {
  const Nanoseconds limit = newest_ - horizon_;
  while (!open_.empty() && *open_.begin() < limit) {
    open_.erase(open_.begin());
    ++dropped_;
  }
  while (!taken_.empty() && *taken_.begin() < limit) taken_.erase(taken_.begin());
}

double statistic(const LatencySummary& summary, const std::string& name) {
  if (name == "p50") return summary.p50;
  if (name == "p95") return summary.p95;
  if (name == "p99") return summary.p99;
  if (name == "max") return summary.max;
  if (name == "mean") return summary.mean;
  throw std::invalid_argument("unknown latency statistic '" + name + "' (p50, p95, p99, max, mean)");
}

LatencyLevel classify(const LatencySummary& latency, const LatencySummary& time, double fps,
                      const LatencyThreshold& threshold, std::string* why) {
  LatencyLevel level = LatencyLevel::kOk;
  std::string reasons;
  char text[160];
  const LatencySummary& measured = threshold.of_time ? time : latency;
  if (measured.count > 0) {
    const double value = statistic(measured, threshold.statistic);
    const char* what = threshold.of_time ? "time" : "latency";
    if (threshold.error_ms > 0.0 && value > threshold.error_ms) {
      level = LatencyLevel::kError;
      std::snprintf(text, sizeof(text), "%s %s %.1f ms > %.4g ms", threshold.statistic.c_str(), what, value,
                    threshold.error_ms);
      reasons = text;
    } else if (threshold.warn_ms > 0.0 && value > threshold.warn_ms) {
      level = LatencyLevel::kWarn;
      std::snprintf(text, sizeof(text), "%s %s %.1f ms > %.4g ms", threshold.statistic.c_str(), what, value,
                    threshold.warn_ms);
      reasons = text;
    }
  }
  if (threshold.min_fps > 0.0 && measured.count > 0 && fps < threshold.min_fps) {
    level = std::max(level, LatencyLevel::kWarn);
    std::snprintf(text, sizeof(text), "%.1f fps < %.4g fps", fps, threshold.min_fps);
    reasons += (reasons.empty() ? "" : "; ") + std::string(text);
  }
  if (why) *why = reasons;
  return level;
}

double syncLatencyWorst(double rate_hz) { return rate_hz > 0.0 ? 1.0 / rate_hz : 0.0; }

double syncLatencyMean(double rate_hz) { return rate_hz > 0.0 ? 0.5 / rate_hz : 0.0; }

double sequentialLatency(double t_s, double t_b, double t_r) { return t_s + t_b + t_r; }

double parallelAsyncLatency(double t_s, double t_b, double t_r) { return t_s + t_b + t_r + 0.5 * (t_s + t_b); }

double useProbability(double t_producer, double t_consumer) {
  if (t_producer < t_consumer && t_consumer > 0.0) return t_producer / t_consumer;
  return 1.0;
}

double pipelinedLatency(const std::vector<double>& stage_times) {
  if (stage_times.empty()) return 0.0;
  return static_cast<double>(stage_times.size()) * *std::max_element(stage_times.begin(), stage_times.end());
}

}  // namespace world
}  // namespace vrm_sim
