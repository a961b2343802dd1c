// Graph test of the optical tracking (tracking.test): the tracked tip and eye rotation follow the ground truth,
// every output stamp is a ground-truth (camera exposure) stamp, tracking continues when a camera stops, and the
// detector survives malformed images. Every wait is a condition with a timeout, never a fixed sleep.

#include <gtest/gtest.h>
#include <ros/ros.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/image_encodings.h>
#include <vrm_msgs/EyeState.h>
#include <vrm_msgs/InstrumentState.h>
#include <vrm_msgs/MarkerObservations.h>

#include <algorithm>
#include <boost/make_shared.hpp>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "vrm_tracking/conversions.h"

namespace vrm_tracking {
namespace {

constexpr double kTimeout = 60.0;  // s; rendering three cameras on a shared 2-core machine can be slow

class Listener {
 public:
  explicit Listener(ros::NodeHandle& nh) {
    subs_.push_back(nh.subscribe("ground_truth/eye_state", 500, &Listener::onTruthEye, this));
    subs_.push_back(nh.subscribe("ground_truth/instrument_state", 1000, &Listener::onTruthInstrument, this));
    subs_.push_back(nh.subscribe("eye_state", 500, &Listener::onEye, this));
    subs_.push_back(nh.subscribe("instrument_state", 1000, &Listener::onInstrument, this));
    subs_.push_back(nh.subscribe("camera_2/markers", 500, &Listener::onCamera2, this));
    subs_.push_back(nh.subscribe("bad/cam_bad/markers", 10, &Listener::onBad, this));
  }

  bool waitFor(const std::function<bool()>& pred, double timeout_s) {
    std::unique_lock<std::mutex> lock(mutex_);
    return cv_.wait_for(lock, std::chrono::duration<double>(timeout_s), pred);
  }

  std::mutex mutex_;
  std::map<ros::Time, vrm_msgs::EyeState::ConstPtr> truth_eye;
  std::map<std::pair<std::string, ros::Time>, vrm_msgs::InstrumentState::ConstPtr> truth_instrument;
  std::vector<vrm_msgs::EyeState::ConstPtr> eye;
  std::vector<vrm_msgs::InstrumentState::ConstPtr> instrument;
  std::vector<ros::Time> camera2;
  std::vector<vrm_msgs::MarkerObservations::ConstPtr> bad;

 private:
  template <class F>
  void locked(F f) {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      f();
    }
    cv_.notify_all();
  }
  void onTruthEye(const vrm_msgs::EyeState::ConstPtr& m) {
    locked([&] { truth_eye[m->header.stamp] = m; });
  }
  void onTruthInstrument(const vrm_msgs::InstrumentState::ConstPtr& m) {
    locked([&] { truth_instrument[{m->instrument_id, m->header.stamp}] = m; });
  }
  void onEye(const vrm_msgs::EyeState::ConstPtr& m) {
    locked([&] { eye.push_back(m); });
  }
  void onInstrument(const vrm_msgs::InstrumentState::ConstPtr& m) {
    locked([&] { instrument.push_back(m); });
  }
  void onCamera2(const vrm_msgs::MarkerObservations::ConstPtr& m) {
    locked([&] { camera2.push_back(m->header.stamp); });
  }
  void onBad(const vrm_msgs::MarkerObservations::ConstPtr& m) {
    locked([&] { bad.push_back(m); });
  }

  std::condition_variable cv_;
  std::vector<ros::Subscriber> subs_;
};

std::unique_ptr<Listener> g_listener;
int g_stop_after = 150;

struct TipErrors {
  std::vector<double> um;
  int unmatched_stamps = 0;
  int invalid = 0;
};

// Tip errors (eye frame, µm) of the tracked instruments whose stamp lies in [from, to). Frames before the first
// ground truth this test received (published before it connected) are skipped.
TipErrors tipErrors(const Listener& l, ros::Time from, ros::Time to) {
  TipErrors e;
  if (l.truth_instrument.empty()) return e;
  ros::Time first = ros::TIME_MAX;
  for (const auto& t : l.truth_instrument) first = std::min(first, t.first.second);
  // Half a second of start-up (subscriptions of the detector and tracker connecting camera by camera) is skipped.
  from = std::max(from, first + ros::Duration(0.5));
  for (const auto& m : l.instrument) {
    if (m->header.stamp < from || m->header.stamp >= to) continue;
    const auto it = l.truth_instrument.find({m->instrument_id, m->header.stamp});
    if (it == l.truth_instrument.end()) {
      ++e.unmatched_stamps;
      continue;
    }
    if (!m->valid) {
      ++e.invalid;
      continue;
    }
    e.um.push_back((toEigen(m->tip_pose.position) - toEigen(it->second->tip_pose.position)).norm() * 1e6);
  }
  return e;
}

double percentile(std::vector<double> v, double p) {
  if (v.empty()) return NAN;
  std::sort(v.begin(), v.end());
  return v[static_cast<std::size_t>(p * (v.size() - 1))];
}

TEST(TrackingGraph, TrackedTipFollowsGroundTruthWithPreservedStamps) {
  auto& l = *g_listener;
  ASSERT_TRUE(l.waitFor([&] { return l.instrument.size() >= 200; }, kTimeout)) << "instrument_state not tracked";
  std::lock_guard<std::mutex> lock(l.mutex_);
  // Only stamps the ground truth has: the tracker copies the camera stamps, which are the surgeon's ticks.
  // The three-camera phase: up to camera_2's last frame if it has stopped already.
  const ros::Time until = l.camera2.empty() ? ros::TIME_MAX : l.camera2.back();
  const TipErrors e = tipErrors(l, ros::Time(0, 1), until);
  EXPECT_EQ(e.unmatched_stamps, 0) << "tracked stamps that no ground-truth frame has";
  ASSERT_GE(e.um.size(), 100u);
  EXPECT_LE(e.invalid, static_cast<int>(0.02 * e.um.size()) + 2);
  // ~105 µm/px rig, rendered with noise: tens of µm (bench: ~5 µm RMS); the bound leaves room for load.
  EXPECT_LT(percentile(e.um, 0.5), 40.0);
  EXPECT_LT(percentile(e.um, 0.95), 150.0);
  for (const auto& m : l.instrument) EXPECT_EQ(m->header.frame_id, "eye");
}

TEST(TrackingGraph, EyeRotationFollowsGroundTruth) {
  auto& l = *g_listener;
  ASSERT_TRUE(l.waitFor([&] { return l.eye.size() >= 100; }, kTimeout)) << "eye_state not tracked";
  std::lock_guard<std::mutex> lock(l.mutex_);
  int matched = 0;
  ASSERT_FALSE(l.truth_eye.empty());
  const ros::Time first = l.truth_eye.begin()->first;
  for (const auto& m : l.eye) {
    if (m->header.stamp < first) continue;  // published before this test connected to the ground truth
    const auto it = l.truth_eye.find(m->header.stamp);
    ASSERT_TRUE(it != l.truth_eye.end()) << "eye_state stamp not a ground-truth stamp";
    EXPECT_EQ(m->header.frame_id, "world");
    if (!m->valid) continue;
    ++matched;
    EXPECT_LT(toEigen(m->rotation).angularDistance(toEigen(it->second->rotation)) * 180.0 / M_PI, 0.5);
  }
  EXPECT_GE(matched, 90);
}

TEST(TrackingGraph, TrackingContinuesWhenACameraStops) {
  auto& l = *g_listener;
  // camera_2 stops after g_stop_after frames (this test may have missed the first ones); wait for a second of
  // tracking beyond its last frame.
  ASSERT_TRUE(l.waitFor(
      [&] {
        if (l.camera2.empty()) return false;
        const ros::Time last = l.camera2.back();
        int after = 0;
        for (const auto& m : l.instrument) after += m->header.stamp > last + ros::Duration(0.1);
        return after >= 100;
      },
      kTimeout))
      << "no tracking after camera_2 stopped";
  std::lock_guard<std::mutex> lock(l.mutex_);
  EXPECT_LE(l.camera2.size(), static_cast<std::size_t>(g_stop_after));
  const TipErrors e = tipErrors(l, l.camera2.back() + ros::Duration(0.1), ros::TIME_MAX);
  EXPECT_EQ(e.unmatched_stamps, 0);
  // With two cameras a marker hidden by a shaft in either of them cannot be reconstructed (tracking_eval on this
  // trajectory: 96 % of instrument frames valid); the frames that are valid must be accurate.
  ASSERT_GE(e.um.size(), 80u);
  EXPECT_GE(e.um.size(), 0.8 * (e.um.size() + e.invalid));
  EXPECT_LT(percentile(e.um, 0.5), 60.0);
  EXPECT_LT(percentile(e.um, 0.95), 200.0);
}

sensor_msgs::ImagePtr image(const std::string& encoding, int width, int height, int channels, ros::Time stamp) {
  auto img = boost::make_shared<sensor_msgs::Image>();
  img->header.stamp = stamp;
  img->header.frame_id = "cam_bad_optical";
  img->encoding = encoding;
  img->width = static_cast<std::uint32_t>(width);
  img->height = static_cast<std::uint32_t>(height);
  img->step = static_cast<std::uint32_t>(width * channels);
  img->data.assign(static_cast<std::size_t>(img->step) * height, 40);
  return img;
}

TEST(TrackingGraph, DetectorSurvivesMalformedImages) {
  auto& l = *g_listener;
  ros::NodeHandle nh;
  ros::Publisher pub = nh.advertise<sensor_msgs::Image>("bad/cam_bad/image_raw", 10);
  ASSERT_TRUE(l.waitFor([&] { return pub.getNumSubscribers() > 0; }, kTimeout)) << "detector not subscribed";
  // Malformed frames: wrong encoding, empty, truncated. None may produce output or stop the detector.
  pub.publish(image(sensor_msgs::image_encodings::MONO8, 64, 48, 1, ros::Time(1.0)));
  pub.publish(image(sensor_msgs::image_encodings::TYPE_32FC1, 64, 48, 4, ros::Time(2.0)));
  pub.publish(image(sensor_msgs::image_encodings::BGR8, 0, 0, 3, ros::Time(3.0)));
  auto truncated = image(sensor_msgs::image_encodings::BGR8, 64, 48, 3, ros::Time(4.0));
  truncated->data.resize(100);
  pub.publish(truncated);
  // Then a good frame with one red disc (class eye_a) centred at (30.0, 20.0).
  auto good = image(sensor_msgs::image_encodings::BGR8, 64, 48, 3, ros::Time(5.0));
  for (int y = 0; y < 48; ++y) {
    for (int x = 0; x < 64; ++x) {
      if (std::hypot(x - 30.0, y - 20.0) <= 4.0) {
        std::uint8_t* p = &good->data[static_cast<std::size_t>(y) * good->step + 3 * x];
        p[0] = 40;
        p[1] = 40;
        p[2] = 230;
      }
    }
  }
  bool seen = false;
  const ros::WallTime deadline = ros::WallTime::now() + ros::WallDuration(kTimeout);
  while (!seen && ros::WallTime::now() < deadline) {
    pub.publish(good);
    seen = l.waitFor([&] { return !l.bad.empty(); }, 0.5);
  }
  ASSERT_TRUE(seen) << "detector produced nothing for a good frame after malformed ones";
  std::lock_guard<std::mutex> lock(l.mutex_);
  for (const auto& m : l.bad) {
    EXPECT_EQ(m->header.stamp, ros::Time(5.0)) << "a malformed frame produced output";
    ASSERT_EQ(m->markers.size(), 1u);
    EXPECT_EQ(m->markers[0].class_id, 0);
    EXPECT_NEAR(m->markers[0].u, 30.0, 0.05);
    EXPECT_NEAR(m->markers[0].v, 20.0, 0.05);
  }
}

}  // namespace
}  // namespace vrm_tracking

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_tracking_graph");
  ros::NodeHandle nh;
  ros::NodeHandle pnh("~");
  pnh.param("stop_after", vrm_tracking::g_stop_after, 150);
  vrm_tracking::g_listener = std::make_unique<vrm_tracking::Listener>(nh);
  ros::AsyncSpinner spinner(2);
  spinner.start();
  const int result = RUN_ALL_TESTS();
  spinner.stop();
  vrm_tracking::g_listener.reset();
  ros::shutdown();
  return result;
}
