// scenario_manager in a manager: LOAD -> START -> the scripted expert's instrument states -> FINISHED, the Score
// message and the result file checked; refused commands (START while running, LOAD of a broken YAML) say why in the
// status and leave the running scenario alone. A scenario_manager unloaded while its frames run leaves the manager
// running.
#include <gtest/gtest.h>
#include <nodelet/NodeletList.h>
#include <nodelet/NodeletLoad.h>
#include <nodelet/NodeletUnload.h>
#include <ros/master.h>
#include <ros/ros.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <fstream>
#include <map>
#include <mutex>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include "graph_test_util.h"
#include "vrm_msgs/InputFrame.h"
#include "vrm_msgs/InstrumentState.h"
#include "vrm_msgs/ScenarioCommand.h"
#include "vrm_msgs/ScenarioStatus.h"
#include "vrm_msgs/Score.h"
#include "vrm_msgs/SimulationState.h"
#include "vrm_scene/scene_loader.h"
#include "vrm_sim/conversions.h"
#include "vrm_sim/world/offline.h"

namespace vrm_sim {
namespace {

using testing::waitFor;
using testing::waitForPublishers;
using testing::waitForSubscribers;

// The stamp after the last input LoadStartPlayFinishScore published (the next test goes on from there, in the same
// graph).
double g_next_stamp = 100.0;

struct Observed {
  std::mutex mutex;
  vrm_msgs::ScenarioStatus status;
  bool have_status = false;
  std::vector<std::string> messages;
  vrm_msgs::Score score;
  bool have_score = false;
  world::Stamp last_frame = -1;
};

TEST(ScenarioGraph, LoadStartPlayFinishScore) {
  std::remove("/tmp/vrm_sim_scenario_test_result.json");
  ros::NodeHandle nh;
  Observed observed;
  ros::Subscriber status_subscriber = nh.subscribe<vrm_msgs::ScenarioStatus>(
      "scenario_status", 50, [&](const vrm_msgs::ScenarioStatus::ConstPtr& status) {
        std::lock_guard<std::mutex> lock(observed.mutex);
        observed.status = *status;
        observed.have_status = true;
        observed.messages.push_back(status->message);
      });
  ros::Subscriber score_subscriber =
      nh.subscribe<vrm_msgs::Score>("score", 5, [&](const vrm_msgs::Score::ConstPtr& score) {
        std::lock_guard<std::mutex> lock(observed.mutex);
        observed.score = *score;
        observed.have_score = true;
      });
  ros::Subscriber frames = nh.subscribe<vrm_msgs::SimulationState>(
      "simulation_state", 100, [&](const vrm_msgs::SimulationState::ConstPtr& state) {
        std::lock_guard<std::mutex> lock(observed.mutex);
        observed.last_frame = toStamp(state->header.stamp);
      });
  ros::Publisher commands = nh.advertise<vrm_msgs::ScenarioCommand>("scenario_command", 10);
  ros::Publisher instruments = nh.advertise<vrm_msgs::InstrumentState>("instrument_state", 100);
  ros::AsyncSpinner spinner(2);
  spinner.start();
  auto status = [&] {
    std::lock_guard<std::mutex> lock(observed.mutex);
    return observed.status;
  };
  ASSERT_TRUE(waitFor(
      [&] {
        std::lock_guard<std::mutex> lock(observed.mutex);
        return observed.have_status && commands.getNumSubscribers() > 0 && instruments.getNumSubscribers() > 0;
      },
      30.0))
      << "scenario_manager did not come up";
  EXPECT_EQ(status().scenario, "membrane_peeling");
  EXPECT_EQ(status().state, vrm_msgs::ScenarioStatus::IDLE);  // auto_start false: waits for START

  auto command = [&](std::uint8_t type, const std::string& scenario, const std::string& argument, double stamp) {
    auto message = boost::make_shared<vrm_msgs::ScenarioCommand>();
    message->header.stamp = ros::Time(stamp);
    message->command = type;
    message->scenario = scenario;
    message->argument = argument;
    message->seed = 5;
    commands.publish(message);
  };
  // LOAD switches the scene at run time.
  command(vrm_msgs::ScenarioCommand::LOAD, "navigation", "easy", 99.0);
  ASSERT_TRUE(waitFor([&] { return status().scenario == "navigation"; }, 20.0)) << status().message;
  EXPECT_EQ(status().difficulty, "easy");
  EXPECT_EQ(status().state, vrm_msgs::ScenarioStatus::IDLE);

  const scene::SceneDescription scene =
      scene::withScript(scene::loadScene(scene::shippedScenePath("navigation"), "easy"), "expert");
  const double start = 100.0;
  command(vrm_msgs::ScenarioCommand::START, "", "", start);
  const std::vector<world::InstrumentState> inputs =
      world::scriptedInputs(scene, 50.0, scene.scriptedDuration() + 2.0, world::fromSeconds(start));
  bool refused_start = false, refused_load = false;
  auto last_frame = [&] {
    std::lock_guard<std::mutex> lock(observed.mutex);
    return observed.last_frame;
  };
  ASSERT_TRUE(playTicks(instruments, inputs, last_frame, [&](world::Stamp stamp, std::size_t tick) {
    g_next_stamp = world::toSeconds(stamp) + 0.02;
    // The two refusals ten ticks apart: commands of one frame leave only the last one's message in the status.
    if (tick == 50) {
      EXPECT_EQ(status().state, vrm_msgs::ScenarioStatus::RUNNING) << status().message;
      command(vrm_msgs::ScenarioCommand::START, "", "", world::toSeconds(stamp));
    }
    if (tick == 60) {
      command(vrm_msgs::ScenarioCommand::LOAD,
              std::string(VRM_SCENE_SOURCE_DIR) + "/test/data/scenes/syntax_error.yaml", "", world::toSeconds(stamp));
    }
    if (tick > 50 && !(refused_start && refused_load)) {
      std::lock_guard<std::mutex> lock(observed.mutex);
      for (const std::string& message : observed.messages) {
        refused_start = refused_start || message.find("START refused") != std::string::npos;
        refused_load = refused_load || message.find("syntax_error.yaml") != std::string::npos;
      }
    }
    return status().state != vrm_msgs::ScenarioStatus::FINISHED;
  }));
  EXPECT_TRUE(refused_start) << "no status message for START while running";
  EXPECT_TRUE(refused_load) << "no status message for the broken LOAD";
  ASSERT_TRUE(waitFor([&] { return status().state == vrm_msgs::ScenarioStatus::FINISHED; }, 10.0))
      << "state " << int(status().state) << ": " << status().message;
  EXPECT_EQ(status().scenario, "navigation");  // the broken LOAD left it running
  ASSERT_TRUE(waitFor(
      [&] {
        std::lock_guard<std::mutex> lock(observed.mutex);
        return observed.have_score;
      },
      10.0));
  vrm_msgs::Score score;
  {
    std::lock_guard<std::mutex> lock(observed.mutex);
    score = observed.score;
  }
  EXPECT_GT(score.total, 50.0);
  std::map<std::string, double> items;
  for (const auto& item : score.items) items[item.name] = item.value;
  EXPECT_EQ(items.at("completed"), 1.0);
  EXPECT_GT(items.at("time"), 0.0);
  EXPECT_EQ(items.at("targets_touched"), 4.0);

  // The same inputs offline give the same score (one core).
  world::ScenarioRunOptions options;
  const world::ScenarioRunResult offline =
      world::runScenario(scene::loadScene(scene::shippedScenePath("navigation"), "easy"), options);
  EXPECT_NEAR(offline.score.total, score.total, 1e-9);

  ASSERT_TRUE(waitFor([] { return std::ifstream("/tmp/vrm_sim_scenario_test_result.json").good(); }, 10.0));
  std::stringstream text;
  text << std::ifstream("/tmp/vrm_sim_scenario_test_result.json").rdbuf();
  for (const char* field : {"\"scene\": \"navigation\"", "\"difficulty\": \"easy\"", "\"seed\": 5",
                            "\"state\": \"finished\"", "\"start_stamp\": 100", "\"items\": [", "\"bag\": null"}) {
    EXPECT_NE(text.str().find(field), std::string::npos) << field << " missing in " << text.str();
  }
}

// A command must not wait behind the device inputs queued ahead of it. On a simulation slower than its inputs (a
// loaded or sanitizer-built machine) those queues hold seconds of input; a STOP that waited for them all took effect
// 12 s after its stamp under ASan and the recording ended before it. Here ticks 6..90 of input arrive at once, faster
// than the simulation closes their frames, then a STOP stamped between ticks 70 and 71: it takes effect in frame 71,
// the frame its stamp belongs to, not in one of the frames after the queued inputs (frame 90).
TEST(ScenarioGraph, ACommandTakesEffectAtItsStampThoughInputsQueueAheadOfIt) {
  ros::NodeHandle nh;
  std::mutex mutex;
  std::string scenario;
  std::uint8_t state = 255;
  std::optional<double> stop_frame;  // stamp of the input frame that applied the STOP
  world::Stamp last_frame = -1;
  ros::Subscriber status_subscriber = nh.subscribe<vrm_msgs::ScenarioStatus>(
      "scenario_status", 50, [&](const vrm_msgs::ScenarioStatus::ConstPtr& status) {
        std::lock_guard<std::mutex> lock(mutex);
        scenario = status->scenario;
        state = status->state;
      });
  ros::Subscriber frame_subscriber =
      nh.subscribe<vrm_msgs::InputFrame>("input_frame", 500, [&](const vrm_msgs::InputFrame::ConstPtr& frame) {
        std::lock_guard<std::mutex> lock(mutex);
        for (const auto& command : frame->commands) {
          if (command.command == vrm_msgs::ScenarioCommand::STOP && !stop_frame)
            stop_frame = frame->header.stamp.toSec();
        }
        last_frame = std::max(last_frame, toStamp(frame->header.stamp));
      });
  ros::Publisher commands = nh.advertise<vrm_msgs::ScenarioCommand>("scenario_command", 10);
  ros::Publisher instruments = nh.advertise<vrm_msgs::InstrumentState>("instrument_state", 1000);
  ros::AsyncSpinner spinner(2);
  spinner.start();
  ASSERT_TRUE(waitFor(
      [&] {
        return commands.getNumSubscribers() > 0 && instruments.getNumSubscribers() > 0 &&
               frame_subscriber.getNumPublishers() > 0;
      },
      30.0));
  auto command = [&](std::uint8_t type, const std::string& scene_name, double stamp) {
    auto message = boost::make_shared<vrm_msgs::ScenarioCommand>();
    message->header.stamp = ros::Time(stamp);
    message->command = type;
    message->scenario = scene_name;
    commands.publish(message);
  };
  const double base = g_next_stamp;
  command(vrm_msgs::ScenarioCommand::LOAD, "membrane_peeling", base);
  ASSERT_TRUE(waitFor(
      [&] {
        std::lock_guard<std::mutex> lock(mutex);
        return scenario == "membrane_peeling";
      },
      20.0));
  command(vrm_msgs::ScenarioCommand::START, "", base + 0.01);

  const scene::SceneDescription scene =
      scene::withScript(scene::loadScene(scene::shippedScenePath("membrane_peeling")), "expert");
  const std::vector<world::InstrumentState> inputs =
      world::scriptedInputs(scene, 50.0, 1.8, world::fromSeconds(base + 0.02));
  std::map<world::Stamp, std::vector<world::InstrumentState>> ticks;
  for (const auto& input : inputs) ticks[input.stamp].push_back(input);
  constexpr std::size_t kLead = 5, kTicks = 90, kStopAfter = 70;
  ASSERT_GE(ticks.size(), kTicks);
  ASSERT_LE(inputs.size(), 200u) << "more than scenario_manager's instrument queue holds";
  std::vector<world::Stamp> tick_stamps;
  for (const auto& tick : ticks) tick_stamps.push_back(tick.first);
  auto publish_tick = [&](std::size_t tick) {
    for (const auto& input : ticks.at(tick_stamps[tick])) {
      instruments.publish(boost::make_shared<vrm_msgs::InstrumentState>(toMsg(input)));
    }
  };
  // The first ticks alone, so that the START is applied and the scenario runs before the burst (a slot the script
  // does not move holds a frame back for two later ones, then it is not waited for).
  for (std::size_t tick = 0; tick < kLead; ++tick) publish_tick(tick);
  ASSERT_TRUE(waitFor(
      [&] {
        std::lock_guard<std::mutex> lock(mutex);
        return state == vrm_msgs::ScenarioStatus::RUNNING;
      },
      20.0))
      << "START not applied";
  for (std::size_t tick = kLead; tick < kTicks; ++tick) publish_tick(tick);
  // Sent once the burst's first frame closed, so the burst is in the manager's queues (from another connection the
  // STOP could otherwise arrive among its first messages) while most of its frames are still to come.
  ASSERT_TRUE(waitFor(
      [&] {
        std::lock_guard<std::mutex> lock(mutex);
        return last_frame >= tick_stamps[kLead];
      },
      30.0));
  const double stop_stamp = world::toSeconds(tick_stamps[kStopAfter - 1]) + 0.01;  // between ticks 70 and 71
  command(vrm_msgs::ScenarioCommand::STOP, "", stop_stamp);
  ASSERT_TRUE(waitFor(
      [&] {
        std::lock_guard<std::mutex> lock(mutex);
        return last_frame >= tick_stamps[kTicks - 1];
      },
      30.0))
      << "the burst's frames did not close";
  std::lock_guard<std::mutex> lock(mutex);
  ASSERT_TRUE(stop_frame) << "the STOP was never applied";
  const double own_frame = world::toSeconds(tick_stamps[kStopAfter]);
  EXPECT_NEAR(*stop_frame, own_frame, 1e-6)
      << "the STOP (stamped " << std::fixed << stop_stamp - base << " s after the LOAD) took effect in the frame at "
      << *stop_frame - base << " s, not in the frame of its stamp (" << own_frame - base
      << " s); the last queued tick is at " << world::toSeconds(tick_stamps[kTicks - 1]) - base << " s";
}

// The manager's XML-RPC URI: a manager that died and was started again by supervised_manager has another one.
std::string managerUri() {
  XmlRpc::XmlRpcValue args, result, payload;
  args[0] = ros::this_node::getName();
  args[1] = "/vrm_manager";
  if (!ros::master::execute("lookupNode", args, result, payload, false)) return "";
  return static_cast<std::string>(payload);
}

// A second scenario_manager, in a namespace of its own, is flooded with inputs and unloaded while its frames run on a
// worker thread. nodelet 1.10 frees a nodelet's two callback queues at unload; the nodelet itself dies on the worker
// after that frame, so a handle on the queue the worker is not running unregisters from freed memory. With the
// commands on the nodelet's multi-threaded queue this killed the manager at a graph's shutdown under ASan (a SEGV
// in Subscription::removeCallback, 2026-12-03). The same manager must answer after each round.
TEST(ScenarioGraph, UnloadedWhileItsFramesRunLeavesTheManagerRunning) {
  ros::NodeHandle nh;
  const std::string name = "/unload_probe/scenario_manager";
  char result_path[] = "/tmp/unload_probe_result_XXXXXX";
  const int fd = mkstemp(result_path);
  ASSERT_GE(fd, 0);
  close(fd);
  nh.setParam(name + "/scene", std::string("membrane_peeling"));
  nh.setParam(name + "/auto_start", true);
  nh.setParam(name + "/result_file", std::string(result_path));
  std::mutex mutex;
  std::size_t frames = 0;
  ros::Subscriber frame_subscriber =
      nh.subscribe<vrm_msgs::InputFrame>("/unload_probe/input_frame", 500, [&](const vrm_msgs::InputFrame::ConstPtr&) {
        std::lock_guard<std::mutex> lock(mutex);
        ++frames;
      });
  ros::Publisher instruments = nh.advertise<vrm_msgs::InstrumentState>("/unload_probe/instrument_state", 1000);
  ros::AsyncSpinner spinner(1);
  spinner.start();
  ASSERT_TRUE(ros::service::waitForService("/vrm_manager/load_nodelet", ros::Duration(30.0)));
  const std::string uri = managerUri();
  ASSERT_FALSE(uri.empty());

  const scene::SceneDescription scene =
      scene::withScript(scene::loadScene(scene::shippedScenePath("membrane_peeling")), "expert");
  const std::vector<world::InstrumentState> inputs =
      world::scriptedInputs(scene, 50.0, 1.5, world::fromSeconds(1000.0));
  ASSERT_LE(inputs.size(), 200u) << "more than scenario_manager's instrument queue holds";
  constexpr int kRounds = 3;
  for (int round = 0; round < kRounds; ++round) {
    SCOPED_TRACE("round " + std::to_string(round));
    nodelet::NodeletLoad load;
    load.request.name = name;
    load.request.type = "vrm_sim/scenario_manager";
    ASSERT_TRUE(ros::service::call("/vrm_manager/load_nodelet", load) && load.response.success);
    ASSERT_TRUE(waitForSubscribers(instruments, 30.0) && waitForPublishers(frame_subscriber, 30.0));
    {
      std::lock_guard<std::mutex> lock(mutex);
      frames = 0;
    }
    for (const auto& input : inputs) instruments.publish(boost::make_shared<vrm_msgs::InstrumentState>(toMsg(input)));
    ASSERT_TRUE(waitFor(
        [&] {
          std::lock_guard<std::mutex> lock(mutex);
          return frames >= 3;
        },
        30.0))
        << "the probe ran no frames";
    nodelet::NodeletUnload unload;
    unload.request.name = name;
    ASSERT_TRUE(ros::service::call("/vrm_manager/unload_nodelet", unload) && unload.response.success);
    // Gone once its frame in progress ended and it was destroyed (or the manager died with it).
    ASSERT_TRUE(waitFor([&] { return frame_subscriber.getNumPublishers() == 0; }, 30.0));
    nodelet::NodeletList list;
    ASSERT_TRUE(ros::service::call("/vrm_manager/list", list)) << "the manager is gone";
    EXPECT_EQ(managerUri(), uri) << "the manager died and was started again";
    EXPECT_EQ(std::count(list.response.nodelets.begin(), list.response.nodelets.end(), name), 0);
  }
  std::remove(result_path);
}

}  // namespace
}  // namespace vrm_sim

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_scenario");
  ros::NodeHandle nh;  // keeps the node's connections up between the tests
  return RUN_ALL_TESTS();
}
