// Lazy subscription graph test (lazy_subscription.test): the detector subscribes to a camera's images only while
// someone subscribes to that camera's markers, and the rig twin to the ground truth only while someone subscribes to
// one of its camera outputs; /diagnostics and tracking_timing subscribers never count. Conditions are awaited with
// timeouts (no fixed sleeps).
#include <diagnostic_msgs/DiagnosticArray.h>
#include <gtest/gtest.h>
#include <ros/ros.h>
#include <vrm_msgs/MarkerObservations.h>
#include <vrm_msgs/StageTiming.h>

#include <atomic>
#include <map>
#include <mutex>
#include <string>
#include <vector>

#include "vrm_sim/testing/graph_test.h"

namespace {

using vrm_sim::testing::waitFor;

constexpr double kTimeout = 20.0;
constexpr double kMasterPoll = 0.05;  // s between queries of the master

// Subscribers of `topic` per the master (node names).
std::vector<std::string> subscribersOf(const std::string& topic) {
  XmlRpc::XmlRpcValue request, response, payload;
  request[0] = ros::this_node::getName();
  std::vector<std::string> nodes;
  if (!ros::master::execute("getSystemState", request, response, payload, false)) return nodes;
  const XmlRpc::XmlRpcValue& subscriptions = payload[1];
  for (int i = 0; i < subscriptions.size(); ++i) {
    if (static_cast<std::string>(subscriptions[i][0]) != topic) continue;
    for (int j = 0; j < subscriptions[i][1].size(); ++j)
      nodes.push_back(static_cast<std::string>(subscriptions[i][1][j]));
  }
  return nodes;
}

bool managerSubscribes(const std::string& topic) {
  for (const std::string& node : subscribersOf(topic)) {
    if (node == "/vrm_manager") return true;  // simulator.launch's manager
  }
  return false;
}

struct Diagnostics {
  std::mutex mutex;
  std::map<std::string, std::string> message;  // newest per status name
  void onArray(const diagnostic_msgs::DiagnosticArray::ConstPtr& msg) {
    std::lock_guard<std::mutex> lock(mutex);
    for (const auto& status : msg->status) message[status.name] = status.message;
  }
  std::string of(const std::string& camera) {
    std::lock_guard<std::mutex> lock(mutex);
    for (const auto& [name, text] : message) {
      if (name.find("marker_detector: " + camera) != std::string::npos) return text;
    }
    return "";
  }
};

TEST(LazySubscription, InputsAreSubscribedOnlyWhileMarkersAreWanted) {
  ros::NodeHandle nh;
  Diagnostics diagnostics;
  // Watching diagnostics and timing must not wake the pipeline.
  ros::Subscriber diag_sub = nh.subscribe("/diagnostics", 50, &Diagnostics::onArray, &diagnostics);
  const boost::function<void(const vrm_msgs::StageTiming::ConstPtr&)> ignore =
      [](const vrm_msgs::StageTiming::ConstPtr&) {};
  ros::Subscriber timing_sub = nh.subscribe<vrm_msgs::StageTiming>("tracking_timing", 10, ignore);
  ASSERT_TRUE(waitFor([&] { return diagnostics.of("camera_1").rfind("idle", 0) == 0; }, kTimeout))
      << "detector camera_1: " << diagnostics.of("camera_1");
  EXPECT_FALSE(managerSubscribes("/camera_1/image_raw"));
  EXPECT_FALSE(managerSubscribes("/ground_truth/eye_state")) << "the rig twin renders for nobody";

  std::atomic<int> markers{0};
  ros::Subscriber markers_sub = nh.subscribe<vrm_msgs::MarkerObservations>(
      "camera_1/markers", 10, [&](const vrm_msgs::MarkerObservations::ConstPtr&) { ++markers; });
  EXPECT_TRUE(waitFor([&] { return markers > 5; }, kTimeout)) << "no markers once subscribed";
  EXPECT_TRUE(managerSubscribes("/camera_1/image_raw"));
  EXPECT_TRUE(managerSubscribes("/ground_truth/eye_state"));
  EXPECT_FALSE(managerSubscribes("/camera_0/image_raw")) << "camera_0's markers are still unwanted";
  EXPECT_TRUE(waitFor([&] { return diagnostics.of("camera_1") == "detecting"; }, kTimeout))
      << "detector camera_1: " << diagnostics.of("camera_1");

  markers_sub.shutdown();
  EXPECT_TRUE(waitFor([&] { return !managerSubscribes("/camera_1/image_raw"); }, kTimeout, kMasterPoll));
  EXPECT_TRUE(waitFor([&] { return !managerSubscribes("/ground_truth/eye_state"); }, kTimeout, kMasterPoll));
  EXPECT_TRUE(waitFor([&] { return diagnostics.of("camera_1").rfind("idle", 0) == 0; }, kTimeout))
      << "detector camera_1: " << diagnostics.of("camera_1");
}

}  // namespace

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_lazy_subscription");
  ros::AsyncSpinner spinner(2);
  spinner.start();
  return RUN_ALL_TESTS();
}
