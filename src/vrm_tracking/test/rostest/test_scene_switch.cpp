// The tracking side follows the running scene (scene_switch.test, issue 32). The test is the scene owner's stand-in:
// it announces running_scene (latched) as scenario_manager does — the start-up scene, then a scene with the eye
// centre 1 mm off and the trocars at azimuths 140 / 40 deg, then a file that does not exist — and checks what the
// tracker says it uses (/diagnostics) and what tracker and scripted surgeon publish: the eye's rotation centre and
// each instrument's trocar (tip - insertion_depth * shaft_axis). Conditions are awaited with timeouts, never slept.
#include <diagnostic_msgs/DiagnosticArray.h>
#include <gtest/gtest.h>
#include <ros/ros.h>
#include <rosgraph_msgs/Log.h>
#include <vrm_msgs/EyeState.h>
#include <vrm_msgs/InstrumentState.h>
#include <vrm_msgs/RunningScene.h>

#include <Eigen/Core>
#include <boost/make_shared.hpp>
#include <map>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "vrm_scene/package_data.h"
#include "vrm_scene/scene_loader.h"
#include "vrm_sim/testing/graph_test.h"
#include "vrm_tracking/conversions.h"
#include "vrm_tracking/scene_trocars.h"

namespace vrm_tracking {
namespace {

using Values = std::map<std::string, std::string>;

Eigen::Vector3d trocarOf(const vrm_msgs::InstrumentState& msg) {
  return toEigen(msg.tip_pose.position) - msg.insertion_depth * toEigen(msg.shaft_axis);
}

class Listener : public vrm_sim::testing::AwaitedState {
 public:
  explicit Listener(ros::NodeHandle& nh) {
    subs_.push_back(nh.subscribe("/diagnostics", 100, &Listener::onDiagnostics, this));
    subs_.push_back(nh.subscribe("/rosout", 100, &Listener::onLog, this));
    subs_.push_back(nh.subscribe("eye_state", 20, &Listener::onEye, this));
    subs_.push_back(nh.subscribe("instrument_state", 20, &Listener::onInstrument, this));
    subs_.push_back(nh.subscribe("ground_truth/eye_state", 20, &Listener::onTruthEye, this));
    subs_.push_back(nh.subscribe("ground_truth/instrument_state", 20, &Listener::onTruthInstrument, this));
  }

  // The tracker's statuses, in arrival order (key/values of each).
  std::vector<Values> statuses;
  std::vector<std::string> errors;                                        // ERROR log lines of the graph
  std::optional<vrm_msgs::EyeState> tracked_eye, truth_eye;               // the newest valid ones
  std::map<std::string, Eigen::Vector3d> tracked_trocars, truth_trocars;  // per slot, from the newest valid state

  // Forgets the poses, so a wait sees only states published from now on.
  void clearPoses() {
    tracked_eye.reset();
    truth_eye.reset();
    tracked_trocars.clear();
    truth_trocars.clear();
  }

 private:
  void onDiagnostics(const diagnostic_msgs::DiagnosticArray::ConstPtr& m) {
    for (const auto& status : m->status) {
      if (status.name.find("pose reconstruction") == std::string::npos) continue;
      Values values;
      for (const auto& kv : status.values) values[kv.key] = kv.value;
      update([&] { statuses.push_back(values); });
    }
  }
  void onLog(const rosgraph_msgs::Log::ConstPtr& m) {
    if (m->level >= rosgraph_msgs::Log::ERROR) update([&] { errors.push_back(m->msg); });
  }
  void onEye(const vrm_msgs::EyeState::ConstPtr& m) {
    if (m->valid) update([&] { tracked_eye = *m; });
  }
  void onTruthEye(const vrm_msgs::EyeState::ConstPtr& m) {
    update([&] { truth_eye = *m; });
  }
  void onInstrument(const vrm_msgs::InstrumentState::ConstPtr& m) {
    if (m->valid) update([&] { tracked_trocars[m->instrument_id] = trocarOf(*m); });
  }
  void onTruthInstrument(const vrm_msgs::InstrumentState::ConstPtr& m) {
    update([&] { truth_trocars[m->instrument_id] = trocarOf(*m); });
  }

  std::vector<ros::Subscriber> subs_;
};

// What scenario_manager announces for a scene it loaded.
vrm_msgs::RunningScene::Ptr announcement(const vrm_sim::scene::SceneDescription& scene, std::uint32_t load) {
  auto msg = boost::make_shared<vrm_msgs::RunningScene>();
  msg->load = load;
  msg->name = scene.name;
  msg->file = scene.source_file;
  msg->difficulty = scene.scenario ? scene.scenario->difficulty : "";
  msg->seed = 1;
  msg->content_hash = vrm_sim::scene::sceneContentHash(msg->file, msg->difficulty);
  return msg;
}

bool near(const Eigen::Vector3d& a, const Eigen::Vector3d& b, double tolerance) { return (a - b).norm() < tolerance; }

std::string get(const Values& values, const std::string& key) {
  const auto it = values.find(key);
  return it == values.end() ? "<missing>" : it->second;
}

// Whether the newest status shows `scene_name` at `load`.
bool statusShows(const Listener& l, const std::string& scene_name, const std::string& load) {
  return !l.statuses.empty() && get(l.statuses.back(), "scene") == scene_name &&
         get(l.statuses.back(), "scene_load") == load;
}

// The poses of both slots, tracked and true, all at the trocars and eye centre of `scene`.
bool posesFollow(const Listener& l, const vrm_sim::scene::SceneDescription& scene, double tolerance) {
  if (!l.tracked_eye || !l.truth_eye) return false;
  const Eigen::Vector3d centre = scene.eye.centre_in_world;
  if (!near(toEigen(l.tracked_eye->rotation_center), centre, 1e-9)) return false;
  if (!near(toEigen(l.truth_eye->rotation_center), centre, 1e-9)) return false;
  for (const std::string slot : {"left", "right"}) {
    const Eigen::Vector3d trocar = sceneTrocarForSlot(scene, slot);
    const auto tracked = l.tracked_trocars.find(slot);
    const auto truth = l.truth_trocars.find(slot);
    if (tracked == l.tracked_trocars.end() || !near(tracked->second, trocar, tolerance)) return false;
    if (truth == l.truth_trocars.end() || !near(truth->second, trocar, tolerance)) return false;
  }
  return true;
}

TEST(SceneSwitch, TrackerAndSurgeonFollowTheRunningSceneAndKeepItOnABadAnnouncement) {
  ros::NodeHandle nh;
  ros::NodeHandle pnh("~");
  vrm_sim::usePackageData();
  const vrm_sim::scene::SceneDescription start =
      vrm_sim::scene::loadScene(pnh.param<std::string>("start_scene", "membrane_peeling"));
  const vrm_sim::scene::SceneDescription moved = vrm_sim::scene::loadScene(pnh.param<std::string>("test_scene", ""));
  ASSERT_EQ(moved.eye.centre_in_world, Eigen::Vector3d(0.001, 0.0, 0.0)) << "the test scene's eye moved 1 mm";

  Listener l(nh);
  ros::Publisher running_scene = nh.advertise<vrm_msgs::RunningScene>("running_scene", 1, /*latch=*/true);
  // The manager (one connection for tracker and surgeon, both in it) is up; the announcements are latched anyway.
  ASSERT_TRUE(vrm_sim::testing::waitForSubscribers(running_scene, 60.0))
      << "nobody subscribes to running_scene (tracker, scripted surgeon)";

  // 1. The start-up scene, the one both started with: nothing to load; the status says which announcement it is.
  running_scene.publish(announcement(start, 0));
  ASSERT_TRUE(l.waitFor([&] { return statusShows(l, start.name, "0"); }, 30.0))
      << "the tracker's status does not show the start-up scene " << start.name << " at load 0";
  // Trocar positions are exact in the tracker (the layout's); in the truth recovered from tip and shaft (float
  // arithmetic over a 12 mm lever: well below 1 um).
  ASSERT_TRUE(l.waitFor([&] { return posesFollow(l, start, 1e-6); }, 30.0))
      << "tracked and true poses are not at the start-up scene's eye centre and trocars";

  // 2. Another scene: eye centre 1 mm off, trocars at azimuths 140 / 40 deg.
  running_scene.publish(announcement(moved, 1));
  ASSERT_TRUE(l.waitFor([&] { return statusShows(l, moved.name, "1"); }, 30.0))
      << "the tracker's status does not show the announced scene " << moved.name;
  {
    std::lock_guard<std::mutex> lock(l.mutex_);
    const Values& status = l.statuses.back();
    EXPECT_EQ(get(status, "eye_centre"), "0.001000 0.000000 0.000000");
    EXPECT_EQ(get(status, "trocar_left_azimuth_deg"), "140.00");
    EXPECT_EQ(get(status, "trocar_right_azimuth_deg"), "40.00");
    EXPECT_EQ(get(status, "scene_file"), moved.source_file);
    l.clearPoses();
  }
  EXPECT_TRUE(l.waitFor([&] { return posesFollow(l, moved, 1e-6); }, 30.0))
      << "tracked and true poses are not at the new scene's eye centre and trocars: the surgeon (truth) or the "
         "tracker did not switch";

  // 3. A scene that cannot be loaded: both say why (ERROR) and keep the scene they have.
  const std::string missing = "/nonexistent/scene_switch_missing.yaml";
  auto bad = boost::make_shared<vrm_msgs::RunningScene>(*announcement(moved, 2));
  bad->name = "missing";
  bad->file = missing;
  bad->content_hash = 12345;
  std::size_t statuses_before = 0;
  {
    std::lock_guard<std::mutex> lock(l.mutex_);
    statuses_before = l.statuses.size();
  }
  running_scene.publish(bad);
  const auto errorsAbout = [&](const std::string& prefix) {
    for (const std::string& e : l.errors) {
      if (e.rfind(prefix, 0) == 0 && e.find(missing) != std::string::npos) return true;
    }
    return false;
  };
  EXPECT_TRUE(l.waitFor([&] { return errorsAbout("tracker: cannot follow running scene"); }, 30.0))
      << "no ERROR from the tracker about the missing scene file";
  EXPECT_TRUE(l.waitFor([&] { return errorsAbout("cannot follow running scene"); }, 30.0))
      << "no ERROR from the scripted surgeon about the missing scene file";
  // Two statuses after the error: the geometry in use is still the test scene's.
  ASSERT_TRUE(l.waitFor([&] { return l.statuses.size() >= statuses_before + 2; }, 30.0));
  {
    std::lock_guard<std::mutex> lock(l.mutex_);
    const Values& status = l.statuses.back();
    EXPECT_EQ(get(status, "scene"), moved.name);
    EXPECT_EQ(get(status, "scene_load"), "1");
    EXPECT_EQ(get(status, "eye_centre"), "0.001000 0.000000 0.000000");
    EXPECT_EQ(get(status, "trocar_left_azimuth_deg"), "140.00");
    EXPECT_EQ(get(status, "trocar_right_azimuth_deg"), "40.00");
    l.clearPoses();
  }
  EXPECT_TRUE(l.waitFor([&] { return posesFollow(l, moved, 1e-6); }, 30.0))
      << "after a bad announcement the poses left the test scene's geometry";
}

}  // namespace
}  // namespace vrm_tracking

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_scene_switch");
  ros::AsyncSpinner spinner(1);
  spinner.start();
  const int result = RUN_ALL_TESTS();
  spinner.stop();
  ros::shutdown();
  return result;
}
