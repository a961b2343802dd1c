// Latency monitor (issue 12, thesis §2.5): collects the StageTiming every stage of the graph publishes for the frame
// it handled (header.stamp = the frame's input stamp) and reports, per canonical stage (world/latency.h: camera,
// detection, reconstruction, tracking, collision, simulation, render, image_published, end_to_end,
// end_to_end_world), p50/p95/p99/max of the time since the input stamp and of the stage's compute time over a sliding
// window, its frame rate and the frames it never used, on /diagnostics with OK/WARN/ERROR from thresholds.
//
// Subscribes: ~timing_topics (default [tracking_timing, tissue_timing, render_timing]; the rig twin, marker detector
//   and tracker share tracking_timing).
// Publishes: /diagnostics (diagnostic_msgs/DiagnosticArray), one status per stage seen, every ~period s (wall).
// Parameters (private): window (s of input time, default 10), max_samples (per stage, 4096), period (s, 1.0),
//   drop_horizon (s, 1.0: a frame not used by the next stage this long after a newer one was offered is dropped),
//   and per stage <stage>/warn_ms, <stage>/error_ms (on <stage>/statistic: p50 | p95 | p99 | max | mean, default
//   p99, of the latency since the input stamp, or of the compute time with <stage>/of_time), <stage>/min_fps.
//   Defaults: end_to_end p99 WARN above 57 ms (EyeSi's membrane scene, thesis §7.4.2), ERROR above 150 ms (criticised
//   by every test user, §1.3), WARN below 20 fps (§1.3).
#include <diagnostic_msgs/DiagnosticArray.h>
#include <nodelet/nodelet.h>
#include <ros/ros.h>

#include <algorithm>
#include <boost/make_shared.hpp>
#include <cstdio>
#include <map>
#include <mutex>
#include <pluginlib/class_list_macros.hpp>
#include <string>
#include <vector>

#include "vrm_msgs/StageTiming.h"
#include "vrm_msgs/publish.h"
#include "vrm_sim/world/latency.h"

namespace vrm_graph {

// The statistics are vrm_sim's (world/latency.h): bench_latency and the display twin compute the same ones.
namespace world = vrm_sim::world;

class LatencyMonitor : public nodelet::Nodelet {
 public:
  void onInit() override {
    ros::NodeHandle& nh = getNodeHandle();
    ros::NodeHandle& pnh = getPrivateNodeHandle();
    std::vector<std::string> topics = {"tracking_timing", "tissue_timing", "render_timing"};
    pnh.param("timing_topics", topics, topics);
    const double window = pnh.param("window", 10.0);
    max_samples_ = static_cast<std::size_t>(std::max(16, pnh.param("max_samples", 4096)));
    window_ = static_cast<world::Nanoseconds>(window * 1e9);
    const double period = pnh.param("period", 1.0);
    const auto horizon = static_cast<world::Nanoseconds>(pnh.param("drop_horizon", 1.0) * 1e9);
    tracking_drops_ = world::DropCounter(horizon);
    simulation_drops_ = world::DropCounter(horizon);
    render_drops_ = world::DropCounter(horizon);

    for (const std::string& stage : world::canonicalStages()) {
      world::LatencyThreshold threshold;
      if (stage == world::kEndToEndStage) {
        threshold.warn_ms = 57.0;
        threshold.error_ms = 150.0;
        threshold.min_fps = 20.0;
      }
      pnh.param(stage + "/statistic", threshold.statistic, threshold.statistic);
      pnh.param(stage + "/of_time", threshold.of_time, threshold.of_time);
      pnh.param(stage + "/warn_ms", threshold.warn_ms, threshold.warn_ms);
      pnh.param(stage + "/error_ms", threshold.error_ms, threshold.error_ms);
      pnh.param(stage + "/min_fps", threshold.min_fps, threshold.min_fps);
      try {
        world::statistic(world::LatencySummary{}, threshold.statistic);
      } catch (const std::invalid_argument& error) {
        NODELET_ERROR("latency_monitor: %s/statistic: %s; using p99", stage.c_str(), error.what());
        threshold.statistic = "p99";
      }
      thresholds_[stage] = threshold;
    }
    diagnostics_publisher_ = nh.advertise<diagnostic_msgs::DiagnosticArray>("/diagnostics", 10);
    for (const std::string& topic : topics) {
      subscribers_.push_back(nh.subscribe(topic, 50, &LatencyMonitor::onTiming, this));
    }
    timer_ = nh.createWallTimer(ros::WallDuration(period), &LatencyMonitor::publishDiagnostics, this);
    NODELET_INFO("latency_monitor: %zu timing topics, window %.1f s, end_to_end %s WARN > %.0f ms, ERROR > %.0f ms",
                 topics.size(), window, thresholds_[world::kEndToEndStage].statistic.c_str(),
                 thresholds_[world::kEndToEndStage].warn_ms, thresholds_[world::kEndToEndStage].error_ms);
  }

 private:
  struct StageWindows {
    world::SlidingWindow latency, time;
  };

  void onTiming(const vrm_msgs::StageTiming::ConstPtr& timing) {
    const world::Nanoseconds stamp = static_cast<world::Nanoseconds>(timing->header.stamp.toNSec());
    std::vector<world::StageSpan> spans;
    spans.reserve(timing->stages.size());
    for (const vrm_msgs::StageStamp& stage : timing->stages) {
      spans.push_back({stage.stage, static_cast<world::Nanoseconds>(stage.start.toNSec()),
                       static_cast<world::Nanoseconds>(stage.end.toNSec())});
    }
    std::lock_guard<std::mutex> lock(mutex_);
    for (const world::StageSample& sample : chain_.add(stamp, spans)) {
      auto found = windows_.find(sample.stage);
      if (found == windows_.end()) {
        found = windows_
                    .emplace(sample.stage, StageWindows{world::SlidingWindow(window_, max_samples_),
                                                        world::SlidingWindow(window_, max_samples_)})
                    .first;
      }
      found->second.latency.add(stamp, sample.latency_ms);
      if (sample.time_ms) found->second.time.add(stamp, *sample.time_ms);
      // Links of the chain: a frame offered by one stage and never used by the next is dropped.
      if (sample.stage == world::kCameraStage) tracking_drops_.offer(stamp);
      if (sample.stage == world::kTrackingStage) {
        tracking_drops_.take(stamp);
        simulation_drops_.offer(stamp);
      }
      if (sample.stage == world::kSimulationStage) {
        simulation_drops_.take(stamp);
        render_drops_.offer(stamp);
      }
    }
    for (const world::StageSpan& span : spans) {
      if (span.stage == world::kSimulationInputMarker) render_drops_.take(span.start);
    }
  }

  std::uint64_t droppedAt(const std::string& stage) const {
    if (stage == world::kTrackingStage) return tracking_drops_.dropped();
    if (stage == world::kSimulationStage) return simulation_drops_.dropped();
    if (stage == world::kRenderStage || stage == world::kEndToEndWorldStage) return render_drops_.dropped();
    return 0;
  }

  void publishDiagnostics(const ros::WallTimerEvent&) {
    namespace d = diagnostic_msgs;
    auto array = boost::make_shared<d::DiagnosticArray>();
    array->header.stamp = ros::Time::now();  // diagnostics describe the live graph, not one frame
    const world::Nanoseconds now = static_cast<world::Nanoseconds>(array->header.stamp.toNSec());
    std::lock_guard<std::mutex> lock(mutex_);
    for (const std::string& stage : world::canonicalStages()) {
      d::DiagnosticStatus status;
      status.name = getName() + ": " + stage;
      status.hardware_id = "vrm_graph";
      auto found = windows_.find(stage);
      if (found == windows_.end()) {
        // Only end_to_end is always reported: no image means nobody watches the stereo view (it renders only then).
        if (stage != world::kEndToEndStage) continue;
        status.level = d::DiagnosticStatus::OK;
        status.message = "no image yet (the stereo view renders only while watched)";
        array->status.push_back(status);
        continue;
      }
      found->second.latency.expire(now);
      found->second.time.expire(now);
      const world::LatencySummary latency = found->second.latency.summary();
      const world::LatencySummary time = found->second.time.summary();
      const double fps = found->second.latency.rate(now);
      auto value = [&status](const std::string& key, const std::string& text) {
        d::KeyValue entry;
        entry.key = key;
        entry.value = text;
        status.values.push_back(entry);
      };
      auto number = [](double v) {
        char text[32];
        std::snprintf(text, sizeof(text), "%.2f", v);
        return std::string(text);
      };
      value("frames in window", std::to_string(latency.count));
      value("fps", number(fps));
      value("latency p50 ms", number(latency.p50));
      value("latency p95 ms", number(latency.p95));
      value("latency p99 ms", number(latency.p99));
      value("latency max ms", number(latency.max));
      if (time.count > 0) {
        value("time p50 ms", number(time.p50));
        value("time p95 ms", number(time.p95));
        value("time p99 ms", number(time.p99));
        value("time max ms", number(time.max));
      }
      value("dropped", std::to_string(droppedAt(stage)));
      std::string why;
      const world::LatencyLevel level = world::classify(latency, time, fps, thresholds_.at(stage), &why);
      status.level = static_cast<std::uint8_t>(level);
      if (latency.count == 0) {
        status.message = "no frames in the last window";
      } else if (!why.empty()) {
        status.message = why;
      } else {
        char text[96];
        std::snprintf(text, sizeof(text), "p50 %.1f ms, p99 %.1f ms since input, %.1f fps", latency.p50, latency.p99,
                      fps);
        status.message = text;
      }
      array->status.push_back(status);
    }
    vrm_msgs::publishShared(diagnostics_publisher_, array);
  }

  std::mutex mutex_;
  world::StageChain chain_;
  world::Nanoseconds window_ = 10'000'000'000;
  std::size_t max_samples_ = 4096;
  std::map<std::string, StageWindows> windows_;
  std::map<std::string, world::LatencyThreshold> thresholds_;
  world::DropCounter tracking_drops_, simulation_drops_, render_drops_;
  std::vector<ros::Subscriber> subscribers_;
  ros::Publisher diagnostics_publisher_;
  ros::WallTimer timer_;
};

}  // namespace vrm_graph

PLUGINLIB_EXPORT_CLASS(vrm_graph::LatencyMonitor, nodelet::Nodelet)
