// scene_manager follows the input frames (scene_manager_frames.test, issue 31): the pose tf is what the World
// applied in each KIND_FRAME frame, at the frame's stamp; state frames carry no poses; an instrument that is not
// valid keeps its last applied pose on tf. Conditions are awaited with timeouts (no fixed sleeps).
#include <gtest/gtest.h>
#include <ros/ros.h>
#include <tf2_eigen/tf2_eigen.h>
#include <tf2_ros/buffer.h>
#include <tf2_ros/transform_listener.h>

#include <boost/make_shared.hpp>
#include <string>

#include "vrm_msgs/InputFrame.h"
#include "vrm_sim/conversions.h"
#include "vrm_sim/testing/graph_test.h"

namespace {

using vrm_sim::toPoseMsg;

Eigen::Isometry3d pose(const Eigen::Vector3d& translation, double angle_z) {
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.translate(translation);
  pose.rotate(Eigen::AngleAxisd(angle_z, Eigen::Vector3d::UnitZ()));
  return pose;
}

vrm_msgs::AppliedInstrument applied(const std::string& slot, const Eigen::Isometry3d& eye_from_instrument, bool valid) {
  vrm_msgs::AppliedInstrument instrument;
  instrument.slot = slot;
  instrument.type = "forceps";
  instrument.header.frame_id = "eye";
  instrument.pose = toPoseMsg(eye_from_instrument);
  instrument.jaw_angle = 1.0;
  instrument.valid = valid;
  instrument.delivered = valid;
  return instrument;
}

vrm_msgs::InputFrame::Ptr frame(std::uint8_t kind, const ros::Time& stamp, std::uint64_t sequence,
                                const Eigen::Isometry3d& world_from_eye) {
  auto frame = boost::make_shared<vrm_msgs::InputFrame>();
  frame->header.stamp = stamp;
  frame->header.frame_id = "world";
  frame->sequence = sequence;
  frame->kind = kind;
  frame->eye_pose = toPoseMsg(world_from_eye);
  frame->eye_valid = true;
  return frame;
}

void expectNear(const Eigen::Isometry3d& expected, const geometry_msgs::TransformStamped& actual, const char* what) {
  const Eigen::Isometry3d got = tf2::transformToEigen(actual);
  EXPECT_TRUE(got.isApprox(expected, 1e-9)) << what << ": expected\n" << expected.matrix() << "\ngot\n" << got.matrix();
}

TEST(SceneManagerFrames, TfFollowsTheAppliedPosesOfEachFrame) {
  ros::NodeHandle nh;
  tf2_ros::Buffer buffer;
  tf2_ros::TransformListener listener(buffer);
  ros::Publisher frames = nh.advertise<vrm_msgs::InputFrame>("input_frame", 10);
  ASSERT_TRUE(vrm_sim::testing::waitForSubscribers(frames, 20.0)) << "scene_manager does not subscribe input_frame";

  // tf is not latched: a transform scene_manager sends before this test's /tf subscription is connected to it is
  // lost. Warm up with eye-only frames (earlier stamps, no instruments) until one of them reaches the buffer.
  ros::Time warm_up_stamp = ros::Time::now();
  std::uint64_t sequence = 0;
  const ros::WallTime warm_up_deadline = ros::WallTime::now() + ros::WallDuration(20.0);
  while (!buffer._frameExists("eye") && ros::WallTime::now() < warm_up_deadline) {
    frames.publish(frame(vrm_msgs::InputFrame::KIND_FRAME, warm_up_stamp, ++sequence, pose({0.001, 0.0, 0.0}, 0.0)));
    warm_up_stamp += ros::Duration(0.001);
    ros::WallDuration(0.05).sleep();  // polling interval of the condition, not a wait for an event
  }
  ASSERT_TRUE(buffer._frameExists("eye")) << "no input frame reached tf within 20 s";

  const ros::Time t1 = warm_up_stamp + ros::Duration(0.1);
  const ros::Time t2 = t1 + ros::Duration(0.010);
  const ros::Time t3 = t1 + ros::Duration(0.020);
  const Eigen::Isometry3d eye1 = pose({0.001, 0.0, 0.0}, 0.0);
  const Eigen::Isometry3d eye3 = pose({0.003, 0.0, 0.0}, 0.0);
  const Eigen::Isometry3d right1 = pose({0.002, -0.001, 0.004}, 0.3);

  // Frame 1: eye and right applied; the left slot has never been valid (no transform at all).
  auto first = frame(vrm_msgs::InputFrame::KIND_FRAME, t1, ++sequence, eye1);
  first->instruments = {applied("left", pose({0.0, 0.0, 0.0}, 0.0), false), applied("right", right1, true)};
  frames.publish(first);
  std::string error;
  ASSERT_TRUE(buffer.canTransform("world", "instrument_right", t1, ros::Duration(10.0), &error)) << error;
  expectNear(eye1, buffer.lookupTransform("world", "eye", t1), "world <- eye at frame 1");
  expectNear(right1, buffer.lookupTransform("eye", "instrument_right", t1), "eye <- instrument_right at frame 1");
  expectNear(eye1 * right1, buffer.lookupTransform("world", "instrument_right", t1), "world <- instrument_right");
  // The instrument hangs below its trocar: world -> eye -> trocar_right -> instrument_right.
  std::string parent;
  EXPECT_TRUE(buffer._getParent("instrument_right", t1, parent));
  EXPECT_EQ(parent, "trocar_right");
  EXPECT_FALSE(buffer._frameExists("instrument_left")) << "a slot never applied valid is on tf";

  // A state frame (pedals / a command between frames) carries no poses: its eye pose must not reach tf.
  auto state = frame(vrm_msgs::InputFrame::KIND_STATE, t2, ++sequence, pose({1.0, 1.0, 1.0}, 1.0));
  frames.publish(state);
  // Frame 3: the right instrument is lost (not valid; its pose here is what it would be if drawn elsewhere).
  auto third = frame(vrm_msgs::InputFrame::KIND_FRAME, t3, ++sequence, eye3);
  third->instruments = {applied("left", pose({0.0, 0.0, 0.0}, 0.0), false),
                        applied("right", pose({0.005, 0.005, 0.005}, -1.0), false)};
  frames.publish(third);
  ASSERT_TRUE(buffer.canTransform("world", "eye", t3, ros::Duration(10.0), &error)) << error;
  // Between the frames tf interpolates the applied eye poses; the state frame's pose is not among them.
  expectNear(pose({0.002, 0.0, 0.0}, 0.0), buffer.lookupTransform("world", "eye", t2), "world <- eye between frames");
  // The lost instrument keeps its last applied pose (frame 1) as tf's latest.
  const geometry_msgs::TransformStamped latest = buffer.lookupTransform("eye", "instrument_right", ros::Time(0));
  expectNear(right1, latest, "eye <- instrument_right after it was lost");
  EXPECT_FALSE(buffer._frameExists("instrument_left"));
}

}  // namespace

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_scene_manager_frames");
  ros::AsyncSpinner spinner(1);
  spinner.start();
  const int result = RUN_ALL_TESTS();
  spinner.stop();
  ros::shutdown();
  return result;
}
