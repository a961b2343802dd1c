// Record -> replay -> compare (thesis §2.4.2: a session is its recorded inputs). Runs the launch files exactly as a
// user would, against the rostest master, and waits on conditions (process exit, recorder subscriptions), never
// on fixed sleeps.
#include <gtest/gtest.h>
#include <ros/master.h>
#include <ros/ros.h>
#include <rosbag/bag.h>
#include <rosbag/view.h>
#include <unistd.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include "child_process.h"
#include "vrm_sim/testing/graph_test.h"

namespace {

using vrm_sim::ChildProcess;
using vrm_sim::testing::waitFor;
namespace fs = std::filesystem;

bool nodeSubscribesTo(const std::string& node, const std::vector<std::string>& topics) {
  XmlRpc::XmlRpcValue request, response, payload;
  request[0] = ros::this_node::getName();
  if (!ros::master::execute("getSystemState", request, response, payload, false)) return false;
  const XmlRpc::XmlRpcValue& subscriptions = payload[1];
  for (const auto& topic : topics) {
    bool found = false;
    for (int i = 0; i < subscriptions.size() && !found; ++i) {
      if (static_cast<std::string>(subscriptions[i][0]) != topic) continue;
      for (int j = 0; j < subscriptions[i][1].size(); ++j) {
        found = found || static_cast<std::string>(subscriptions[i][1][j]) == node;
      }
    }
    if (!found) return false;
  }
  return true;
}

using SerializedStream = std::map<std::string, std::vector<std::vector<std::uint8_t>>>;

SerializedStream readBag(const std::string& path, const std::vector<std::string>& topics) {
  rosbag::Bag bag(path, rosbag::bagmode::Read);
  rosbag::View view(bag, rosbag::TopicQuery(topics));
  SerializedStream stream;
  for (const rosbag::MessageInstance& message : view) {
    std::vector<std::uint8_t> bytes(message.size());
    ros::serialization::OStream out(bytes.data(), bytes.size());
    message.write(out);
    // The replay's simulation node publishes input_frame anew (from the recorded frames): its header.seq is roscpp's
    // count of that publisher's messages, not data; every other byte must be equal.
    if (message.getTopic() == "/input_frame" && bytes.size() >= 4) std::fill(bytes.begin(), bytes.begin() + 4, 0);
    stream[message.getTopic()].push_back(std::move(bytes));
  }
  return stream;
}

TEST(RecordReplay, ReplayedInputStreamEqualsTheRecordedOne) {
  ros::NodeHandle private_nh("~");
  const std::string launch_dir = private_nh.param<std::string>("launch_dir", "");
  const double record_seconds = private_nh.param("record_seconds", 5.0);
  std::vector<std::string> topics;
  ASSERT_TRUE(private_nh.getParam("topics", topics));
  ASSERT_TRUE(fs::exists(launch_dir + "/simulator.launch")) << launch_dir;

  const fs::path work = fs::temp_directory_path() / ("vrm_record_replay_" + std::to_string(getpid()));
  fs::create_directories(work);
  const std::string recorded = (work / "recorded.bag").string();
  const std::string replayed = (work / "replayed.bag").string();

  {
    ChildProcess session({"roslaunch", launch_dir + "/simulator.launch", "sim:=true", "headless:=true", "record:=true",
                          "duration:=" + std::to_string(record_seconds), "bag:=" + recorded});
    ASSERT_TRUE(session.started());
    EXPECT_EQ(session.waitFor(record_seconds + 60.0), 0) << "the recording session did not end by itself";
  }
  ASSERT_TRUE(fs::exists(recorded)) << "no bag at " << recorded;
  const SerializedStream original = readBag(recorded, topics);
  for (const auto& topic : topics) {
    ASSERT_GT(original.count(topic) ? original.at(topic).size() : 0u, 0u) << topic << " was not recorded";
  }

  // The recorder binary itself rather than the `rosbag record` Python wrapper, so SIGINT reaches the process that
  // closes the bag (Debian installs it in /usr/lib/rosbag).
  const std::string recorder_binary = fs::exists("/usr/lib/rosbag/record") ? "/usr/lib/rosbag/record" : "";
  std::vector<std::string> recorder_args = {"-O", replayed, "__name:=replay_check_recorder"};
  if (recorder_binary.empty()) {
    recorder_args.insert(recorder_args.begin(), {"rosbag", "record"});
  } else {
    recorder_args.insert(recorder_args.begin(), recorder_binary);
  }
  recorder_args.insert(recorder_args.end(), topics.begin(), topics.end());
  ChildProcess topic_recorder(recorder_args);
  ASSERT_TRUE(topic_recorder.started());
  ASSERT_TRUE(waitFor([&] { return nodeSubscribesTo("/replay_check_recorder", topics); }, 30.0, 0.05))
      << "re-recorder never subscribed";

  {
    ChildProcess replay({"roslaunch", launch_dir + "/replay.launch", "bag:=" + recorded});
    ASSERT_TRUE(replay.started());
    EXPECT_EQ(replay.waitFor(record_seconds + 60.0), 0) << "the replay did not end by itself";
  }
  topic_recorder.interrupt();
  EXPECT_EQ(topic_recorder.waitFor(20.0), 0);
  // The recorder renames <bag>.active to <bag> when it has closed the file; on a loaded machine that may trail
  // the exit of the process that was signalled.
  waitFor([&] { return fs::exists(replayed); }, 20.0, 0.05);
  EXPECT_FALSE(fs::exists(replayed + ".active") && !fs::exists(replayed)) << "the re-recorder never closed its bag";
  ASSERT_TRUE(fs::exists(replayed)) << "the re-recorder left no bag";

  const SerializedStream replayed_stream = readBag(replayed, topics);
  for (const auto& topic : topics) {
    const auto& expected = original.at(topic);
    ASSERT_TRUE(replayed_stream.count(topic)) << topic << " missing from the replay";
    const auto& actual = replayed_stream.at(topic);
    ASSERT_EQ(actual.size(), expected.size()) << topic;
    for (std::size_t i = 0; i < expected.size(); ++i) {
      ASSERT_EQ(actual[i], expected[i]) << topic << " message " << i << " differs";
    }
  }
  fs::remove_all(work);
}

}  // namespace

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_record_replay");
  ros::NodeHandle nh;
  return RUN_ALL_TESTS();
}
