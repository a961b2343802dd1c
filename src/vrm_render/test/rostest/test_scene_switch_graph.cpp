// Graph test (issue 32): the renderer follows the running scene that scenario_manager announces (latched
// vrm_msgs/RunningScene) without a restart. The test stands in for scenario_manager: it announces the renderer's own
// start-up scene (navigation: nothing changes), then membrane_peeling (the renderer reports it on /diagnostics and in
// its log with the switch time, subscribes the new scene's tissue topics, and its images change, from the first one
// stamped after the LOAD; announcements go out between two frames, as scenario_manager sends them), then a scene file
// that does not exist (an ERROR; the renderer keeps membrane_peeling and keeps rendering), then navigation again (the
// images are those of the start again: nothing of membrane_peeling is left).

#include <diagnostic_msgs/DiagnosticArray.h>
#include <gtest/gtest.h>
#include <ros/ros.h>
#include <rosgraph_msgs/Log.h>
#include <sensor_msgs/Image.h>
#include <vrm_msgs/InputFrame.h>
#include <vrm_msgs/RunningScene.h>
#include <vrm_msgs/TissueMesh.h>

#include <Eigen/Geometry>
#include <atomic>
#include <boost/make_shared.hpp>
#include <chrono>
#include <condition_variable>
#include <cstdlib>
#include <map>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "input_frames.h"
#include "vrm_scene/package_data.h"
#include "vrm_scene/scene_loader.h"
#include "vrm_sim/testing/graph_test.h"

namespace {

using vrm_sim::testing::AwaitedState;
using vrm_sim::testing::waitFor;

constexpr double kTimeout = 30.0;  // s of wall time for any one condition (loading a scene takes well under 1 s)

// What the renderer shows and says: its images, its /diagnostics status and its log lines.
class RendererWatch : public AwaitedState {
 public:
  explicit RendererWatch(ros::NodeHandle& nh)
      : images_(nh.subscribe("stereo/left/image_raw", 5, &RendererWatch::onImage, this)),
        diagnostics_(nh.subscribe("/diagnostics", 20, &RendererWatch::onDiagnostics, this)),
        log_(nh.subscribe("/rosout", 200, &RendererWatch::onLog, this)) {}

  // Guarded by mutex_.
  std::vector<sensor_msgs::Image::ConstPtr> images;
  std::vector<std::map<std::string, std::string>> statuses;  // the renderer's, in order of arrival
  std::vector<rosgraph_msgs::Log::ConstPtr> lines;           // the renderer's scene lines

  // The renderer's newest status says `key` = `value` (mutex_ held).
  bool reports(const std::string& key, const std::string& value) const {
    if (statuses.empty()) return false;
    const auto found = statuses.back().find(key);
    return found != statuses.back().end() && found->second == value;
  }
  // A log line of `level` containing `text` (mutex_ held).
  rosgraph_msgs::Log::ConstPtr line(std::uint8_t level, const std::string& text) const {
    for (const auto& entry : lines) {
      if (entry->level == level && entry->msg.find(text) != std::string::npos) return entry;
    }
    return nullptr;
  }

 private:
  void onImage(const sensor_msgs::Image::ConstPtr& image) {
    update([&] { images.push_back(image); });
  }
  void onDiagnostics(const diagnostic_msgs::DiagnosticArray::ConstPtr& array) {
    for (const auto& status : array->status) {
      if (status.hardware_id != "stereo_view") continue;
      std::map<std::string, std::string> values;
      for (const auto& entry : status.values) values[entry.key] = entry.value;
      update([&] { statuses.push_back(values); });
    }
  }
  void onLog(const rosgraph_msgs::Log::ConstPtr& line) {
    if (line->msg.find("stereo_renderer: ") == std::string::npos || line->msg.find("scene") == std::string::npos)
      return;
    update([&] { lines.push_back(line); });
  }

  ros::Subscriber images_, diagnostics_, log_;
};

// Stands in for scenario_manager's input frames: 50 Hz, stamped now, the eye at rest and membrane_peeling's two
// instruments held still (slots and types that navigation has as well, so both scenes show instruments).
class FrameSource {
 public:
  explicit FrameSource(ros::NodeHandle& nh) : publisher_(nh.advertise<vrm_msgs::InputFrame>("input_frame", 10)) {
    const vrm_sim::scene::SceneDescription scene = vrm_sim::scene::loadScene("membrane_peeling");
    for (const auto& instrument : scene.instruments) {
      const Eigen::Vector3d tip =
          instrument.path.empty() ? Eigen::Vector3d(-0.002, 0.001, -0.006) : instrument.path.front().tip_in_eye;
      instruments_.push_back(vrm_render::testing::appliedInstrument(
          vrm_sim::scene::toString(instrument.slot), vrm_sim::scene::toString(instrument.type),
          vrm_render::testing::poseThroughTrocar(scene, instrument, tip), 0.3, true));
    }
    thread_ = std::thread([this] {
      ros::WallRate rate(50.0);
      for (std::uint64_t sequence = 1; running_ && ros::ok(); ++sequence) {
        publishAnnouncement(&sequence);
        publisher_.publish(vrm_render::testing::simulationFrame(ros::Time::now(), sequence, instruments_));
        rate.sleep();
      }
    });
  }
  // Announces a scene between two frames, as scenario_manager does: a LOAD (load > 0) is an input frame of its own
  // (KIND_LOAD), stamped after every frame before it, then comes its announcement with the LOAD's stamp (on another
  // topic: it may reach the renderer after the frames that follow it). Returns once published.
  void announce(ros::Publisher& publisher, const vrm_msgs::RunningScene::Ptr& message) {
    std::unique_lock<std::mutex> lock(mutex_);
    announcement_publisher_ = &publisher;
    announcement_ = message;
    const bool published =
        announced_.wait_for(lock, std::chrono::duration<double>(kTimeout), [&] { return announcement_ == nullptr; });
    EXPECT_TRUE(published) << "the frame thread did not publish the announcement";
  }
  ~FrameSource() {
    running_ = false;
    thread_.join();
  }

 private:
  void publishAnnouncement(std::uint64_t* sequence) {
    std::lock_guard<std::mutex> lock(mutex_);
    if (!announcement_) return;
    if (announcement_->load != 0) {
      announcement_->header.stamp = ros::Time::now();
      auto load = vrm_render::testing::simulationFrame(announcement_->header.stamp, (*sequence)++, instruments_);
      load->kind = vrm_msgs::InputFrame::KIND_LOAD;
      publisher_.publish(load);
    }
    announcement_publisher_->publish(announcement_);
    announcement_ = nullptr;
    announced_.notify_all();
  }

  ros::Publisher publisher_;
  std::mutex mutex_;
  std::condition_variable announced_;
  ros::Publisher* announcement_publisher_ = nullptr;  // guarded by mutex_, like announcement_
  vrm_msgs::RunningScene::Ptr announcement_;
  std::vector<vrm_msgs::AppliedInstrument> instruments_;
  std::atomic<bool> running_{true};
  std::thread thread_;
};

// The announcement scenario_manager makes after loading `name` (load 0: its start-up scene).
vrm_msgs::RunningScene::Ptr announcement(const std::string& name, std::uint32_t load) {
  const vrm_sim::scene::SceneDescription scene = vrm_sim::scene::loadScene(name);
  auto message = boost::make_shared<vrm_msgs::RunningScene>();
  message->header.stamp = load == 0 ? ros::Time(0) : ros::Time::now();
  message->load = load;
  message->name = scene.name;
  message->file = scene.source_file;
  message->difficulty = scene.scenario ? scene.scenario->difficulty : "";
  message->seed = 1;
  message->content_hash = vrm_sim::scene::sceneContentHash(message->file, message->difficulty);
  return message;
}

// Pixels that differ by more than a few levels in some channel.
int differingPixels(const sensor_msgs::Image& a, const sensor_msgs::Image& b) {
  if (a.data.size() != b.data.size()) return static_cast<int>(a.width * a.height);
  int count = 0;
  for (std::size_t i = 0; i + 2 < a.data.size(); i += 3) {
    bool differs = false;
    for (std::size_t c = 0; c < 3; ++c) differs |= std::abs(int(a.data[i + c]) - int(b.data[i + c])) > 8;
    count += differs ? 1 : 0;
  }
  return count;
}

class SceneSwitchGraph : public ::testing::Test {
 protected:
  SceneSwitchGraph() : spinner_(2) {
    vrm_sim::usePackageData();
    spinner_.start();
  }

  // A frame rendered after everything the renderer reported so far: the status and the log line of a switch come
  // after the switch, and images are taken from a few frames later (topics are not ordered among each other).
  sensor_msgs::Image::ConstPtr nextFrames(RendererWatch& watch, std::size_t count = 3) {
    std::size_t seen = 0;
    {
      std::lock_guard<std::mutex> lock(watch.mutex_);
      seen = watch.images.size();
    }
    EXPECT_TRUE(watch.waitFor([&] { return watch.images.size() >= seen + count; }, kTimeout))
        << "no frames from the renderer";
    std::lock_guard<std::mutex> lock(watch.mutex_);
    return watch.images.empty() ? nullptr : watch.images.back();
  }
  // Two more statuses: the newest then describes the renderer after everything it received before the first.
  bool twoMoreStatuses(RendererWatch& watch) {
    std::size_t seen = 0;
    {
      std::lock_guard<std::mutex> lock(watch.mutex_);
      seen = watch.statuses.size();
    }
    return watch.waitFor([&] { return watch.statuses.size() >= seen + 2; }, kTimeout);
  }

  ros::AsyncSpinner spinner_;
};

TEST_F(SceneSwitchGraph, TheRendererFollowsTheAnnouncedSceneAndKeepsItsSceneWhenOneCannotBeLoaded) {
  ros::NodeHandle nh;
  RendererWatch watch(nh);
  FrameSource frames(nh);
  ros::Publisher running_scene = nh.advertise<vrm_msgs::RunningScene>("running_scene", 1, /*latch=*/true);
  ros::Publisher tissue_membrane = nh.advertise<vrm_msgs::TissueMesh>("tissue/membrane", 1);
  ASSERT_TRUE(waitFor([&] { return running_scene.getNumSubscribers() > 0; }, kTimeout)) << "running_scene unheard";

  // 1. The start-up announcement of the scene the renderer runs already: no switch.
  frames.announce(running_scene, announcement("navigation", 0));
  const sensor_msgs::Image::ConstPtr navigation = nextFrames(watch);
  ASSERT_TRUE(navigation);
  ASSERT_TRUE(twoMoreStatuses(watch));
  {
    std::lock_guard<std::mutex> lock(watch.mutex_);
    EXPECT_TRUE(watch.reports("scene", "navigation"));
    EXPECT_TRUE(watch.reports("scene switches", "0")) << "announcing the shown scene must change nothing";
  }
  EXPECT_EQ(tissue_membrane.getNumSubscribers(), 0u) << "navigation has no membrane";

  // 2. A LOAD the simulation accepted: the renderer switches, says so, and draws the new scene.
  const vrm_msgs::RunningScene::Ptr peeling_announced = announcement("membrane_peeling", 1);
  frames.announce(running_scene, peeling_announced);
  EXPECT_TRUE(watch.waitFor([&] { return watch.reports("scene", "membrane_peeling"); }, kTimeout))
      << "the renderer's diagnostics do not report the announced scene";
  {
    std::lock_guard<std::mutex> lock(watch.mutex_);
    EXPECT_TRUE(watch.reports("scene load", "1"));
    EXPECT_TRUE(watch.reports("scene switches", "1"));
  }
  ASSERT_TRUE(watch.waitFor(
      [&] { return watch.line(rosgraph_msgs::Log::INFO, "'membrane_peeling' (load 1)") != nullptr; }, kTimeout))
      << "no log line of the switch";
  {
    std::lock_guard<std::mutex> lock(watch.mutex_);
    const std::string& text = watch.line(rosgraph_msgs::Log::INFO, "'membrane_peeling' (load 1)")->msg;
    std::printf("switch logged: %s\n", text.c_str());
    EXPECT_NE(text.find("replaces 'navigation'"), std::string::npos) << text;
    EXPECT_NE(text.find(" ms"), std::string::npos) << text;
  }
  EXPECT_TRUE(waitFor([&] { return tissue_membrane.getNumSubscribers() > 0; }, kTimeout))
      << "the new scene's deformable membrane: tissue/membrane not subscribed";
  const sensor_msgs::Image::ConstPtr peeling = nextFrames(watch);
  ASSERT_TRUE(peeling);
  const int pixels = static_cast<int>(peeling->width * peeling->height);
  const int changed = differingPixels(*navigation, *peeling);
  std::printf("navigation -> membrane_peeling: %d of %d pixels differ\n", changed, pixels);
  EXPECT_GT(changed, pixels / 50) << "the image did not change with the scene";
  {
    // An image stamped after the LOAD shows the scene that ran then: none shows navigation's objects.
    std::lock_guard<std::mutex> lock(watch.mutex_);
    int after_load = 0;
    for (const auto& image : watch.images) {
      if (image->header.stamp < peeling_announced->header.stamp) continue;
      ++after_load;
      EXPECT_GT(differingPixels(*navigation, *image), pixels / 50)
          << "an image stamped after the LOAD still shows navigation (stamp " << image->header.stamp << ")";
    }
    EXPECT_GT(after_load, 0);
  }

  // 3. An announcement of a scene that cannot be loaded: an ERROR, and the renderer keeps its scene and renders.
  auto bad = announcement("membrane_peeling", 2);
  bad->name = "no_such_scene";
  bad->file = "/nonexistent/no_such_scene.yaml";
  bad->content_hash = 0;
  frames.announce(running_scene, bad);
  EXPECT_TRUE(
      watch.waitFor([&] { return watch.line(rosgraph_msgs::Log::ERROR, "no_such_scene") != nullptr; }, kTimeout))
      << "no ERROR for a scene that cannot be loaded";
  const sensor_msgs::Image::ConstPtr still = nextFrames(watch);
  ASSERT_TRUE(still) << "the renderer stopped rendering";
  ASSERT_TRUE(twoMoreStatuses(watch));
  {
    std::lock_guard<std::mutex> lock(watch.mutex_);
    EXPECT_TRUE(watch.reports("scene", "membrane_peeling"));
    EXPECT_TRUE(watch.reports("scene switches", "1"));
  }
  EXPECT_LT(differingPixels(*peeling, *still), pixels / 200) << "the scene changed after a failed load";
  EXPECT_GT(tissue_membrane.getNumSubscribers(), 0u);

  // 4. Back to navigation: the images are those of the start (nothing of membrane_peeling left), the membrane's
  // tissue is no longer listened to.
  frames.announce(running_scene, announcement("navigation", 3));
  EXPECT_TRUE(watch.waitFor([&] { return watch.reports("scene switches", "2"); }, kTimeout));
  {
    std::lock_guard<std::mutex> lock(watch.mutex_);
    EXPECT_TRUE(watch.reports("scene", "navigation"));
  }
  EXPECT_TRUE(waitFor([&] { return tissue_membrane.getNumSubscribers() == 0; }, kTimeout))
      << "tissue/membrane still subscribed in a scene without a membrane";
  const sensor_msgs::Image::ConstPtr again = nextFrames(watch);
  ASSERT_TRUE(again);
  const int left_over = differingPixels(*navigation, *again);
  std::printf("navigation at the start -> navigation after membrane_peeling: %d of %d pixels differ\n", left_over,
              pixels);
  EXPECT_LT(left_over, pixels / 200) << "the scene after a round trip differs from the same scene at the start";
}

}  // namespace

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_scene_switch_graph");
  return RUN_ALL_TESTS();
}
