// The object manipulation modules (issue 36), laser coagulation (issue 37), retina relocation and posterior hyaloid
// detachment (issue 38) in one running graph: LOAD object_manipulation, expert then novice (each session begun by a
// LOAD of the module and its START), then LOAD bimanual, laser_coagulation (its sessions' pedal tracks played too: the
// laser fires on the pedal), retina_relocation (the needle's injection flow rides on its instrument states) and
// posterior_hyaloid, the same.
// Each expert finishes and outscores its novice with the score the same inputs give headless (one simulation core),
// simulation_state carries the objects the scenario moves (what the renderer draws) away from their scene poses while
// they are carried, and the laser burns.
#include <gtest/gtest.h>
#include <ros/ros.h>

#include <map>
#include <mutex>
#include <optional>
#include <string>

#include "graph_test_util.h"
#include "vrm_msgs/InstrumentState.h"
#include "vrm_msgs/PedalState.h"
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

struct Observed {
  std::mutex mutex;
  vrm_msgs::ScenarioStatus status;
  bool have_status = false;
  vrm_msgs::Score score;
  std::uint64_t scores = 0;
  world::Stamp last_frame = -1;
  std::map<std::string, double> farthest_move;  // per moved object: its largest distance from its scene pose (m)
  std::size_t most_burns = 0;                   // laser burns in one simulation_state
};

class ManipulationModules : public ::testing::Test {
 protected:
  void SetUp() override {
    status_sub_ = nh_.subscribe<vrm_msgs::ScenarioStatus>("scenario_status", 50,
                                                          [this](const vrm_msgs::ScenarioStatus::ConstPtr& status) {
                                                            std::lock_guard<std::mutex> lock(observed_.mutex);
                                                            observed_.status = *status;
                                                            observed_.have_status = true;
                                                          });
    score_sub_ = nh_.subscribe<vrm_msgs::Score>("score", 5, [this](const vrm_msgs::Score::ConstPtr& score) {
      std::lock_guard<std::mutex> lock(observed_.mutex);
      observed_.score = *score;
      ++observed_.scores;
    });
    state_sub_ = nh_.subscribe<vrm_msgs::SimulationState>(
        "simulation_state", 100, [this](const vrm_msgs::SimulationState::ConstPtr& state) {
          std::lock_guard<std::mutex> lock(observed_.mutex);
          observed_.last_frame = toStamp(state->header.stamp);
          observed_.most_burns = std::max(observed_.most_burns, state->burns.size());
          for (const vrm_msgs::ObjectPose& object : state->objects) {
            const auto start = scene_start_.find(object.name);
            if (start == scene_start_.end()) continue;
            const double moved = (toEigen(object.pose).translation() - start->second).norm();
            double& farthest = observed_.farthest_move[object.name];
            farthest = std::max(farthest, moved);
          }
        });
    commands_ = nh_.advertise<vrm_msgs::ScenarioCommand>("scenario_command", 10);
    instruments_ = nh_.advertise<vrm_msgs::InstrumentState>("instrument_state", 100);
    pedals_ = nh_.advertise<vrm_msgs::PedalState>("pedals", 100);
    spinner_.start();
    ASSERT_TRUE(waitFor(
        [&] {
          std::lock_guard<std::mutex> lock(observed_.mutex);
          return observed_.have_status && commands_.getNumSubscribers() > 0 && instruments_.getNumSubscribers() > 0;
        },
        30.0))
        << "scenario_manager did not come up";
  }

  vrm_msgs::ScenarioStatus status() {
    std::lock_guard<std::mutex> lock(observed_.mutex);
    return observed_.status;
  }

  void command(std::uint8_t type, const std::string& scenario, double stamp) {
    auto message = boost::make_shared<vrm_msgs::ScenarioCommand>();
    message->header.stamp = ros::Time(stamp);
    message->command = type;
    message->scenario = scenario;
    commands_.publish(message);
  }

  // A fresh session of `module` (LOAD), started at `start`, with the scene's scripted `script` played tick by tick;
  // returns the final score (total < 0 when the session did not end). `start` becomes the stamp after the session's
  // last tick: the sessions follow each other on one clock, as a trainee's do (the mediator holds back a stamp that
  // jumps far ahead of the others as implausible).
  vrm_msgs::Score play(const std::string& module, const std::string& script, double& start) {
    const std::uint64_t scores_before = [&] {
      std::lock_guard<std::mutex> lock(observed_.mutex);
      return observed_.scores;
    }();
    command(vrm_msgs::ScenarioCommand::LOAD, module, start - 0.2);
    EXPECT_TRUE(
        waitFor([&] { return status().scenario == module && status().state == vrm_msgs::ScenarioStatus::IDLE; }, 20.0))
        << module << ": " << status().message;
    const scene::SceneDescription scene = scene::withScript(scene::loadScene(scene::shippedScenePath(module)), script);
    {
      std::lock_guard<std::mutex> lock(observed_.mutex);
      scene_start_.clear();
      for (const scene::ObjectDescription& object : scene.objects) scene_start_[object.name] = object.pose.xyz;
    }
    command(vrm_msgs::ScenarioCommand::START, "", start);
    const std::vector<world::InstrumentState> inputs =
        world::scriptedInputs(scene, 50.0, scene.scriptedDuration() + 2.0, world::fromSeconds(start));
    auto last_frame = [&] {
      std::lock_guard<std::mutex> lock(observed_.mutex);
      return observed_.last_frame;
    };
    auto ended = [&] {
      const std::uint8_t state = status().state;
      return state == vrm_msgs::ScenarioStatus::FINISHED || state == vrm_msgs::ScenarioStatus::FAILED;
    };
    // The session's pedal track, sampled at each tick's stamp (the pedal twin's part in the product).
    const std::vector<scene::PedalWaypoint> pedals =
        scene::findScript(scene::loadScene(scene::shippedScenePath(module)), script).pedals;
    const world::Stamp origin = world::fromSeconds(start);
    world::Stamp played = origin;
    std::optional<world::Stamp> pedal_published;
    EXPECT_TRUE(playTicks(
        instruments_, inputs, last_frame,
        [&](world::Stamp stamp, std::size_t) {
          played = stamp;
          return !ended();
        },
        [&](world::Stamp stamp) {
          if (pedals.empty()) return;
          // Lockstep: the mediator holds a frame back for its pedal state one frame at most, so a pose of the next
          // stamp overtaking the pedal state (two connections; it happens on a loaded machine) would move the pedal
          // edge one frame later than headless. The previous tick's frame, closed, had its pedal state.
          if (pedal_published) {
            EXPECT_TRUE(waitFor([&] { return last_frame() >= *pedal_published; }, 10.0))
                << module << " " << script << ": no frame for the pedal state of " << *pedal_published;
          }
          pedal_published = stamp;
          world::PedalState pedal;
          pedal.stamp = stamp;
          pedal.travel = scene::samplePedals(pedals, world::toSeconds(stamp - origin)).travel;
          pedals_.publish(boost::make_shared<vrm_msgs::PedalState>(toMsg(pedal)));
        }))
        << module << " " << script;
    start = world::toSeconds(played) + 0.5;
    vrm_msgs::Score score;
    score.total = -1.0;
    if (!waitFor([&] { return ended(); }, 10.0)) return score;
    EXPECT_TRUE(waitFor(
        [&] {
          std::lock_guard<std::mutex> lock(observed_.mutex);
          return observed_.scores > scores_before;
        },
        10.0));
    std::lock_guard<std::mutex> lock(observed_.mutex);
    return observed_.score;
  }

  double farthestMove(const std::string& object) {
    std::lock_guard<std::mutex> lock(observed_.mutex);
    return observed_.farthest_move[object];
  }

  static double item(const vrm_msgs::Score& score, const std::string& name) {
    for (const auto& entry : score.items) {
      if (entry.name == name) return entry.value;
    }
    ADD_FAILURE() << "no item " << name;
    return std::nan("");
  }

  ros::NodeHandle nh_;
  ros::AsyncSpinner spinner_{2};
  Observed observed_;
  std::map<std::string, Eigen::Vector3d> scene_start_;  // guarded by observed_.mutex
  ros::Subscriber status_sub_, score_sub_, state_sub_;
  ros::Publisher commands_, instruments_, pedals_;
};

TEST_F(ManipulationModules, EveryModuleLoadedInOneGraphExpertsFinishAndOutscoreTheirNovices) {
  double start = 100.0;
  for (const std::string module :
       {"object_manipulation", "bimanual", "laser_coagulation", "retina_relocation", "posterior_hyaloid"}) {
    std::map<std::string, vrm_msgs::Score> scores;
    for (const std::string script : {"expert", "novice"}) {
      scores[script] = play(module, script, start);
      EXPECT_EQ(status().state, vrm_msgs::ScenarioStatus::FINISHED)
          << module << " " << script << ": " << status().message;
      // One simulation core: the graph scores what the same inputs score headless.
      world::ScenarioRunOptions options;
      options.script = script;
      const world::ScenarioRunResult offline =
          world::runScenario(scene::loadScene(scene::shippedScenePath(module)), options);
      EXPECT_NEAR(scores[script].total, offline.score.total, 1e-9) << module << " " << script;
    }
    EXPECT_GT(scores["expert"].total, scores["novice"].total + 10.0) << module;
    EXPECT_EQ(item(scores["expert"], "completed"), 1.0) << module;
  }
  // simulation_state carried the objects while the scenarios moved them (the renderer draws them from it).
  EXPECT_GT(farthestMove("box"), 2e-3) << "the box was never drawn away from its scene pose";
  EXPECT_GT(farthestMove("key"), 2e-3);
  EXPECT_GT(farthestMove("bar"), 2e-3);
  // and the laser burns (the renderer paints them into the fundus): the expert's row of 12.
  std::lock_guard<std::mutex> lock(observed_.mutex);
  EXPECT_GE(observed_.most_burns, 12u);
}

}  // namespace
}  // namespace vrm_sim

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_manipulation_modules");
  return RUN_ALL_TESTS();
}
