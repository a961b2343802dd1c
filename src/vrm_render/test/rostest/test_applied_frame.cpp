// Graph test (issue 31): the renderer draws each instrument as the World applied it in the input frame — its type
// and its validity — never as the raw device input in the same frame said. The test stands in for scenario_manager:
// frames in which the World refused a type switch (instrument_inputs: the right slot asks for the vitrector;
// instruments[]: it keeps the forceps) or marked an instrument invalid (instrument_inputs: valid; instruments[]: not
// valid) must render like frames whose raw inputs agree with the applied values, and unlike frames built the other
// way round. A renderer that read instrument_inputs would draw the vitrector, or the forceps, and fail.

#include <gtest/gtest.h>
#include <ros/ros.h>
#include <sensor_msgs/Image.h>
#include <vrm_msgs/InputFrame.h>
#include <vrm_msgs/InstrumentState.h>
#include <vrm_msgs/ObjectPose.h>
#include <vrm_msgs/SimulationState.h>

#include <Eigen/Geometry>
#include <boost/make_shared.hpp>
#include <cmath>
#include <cstdlib>
#include <map>
#include <mutex>
#include <string>
#include <utility>
#include <vector>

#include "input_frames.h"
#include "vrm_scene/package_data.h"
#include "vrm_scene/scene_loader.h"
#include "vrm_sim/testing/graph_test.h"

namespace {

using vrm_render::testing::appliedInstrument;
using vrm_render::testing::poseThroughTrocar;
using vrm_render::testing::simulationFrame;
using vrm_sim::testing::waitFor;
using vrm_sim::testing::waitForSubscribers;

// rad: the forceps' jaws wide open, so forceps and vitrector differ in more than a few pixels.
constexpr double kJawAngle = 0.6;

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

// What the right slot's device said (instrument_inputs) and what the World applied (instruments[]).
struct RightSlot {
  std::string applied_type;  // "forceps" / "vitrector"
  bool applied_valid = true;
  std::uint8_t raw_type = vrm_msgs::InstrumentState::FORCEPS;
  bool raw_valid = true;
};

class AppliedFrameTest : public ::testing::Test {
 protected:
  void SetUp() override {
    vrm_sim::usePackageData();
    scene_ = vrm_sim::scene::loadScene("membrane_peeling");
    for (const auto& instrument : scene_.instruments) {
      // The light pipe aimed at the posterior pole; the forceps slot at the start of the scripted peel.
      const Eigen::Vector3d tip =
          instrument.path.empty() ? Eigen::Vector3d(-0.002, 0.001, -0.006) : instrument.path.front().tip_in_eye;
      poses_[vrm_sim::scene::toString(instrument.slot)] = poseThroughTrocar(scene_, instrument, tip);
    }
    ASSERT_EQ(poses_.count("left"), 1u);
    ASSERT_EQ(poses_.count("right"), 1u);
    // Watching the view makes the renderer subscribe to its inputs (lazy).
    images_sub_ =
        nh_.subscribe<sensor_msgs::Image>("stereo/left/image_raw", 20, [this](const sensor_msgs::Image::ConstPtr& m) {
          std::lock_guard<std::mutex> lock(mutex_);
          images_[m->header.stamp] = m;
        });
    frames_pub_ = nh_.advertise<vrm_msgs::InputFrame>("input_frame", 10);
    states_pub_ = nh_.advertise<vrm_msgs::SimulationState>("simulation_state", 10);
    spinner_.start();
    ASSERT_TRUE(waitForSubscribers(frames_pub_, 60.0)) << "the renderer did not subscribe input_frame";
    ASSERT_TRUE(waitForSubscribers(states_pub_, 10.0)) << "the renderer did not subscribe simulation_state";
    base_ = ros::Time::now();
  }

  // One simulation frame: the input frame, then the simulation_state of its stamp (what scenario_manager publishes);
  // returns the image stamped with it (nullptr after the timeout).
  sensor_msgs::Image::ConstPtr render(const RightSlot& right, const std::vector<vrm_msgs::ObjectPose>& objects = {}) {
    ++sequence_;
    const ros::Time stamp = base_ + ros::Duration(0.02 * static_cast<double>(sequence_));
    auto frame = simulationFrame(
        stamp, sequence_,
        {appliedInstrument("left", "light_pipe", poses_["left"], 1.0, true),
         appliedInstrument("right", right.applied_type, poses_["right"], kJawAngle, right.applied_valid)});
    const std::vector<std::pair<std::string, std::uint8_t>> raw_types = {
        {"left", vrm_msgs::InstrumentState::LIGHT_PIPE}, {"right", right.raw_type}};
    for (const auto& slot : raw_types) {
      vrm_msgs::InstrumentState raw;
      raw.header.stamp = stamp;
      raw.header.frame_id = "eye";
      raw.instrument_id = slot.first;
      raw.type = slot.second;
      raw.tip_pose = poses_[slot.first];
      raw.jaw_angle = kJawAngle;
      raw.valid = slot.first == "left" || right.raw_valid;
      raw.tracking_quality = raw.valid ? 1.0f : 0.0f;
      frame->instrument_inputs.push_back(raw);
    }
    frames_pub_.publish(frame);
    auto state = boost::make_shared<vrm_msgs::SimulationState>();
    state->header.stamp = stamp;
    state->frame = sequence_;
    state->input_sequence = sequence_;
    state->objects = objects;
    states_pub_.publish(state);
    sensor_msgs::Image::ConstPtr image;
    waitFor(
        [&] {
          std::lock_guard<std::mutex> lock(mutex_);
          const auto found = images_.find(stamp);
          if (found != images_.end()) image = found->second;
          return image != nullptr;
        },
        30.0);
    return image;
  }

  ros::NodeHandle nh_;
  ros::AsyncSpinner spinner_{2};
  vrm_sim::scene::SceneDescription scene_;
  std::map<std::string, geometry_msgs::Pose> poses_;
  ros::Subscriber images_sub_;
  ros::Publisher frames_pub_, states_pub_;
  std::mutex mutex_;
  std::map<ros::Time, sensor_msgs::Image::ConstPtr> images_;
  ros::Time base_;
  std::uint64_t sequence_ = 0;
};

TEST_F(AppliedFrameTest, DrawsTheAppliedTypeAndValidityNotTheRawInputs) {
  const RightSlot forceps{"forceps", true, vrm_msgs::InstrumentState::FORCEPS, true};
  const RightSlot vitrector{"vitrector", true, vrm_msgs::InstrumentState::VITRECTOR, true};
  const RightSlot lost{"forceps", false, vrm_msgs::InstrumentState::FORCEPS, false};

  // Until the latched scene meshes have arrived, frames of the same inputs may differ: wait for two equal ones.
  sensor_msgs::Image::ConstPtr previous = render(forceps);
  ASSERT_TRUE(previous) << "no image for the first simulation frame";
  bool settled = false;
  for (int attempt = 0; attempt < 20 && !settled; ++attempt) {
    const sensor_msgs::Image::ConstPtr next = render(forceps);
    ASSERT_TRUE(next) << "no image for simulation frame " << sequence_;
    settled = differingPixels(*previous, *next) == 0;
    previous = next;
  }
  ASSERT_TRUE(settled) << "frames of the same inputs kept changing";

  // References: raw inputs that agree with what was applied.
  const sensor_msgs::Image::ConstPtr forceps_image = render(forceps);
  const sensor_msgs::Image::ConstPtr vitrector_image = render(vitrector);
  const sensor_msgs::Image::ConstPtr lost_image = render(lost);
  ASSERT_TRUE(forceps_image && vitrector_image && lost_image) << "reference frames not rendered";
  const int type_difference = differingPixels(*forceps_image, *vitrector_image);
  const int visibility_difference = differingPixels(*forceps_image, *lost_image);
  // Switching or hiding the right instrument must show (forceps and vitrector differ at the tip only: ~90 pixels at
  // 480x360; hiding the forceps removes its shaft).
  ASSERT_GE(type_difference, 40) << "forceps and vitrector look alike here";
  ASSERT_GE(visibility_difference, 40) << "the forceps does not show in the view";

  // (a) The World refused the switch to the vitrector: the forceps is drawn.
  const sensor_msgs::Image::ConstPtr refused = render({"forceps", true, vrm_msgs::InstrumentState::VITRECTOR, true});
  // The other way round (a vitrector in use, the device asks for the forceps): the vitrector is drawn.
  const sensor_msgs::Image::ConstPtr kept = render({"vitrector", true, vrm_msgs::InstrumentState::FORCEPS, true});
  // (b) The World marked the forceps invalid (e.g. a rejected input) although the device said valid: hidden.
  const sensor_msgs::Image::ConstPtr rejected = render({"forceps", false, vrm_msgs::InstrumentState::FORCEPS, true});
  ASSERT_TRUE(refused && kept && rejected) << "frames not rendered";

  const int refused_vs_forceps = differingPixels(*refused, *forceps_image);
  const int refused_vs_vitrector = differingPixels(*refused, *vitrector_image);
  const int kept_vs_vitrector = differingPixels(*kept, *vitrector_image);
  const int kept_vs_forceps = differingPixels(*kept, *forceps_image);
  const int rejected_vs_lost = differingPixels(*rejected, *lost_image);
  const int rejected_vs_forceps = differingPixels(*rejected, *forceps_image);
  RecordProperty("type_difference", type_difference);
  RecordProperty("visibility_difference", visibility_difference);
  // Equal up to a few pixels (the same scene, inputs and renderer), and far from the raw inputs' image.
  EXPECT_LE(refused_vs_forceps, type_difference / 20) << "refused switch: not the applied forceps";
  EXPECT_GT(refused_vs_vitrector, type_difference / 2) << "refused switch: drew the raw vitrector";
  EXPECT_LE(kept_vs_vitrector, type_difference / 20) << "vitrector in use: not the applied vitrector";
  EXPECT_GT(kept_vs_forceps, type_difference / 2) << "vitrector in use: drew the raw forceps";
  EXPECT_LE(rejected_vs_lost, visibility_difference / 20) << "invalid instrument: drawn";
  EXPECT_GT(rejected_vs_forceps, visibility_difference / 2) << "invalid instrument: drew the raw (valid) input";
}

// Issue 36: an object the scenario moves (SimulationState.objects: a carried box, a falling ring) is drawn where the
// frame's simulation state has it; a frame without it draws it at its scene pose again; an unknown name or a
// non-finite pose changes nothing.
TEST_F(AppliedFrameTest, DrawsTheObjectsWhereTheSimulationStateHasThem) {
  const RightSlot forceps{"forceps", true, vrm_msgs::InstrumentState::FORCEPS, true};
  sensor_msgs::Image::ConstPtr previous = render(forceps);
  ASSERT_TRUE(previous) << "no image for the first simulation frame";
  bool settled = false;
  for (int attempt = 0; attempt < 20 && !settled; ++attempt) {
    const sensor_msgs::Image::ConstPtr next = render(forceps);
    ASSERT_TRUE(next);
    settled = differingPixels(*previous, *next) == 0;
    previous = next;
  }
  ASSERT_TRUE(settled) << "frames of the same inputs kept changing";
  const vrm_sim::scene::ObjectDescription* retina = scene_.findObject("retina");
  ASSERT_NE(retina, nullptr);
  auto placed = [&](const std::string& name, const Eigen::Vector3d& offset) {
    vrm_msgs::ObjectPose object;
    object.header.frame_id = "eye";
    object.name = name;
    const Eigen::Isometry3d pose = retina->pose.toIsometry();
    const Eigen::Vector3d position = pose.translation() + offset;
    const Eigen::Quaterniond rotation(pose.linear());
    object.pose.position.x = position.x();
    object.pose.position.y = position.y();
    object.pose.position.z = position.z();
    object.pose.orientation.w = rotation.w();
    object.pose.orientation.x = rotation.x();
    object.pose.orientation.y = rotation.y();
    object.pose.orientation.z = rotation.z();
    return object;
  };
  const sensor_msgs::Image::ConstPtr moved = render(forceps, {placed("retina", {0.0015, 0.0, 0.0})});
  const sensor_msgs::Image::ConstPtr unknown = render(forceps, {placed("no_such_object", {0.0015, 0.0, 0.0})});
  vrm_msgs::ObjectPose broken = placed("retina", {0.0015, 0.0, 0.0});
  broken.pose.position.x = std::nan("");
  const sensor_msgs::Image::ConstPtr non_finite = render(forceps, {broken});
  const sensor_msgs::Image::ConstPtr back = render(forceps);
  ASSERT_TRUE(moved && unknown && non_finite && back) << "frames not rendered";
  const int moved_difference = differingPixels(*moved, *previous);
  RecordProperty("moved_difference", moved_difference);
  // The fundus shifted 1.5 mm sideways: its vessels move across most of the view.
  EXPECT_GE(moved_difference, 2000) << "the moved retina is drawn where it was";
  EXPECT_LE(differingPixels(*unknown, *previous), moved_difference / 50) << "an unknown object moved something";
  EXPECT_LE(differingPixels(*non_finite, *previous), moved_difference / 50) << "a non-finite pose was drawn";
  EXPECT_LE(differingPixels(*back, *previous), moved_difference / 50) << "not back at its scene pose";
}

}  // namespace

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_applied_frame");
  return RUN_ALL_TESTS();
}
