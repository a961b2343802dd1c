// Core <-> vrm_msgs conversions (no master needed).

#include <gtest/gtest.h>

#include "vrm_tracking/conversions.h"

namespace vrm_tracking {
namespace {

TEST(Conversions, InstrumentTypesMatchMessageConstants) {
  EXPECT_EQ(toMsgType(InstrumentType::kLightPipe), vrm_msgs::InstrumentState::LIGHT_PIPE);
  EXPECT_EQ(toMsgType(InstrumentType::kForceps), vrm_msgs::InstrumentState::FORCEPS);
  EXPECT_EQ(toMsgType(InstrumentType::kVitrector), vrm_msgs::InstrumentState::VITRECTOR);
  EXPECT_EQ(toMsgType(InstrumentType::kNeedle), vrm_msgs::InstrumentState::NEEDLE);
  EXPECT_EQ(toMsgType(InstrumentType::kHook), vrm_msgs::InstrumentState::HOOK);
  for (std::uint8_t t = 0; t <= vrm_msgs::InstrumentState::HOOK; ++t) EXPECT_EQ(toMsgType(fromMsgType(t)), t);
  EXPECT_THROW(fromMsgType(200), std::invalid_argument);
}

TEST(Conversions, InstrumentRoundTripRecoversTrocar) {
  SurgeonScript script = SurgeonScript::builtin("demo");
  script.setTremor(30e-6, 5);
  const SurgeonSnapshot snap = script.sample(13.3);
  for (const InstrumentSample& in : snap.instruments) {
    vrm_msgs::InstrumentState msg;
    toMsg(in, &msg);
    EXPECT_EQ(msg.instrument_id, in.slot);
    EXPECT_TRUE(msg.valid);
    EXPECT_FLOAT_EQ(msg.tracking_quality, 1.0f);
    EXPECT_DOUBLE_EQ(msg.tip_pose.position.z, in.tip.z());
    const InstrumentSample back = fromMsg(msg);
    EXPECT_EQ(back.slot, in.slot);
    EXPECT_EQ(back.type, in.type);
    EXPECT_EQ(back.tip, in.tip);
    EXPECT_EQ(back.shaft_axis, in.shaft_axis);
    EXPECT_TRUE(back.orientation.isApprox(in.orientation, 1e-15));
    EXPECT_LT((back.trocar - in.trocar).norm(), 1e-15);
    EXPECT_DOUBLE_EQ(back.insertion_depth, in.insertion_depth);
    EXPECT_DOUBLE_EQ(back.roll, in.roll);
    EXPECT_DOUBLE_EQ(back.jaw_angle, in.jaw_angle);
  }
}

TEST(Conversions, EyePedalsMicroscope) {
  SurgeonSnapshot snap;
  snap.eye_rotation = Eigen::Quaterniond(Eigen::AngleAxisd(0.1, Eigen::Vector3d(1, 2, 3).normalized()));
  snap.rotation_center = Eigen::Vector3d(0.1, -0.2, 0.3);
  vrm_msgs::EyeState eye;
  toMsg(snap, &eye);
  EXPECT_TRUE(toEigen(eye.rotation).isApprox(snap.eye_rotation));
  EXPECT_EQ(toEigen(eye.rotation_center), snap.rotation_center);
  EXPECT_TRUE(eye.valid);

  PedalSample pedals;
  pedals.travel = 0.3;
  pedals.reflux = pedals.focus_far = pedals.zoom_out = true;
  vrm_msgs::PedalState pedal_msg;
  toMsg(pedals, &pedal_msg);
  const PedalSample p = fromMsg(pedal_msg);
  EXPECT_DOUBLE_EQ(p.travel, 0.3);
  EXPECT_TRUE(p.reflux && p.focus_far && p.zoom_out);
  EXPECT_FALSE(p.zoom_in || p.focus_near || p.instrument_switch);

  MicroscopeSample micro;
  micro.zoom = 2.5;
  micro.focus_distance = 0.19;
  micro.ambient_light = 0.7;
  micro.disparity_scale = 0.4;
  vrm_msgs::MicroscopeSettings micro_msg;
  toMsg(micro, &micro_msg);
  const MicroscopeSample m = fromMsg(micro_msg);
  EXPECT_DOUBLE_EQ(m.zoom, 2.5);
  EXPECT_DOUBLE_EQ(m.focus_distance, 0.19);
  EXPECT_DOUBLE_EQ(m.ambient_light, 0.7);
  EXPECT_DOUBLE_EQ(m.disparity_scale, 0.4);
}

}  // namespace
}  // namespace vrm_tracking
