// Graph test of the stereo_renderer nodelet: with a scripted scene running, left and right images arrive in pairs
// with equal stamps, the stamps increase monotonically, the stamp spacing matches the configured rate (stamps are
// input stamps, so this is not a wall-clock assertion), and the images show the lit scene.

#include <gtest/gtest.h>
#include <ros/ros.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>

#include <algorithm>
#include <map>
#include <mutex>
#include <vector>

namespace {

struct Collected {
  std::mutex mutex;
  std::vector<sensor_msgs::Image::ConstPtr> left, right;
  std::vector<sensor_msgs::CameraInfo::ConstPtr> right_info;
};

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
  ros::AsyncSpinner spinner(2);
  spinner.start();
  // Wait on the condition (enough frames), bounded by a generous timeout; no fixed sleeps.
  const ros::WallTime deadline = ros::WallTime::now() + ros::WallDuration(90.0);
  while (ros::ok() && ros::WallTime::now() < deadline) {
    {
      std::lock_guard<std::mutex> lock(c.mutex);
      if (static_cast<int>(std::min(c.left.size(), c.right.size())) >= frames + 2) break;
    }
    ros::WallDuration(0.05).sleep();
  }
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
  // Each frame reflects the newest input (50 Hz surgeon), rendered at most `rate` times a second.
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
}

}  // namespace

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_stereo_renderer_graph");
  return RUN_ALL_TESTS();
}
