// Graph test of the optical tracking (tracking.test): the tracked tip and eye rotation follow the ground truth,
// every output stamp is a ground-truth (camera exposure) stamp, tracking continues when a camera stops, and the
// detector survives malformed images, the tracker's tf chain world -> eye -> trocar_* -> instrument_* composes to
// the published states at their camera stamps, and /diagnostics reports the stopped camera and the bad input.
// Every wait is a condition with a timeout, never a fixed sleep.

#include <diagnostic_msgs/DiagnosticArray.h>
#include <gtest/gtest.h>
#include <nodelet/NodeletList.h>
#include <nodelet/NodeletLoad.h>
#include <ros/ros.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/image_encodings.h>
#include <tf2_ros/buffer.h>
#include <tf2_ros/transform_listener.h>
#include <unistd.h>
#include <vrm_msgs/EyeState.h>
#include <vrm_msgs/InstrumentState.h>
#include <vrm_msgs/MarkerObservations.h>

#include <algorithm>
#include <boost/make_shared.hpp>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <map>
#include <memory>
#include <mutex>
#include <sstream>
#include <string>
#include <vector>

#include "vrm_scene/package_data.h"
#include "vrm_scene/scene_loader.h"
#include "vrm_sim/testing/graph_test.h"
#include "vrm_sim/testing/sanitizer.h"
#include "vrm_tracking/conversions.h"
#include "vrm_tracking/scene_trocars.h"

namespace vrm_tracking {
namespace {

using vrm_sim::testing::waitForSubscribers;

constexpr double kTimeout = 60.0;  // s; rendering three cameras on a shared 2-core machine can be slow

// The tip's accuracy against the ground truth at the same stamp is a real-time property of the rig twin: its
// ground-truth queues hold about one tick (a camera exposes the present), so a render slower than the script's 50 Hz
// drops instrument states and draws a slot at its last one under the new stamp. Under ASan (scripts/test.sh --sanitize)
// the instrumented rig is that slow (its log: "instrument:right stopped delivering"), and the tracked tip, true to the
// images, is off the truth by a tick's motion in some frames (2026-12-02, AMD EPYC: median 53.8 um, p95 2,955 um;
// 61.0 / 2,534 um with two cameras). There the percentiles are reported, not judged; stamps, validity and frames are
// checked as in Release, where the bounds hold.
constexpr bool kJudgeAccuracy = !vrm_sim::testing::kUnderSanitizer;

class Listener : public vrm_sim::testing::AwaitedState {
 public:
  explicit Listener(ros::NodeHandle& nh) {
    subs_.push_back(nh.subscribe("ground_truth/eye_state", 500, &Listener::onTruthEye, this));
    subs_.push_back(nh.subscribe("ground_truth/instrument_state", 1000, &Listener::onTruthInstrument, this));
    subs_.push_back(nh.subscribe("eye_state", 500, &Listener::onEye, this));
    subs_.push_back(nh.subscribe("instrument_state", 1000, &Listener::onInstrument, this));
    subs_.push_back(nh.subscribe("camera_2/markers", 500, &Listener::onCamera2, this));
    subs_.push_back(nh.subscribe("bad/cam_bad/markers", 10, &Listener::onBad, this));
    subs_.push_back(nh.subscribe("/diagnostics", 100, &Listener::onDiagnostics, this));
  }

  std::map<ros::Time, vrm_msgs::EyeState::ConstPtr> truth_eye;
  std::map<std::pair<std::string, ros::Time>, vrm_msgs::InstrumentState::ConstPtr> truth_instrument;
  std::vector<vrm_msgs::EyeState::ConstPtr> eye;
  std::vector<vrm_msgs::InstrumentState::ConstPtr> instrument;
  std::vector<ros::Time> camera2;
  std::vector<vrm_msgs::MarkerObservations::ConstPtr> bad;
  std::vector<diagnostic_msgs::DiagnosticStatus> diagnostics;

 private:
  void onTruthEye(const vrm_msgs::EyeState::ConstPtr& m) {
    update([&] { truth_eye[m->header.stamp] = m; });
  }
  void onTruthInstrument(const vrm_msgs::InstrumentState::ConstPtr& m) {
    update([&] { truth_instrument[{m->instrument_id, m->header.stamp}] = m; });
  }
  void onEye(const vrm_msgs::EyeState::ConstPtr& m) {
    update([&] { eye.push_back(m); });
  }
  void onInstrument(const vrm_msgs::InstrumentState::ConstPtr& m) {
    update([&] { instrument.push_back(m); });
  }
  void onCamera2(const vrm_msgs::MarkerObservations::ConstPtr& m) {
    update([&] { camera2.push_back(m->header.stamp); });
  }
  void onBad(const vrm_msgs::MarkerObservations::ConstPtr& m) {
    update([&] { bad.push_back(m); });
  }
  void onDiagnostics(const diagnostic_msgs::DiagnosticArray::ConstPtr& m) {
    update([&] { diagnostics.insert(diagnostics.end(), m->status.begin(), m->status.end()); });
  }

  std::vector<ros::Subscriber> subs_;
};

std::unique_ptr<Listener> g_listener;
std::unique_ptr<tf2_ros::Buffer> g_tf;
int g_stop_after = 150;
std::string g_scene;        // ~scene of surgeon and tracker: its trocars replace the script's and the layout's
std::string g_layout_file;  // the tracker's layout, whose own trocars the scene overrides

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

// Median and 95th percentile of the tip errors: asserted where the rig keeps up (kJudgeAccuracy), else recorded.
void checkAccuracy(const std::vector<double>& um, double median_bound, double p95_bound, const std::string& name) {
  const double median = percentile(um, 0.5), p95 = percentile(um, 0.95);
  ::testing::Test::RecordProperty(name + "_median_um", std::to_string(median));
  ::testing::Test::RecordProperty(name + "_p95_um", std::to_string(p95));
  if (!kJudgeAccuracy) {
    std::printf("%s: tip error median %.1f um, p95 %.1f um (not judged under ASan)\n", name.c_str(), median, p95);
    return;
  }
  EXPECT_LT(median, median_bound);
  EXPECT_LT(p95, p95_bound);
}

TEST(TrackingGraph, TrackedTipFollowsGroundTruthWithPreservedStamps) {
  auto& l = *g_listener;
  // Enough three-camera frames (until camera_2 stops), or camera_2 has stopped and no more can come.
  auto three_camera_until = [&l] { return l.camera2.empty() ? ros::TIME_MAX : l.camera2.back(); };
  ASSERT_TRUE(l.waitFor(
      [&] {
        if (l.instrument.size() < 200) return false;
        if (tipErrors(l, ros::Time(0, 1), three_camera_until()).um.size() >= 120) return true;
        return !l.camera2.empty() && l.instrument.back()->header.stamp > l.camera2.back() + ros::Duration(0.5);
      },
      kTimeout))
      << "instrument_state not tracked";
  std::lock_guard<std::mutex> lock(l.mutex_);
  // Only stamps the ground truth has: the tracker copies the camera stamps, which are the surgeon's ticks.
  // The three-camera phase: up to camera_2's last frame if it has stopped already.
  const ros::Time until = l.camera2.empty() ? ros::TIME_MAX : l.camera2.back();
  const TipErrors e = tipErrors(l, ros::Time(0, 1), until);
  EXPECT_EQ(e.unmatched_stamps, 0) << "tracked stamps that no ground-truth frame has";
  ASSERT_GE(e.um.size(), 100u);
  EXPECT_LE(e.invalid, static_cast<int>(0.02 * e.um.size()) + 2);
  // ~105 µm/px rig, rendered with noise: tens of µm (bench: ~5 µm RMS); the bound leaves room for load.
  checkAccuracy(e.um, 40.0, 150.0, "three_cameras");
  for (const auto& m : l.instrument) EXPECT_EQ(m->header.frame_id, "eye");
}

std::string truthNeighbours(const std::map<ros::Time, vrm_msgs::EyeState::ConstPtr>& truth, const ros::Time& stamp) {
  std::ostringstream out;
  const auto after = truth.upper_bound(stamp);
  if (after != truth.begin()) out << "before " << std::prev(after)->first << " ";
  if (after != truth.end()) out << "after " << after->first;
  return out.str();
}

TEST(TrackingGraph, EyeRotationFollowsGroundTruth) {
  auto& l = *g_listener;
  // 100 eye states stamped since the ground truth reached the test (a loaded machine connects it later: counting
  // every state received made the matched count fall short of 90 with all of them valid).
  const auto since_truth = [&] {
    if (l.truth_eye.empty()) return std::size_t{0};
    const ros::Time first = l.truth_eye.begin()->first;
    return static_cast<std::size_t>(
        std::count_if(l.eye.begin(), l.eye.end(), [&](const auto& m) { return m->header.stamp >= first; }));
  };
  ASSERT_TRUE(l.waitFor([&] { return since_truth() >= 100; }, kTimeout)) << "eye_state not tracked";
  std::lock_guard<std::mutex> lock(l.mutex_);
  int matched = 0;
  ASSERT_FALSE(l.truth_eye.empty());
  const ros::Time first = l.truth_eye.begin()->first;
  for (const auto& m : l.eye) {
    if (m->header.stamp < first) continue;  // published before this test connected to the ground truth
    const auto it = l.truth_eye.find(m->header.stamp);
    // The neighbours say which side lost it: ground truth that reached this test on both sides one tick apart means
    // the tracker made the stamp up; a wider hole means this test's subscription lost truth messages.
    ASSERT_TRUE(it != l.truth_eye.end()) << "eye_state stamp " << m->header.stamp
                                         << " not a ground-truth stamp; truth received around it: "
                                         << truthNeighbours(l.truth_eye, m->header.stamp);
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
  checkAccuracy(e.um, 60.0, 200.0, "two_cameras");
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
  ASSERT_TRUE(waitForSubscribers(pub, kTimeout)) << "detector not subscribed";
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

Eigen::Isometry3d toIsometry(const geometry_msgs::Transform& t) {
  Eigen::Isometry3d x = Eigen::Isometry3d::Identity();
  x.translation() = Eigen::Vector3d(t.translation.x, t.translation.y, t.translation.z);
  x.linear() =
      Eigen::Quaterniond(t.rotation.w, t.rotation.x, t.rotation.y, t.rotation.z).normalized().toRotationMatrix();
  return x;
}

TEST(TrackingGraph, TfChainComposesTheStatesAtCameraStamps) {
  auto& l = *g_listener;
  // A tracked left instrument whose eye rotation was reconstructed in the same frame (same camera stamp).
  vrm_msgs::InstrumentState::ConstPtr inst;
  vrm_msgs::EyeState::ConstPtr eye;
  ASSERT_TRUE(l.waitFor(
      [&] {
        for (auto it = l.instrument.rbegin(); it != l.instrument.rend(); ++it) {
          if ((*it)->instrument_id != "left" || !(*it)->valid) continue;
          for (const auto& e : l.eye) {
            if (e->header.stamp == (*it)->header.stamp && e->valid) {
              inst = *it;
              eye = e;
              return true;
            }
          }
        }
        return false;
      },
      kTimeout))
      << "no frame with a valid eye and left instrument";
  const ros::Time stamp = inst->header.stamp;
  std::string error;
  ASSERT_TRUE(g_tf->canTransform("world", "instrument_left", stamp, ros::Duration(10.0), &error)) << error;
  const geometry_msgs::TransformStamped world_inst = g_tf->lookupTransform("world", "instrument_left", stamp);
  const geometry_msgs::TransformStamped eye_inst = g_tf->lookupTransform("eye", "instrument_left", stamp);
  const geometry_msgs::TransformStamped trocar_inst = g_tf->lookupTransform("trocar_left", "instrument_left", stamp);
  EXPECT_EQ(world_inst.header.stamp, stamp) << "tf stamp is not the camera stamp";
  EXPECT_EQ(trocar_inst.header.stamp, stamp);
  std::string parent;
  ASSERT_TRUE(g_tf->_getParent("instrument_left", stamp, parent));
  EXPECT_EQ(parent, "trocar_left");
  ASSERT_TRUE(g_tf->_getParent("trocar_left", stamp, parent));
  EXPECT_EQ(parent, "eye");
  ASSERT_TRUE(g_tf->_getParent("eye", stamp, parent));
  EXPECT_EQ(parent, "world");

  // world -> instrument_left equals eye pose (rotation about the centre) ∘ the instrument's eye-frame tip pose.
  Eigen::Isometry3d world_eye = Eigen::Isometry3d::Identity();
  world_eye.translation() = toEigen(eye->rotation_center);
  world_eye.linear() = toEigen(eye->rotation).normalized().toRotationMatrix();
  Eigen::Isometry3d eye_tip = Eigen::Isometry3d::Identity();
  eye_tip.translation() = toEigen(inst->tip_pose.position);
  eye_tip.linear() = toEigen(inst->tip_pose.orientation).normalized().toRotationMatrix();
  const Eigen::Isometry3d expected = world_eye * eye_tip;
  const Eigen::Isometry3d got = toIsometry(world_inst.transform);
  EXPECT_LT((got.translation() - expected.translation()).norm(), 1e-9);
  EXPECT_LT(Eigen::Quaterniond(got.linear()).angularDistance(Eigen::Quaterniond(expected.linear())), 1e-6);
  EXPECT_LT((toIsometry(eye_inst.transform).translation() - eye_tip.translation()).norm(), 1e-9);
}

// One trocar for everyone: the tracker's static trocar frames and the surgeon's pivots are the scene's, not the
// layout's or the script's own copies.
TEST(TrackingGraph, TrocarsComeFromTheScene) {
  if (g_scene.empty()) GTEST_SKIP() << "no ~scene given";
  const vrm_sim::scene::SceneDescription scene = vrm_sim::scene::loadScene(g_scene);
  const vrm_sim::scene::SceneDescription fallback = vrm_sim::scene::loadScene(sceneOrDefault(""));
  const MarkerLayout layout = loadLayoutYaml(g_layout_file);
  ASSERT_EQ(layout.instruments.size(), 2u);
  for (const InstrumentMarker& marker : layout.instruments) {
    SCOPED_TRACE(marker.slot);
    const Eigen::Vector3d expected = sceneTrocarForSlot(scene, marker.slot);
    ASSERT_GT((expected - sceneTrocarForSlot(fallback, marker.slot)).norm(), 1e-4)
        << "the test scene must move the trocars away from the default scene's";
    std::string error;
    ASSERT_TRUE(g_tf->canTransform("eye", "trocar_" + marker.slot, ros::Time(0), ros::Duration(10.0), &error)) << error;
    const geometry_msgs::TransformStamped frame = g_tf->lookupTransform("eye", "trocar_" + marker.slot, ros::Time(0));
    EXPECT_LT((toIsometry(frame.transform).translation() - expected).norm(), 1e-9) << "tracker: trocar frame";

    auto& l = *g_listener;
    ASSERT_TRUE(l.waitFor(
        [&] {
          for (const auto& t : l.truth_instrument) {
            if (t.first.first == marker.slot) return true;
          }
          return false;
        },
        kTimeout))
        << "no ground truth for " << marker.slot;
    std::lock_guard<std::mutex> lock(l.mutex_);
    for (const auto& t : l.truth_instrument) {
      if (t.first.first != marker.slot) continue;
      const InstrumentSample truth = fromMsg(*t.second);  // trocar = tip - insertion_depth * shaft_axis
      EXPECT_LT((truth.trocar - expected).norm(), 1e-9) << "surgeon: shaft misses the scene's trocar";
    }
  }
}

bool hasStatus(const Listener& l, const std::string& name_part, int min_level, const std::string& message_part) {
  for (const auto& s : l.diagnostics) {
    if (s.name.find(name_part) != std::string::npos && s.level >= min_level &&
        s.message.find(message_part) != std::string::npos) {
      return true;
    }
  }
  return false;
}

TEST(TrackingGraph, DiagnosticsReportTheStoppedCameraAndBadInput) {
  auto& l = *g_listener;
  using diagnostic_msgs::DiagnosticStatus;
  // A wrong encoding, repeated until reported (the detector's input queue is short: a burst may lose frames).
  ros::NodeHandle nh;
  ros::Publisher pub = nh.advertise<sensor_msgs::Image>("bad/cam_bad/image_raw", 10);
  ASSERT_TRUE(waitForSubscribers(pub, kTimeout)) << "detector not subscribed";
  bool reported = false;
  const ros::WallTime deadline = ros::WallTime::now() + ros::WallDuration(kTimeout);
  while (!reported && ros::WallTime::now() < deadline) {
    pub.publish(image(sensor_msgs::image_encodings::MONO8, 64, 48, 1, ros::Time(6.0)));
    reported = l.waitFor([&] { return hasStatus(l, "cam_bad", DiagnosticStatus::WARN, "encoding 'mono8'"); }, 0.5);
  }
  EXPECT_TRUE(reported) << "no diagnostic for the wrong encoding";
  EXPECT_TRUE(l.waitFor([&] { return hasStatus(l, "cam_bad", DiagnosticStatus::WARN, "no CameraInfo"); }, kTimeout));
  EXPECT_TRUE(l.waitFor([&] { return hasStatus(l, "marker_detector: camera_2", DiagnosticStatus::ERROR, "stopped"); },
                        kTimeout))
      << "the stopped camera is not reported";
  EXPECT_TRUE(l.waitFor([&] { return hasStatus(l, "tracker", DiagnosticStatus::WARN, "camera_2"); }, kTimeout))
      << "the tracker does not report the missing camera";
  // Start-up (cameras connecting one by one) may legitimately report errors; from camera_2's stop on, two cameras
  // remain: the tracker warns but never errs, camera_0 stays healthy. Wait for two reports of each after it.
  auto stopIndex = [&l] {
    std::size_t from = 0;
    while (from < l.diagnostics.size() &&
           !(l.diagnostics[from].name.find("marker_detector: camera_2") != std::string::npos &&
             l.diagnostics[from].message.find("stopped") != std::string::npos)) {
      ++from;
    }
    return from;
  };
  auto reportsAfter = [&l](std::size_t from, const std::string& name_part) {
    int n = 0;
    for (std::size_t i = from; i < l.diagnostics.size(); ++i)
      n += l.diagnostics[i].name.find(name_part) != std::string::npos;
    return n;
  };
  EXPECT_TRUE(l.waitFor(
      [&] {
        const std::size_t from = stopIndex();
        return reportsAfter(from, "marker_detector: camera_0") >= 2 && reportsAfter(from, "tracker") >= 2;
      },
      kTimeout));
  std::lock_guard<std::mutex> lock(l.mutex_);
  const std::size_t from = stopIndex();
  bool camera0_ok = false;
  int tracker_reports = 0;
  for (std::size_t i = from; i < l.diagnostics.size(); ++i) {
    const auto& s = l.diagnostics[i];
    if (s.name.find("marker_detector: camera_0") != std::string::npos) {
      EXPECT_LT(s.level, DiagnosticStatus::ERROR) << s.message;
      camera0_ok |= s.level == DiagnosticStatus::OK;
      for (const auto& kv : s.values) {
        if (kv.key == "camera_info") EXPECT_EQ(kv.value, "yes");
      }
    }
    if (s.name.find("tracker") != std::string::npos) {
      ++tracker_reports;
      EXPECT_LT(s.level, DiagnosticStatus::ERROR) << s.message;
    }
  }
  EXPECT_TRUE(camera0_ok);
  EXPECT_GE(tracker_reports, 1);
}

std::string g_rig_file;  // the product's rig, from which RefusedNodeletsLeaveTheManagerRunning derives a broken one

// Asks the product's manager to load `type` as `name` (its private parameters set beforehand); true if it loaded.
bool loadIntoManager(const std::string& name, const std::string& type) {
  nodelet::NodeletLoad load;
  load.request.name = name;
  load.request.type = type;
  // The manager's load service fails the call when the nodelet is refused (it returns the load's success).
  return ros::service::call("/vrm_manager/load_nodelet", load) && load.response.success;
}

// A rig twin and a tracker whose rig has a second camera named "camera 1" (no ROS name), and a detector whose second
// camera is: each opens handles on topics the running graph uses (tracking_timing, camera_0's, eye_state), then a
// topic name throws. The manager must refuse them and go on. It frees a refused nodelet's callback queues before it
// destroys the nodelet, so a handle left open would unregister from freed memory: before the fix this manager died
// of a SEGV in Release (2026-12-02). Runs last.
TEST(TrackingGraph, RefusedNodeletsLeaveTheManagerRunning) {
  ASSERT_FALSE(g_rig_file.empty()) << "no ~rig_file given";
  std::ifstream in(g_rig_file);
  ASSERT_TRUE(in) << g_rig_file;
  std::stringstream rig;
  rig << in.rdbuf();
  std::string text = rig.str();
  const std::string good = "camera_name: camera_1";
  const auto at = text.find(good);
  ASSERT_NE(at, std::string::npos) << g_rig_file << " has no camera_1";
  text.replace(at, good.size(), "camera_name: camera 1");
  char path[] = "/tmp/refused_rig_XXXXXX";
  const int fd = mkstemp(path);
  ASSERT_GE(fd, 0);
  close(fd);
  std::ofstream(path) << text;

  ros::NodeHandle nh;
  nh.setParam("/refused_rig/rig_file", std::string(path));
  nh.setParam("/refused_tracker/rig_file", std::string(path));
  nh.setParam("/refused_detector/cameras", std::vector<std::string>{"camera_0", "camera 1"});
  auto& l = *g_listener;
  std::size_t eye_states_before = 0;
  {
    std::lock_guard<std::mutex> lock(l.mutex_);
    eye_states_before = l.eye.size();
  }
  ASSERT_TRUE(ros::service::waitForService("/vrm_manager/load_nodelet", ros::Duration(kTimeout)));
  EXPECT_FALSE(loadIntoManager("/refused_rig", "vrm_tracking/camera_rig_sim")) << "rig twin: 'camera 1' accepted";
  EXPECT_FALSE(loadIntoManager("/refused_tracker", "vrm_tracking/tracker")) << "tracker: 'camera 1' accepted";
  EXPECT_FALSE(loadIntoManager("/refused_detector", "vrm_tracking/marker_detector")) << "detector: 'camera 1' accepted";
  std::remove(path);

  nodelet::NodeletList list;
  ASSERT_TRUE(ros::service::call("/vrm_manager/list", list)) << "the manager is gone after refusing nodelets";
  const auto loaded = [&](const std::string& name) {
    return std::count(list.response.nodelets.begin(), list.response.nodelets.end(), name);
  };
  EXPECT_EQ(loaded("/refused_rig") + loaded("/refused_tracker") + loaded("/refused_detector"), 0);
  EXPECT_EQ(loaded("/camera_rig_sim"), 1);
  EXPECT_EQ(loaded("/tracker"), 1);
  // The graph still tracks: the running nodelets' topics, which the refused ones shared for a moment, still flow.
  EXPECT_TRUE(l.waitFor([&] { return l.eye.size() >= eye_states_before + 20; }, kTimeout))
      << "no eye states after the refused loads";
}

}  // namespace
}  // namespace vrm_tracking

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_tracking_graph");
  vrm_sim::usePackageData();  // the default scene is a shipped scene
  ros::NodeHandle nh;
  ros::NodeHandle pnh("~");
  pnh.param("stop_after", vrm_tracking::g_stop_after, 150);
  pnh.param<std::string>("scene", vrm_tracking::g_scene, "");
  pnh.param<std::string>("layout_file", vrm_tracking::g_layout_file, "");
  pnh.param<std::string>("rig_file", vrm_tracking::g_rig_file, "");
  vrm_tracking::g_listener = std::make_unique<vrm_tracking::Listener>(nh);
  vrm_tracking::g_tf = std::make_unique<tf2_ros::Buffer>(ros::Duration(30.0));
  // The listener's own thread writes into the buffer: it must go before the buffer does.
  auto tf_listener = std::make_unique<tf2_ros::TransformListener>(*vrm_tracking::g_tf);
  ros::AsyncSpinner spinner(2);
  spinner.start();
  const int result = RUN_ALL_TESTS();
  spinner.stop();
  vrm_tracking::g_listener.reset();
  tf_listener.reset();
  vrm_tracking::g_tf.reset();
  ros::shutdown();
  return result;
}
