// The live graph and the offline tool run one simulation core (world::World): the same instrument sequence through
// scenario_manager (as messages, in ticks) and through tissue_offline (library and process) ends in the same state
// hash.
#include <gtest/gtest.h>
#include <ros/ros.h>

#include <cstdio>
#include <map>
#include <mutex>
#include <string>

#include "graph_test_util.h"
#include "vrm_msgs/InstrumentState.h"
#include "vrm_msgs/SimulationState.h"
#include "vrm_msgs/TissueMesh.h"
#include "vrm_scene/scene_loader.h"
#include "vrm_sim/conversions.h"
#include "vrm_sim/world/offline.h"

namespace vrm_sim {
namespace {

using testing::waitFor;

constexpr double kSeconds = 1.2;
constexpr double kRate = 50.0;

struct Observed {
  std::mutex mutex;
  world::Stamp last_stamp = -1;
  std::uint64_t last_hash = 0;
  std::uint64_t frames = 0;
  std::uint32_t max_grasped = 0;
  std::uint64_t meshes = 0;
};

std::string offlineProcessHash() {
  const std::string command = std::string(VRM_TISSUE_OFFLINE_BINARY) + " --scene membrane_peeling --seconds " +
                              std::to_string(kSeconds) + " --rate " + std::to_string(kRate);
  FILE* pipe = popen(command.c_str(), "r");
  if (pipe == nullptr) return "";
  std::string output;
  char buffer[1024];
  while (std::fgets(buffer, sizeof(buffer), pipe) != nullptr) output += buffer;
  pclose(pipe);
  const std::string key = "\"final_state_hash\": \"";
  const auto at = output.find(key);
  return at == std::string::npos ? output : output.substr(at + key.size(), 18);
}

TEST(CoreEquivalence, TheGraphAndTheOfflineToolEndInTheSameState) {
  ros::NodeHandle nh;
  Observed observed;
  ros::Subscriber states = nh.subscribe<vrm_msgs::SimulationState>(
      "simulation_state", 100, [&](const vrm_msgs::SimulationState::ConstPtr& state) {
        std::lock_guard<std::mutex> lock(observed.mutex);
        observed.last_stamp = toStamp(state->header.stamp);
        observed.last_hash = state->state_hash;
        ++observed.frames;
        for (const auto& tissue : state->tissues)
          observed.max_grasped = std::max(observed.max_grasped, tissue.grasped_nodes);
      });
  ros::Subscriber meshes =
      nh.subscribe<vrm_msgs::TissueMesh>("tissue/membrane", 100, [&](const vrm_msgs::TissueMesh::ConstPtr&) {
        std::lock_guard<std::mutex> lock(observed.mutex);
        ++observed.meshes;
      });
  ros::Publisher instruments = nh.advertise<vrm_msgs::InstrumentState>("instrument_state", 100);
  ros::AsyncSpinner spinner(2);
  spinner.start();
  ASSERT_TRUE(waitFor([&] { return instruments.getNumSubscribers() > 0 && states.getNumPublishers() > 0; }, 30.0))
      << "scenario_manager did not come up";

  const scene::SceneDescription scene = scene::loadScene(scene::shippedScenePath("membrane_peeling"));
  const std::vector<world::InstrumentState> inputs =
      world::scriptedInputs(scene, kRate, kSeconds, world::fromSeconds(1000.0));
  ASSERT_TRUE(playTicks(instruments, inputs, [&] {
    std::lock_guard<std::mutex> lock(observed.mutex);
    return observed.last_stamp;
  }));

  world::OfflineOptions options;
  options.seconds = kSeconds;
  options.rate = kRate;
  const world::OfflineResult offline = world::runOffline(scene, options);
  std::lock_guard<std::mutex> lock(observed.mutex);
  EXPECT_EQ(observed.frames, offline.frames);
  EXPECT_EQ(observed.last_hash, offline.final_state_hash);
  char hash[24];
  std::snprintf(hash, sizeof(hash), "0x%016llx", static_cast<unsigned long long>(observed.last_hash));
  EXPECT_EQ(offlineProcessHash(), std::string(hash));
  // The scripted peel really grasps and moves the membrane in the graph.
  EXPECT_GT(observed.max_grasped, 0u);
  EXPECT_GT(observed.meshes, 10u);
}

}  // namespace
}  // namespace vrm_sim

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_core_equivalence");
  return RUN_ALL_TESTS();
}
