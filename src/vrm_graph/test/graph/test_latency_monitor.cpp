// latency_monitor (issue 12): synthetic StageTiming of a 50 Hz graph (simulation 3 ms, render 20 ms, image published
// 26 ms after the input stamp) must show on /diagnostics with the right percentiles, rate and level; slow frames must
// raise ERROR; simulation frames the renderer never shows must be counted as dropped.
#include <diagnostic_msgs/DiagnosticArray.h>
#include <gtest/gtest.h>
#include <ros/ros.h>

#include <atomic>
#include <boost/make_shared.hpp>
#include <cstdlib>
#include <map>
#include <mutex>
#include <string>
#include <thread>

#include "vrm_msgs/StageTiming.h"
#include "vrm_sim/testing/graph_test.h"

namespace vrm_sim {
namespace {

using testing::waitFor;

vrm_msgs::StageStamp span(const std::string& stage, const ros::Time& stamp, double from_ms, double to_ms) {
  vrm_msgs::StageStamp s;
  s.stage = stage;
  s.start = stamp + ros::Duration(from_ms * 1e-3);
  s.end = stamp + ros::Duration(to_ms * 1e-3);
  return s;
}

class LatencyMonitorGraph : public ::testing::Test {
 protected:
  void SetUp() override {
    tissue_ = nh_.advertise<vrm_msgs::StageTiming>("tissue_timing", 50);
    render_ = nh_.advertise<vrm_msgs::StageTiming>("render_timing", 50);
    diagnostics_ = nh_.subscribe("/diagnostics", 50, &LatencyMonitorGraph::onDiagnostics, this);
    spinner_.start();
    ASSERT_TRUE(waitFor([&] { return tissue_.getNumSubscribers() > 0 && render_.getNumSubscribers() > 0; }, 20.0))
        << "latency_monitor did not subscribe to the timing topics";
  }
  void TearDown() override {
    running_ = false;
    if (player_.joinable()) player_.join();
  }

  // Plays frames at 50 Hz on a thread: image published `latency_ms` after the input stamp; every `render_every`-th
  // simulation frame is rendered.
  void play() {
    player_ = std::thread([this] {
      ros::WallRate rate(50.0);
      for (std::uint64_t frame = 1; running_ && ros::ok(); ++frame) {
        const ros::Time stamp = ros::Time::now();
        auto tissue = boost::make_shared<vrm_msgs::StageTiming>();
        tissue->header.stamp = stamp;
        tissue->frame = frame;
        tissue->stages = {span("collision_membrane", stamp, 1, 2), span("tissue_membrane", stamp, 2, 4)};
        tissue_.publish(tissue);
        if (frame % render_every_ == 0) {
          auto render = boost::make_shared<vrm_msgs::StageTiming>();
          render->header.stamp = stamp;
          render->frame = frame;
          const double latency = latency_ms_;
          render->stages = {span("render", stamp, latency - 21, latency - 1),
                            span("image_published", stamp, latency - 1, latency),
                            span("simulation_input", stamp, 0, 0)};
          render_.publish(render);
        }
        rate.sleep();
      }
    });
  }

  void onDiagnostics(const diagnostic_msgs::DiagnosticArray::ConstPtr& array) {
    std::lock_guard<std::mutex> lock(mutex_);
    for (const auto& status : array->status) statuses_[status.name] = status;
  }

  // The newest status of a stage, if reported.
  bool status(const std::string& stage, diagnostic_msgs::DiagnosticStatus* out) {
    std::lock_guard<std::mutex> lock(mutex_);
    auto found = statuses_.find("/latency_monitor: " + stage);
    if (found == statuses_.end()) return false;
    *out = found->second;
    return true;
  }

  static double value(const diagnostic_msgs::DiagnosticStatus& status, const std::string& key) {
    for (const auto& entry : status.values) {
      if (entry.key == key) return std::atof(entry.value.c_str());
    }
    return -1.0;
  }

  ros::NodeHandle nh_;
  ros::AsyncSpinner spinner_{1};
  ros::Publisher tissue_, render_;
  ros::Subscriber diagnostics_;
  std::thread player_;
  std::atomic<bool> running_{true};
  std::atomic<double> latency_ms_{26.0};
  std::atomic<int> render_every_{1};
  std::mutex mutex_;
  std::map<std::string, diagnostic_msgs::DiagnosticStatus> statuses_;
};

TEST_F(LatencyMonitorGraph, ReportsPercentilesRateAndLevels) {
  play();
  diagnostic_msgs::DiagnosticStatus end_to_end, simulation;
  // A full window of on-time frames: OK, p50 26 ms, about 50 fps.
  ASSERT_TRUE(waitFor(
      [&] {
        return status("end_to_end", &end_to_end) && value(end_to_end, "frames in window") >= 80 &&
               status("simulation", &simulation);
      },
      20.0))
      << "no end_to_end / simulation status with a window of frames";
  EXPECT_EQ(end_to_end.level, diagnostic_msgs::DiagnosticStatus::OK) << end_to_end.message;
  EXPECT_NEAR(value(end_to_end, "latency p50 ms"), 26.0, 0.5);
  EXPECT_NEAR(value(end_to_end, "fps"), 50.0, 15.0);
  EXPECT_NEAR(value(simulation, "time p50 ms"), 3.0, 0.1);  // collision start (1 ms) to tissue end (4 ms)
  EXPECT_NEAR(value(simulation, "latency p50 ms"), 4.0, 0.1);
  diagnostic_msgs::DiagnosticStatus collision;
  ASSERT_TRUE(status("collision", &collision));
  EXPECT_NEAR(value(collision, "time p50 ms"), 1.0, 0.1);
  diagnostic_msgs::DiagnosticStatus render;
  ASSERT_TRUE(status("render", &render));
  EXPECT_EQ(value(render, "dropped"), 0.0);

  // Slow images (200 ms > the 150 ms ERROR threshold of latency.launch): ERROR once they reach the window's p99.
  latency_ms_ = 200.0;
  EXPECT_TRUE(waitFor(
      [&] { return status("end_to_end", &end_to_end) && end_to_end.level == diagnostic_msgs::DiagnosticStatus::ERROR; },
      10.0))
      << end_to_end.message;

  // Only every other simulation frame rendered: the skipped ones are counted as dropped at the render stage.
  latency_ms_ = 26.0;
  render_every_ = 2;
  EXPECT_TRUE(waitFor([&] { return status("render", &render) && value(render, "dropped") >= 10; }, 10.0))
      << "dropped " << value(render, "dropped");
}

}  // namespace
}  // namespace vrm_sim

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_latency_monitor");
  return RUN_ALL_TESTS();
}
