// Graph test for the simulated hardware: scripted_surgeon, pedals_sim and microscope_sim in one nodelet manager
// (simulated_hardware.test). Every wait is a condition with a timeout, never a fixed sleep.

#include <gtest/gtest.h>
#include <ros/ros.h>
#include <vrm_msgs/EyeState.h>
#include <vrm_msgs/InstrumentState.h>
#include <vrm_msgs/MicroscopeSettings.h>
#include <vrm_msgs/PedalState.h>

#include <boost/make_shared.hpp>
#include <cmath>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "vrm_scene/package_data.h"
#include "vrm_scene/scene_loader.h"
#include "vrm_sim/testing/graph_test.h"
#include "vrm_tracking/conversions.h"
#include "vrm_tracking/scene_trocars.h"
#include "vrm_tracking/surgeon_script.h"

namespace vrm_tracking {
namespace {

// Everything one topic delivered, with wall-clock receipt times (the rate a subscriber actually sees).
template <class M>
struct Stream {
  std::vector<typename M::ConstPtr> messages;
  std::vector<double> received;  // wall seconds
};

class Listener : public vrm_sim::testing::AwaitedState {
 public:
  explicit Listener(ros::NodeHandle& nh) {
    eye_sub_ = nh.subscribe("eye_state", 100, &Listener::onEye, this);
    instrument_sub_ = nh.subscribe("instrument_state", 200, &Listener::onInstrument, this);
    pedal_sub_ = nh.subscribe("pedals", 200, &Listener::onPedals, this);
    microscope_sub_ = nh.subscribe("microscope", 100, &Listener::onMicroscope, this);
  }

  Stream<vrm_msgs::EyeState> eye;
  std::map<std::string, Stream<vrm_msgs::InstrumentState>> instruments;  // by instrument_id
  Stream<vrm_msgs::PedalState> pedals;
  Stream<vrm_msgs::MicroscopeSettings> microscope;

 private:
  template <class M>
  void add(Stream<M>* stream, const typename M::ConstPtr& msg) {
    update([&] {
      stream->messages.push_back(msg);
      stream->received.push_back(ros::WallTime::now().toSec());
    });
  }
  void onEye(const vrm_msgs::EyeState::ConstPtr& msg) { add(&eye, msg); }
  void onInstrument(const vrm_msgs::InstrumentState::ConstPtr& msg) {
    Stream<vrm_msgs::InstrumentState>* stream;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      stream = &instruments[msg->instrument_id];
    }
    add(stream, msg);
  }
  void onPedals(const vrm_msgs::PedalState::ConstPtr& msg) { add(&pedals, msg); }
  void onMicroscope(const vrm_msgs::MicroscopeSettings::ConstPtr& msg) { add(&microscope, msg); }

  ros::Subscriber eye_sub_, instrument_sub_, pedal_sub_, microscope_sub_;
};

std::unique_ptr<Listener> g_listener;
std::string g_script_path;
std::string g_scene;  // the surgeon's ~scene: its trocars replace the script's
double g_zoom_max = 3.0;

// Mean receive rate over `window` messages, skipping the first `skip` (connection set-up may deliver a burst).
template <class M>
double measuredRate(const Stream<M>& stream, std::size_t skip, std::size_t window) {
  const double span = stream.received[skip + window - 1] - stream.received[skip];
  return static_cast<double>(window - 1) / span;
}

constexpr std::size_t kSkip = 10;
constexpr double kTimeout = 20.0;  // s; generous for a shared 2-core machine

template <class M>
void expectRate(const char* topic, const Stream<M>& stream, double nominal) {
  const std::size_t window = static_cast<std::size_t>(2.0 * nominal);  // about two seconds
  ASSERT_GE(stream.messages.size(), kSkip + window) << topic;
  const double rate = measuredRate(stream, kSkip, window);
  EXPECT_NEAR(rate, nominal, 0.2 * nominal) << topic << " arrives at " << rate << " Hz";
}

bool finite(const geometry_msgs::Point& p) { return std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z); }
bool finite(const geometry_msgs::Vector3& v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); }
bool finite(const geometry_msgs::Quaternion& q) {
  return std::isfinite(q.w) && std::isfinite(q.x) && std::isfinite(q.y) && std::isfinite(q.z);
}

TEST(SimulatedHardware, EyeStateAtTrackingRate) {
  auto& l = *g_listener;
  ASSERT_TRUE(l.waitFor([&] { return l.eye.messages.size() >= kSkip + 100; }, kTimeout)) << "eye_state not received";
  std::lock_guard<std::mutex> lock(l.mutex_);
  expectRate("eye_state", l.eye, 50.0);
  for (const auto& msg : l.eye.messages) {
    EXPECT_EQ(msg->header.frame_id, "world");
    EXPECT_FALSE(msg->header.stamp.isZero());
    ASSERT_TRUE(finite(msg->rotation) && finite(msg->rotation_center));
    EXPECT_NEAR(toEigen(msg->rotation).norm(), 1.0, 1e-9);
    EXPECT_TRUE(msg->valid);
  }
}

TEST(SimulatedHardware, InstrumentStatePerSlotWithTrocarConstraint) {
  // The instruments pivot at the scene's trocars (the scene is the truth; without ~scene the default scene's).
  const vrm_sim::scene::SceneDescription scene = vrm_sim::scene::loadScene(sceneOrDefault(g_scene));
  const SurgeonScript script = playInScene(scene, loadSession(g_script_path, scene));
  std::map<std::string, Eigen::Vector3d> trocars;  // slot -> the scene's trocar
  for (std::size_t i = 0; i < script.tracks().size(); ++i) {
    trocars[vrm_sim::scene::toString(script.session().instruments[i].slot)] = script.tracks()[i].trocar;
  }
  ASSERT_EQ(trocars.size(), 2u);
  if (!g_scene.empty()) {
    const vrm_sim::scene::SceneDescription fallback = vrm_sim::scene::loadScene(sceneOrDefault(""));
    for (const auto& [slot, trocar] : trocars) {  // the test scene really moves them
      EXPECT_GT((trocar - sceneTrocarForSlot(fallback, slot)).norm(), 1e-4);
    }
  }
  auto& l = *g_listener;
  ASSERT_TRUE(l.waitFor(
      [&] {
        for (const auto& [slot, trocar] : trocars) {
          const auto it = l.instruments.find(slot);
          if (it == l.instruments.end() || it->second.messages.size() < kSkip + 100) return false;
        }
        return true;
      },
      kTimeout))
      << "instrument_state not received for every slot";

  std::lock_guard<std::mutex> lock(l.mutex_);
  EXPECT_EQ(l.instruments.size(), trocars.size()) << "unexpected instrument_id";
  for (const auto& [slot, trocar] : trocars) {
    const auto& stream = l.instruments.at(slot);
    expectRate(("instrument_state/" + slot).c_str(), stream, 50.0);
    for (const auto& msg : stream.messages) {
      EXPECT_EQ(msg->header.frame_id, "eye");
      ASSERT_TRUE(finite(msg->tip_pose.position) && finite(msg->tip_pose.orientation) && finite(msg->shaft_axis));
      ASSERT_TRUE(std::isfinite(msg->insertion_depth) && std::isfinite(msg->roll) && std::isfinite(msg->jaw_angle) &&
                  std::isfinite(msg->suction) && std::isfinite(msg->cut_rate) && std::isfinite(msg->injection_flow));
      const InstrumentSample s = fromMsg(*msg);
      EXPECT_NEAR(s.shaft_axis.norm(), 1.0, 1e-9);
      // Trocar constraint: the shaft line, followed back from the tip by the insertion depth, hits the trocar.
      EXPECT_LT((s.trocar - trocar).norm(), 1e-9) << slot << " shaft misses its trocar";
      // The tip frame's z axis is the shaft.
      EXPECT_LT((s.orientation.normalized() * Eigen::Vector3d::UnitZ() - s.shaft_axis).norm(), 1e-9);
      EXPECT_LE(s.tip.norm(), script.eye().radius + script.eye().margin + 1e-4);
      EXPECT_TRUE(msg->valid);
    }
  }
}

TEST(SimulatedHardware, PedalsAtRate) {
  auto& l = *g_listener;
  ASSERT_TRUE(l.waitFor([&] { return l.pedals.messages.size() >= kSkip + 200; }, kTimeout)) << "pedals not received";
  std::lock_guard<std::mutex> lock(l.mutex_);
  expectRate("pedals", l.pedals, 100.0);
  for (const auto& msg : l.pedals.messages) {
    ASSERT_TRUE(std::isfinite(msg->travel));
    EXPECT_GE(msg->travel, 0.0);
    EXPECT_LE(msg->travel, 1.0);
  }
}

TEST(SimulatedHardware, MicroscopeAtRateWithinLimits) {
  auto& l = *g_listener;
  ASSERT_TRUE(l.waitFor([&] { return l.microscope.messages.size() >= kSkip + 40; }, kTimeout))
      << "microscope not received";
  std::lock_guard<std::mutex> lock(l.mutex_);
  expectRate("microscope", l.microscope, 20.0);
  for (const auto& msg : l.microscope.messages) {
    ASSERT_TRUE(std::isfinite(msg->zoom) && std::isfinite(msg->focus_distance) && std::isfinite(msg->ambient_light) &&
                std::isfinite(msg->disparity_scale));
    EXPECT_GE(msg->zoom, 1.0);
    EXPECT_LE(msg->zoom, g_zoom_max);
    EXPECT_GT(msg->focus_distance, 0.0);
  }
}

// Runs last: the override holds for the rest of the session (override_timeout 0).
TEST(SimulatedHardware, PedalCommandOverridesScriptAndDrivesZoom) {
  auto& l = *g_listener;
  ros::NodeHandle nh;
  ros::Publisher command = nh.advertise<vrm_msgs::PedalState>("pedals_sim/command", 1);

  constexpr double kTravel = 0.4242;
  auto overridden = [&] {
    return !l.pedals.messages.empty() && l.pedals.messages.back()->travel == kTravel &&
           l.pedals.messages.back()->reflux && l.pedals.messages.back()->zoom_in;
  };
  // Re-send until seen: the first messages may go out before pedals_sim has connected to this publisher.
  bool seen = false;
  const ros::WallTime deadline = ros::WallTime::now() + ros::WallDuration(kTimeout);
  while (!seen && ros::WallTime::now() < deadline) {
    auto msg = boost::make_shared<vrm_msgs::PedalState>();
    msg->header.stamp = ros::Time::now();
    msg->travel = kTravel;
    msg->reflux = true;
    msg->zoom_in = true;
    command.publish(msg);
    seen = l.waitFor(overridden, 0.2);
  }
  ASSERT_TRUE(seen) << "pedals_sim/command did not override the pedal track";

  // Held zoom_in on the pedals moves the microscope's zoom up to its limit (knob twin).
  EXPECT_TRUE(l.waitFor(
      [&] {
        return !l.microscope.messages.empty() && std::abs(l.microscope.messages.back()->zoom - g_zoom_max) < 1e-9;
      },
      kTimeout))
      << "zoom_in held on the pedals did not drive the microscope to zoom_max";

  // The override persists: a further second of pedal messages all carry the commanded state.
  std::size_t from = 0;
  {
    std::lock_guard<std::mutex> lock(l.mutex_);
    from = l.pedals.messages.size();
  }
  ASSERT_TRUE(l.waitFor([&] { return l.pedals.messages.size() >= from + 100; }, kTimeout));
  std::lock_guard<std::mutex> lock(l.mutex_);
  for (std::size_t i = from; i < l.pedals.messages.size(); ++i) {
    EXPECT_EQ(l.pedals.messages[i]->travel, kTravel);
  }
}

}  // namespace
}  // namespace vrm_tracking

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_simulated_hardware");
  vrm_sim::usePackageData();  // the default scene is a shipped scene
  ros::NodeHandle nh;
  ros::NodeHandle pnh("~");
  pnh.param<std::string>("script", vrm_tracking::g_script_path, "");
  pnh.param<std::string>("scene", vrm_tracking::g_scene, "");
  pnh.param("zoom_max", vrm_tracking::g_zoom_max, 3.0);
  vrm_tracking::g_listener = std::make_unique<vrm_tracking::Listener>(nh);
  ros::AsyncSpinner spinner(2);
  spinner.start();
  const int result = RUN_ALL_TESTS();
  spinner.stop();
  vrm_tracking::g_listener.reset();
  ros::shutdown();
  return result;
}
