// Proves zero copy inside the nodelet manager: the probe loaded next to the simulated devices must see every
// message as the very object that was published; the control probe in another process must see copies.
#include <diagnostic_msgs/DiagnosticArray.h>
#include <gtest/gtest.h>
#include <ros/ros.h>

#include <map>
#include <mutex>
#include <sstream>
#include <string>

#include "vrm_sim/testing/graph_test.h"

namespace {

using vrm_sim::testing::waitFor;

struct TopicCounts {
  std::uint64_t received = 0;
  std::uint64_t zero_copy = 0;
};
using ProbeReport = std::map<std::string, TopicCounts>;

class ProbeListener {
 public:
  explicit ProbeListener(ros::NodeHandle& nh) {
    subscriber_ = nh.subscribe("/diagnostics", 50, &ProbeListener::onDiagnostics, this);
  }

  ProbeReport latest(const std::string& probe) {
    std::lock_guard<std::mutex> lock(mutex_);
    return reports_[probe];
  }

 private:
  void onDiagnostics(const diagnostic_msgs::DiagnosticArray::ConstPtr& array) {
    std::lock_guard<std::mutex> lock(mutex_);
    for (const auto& status : array->status) {
      ProbeReport report;
      for (const auto& value : status.values) {
        std::istringstream fields(value.value);
        TopicCounts counts;
        fields >> counts.received >> counts.zero_copy;
        report[value.key] = counts;
      }
      reports_[status.name] = report;
    }
  }

  ros::Subscriber subscriber_;
  std::mutex mutex_;
  std::map<std::string, ProbeReport> reports_;
};

bool everyTopicHasAtLeast(const ProbeReport& report, const std::vector<std::string>& topics, std::uint64_t count) {
  for (const auto& topic : topics) {
    auto it = report.find(topic);
    if (it == report.end() || it->second.received < count) return false;
  }
  return true;
}

TEST(ZeroCopyGraph, SameManagerGetsThePublishedPointerAnotherProcessGetsCopies) {
  ros::NodeHandle nh;
  ros::NodeHandle private_nh("~");
  const std::string probe = private_nh.param<std::string>("probe", "/zero_copy_probe");
  const std::string control_probe = private_nh.param<std::string>("control_probe", "/remote_probe");
  const auto min_messages = static_cast<std::uint64_t>(private_nh.param("min_messages", 20));
  const std::vector<std::string> streaming_topics = {"/eye_state", "/instrument_state", "/pedals", "/microscope"};

  ProbeListener listener(nh);
  waitFor(
      [&] {
        return everyTopicHasAtLeast(listener.latest(probe), streaming_topics, min_messages) &&
               everyTopicHasAtLeast(listener.latest(control_probe), streaming_topics, min_messages);
      },
      60.0, 0.05);

  const ProbeReport local = listener.latest(probe);
  const ProbeReport remote = listener.latest(control_probe);
  ASSERT_TRUE(everyTopicHasAtLeast(local, streaming_topics, min_messages)) << "probe in the manager got too little";
  ASSERT_TRUE(everyTopicHasAtLeast(remote, streaming_topics, min_messages)) << "control probe got too little";
  for (const auto& [topic, counts] : local) {
    EXPECT_EQ(counts.zero_copy, counts.received) << topic << ": copies inside the manager";
  }
  for (const auto& topic : streaming_topics) {
    EXPECT_EQ(remote.at(topic).zero_copy, 0u) << topic << ": the control must see copies, else the probe is blind";
  }
}

}  // namespace

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_zero_copy_graph");
  ros::AsyncSpinner spinner(1);
  spinner.start();
  return RUN_ALL_TESTS();
}
