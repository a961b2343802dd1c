// Camera dropout in the full simulator graph with tracking (issue 14, camera_dropout.test): the rig twin's cameras
// are stopped and resumed at run time through camera_rig_sim/fault.
//   * All three stop for 2 s while the forceps hold the membrane: instrument_state keeps coming, marked invalid with
//     quality 0 and the last valid pose; /diagnostics ERROR; the VR part releases the grasp and no instrument moves
//     tissue (no grasped nodes, no new lift, tears, cuts or retina contacts in the held frames); valid poses return.
//   * One camera stops for 2 s: valid poses keep coming from the other two at >= 80 % of the rate before; the
//     tracker WARNs naming the camera; after its return the tracker uses every camera again within 3 frames and
//     reports OK.
//   * Throughout: every eye_state / instrument_state / simulation_state / tissue mesh field finite, instrument
//     stamps strictly increasing (held frames included).
// Every wait is a condition with a timeout, never a fixed sleep. The measured numbers are printed and recorded as
// test properties (the XML result).

#include <diagnostic_msgs/DiagnosticArray.h>
#include <gtest/gtest.h>
#include <ros/ros.h>
#include <std_msgs/String.h>
#include <vrm_msgs/EyeState.h>
#include <vrm_msgs/InstrumentState.h>
#include <vrm_msgs/MarkerObservations.h>
#include <vrm_msgs/SimulationState.h>
#include <vrm_msgs/TissueMesh.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <memory>
#include <mutex>
#include <set>
#include <string>
#include <vector>

#include "vrm_sim/testing/graph_test.h"
#include "vrm_sim/testing/sanitizer.h"

namespace vrm_tracking {
namespace {

using vrm_sim::testing::kUnderSanitizer;
using vrm_sim::testing::waitForSubscribers;

constexpr double kTimeout = 60.0;  // s; three cameras rendered on a shared 2-core machine can be slow
constexpr double kPeriod = 0.02;   // the rig's nominal frame period (50 Hz)
// Under ASan (scripts/test.sh --sanitize) the instrumented rig twin, tracker and simulation run below the rig's 50 Hz
// and the tracker holds (invalid) the frames whose camera images come late: valid poses arrive at a fraction of the
// rate, so the counts the tests wait for are smaller and the waits longer. The checks on each frame are the same.
constexpr int kSettleValidPoses = kUnderSanitizer ? 2 * 50 : 2 * 150;  // both instruments; 3 s at 50 Hz in Release
constexpr double kSettleTimeout = kUnderSanitizer ? 3 * kTimeout : kTimeout;

bool finite(const geometry_msgs::Pose& p) {
  return std::isfinite(p.position.x) && std::isfinite(p.position.y) && std::isfinite(p.position.z) &&
         std::isfinite(p.orientation.x) && std::isfinite(p.orientation.y) && std::isfinite(p.orientation.z) &&
         std::isfinite(p.orientation.w);
}

bool finite(const vrm_msgs::InstrumentState& m) {
  return finite(m.tip_pose) && std::isfinite(m.shaft_axis.x) && std::isfinite(m.shaft_axis.y) &&
         std::isfinite(m.shaft_axis.z) && std::isfinite(m.insertion_depth) && std::isfinite(m.roll) &&
         std::isfinite(m.jaw_angle) && std::isfinite(m.suction) && std::isfinite(m.cut_rate) &&
         std::isfinite(m.injection_flow) && std::isfinite(m.tracking_quality);
}

bool finite(const vrm_msgs::EyeState& m) {
  return std::isfinite(m.rotation.x) && std::isfinite(m.rotation.y) && std::isfinite(m.rotation.z) &&
         std::isfinite(m.rotation.w) && std::isfinite(m.rotation_center.x) && std::isfinite(m.rotation_center.y) &&
         std::isfinite(m.rotation_center.z) && std::isfinite(m.tracking_quality);
}

bool finite(const vrm_msgs::SimulationState& m) {
  if (!std::isfinite(m.frame_time) || !std::isfinite(m.wall_time) || !std::isfinite(m.max_injury)) return false;
  for (const auto& t : m.tissues) {
    if (!std::isfinite(t.max_strain) || !std::isfinite(t.max_lift) || !std::isfinite(t.lifted_fraction)) return false;
  }
  return true;
}

struct Received {
  double wall = 0.0;  // arrival, s
  vrm_msgs::InstrumentState::ConstPtr msg;
};

struct Status {
  double wall = 0.0;
  diagnostic_msgs::DiagnosticStatus status;
  std::string value(const std::string& key) const {
    for (const auto& kv : status.values) {
      if (kv.key == key) return kv.value;
    }
    return "";
  }
};

double wallNow() { return ros::WallTime::now().toSec(); }

class Listener : public vrm_sim::testing::AwaitedState {
 public:
  explicit Listener(ros::NodeHandle& nh) {
    subs_.push_back(nh.subscribe("instrument_state", 2000, &Listener::onInstrument, this));
    subs_.push_back(nh.subscribe("eye_state", 1000, &Listener::onEye, this));
    subs_.push_back(nh.subscribe("simulation_state", 1000, &Listener::onSimulation, this));
    subs_.push_back(nh.subscribe("tissue/membrane", 2, &Listener::onMesh, this));
    subs_.push_back(nh.subscribe("/diagnostics", 200, &Listener::onDiagnostics, this));
    for (int c = 0; c < 3; ++c) {
      const std::string name = "camera_" + std::to_string(c);
      subs_.push_back(nh.subscribe<vrm_msgs::MarkerObservations>(
          name + "/markers", 200, [this, name](const vrm_msgs::MarkerObservations::ConstPtr& m) {
            std::set<int> classes;
            for (const auto& marker : m->markers) classes.insert(marker.class_id);
            update([&] { cameras[name].push_back({wallNow(), m->header.stamp, classes}); });
          }));
    }
  }

  struct CameraFrame {
    double wall;
    ros::Time stamp;
    std::set<int> classes;
  };

  std::vector<Received> instruments;
  std::vector<vrm_msgs::EyeState::ConstPtr> eyes;
  std::map<ros::Time, vrm_msgs::SimulationState::ConstPtr> simulation;
  std::map<std::string, std::vector<CameraFrame>> cameras;
  std::vector<Status> tracker_status;
  std::map<std::string, ros::Time> last_instrument_stamp;
  int nonfinite = 0, non_monotonic = 0, meshes = 0;
  std::string first_problem;

 private:
  void problem(const std::string& what) {
    if (first_problem.empty()) first_problem = what;
  }
  void onInstrument(const vrm_msgs::InstrumentState::ConstPtr& m) {
    update([&] {
      instruments.push_back({wallNow(), m});
      if (!finite(*m)) {
        ++nonfinite;
        problem("non-finite instrument_state " + m->instrument_id);
      }
      ros::Time& last = last_instrument_stamp[m->instrument_id];
      if (!last.isZero() && m->header.stamp <= last) {
        ++non_monotonic;
        problem("instrument_state " + m->instrument_id + " stamp not increasing");
      }
      last = m->header.stamp;
    });
  }
  void onEye(const vrm_msgs::EyeState::ConstPtr& m) {
    update([&] {
      eyes.push_back(m);
      if (!finite(*m)) {
        ++nonfinite;
        problem("non-finite eye_state");
      }
    });
  }
  void onSimulation(const vrm_msgs::SimulationState::ConstPtr& m) {
    update([&] {
      simulation[m->header.stamp] = m;
      if (!finite(*m)) {
        ++nonfinite;
        problem("non-finite simulation_state");
      }
    });
  }
  void onMesh(const vrm_msgs::TissueMesh::ConstPtr& m) {
    const bool ok = std::all_of(m->positions.begin(), m->positions.end(), [](float v) { return std::isfinite(v); });
    update([&] {
      ++meshes;
      if (!ok) {
        ++nonfinite;
        problem("non-finite tissue/membrane vertex");
      }
    });
  }
  void onDiagnostics(const diagnostic_msgs::DiagnosticArray::ConstPtr& m) {
    update([&] {
      for (const auto& s : m->status) {
        if (s.name.find("tracker") != std::string::npos) tracker_status.push_back({wallNow(), s});
      }
    });
  }

  std::vector<ros::Subscriber> subs_;
};

std::unique_ptr<Listener> g_listener;
ros::Publisher g_fault;

void fault(const std::string& command) {
  std_msgs::String msg;
  msg.data = command;
  g_fault.publish(msg);
}

void record(const std::string& key, double value) {
  std::printf("[camera_dropout] %s = %.4g\n", key.c_str(), value);
  ::testing::Test::RecordProperty(key, std::to_string(value));
}

// The first frame of a camera that arrived after `wall`.
const Listener::CameraFrame* firstAfter(const std::vector<Listener::CameraFrame>& frames, double wall) {
  for (const auto& f : frames) {
    if (f.wall > wall) return &f;
  }
  return nullptr;
}

// Valid instrument_state of `slot` per second of camera time over stamps in (from, to).
double validRate(const Listener& l, const std::string& slot, ros::Time from, ros::Time to) {
  int n = 0;
  for (const auto& r : l.instruments) {
    n += r.msg->instrument_id == slot && r.msg->valid && r.msg->header.stamp > from && r.msg->header.stamp < to;
  }
  return n / std::max(1e-9, (to - from).toSec());
}

bool trackerStatusAfter(const Listener& l, double wall, int level, const std::string& part, double* at = nullptr) {
  for (const auto& s : l.tracker_status) {
    if (s.wall > wall && s.status.level == level && s.status.message.find(part) != std::string::npos) {
      if (at) *at = s.wall;
      return true;
    }
  }
  return false;
}

// Waits until the graph tracks: valid poses of both instruments for a few seconds and the fault topic connected.
void waitForTracking() {
  auto& l = *g_listener;
  ASSERT_TRUE(l.waitFor(
      [&] {
        int valid = 0;
        for (const auto& r : l.instruments) valid += r.msg->valid;
        return valid >= 200 && !l.simulation.empty();
      },
      kTimeout))
      << "no tracked instrument_state / simulation_state";
  ASSERT_TRUE(waitForSubscribers(g_fault, kTimeout)) << "camera_rig_sim/fault not subscribed";
}

TEST(CameraDropout, AllCamerasStoppedHoldTheLastPoseInvalidAndMoveNoTissue) {
  ASSERT_NO_FATAL_FAILURE(waitForTracking());
  auto& l = *g_listener;
  // The built-in demo's forceps grasp the membrane at 5.8 s of each 40 s loop and hold it until 10.6 s: stop the
  // cameras while it is grasped, the case where a stale pose would do harm.
  auto grasped = [&l] {
    if (l.simulation.empty()) return false;
    for (const auto& t : l.simulation.rbegin()->second->tissues) {
      if (t.grasped_nodes > 0) return true;
    }
    return false;
  };
  std::size_t frames_seen = 0, poses_seen = 0;  // copied under the listener's lock, for the failure message
  const bool grasp_seen = l.waitFor(
      [&] {
        frames_seen = l.simulation.size();
        poses_seen = l.instruments.size();
        return grasped();
      },
      kUnderSanitizer ? 3 * kTimeout : 2 * kTimeout);
  if (kUnderSanitizer && !grasp_seen) {
    // Measured under ASan: the simulation ran at ~10 Hz behind its inputs and the mediator closed frames with the
    // tracked tip late against the pedal's jaw command, so the demo's jaws shut above the membrane in all six loops
    // (5559 frames, grasped 0). The grasp, and so this test's premise, is a real-time property the sanitizer build
    // does not have; the other tests of this file still run the dropout paths under it.
    GTEST_SKIP() << "the demo's grasp did not happen under ASan in " << 3 * kTimeout << " s (" << frames_seen
                 << " simulation frames)";
  }
  ASSERT_TRUE(grasp_seen) << "the forceps never grasped the membrane (" << frames_seen << " simulation frames, "
                          << poses_seen << " instrument poses received)";
  const double t_stop = wallNow();
  fault("stop all 2.0");

  // Held frames: both instruments invalid with quality 0, stamped after the cameras' last frame before the stop (a
  // load stall between the command and the stop may have held a frame or two already).
  std::set<ros::Time> held;
  auto lastFrameBeforeStop = [&]() -> const Listener::CameraFrame* {
    const std::vector<Listener::CameraFrame>& frames = l.cameras["camera_0"];
    const Listener::CameraFrame* last = nullptr;
    for (std::size_t i = 0; i + 1 < frames.size(); ++i) {
      if (frames[i + 1].wall > t_stop && frames[i + 1].wall - frames[i].wall > 1.0) last = &frames[i];
    }
    if (!last && !frames.empty() && frames.back().wall > t_stop && wallNow() - frames.back().wall > 0.5) {
      last = &frames.back();  // still stopped
    }
    return last;
  };
  auto collectHeld = [&] {
    held.clear();
    const Listener::CameraFrame* last = lastFrameBeforeStop();
    if (!last) return false;
    const std::vector<Listener::CameraFrame>& frames = l.cameras["camera_0"];
    const ros::Time back = last + 1 < frames.data() + frames.size() ? (last + 1)->stamp : ros::TIME_MAX;
    std::map<ros::Time, int> invalid;
    for (const auto& r : l.instruments) {
      if (r.msg->header.stamp > last->stamp && r.msg->header.stamp < back && !r.msg->valid &&
          r.msg->tracking_quality == 0.0f) {
        ++invalid[r.msg->header.stamp];
      }
    }
    for (const auto& [stamp, n] : invalid) {
      if (n == 2) held.insert(stamp);
    }
    return held.size() >= 10;
  };
  ASSERT_TRUE(l.waitFor(collectHeld, 10.0)) << "no held (invalid) instrument_state after all cameras stopped";
  double t_error = 0.0;
  EXPECT_TRUE(l.waitFor(
      [&] {
        return trackerStatusAfter(l, t_stop, diagnostic_msgs::DiagnosticStatus::ERROR, "holding the last poses",
                                  &t_error);
      },
      10.0))
      << "no tracker ERROR while no camera delivers";
  // The cameras return after 2 s: valid poses again.
  ASSERT_TRUE(l.waitFor(
      [&] {
        for (const auto& r : l.instruments) {
          if (r.wall > t_stop + 1.5 && r.msg->valid) return true;
        }
        return false;
      },
      kTimeout))
      << "no valid instrument_state after the cameras returned";
  // The simulation frames of every held stamp (and the one before the hold).
  ASSERT_TRUE(l.waitFor(
      [&] {
        collectHeld();
        return !held.empty() && !l.simulation.empty() && l.simulation.rbegin()->first >= *held.rbegin();
      },
      kTimeout))
      << "the VR part did not step through the held frames";

  std::lock_guard<std::mutex> lock(l.mutex_);
  collectHeld();
  const ros::Time first_held = *held.begin(), last_held = *held.rbegin();
  // The pose held is the last valid one (tip, shaft, depth exactly; the orientation's roll is a live sensor).
  for (const std::string slot : {"left", "right"}) {
    SCOPED_TRACE(slot);
    vrm_msgs::InstrumentState::ConstPtr last_valid;
    for (const auto& r : l.instruments) {
      if (r.msg->instrument_id == slot && r.msg->valid && r.msg->header.stamp < first_held) last_valid = r.msg;
    }
    ASSERT_TRUE(last_valid);
    int checked = 0;
    for (const auto& r : l.instruments) {
      if (r.msg->instrument_id != slot || !held.count(r.msg->header.stamp)) continue;
      ++checked;
      EXPECT_EQ(r.msg->header.frame_id, "eye");
      EXPECT_EQ(r.msg->tip_pose.position.x, last_valid->tip_pose.position.x);
      EXPECT_EQ(r.msg->tip_pose.position.y, last_valid->tip_pose.position.y);
      EXPECT_EQ(r.msg->tip_pose.position.z, last_valid->tip_pose.position.z);
      EXPECT_EQ(r.msg->shaft_axis.x, last_valid->shaft_axis.x);
      EXPECT_EQ(r.msg->shaft_axis.y, last_valid->shaft_axis.y);
      EXPECT_EQ(r.msg->shaft_axis.z, last_valid->shaft_axis.z);
      EXPECT_EQ(r.msg->insertion_depth, last_valid->insertion_depth);
    }
    EXPECT_EQ(checked, static_cast<int>(held.size()));
  }
  // Held eye states: invalid, quality 0, every held stamp has one.
  int held_eyes = 0;
  for (const auto& e : l.eyes) {
    if (!held.count(e->header.stamp)) continue;
    ++held_eyes;
    EXPECT_FALSE(e->valid);
    EXPECT_EQ(e->tracking_quality, 0.0f);
  }
  EXPECT_EQ(held_eyes, static_cast<int>(held.size()));
  // Held stamps continue the camera stamps on the camera period grid.
  const Listener::CameraFrame* before = lastFrameBeforeStop();  // camera_0's last frame before the hold
  ASSERT_TRUE(before);
  EXPECT_GT(first_held, before->stamp);
  for (const ros::Time& s : held) {
    const double periods = (s - before->stamp).toSec() / kPeriod;
    EXPECT_NEAR(periods, std::round(periods), 1e-6) << "held stamp off the camera period grid";
  }

  // The VR part under the stale pose: the grasp is released and no instrument drives tissue.
  vrm_msgs::SimulationState::ConstPtr previous;
  for (auto it = l.simulation.begin(); it != l.simulation.end() && it->first < first_held; ++it) previous = it->second;
  ASSERT_TRUE(previous) << "no simulation frame before the hold";
  bool was_grasped = false;
  for (const auto& t : previous->tissues) was_grasped |= t.grasped_nodes > 0;
  EXPECT_TRUE(was_grasped) << "the membrane was not grasped when the cameras stopped";
  // The lift to compare with is the one after the last valid tick (camera_0's last frame before the hold). A
  // simulation slower than its inputs closes fuller frames: it may have no frame at that stamp, and its first frame
  // after `previous` then applies the last valid ticks too, the grasp still lifting, before the held ones release it
  // (under ASan). That frame is the baseline; the frames after it apply held ticks only. With a frame per tick
  // (Release) it is `previous` itself.
  const auto baseline = l.simulation.lower_bound(before->stamp);
  ASSERT_TRUE(baseline != l.simulation.end()) << "no simulation frame applied the last valid tick";
  int frames = 0;
  double lift_before = 0.0, lift_max = 0.0;
  for (const auto& t : baseline->second->tissues) lift_before = std::max(lift_before, t.max_lift);
  for (auto it = l.simulation.lower_bound(first_held); it != l.simulation.end() && it->first <= last_held; ++it) {
    const vrm_msgs::SimulationState& s = *it->second;
    ++frames;
    EXPECT_EQ(s.retina_contacts, previous->retina_contacts) << "retina contact with a stale pose";
    ASSERT_EQ(s.tissues.size(), previous->tissues.size());
    for (std::size_t k = 0; k < s.tissues.size(); ++k) {
      const auto& t = s.tissues[k];
      const auto& t0 = previous->tissues[k];
      EXPECT_EQ(t.grasped_nodes, 0u) << t.tissue_id << ": grasped with a stale pose";
      EXPECT_EQ(t.torn_springs, t0.torn_springs) << t.tissue_id;
      EXPECT_EQ(t.cut_nodes, t0.cut_nodes) << t.tissue_id;
      if (it->first > baseline->first) lift_max = std::max(lift_max, t.max_lift);
    }
  }
  // A rate, not checked under ASan, where the instrumented simulation is slower than its inputs and closes fewer,
  // fuller frames (27 for 71 held tracker frames, measured); the checks above still ran on every frame it simulated.
  if (!kUnderSanitizer) EXPECT_GE(frames, static_cast<int>(0.8 * held.size())) << "the VR part skipped held frames";
  // Released, the membrane only falls back towards the retina: nothing lifts it further.
  EXPECT_LE(lift_max, lift_before + 1e-5)
      << "tissue lifted under a stale pose (last valid tick " << before->stamp << ", frame before the hold "
      << previous->header.stamp << ", baseline frame " << baseline->first << ", first held tick " << first_held << ")";

  record("all_stop_held_frames", static_cast<double>(held.size()));
  record("all_stop_held_rate_hz", (held.size() - 1) / std::max(1e-9, (last_held - first_held).toSec()));
  record("all_stop_time_to_error_s", t_error > 0.0 ? t_error - before->wall : -1.0);
  record("all_stop_membrane_lift_before_mm", 1e3 * lift_before);
  record("all_stop_membrane_lift_max_during_mm", 1e3 * lift_max);
  record("all_stop_simulation_frames", frames);
}

TEST(CameraDropout, OneCameraStoppedTracksWithTwoWarnsAndRecovers) {
  ASSERT_NO_FATAL_FAILURE(waitForTracking());
  auto& l = *g_listener;
  // Three seconds of undisturbed tracking first (the rate to compare with).
  const double t_settle = wallNow();
  int settle_valid = 0, settle_invalid = 0;
  ASSERT_TRUE(l.waitFor(
      [&] {
        settle_valid = settle_invalid = 0;
        for (const auto& r : l.instruments) {
          if (r.wall <= t_settle) continue;
          ++(r.msg->valid ? settle_valid : settle_invalid);
        }
        return settle_valid >= kSettleValidPoses;
      },
      kSettleTimeout))
      << "undisturbed tracking before the stop: " << settle_valid << " valid and " << settle_invalid
      << " invalid instrument poses in " << kSettleTimeout << " s (" << kSettleValidPoses << " valid wanted)";
  const double t_stop = wallNow();
  fault("stop camera_1 2.0");
  // camera_1 goes silent, then comes back.
  const Listener::CameraFrame* returned = nullptr;
  ASSERT_TRUE(l.waitFor(
      [&] {
        returned = firstAfter(l.cameras["camera_1"], t_stop + 1.0);
        return returned != nullptr;
      },
      kTimeout))
      << "camera_1 did not return";
  const double t_return = returned->wall;
  const ros::Time return_stamp = returned->stamp;
  // Its recovery (the tracker's count of frames until every camera is used again, for the return at this stamp)
  // and OK afterwards.
  std::string recovery;
  EXPECT_TRUE(l.waitFor(
      [&] {
        for (const auto& s : l.tracker_status) {
          const std::string value = s.value("camera_1 last recovery");
          int frames = 0;
          double silent = 0.0, back = 0.0;
          if (std::sscanf(value.c_str(), "%d frame(s) after %lf s silent (back at %lf", &frames, &silent, &back) == 3 &&
              std::abs(back - return_stamp.toSec()) < 1e-3) {
            recovery = value;
            return true;
          }
        }
        return false;
      },
      20.0))
      << "the tracker did not report camera_1's recovery";
  double t_ok = 0.0;
  EXPECT_TRUE(l.waitFor(
      [&] { return trackerStatusAfter(l, t_return, diagnostic_msgs::DiagnosticStatus::OK, "", &t_ok); }, 30.0))
      << "the tracker did not return to OK";

  std::lock_guard<std::mutex> lock(l.mutex_);
  const auto& cam1 = l.cameras.at("camera_1");
  const Listener::CameraFrame* last = nullptr;  // the frame before the gap
  for (const auto& f : cam1) {
    if (f.stamp < return_stamp) last = &f;
  }
  ASSERT_TRUE(last);
  const ros::Time stop_stamp = last->stamp;
  const double gap_s = (return_stamp - stop_stamp).toSec();
  EXPECT_GT(gap_s, 1.5);
  EXPECT_LT(gap_s, 4.0);
  // Rates by camera time: 3 s before the stop, and while camera_1 was away (its last and first frames excluded).
  // Two cameras cannot reconstruct a marker that one of them does not see (hidden behind another marker or a
  // shaft: what the third camera is for, thesis §7.3.2). Such frames are counted and reported; the rate is asserted
  // over the others, so it measures that tracking continues with two cameras, not the scene's geometry.
  for (const std::string slot : {"left", "right"}) {
    SCOPED_TRACE(slot);
    const int cls = slot == "left" ? 2 : 3;  // markers_default.yaml: green = left tip, yellow = right tip
    auto detectedByBoth = [&](const ros::Time& stamp) {
      for (const std::string cam : {"camera_0", "camera_2"}) {
        const std::vector<Listener::CameraFrame>& frames = l.cameras.at(cam);
        const auto it = std::find_if(frames.begin(), frames.end(),
                                     [&](const Listener::CameraFrame& f) { return f.stamp == stamp; });
        if (it == frames.end() || !it->classes.count(cls)) return false;
      }
      return true;
    };
    int valid = 0, invalid_seen = 0, hidden = 0;
    for (const auto& r : l.instruments) {
      if (r.msg->instrument_id != slot || r.msg->header.stamp <= stop_stamp || r.msg->header.stamp >= return_stamp) {
        continue;
      }
      if (r.msg->valid) {
        ++valid;
      } else if (detectedByBoth(r.msg->header.stamp)) {
        ++invalid_seen;
      } else {
        ++hidden;
      }
    }
    const double before = validRate(l, slot, stop_stamp - ros::Duration(3.0), stop_stamp);
    const double during = validRate(l, slot, stop_stamp, return_stamp);
    const double window = (return_stamp - stop_stamp).toSec();
    const double during_visible = valid / std::max(1e-9, window - hidden * kPeriod);
    EXPECT_GE(during_visible, 0.8 * before)
        << "valid " << slot
        << " poses during the dropout (frames whose marker both remaining cameras saw): " << during_visible << " Hz vs "
        << before << " Hz before";
    EXPECT_LE(invalid_seen, static_cast<int>(0.05 * window / kPeriod) + 1)
        << "frames invalid although both remaining cameras detected the marker";
    record("one_stop_" + slot + "_valid_rate_before_hz", before);
    record("one_stop_" + slot + "_valid_rate_during_hz", during);
    record("one_stop_" + slot + "_valid_rate_during_visible_hz", during_visible);
    record("one_stop_" + slot + "_frames_marker_hidden_in_a_remaining_camera", hidden);
  }
  // WARN naming camera_1 while it was away, never ERROR (two cameras reconstruct).
  double t_warn = 0.0;
  EXPECT_TRUE(trackerStatusAfter(l, t_stop, diagnostic_msgs::DiagnosticStatus::WARN, "camera_1", &t_warn))
      << "no tracker WARN naming camera_1";
  for (const auto& s : l.tracker_status) {
    if (s.wall > t_stop && s.wall < t_return + 0.5) {
      EXPECT_LT(s.status.level, diagnostic_msgs::DiagnosticStatus::ERROR) << s.status.message;
    }
  }
  for (const auto& s : l.tracker_status) {
    if (s.wall > t_stop) {
      std::printf("[camera_dropout] tracker status +%.2f s: %d %s\n", s.wall - t_stop, s.status.level,
                  s.status.message.c_str());
    }
  }
  int frames = -1;
  ASSERT_EQ(std::sscanf(recovery.c_str(), "%d frame", &frames), 1) << recovery;
  EXPECT_GE(frames, 1);
  EXPECT_LE(frames, 3) << "frames until the tracker used three cameras again: " << recovery;
  record("one_stop_gap_s", gap_s);
  record("one_stop_time_to_warn_s", t_warn > 0.0 ? t_warn - last->wall : -1.0);
  record("one_stop_recovery_frames", frames);
  record("one_stop_time_to_ok_after_return_s", t_ok > 0.0 ? t_ok - t_return : -1.0);
}

TEST(CameraDropout, NothingNonFiniteAndStampsMonotonic) {
  auto& l = *g_listener;
  std::lock_guard<std::mutex> lock(l.mutex_);
  EXPECT_EQ(l.nonfinite, 0) << l.first_problem;
  EXPECT_EQ(l.non_monotonic, 0) << l.first_problem;
  EXPECT_GT(l.meshes, 0) << "no tissue/membrane mesh received";
  EXPECT_GT(l.eyes.size(), 100u);
}

}  // namespace
}  // namespace vrm_tracking

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_camera_dropout");
  ros::NodeHandle nh;
  vrm_tracking::g_listener = std::make_unique<vrm_tracking::Listener>(nh);
  vrm_tracking::g_fault = nh.advertise<std_msgs::String>("camera_rig_sim/fault", 10);
  ros::AsyncSpinner spinner(2);
  spinner.start();
  const int result = RUN_ALL_TESTS();
  spinner.stop();
  vrm_tracking::g_listener.reset();
  ros::shutdown();
  return result;
}
