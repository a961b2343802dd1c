// issue 20: `simulator.launch sim:=false` with no devices. Within 5 s of the input monitor coming up, /diagnostics
// names every missing input ("no publisher") at WARN and the console (rosout) carries the warning; an input that then
// arrives at its rate turns OK, one at a fifth of its rate is reported slow.
#include <diagnostic_msgs/DiagnosticArray.h>
#include <gtest/gtest.h>
#include <ros/ros.h>
#include <rosgraph_msgs/Log.h>

#include <boost/make_shared.hpp>
#include <map>
#include <mutex>
#include <set>
#include <string>

#include "vrm_msgs/EyeState.h"
#include "vrm_sim/testing/graph_test.h"

namespace vrm_sim {
namespace {

using testing::waitFor;
using testing::waitForSubscribers;

const std::set<std::string> kInputs = {"eye_state", "instrument_state", "pedals", "microscope"};

class NoDevices : public ::testing::Test {
 protected:
  void SetUp() override {
    diagnostics_ = nh_.subscribe("/diagnostics", 100, &NoDevices::onDiagnostics, this);
    // /rosout itself: rostest starts no rosout node, so nothing is aggregated.
    rosout_ = nh_.subscribe("/rosout", 1000, &NoDevices::onLog, this);
    spinner_.start();
  }

  void onDiagnostics(const diagnostic_msgs::DiagnosticArray::ConstPtr& array) {
    std::lock_guard<std::mutex> lock(mutex_);
    for (const auto& status : array->status) {
      const std::string prefix = "input_monitor: ";
      if (status.name.compare(0, prefix.size(), prefix) != 0) continue;
      statuses_[status.name.substr(prefix.size())] = status;
    }
  }
  void onLog(const rosgraph_msgs::Log::ConstPtr& log) {
    std::lock_guard<std::mutex> lock(mutex_);
    if (log->level == rosgraph_msgs::Log::WARN) warnings_.push_back(log->msg);
  }

  bool allMissing() {
    std::lock_guard<std::mutex> lock(mutex_);
    for (const std::string& input : kInputs) {
      const auto it = statuses_.find(input);
      if (it == statuses_.end() || it->second.level != diagnostic_msgs::DiagnosticStatus::WARN ||
          it->second.message.find("no publisher") == std::string::npos) {
        return false;
      }
    }
    return true;
  }
  bool warned(const std::string& text) {
    std::lock_guard<std::mutex> lock(mutex_);
    for (const std::string& warning : warnings_) {
      if (warning.find(text) != std::string::npos) return true;
    }
    return false;
  }
  std::string allWarnings() {
    std::lock_guard<std::mutex> lock(mutex_);
    std::string all;
    for (const std::string& warning : warnings_) all += warning + "\n";
    return all;
  }
  diagnostic_msgs::DiagnosticStatus status(const std::string& input) {
    std::lock_guard<std::mutex> lock(mutex_);
    return statuses_[input];
  }

  ros::NodeHandle nh_;
  ros::AsyncSpinner spinner_{2};
  ros::Subscriber diagnostics_, rosout_;
  std::mutex mutex_;
  std::map<std::string, diagnostic_msgs::DiagnosticStatus> statuses_;
  std::vector<std::string> warnings_;
};

TEST_F(NoDevices, TheUserIsToldWhatTheSimulatorWaitsFor) {
  // The monitor is up once it subscribes to the inputs (the manager loads it with the rest of the graph).
  ros::Publisher eye = nh_.advertise<vrm_msgs::EyeState>("eye_state", 10);
  ASSERT_TRUE(waitForSubscribers(eye, 60.0)) << "the graph did not come up";
  // Our own publisher counts as one: drop it until the "nothing connected" part is checked.
  eye.shutdown();
  ASSERT_TRUE(waitFor([&] { return allMissing(); }, 5.0))
      << "no WARN 'no publisher' for every input on /diagnostics within 5 s";
  EXPECT_TRUE(waitFor([&] { return warned("waiting for eye_state: no publisher"); }, 5.0))
      << "no console warning for eye_state within 5 s";
  EXPECT_TRUE(waitFor([&] { return warned("waiting for pedals: no publisher"); }, 5.0)) << allWarnings();
  EXPECT_NE(status("eye_state").message.find("tracking:=true"), std::string::npos)
      << "the message should say where eye_state comes from: " << status("eye_state").message;

  // A device that delivers at its rate turns OK; one far below it is reported slow (the check can fail).
  eye = nh_.advertise<vrm_msgs::EyeState>("eye_state", 10);
  ASSERT_TRUE(waitForSubscribers(eye, 10.0));
  auto publishFor = [&](double seconds, double rate_hz) {
    const ros::WallTime end = ros::WallTime::now() + ros::WallDuration(seconds);
    ros::WallRate rate(rate_hz);
    while (ros::ok() && ros::WallTime::now() < end) {
      auto msg = boost::make_shared<vrm_msgs::EyeState>();
      msg->header.stamp = ros::Time::now();
      msg->rotation.w = 1.0;
      eye.publish(msg);
      rate.sleep();
    }
  };
  publishFor(4.0, 50.0);
  EXPECT_EQ(status("eye_state").level, diagnostic_msgs::DiagnosticStatus::OK) << status("eye_state").message;
  publishFor(4.0, 10.0);
  EXPECT_EQ(status("eye_state").level, diagnostic_msgs::DiagnosticStatus::WARN) << status("eye_state").message;
  EXPECT_NE(status("eye_state").message.find("below the expected 50 Hz"), std::string::npos)
      << status("eye_state").message;
  EXPECT_EQ(status("pedals").level, diagnostic_msgs::DiagnosticStatus::WARN) << "pedals are still missing";
}

}  // namespace
}  // namespace vrm_sim

int main(int argc, char** argv) {
  ::testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "no_devices_test");
  return RUN_ALL_TESTS();
}
