// Graph test of the stereo_renderer nodelet: with input frames coming (the test stands in for scenario_manager),
// left and right images arrive in pairs with equal stamps, the stamps increase monotonically, the stamp spacing
// matches the configured rate (stamps are input stamps, so this is not a wall-clock assertion), and the images show
// the lit scene. The camera frames are on tf with the images' stamps (REP-103 optical axes looking down at the eye),
// CameraInfo carries the same frame id, the snapshot service writes the stereo pair, and the replayed ghost
// instruments are subscribed (input frames, and instrument states of a bag recorded before them).

#include <gtest/gtest.h>
#include <ros/ros.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>
#include <std_srvs/Trigger.h>
#include <tf2_ros/transform_listener.h>
#include <vrm_msgs/InputFrame.h>
#include <vrm_msgs/InstrumentState.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <atomic>
#include <cstdio>
#include <fstream>
#include <map>
#include <mutex>
#include <thread>
#include <vector>

#include "input_frames.h"
#include "vrm_scene/package_data.h"
#include "vrm_scene/scene_loader.h"
#include "vrm_sim/testing/graph_test.h"

namespace {

using vrm_sim::testing::waitFor;
using vrm_sim::testing::waitForSubscribers;

struct Collected {
  std::mutex mutex;
  std::vector<sensor_msgs::Image::ConstPtr> left, right;
  std::vector<sensor_msgs::CameraInfo::ConstPtr> right_info;
};

// Stands in for scenario_manager: an input frame every 20 ms of wall time (50 Hz, stamped now), with the scene's
// instruments valid and held still (the light pipe aimed at the posterior pole, the forceps at the start of the
// scripted peel).
class FrameSource {
 public:
  explicit FrameSource(ros::NodeHandle& nh) : publisher_(nh.advertise<vrm_msgs::InputFrame>("input_frame", 10)) {
    vrm_sim::usePackageData();
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
        publisher_.publish(vrm_render::testing::simulationFrame(ros::Time::now(), sequence, instruments_));
        rate.sleep();
      }
    });
  }
  ~FrameSource() {
    running_ = false;
    thread_.join();
  }

 private:
  ros::Publisher publisher_;
  std::vector<vrm_msgs::AppliedInstrument> instruments_;
  std::atomic<bool> running_{true};
  std::thread thread_;
};

bool isPng(const std::string& path) {
  std::ifstream file(path, std::ios::binary);
  char signature[8] = {};
  file.read(signature, 8);
  return file.good() && std::string(signature + 1, 3) == "PNG";
}

TEST(StereoRendererGraph, PublishesPairedImagesAtTheRateWithMonotonicStamps) {
  ros::NodeHandle nh;
  ros::NodeHandle pnh("~");
  const double rate = pnh.param("rate", 10.0);
  const int frames = pnh.param("frames", 12);
  const int width = pnh.param("width", 160);
  const int height = pnh.param("height", 120);
  Collected c;
  auto left = nh.subscribe<sensor_msgs::Image>("stereo/left/image_raw", 50, [&](const sensor_msgs::Image::ConstPtr& m) {
    std::lock_guard<std::mutex> lock(c.mutex);
    c.left.push_back(m);
  });
  auto right =
      nh.subscribe<sensor_msgs::Image>("stereo/right/image_raw", 50, [&](const sensor_msgs::Image::ConstPtr& m) {
        std::lock_guard<std::mutex> lock(c.mutex);
        c.right.push_back(m);
      });
  auto info = nh.subscribe<sensor_msgs::CameraInfo>("stereo/right/camera_info", 50,
                                                    [&](const sensor_msgs::CameraInfo::ConstPtr& m) {
                                                      std::lock_guard<std::mutex> lock(c.mutex);
                                                      c.right_info.push_back(m);
                                                    });
  tf2_ros::Buffer tf_buffer;
  tf2_ros::TransformListener tf_listener(tf_buffer);
  ros::AsyncSpinner spinner(2);
  spinner.start();
  FrameSource frames_source(nh);
  // Wait on the condition (enough frames), bounded by a generous timeout; no fixed sleeps. The counts are
  // asserted below.
  waitFor(
      [&] {
        std::lock_guard<std::mutex> lock(c.mutex);
        return static_cast<int>(std::min(c.left.size(), c.right.size())) >= frames + 2;
      },
      90.0);
  // Camera frames on tf at the stamp of an image (the frame is published with the images).
  sensor_msgs::Image::ConstPtr tf_image;
  {
    std::lock_guard<std::mutex> lock(c.mutex);
    ASSERT_FALSE(c.left.empty());
    tf_image = c.left[c.left.size() / 2];
  }
  EXPECT_EQ(tf_image->header.frame_id, "microscope_left_optical");
  std::string tf_error;
  ASSERT_TRUE(
      tf_buffer.canTransform("world", "microscope_left_optical", tf_image->header.stamp, ros::Duration(5.0), &tf_error))
      << tf_error;
  const auto left_tf = tf_buffer.lookupTransform("world", "microscope_left_optical", tf_image->header.stamp);
  const auto right_tf = tf_buffer.lookupTransform("world", "microscope_right_optical", tf_image->header.stamp);
  const auto objective_tf = tf_buffer.lookupTransform("world", "microscope", tf_image->header.stamp);
  // The microscope hangs above the eye and looks down: the optical z axis (forward) is world -z; the right path
  // is to the right (+x along the image's x axis) of the left one; the objective is between them.
  const auto& q = left_tf.transform.rotation;
  const Eigen::Quaterniond rotation(q.w, q.x, q.y, q.z);
  const Eigen::Vector3d forward = rotation * Eigen::Vector3d::UnitZ();
  const Eigen::Vector3d image_x = rotation * Eigen::Vector3d::UnitX();
  EXPECT_LT(forward.z(), -0.99) << "optical z should look down, got " << forward.transpose();
  const Eigen::Vector3d baseline(right_tf.transform.translation.x - left_tf.transform.translation.x,
                                 right_tf.transform.translation.y - left_tf.transform.translation.y,
                                 right_tf.transform.translation.z - left_tf.transform.translation.z);
  EXPECT_GT(baseline.dot(image_x), 0.005) << "right camera right of the left one";
  EXPECT_GT(objective_tf.transform.translation.z, 0.1) << "objective above the eye";

  // Snapshot service: the stereo pair as PNGs.
  std_srvs::Trigger snapshot;
  ASSERT_TRUE(ros::service::waitForService("stereo_renderer/save_snapshot", ros::Duration(10.0)));
  ASSERT_TRUE(ros::service::call("stereo_renderer/save_snapshot", snapshot));
  EXPECT_TRUE(snapshot.response.success) << snapshot.response.message;
  const std::string prefix = snapshot.response.message;
  EXPECT_TRUE(isPng(prefix + "_left.png")) << prefix;
  EXPECT_TRUE(isPng(prefix + "_right.png")) << prefix;
  std::remove((prefix + "_left.png").c_str());
  std::remove((prefix + "_right.png").c_str());

  // The replayed instructor's instruments (ghost_instruments) are listened to: recorded input frames, and the
  // instrument states of a bag recorded before them.
  ros::Publisher ghost = nh.advertise<vrm_msgs::InputFrame>("ghost/input_frame", 1);
  EXPECT_TRUE(waitForSubscribers(ghost, 10.0)) << "ghost/input_frame not subscribed";
  ros::Publisher legacy_ghost = nh.advertise<vrm_msgs::InstrumentState>("ghost/instrument_state", 1);
  EXPECT_TRUE(waitForSubscribers(legacy_ghost, 10.0)) << "ghost/instrument_state not subscribed";

  spinner.stop();
  std::lock_guard<std::mutex> lock(c.mutex);
  ASSERT_GE(static_cast<int>(c.left.size()), frames) << "left images";
  ASSERT_GE(static_cast<int>(c.right.size()), frames) << "right images";

  std::map<double, int> left_stamps;
  for (const auto& image : c.left) left_stamps[image->header.stamp.toSec()]++;
  int paired = 0;
  for (const auto& image : c.right) paired += left_stamps.count(image->header.stamp.toSec());
  EXPECT_GE(paired, frames - 1) << "right images without a left image of the same stamp";

  std::vector<double> deltas;
  for (std::size_t i = 1; i < c.left.size(); ++i) {
    const double dt = (c.left[i]->header.stamp - c.left[i - 1]->header.stamp).toSec();
    EXPECT_GT(dt, 0.0) << "stamps not strictly increasing at frame " << i;
    deltas.push_back(dt);
  }
  std::sort(deltas.begin(), deltas.end());
  const double median = deltas[deltas.size() / 2];
  // Each frame reflects the newest input frame (50 Hz), rendered at most `rate` times a second.
  EXPECT_GT(median, 0.5 / rate);
  EXPECT_LT(median, 3.0 / rate);

  const sensor_msgs::Image& last = *c.left.back();
  EXPECT_EQ(static_cast<int>(last.width), width);
  EXPECT_EQ(static_cast<int>(last.height), height);
  EXPECT_EQ(last.encoding, "rgb8");
  ASSERT_EQ(last.data.size(), static_cast<std::size_t>(width * height * 3));
  double red = 0.0;
  for (std::size_t i = 0; i < last.data.size(); i += 3) red += last.data[i];
  EXPECT_GT(red / (width * height), 20.0) << "the retina under the light pipe should be visible";
  ASSERT_FALSE(c.right_info.empty());
  EXPECT_LT(c.right_info.back()->P[3], 0.0) << "right camera info carries the stereo baseline (Tx < 0)";
  EXPECT_EQ(c.right_info.back()->header.frame_id, "microscope_right_optical");
  EXPECT_EQ(c.right.back()->header.frame_id, "microscope_right_optical");
}

// Lazy subscription (image_pipeline's pattern): the renderer listens to its inputs only while an image is watched.
// ghost/input_frame is subscribed by the renderer alone, so its subscriber count shows the renderer's inputs.
TEST(StereoRendererGraph, SubscribesToItsInputsOnlyWhileAnImageIsWatched) {
  ros::NodeHandle nh;
  ros::AsyncSpinner spinner(1);
  spinner.start();
  FrameSource frames_source(nh);
  ros::Publisher ghost = nh.advertise<vrm_msgs::InputFrame>("ghost/input_frame", 1);
  // Nobody watches (the previous test's subscribers are gone): no inputs.
  EXPECT_TRUE(waitFor([&] { return ghost.getNumSubscribers() == 0; }, 20.0)) << "inputs subscribed while unwatched";

  std::mutex mutex;
  int images = 0;
  {
    auto left = nh.subscribe<sensor_msgs::Image>("stereo/left/image_raw", 5, [&](const sensor_msgs::Image::ConstPtr&) {
      std::lock_guard<std::mutex> lock(mutex);
      ++images;
    });
    EXPECT_TRUE(waitFor([&] { return ghost.getNumSubscribers() > 0; }, 20.0)) << "a watcher did not subscribe inputs";
    EXPECT_TRUE(waitFor(
        [&] {
          std::lock_guard<std::mutex> lock(mutex);
          return images >= 3;
        },
        60.0))
        << "no frames for the watcher after it subscribed (" << images << ")";
  }
  EXPECT_TRUE(waitFor([&] { return ghost.getNumSubscribers() == 0; }, 20.0)) << "inputs kept after the watcher left";
}

}  // namespace

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_stereo_renderer_graph");
  return RUN_ALL_TESTS();
}
