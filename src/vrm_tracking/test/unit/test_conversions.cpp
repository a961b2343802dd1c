// Core <-> vrm_msgs conversions (no master needed).

#include <gtest/gtest.h>

#include "vrm_scene/scene_loader.h"
#include "vrm_tracking/conversions.h"
#include "vrm_tracking/scene_trocars.h"

namespace vrm_tracking {
namespace {

// The instrument type travels through vrm_sim's one bridge; an unknown constant is an error (not a default type).
TEST(Conversions, InstrumentTypeThroughTheMessageAndUnknownConstantsThrow) {
  using vrm_sim::scene::InstrumentType;
  InstrumentSample sample;
  sample.slot = "right";
  for (InstrumentType type : {InstrumentType::kLightPipe, InstrumentType::kForceps, InstrumentType::kVitrector,
                              InstrumentType::kNeedle, InstrumentType::kHook, InstrumentType::kLaserProbe}) {
    sample.type = type;
    vrm_msgs::InstrumentState msg;
    toMsg(sample, &msg);
    EXPECT_EQ(fromMsg(msg).type, type);
  }
  sample.type = InstrumentType::kHook;
  vrm_msgs::InstrumentState msg;
  toMsg(sample, &msg);
  EXPECT_EQ(msg.type, vrm_msgs::InstrumentState::HOOK);
  msg.type = 200;
  EXPECT_THROW(fromMsg(msg), std::invalid_argument);
}

TEST(Conversions, InstrumentRoundTripRecoversTrocar) {
  const vrm_sim::scene::SceneDescription peeling = vrm_sim::scene::loadScene(vrm_sim::scene::kDefaultSceneName);
  SurgeonScript script = playInScene(peeling, loadSession("", peeling));
  script.setTremorAmplitude(30e-6);
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

TEST(Conversions, CameraInfoRoundTrip) {
  CameraModel cam = makeDefaultRig().cameras[1];
  cam.distortion = {0.1, -0.01, 0.0, 0.0, 0.002};
  sensor_msgs::CameraInfo info;
  toMsg(cam, &info);
  EXPECT_EQ(info.width, 640u);
  EXPECT_EQ(info.distortion_model, "plumb_bob");
  CameraModel back;
  updateIntrinsics(info, &back);
  EXPECT_LT((back.K - cam.K).norm(), 1e-12);
  EXPECT_EQ(back.distortion, cam.distortion);
  sensor_msgs::CameraInfo uncalibrated;
  EXPECT_THROW(updateIntrinsics(uncalibrated, &back), std::invalid_argument);
}

TEST(Conversions, MarkerObservationsRoundTrip) {
  Blob b;
  b.class_id = 3;
  b.u = 12.25;
  b.v = 400.125;
  b.area = 42;
  b.weight = 30.5;
  b.quality = 0.75;
  vrm_msgs::MarkerObservations msg;
  toMsg(std::vector<Blob>{b}, &msg);
  const std::vector<Blob> back = fromMsg(msg);
  ASSERT_EQ(back.size(), 1u);
  EXPECT_EQ(back[0].class_id, 3);
  EXPECT_DOUBLE_EQ(back[0].u, 12.25);
  EXPECT_DOUBLE_EQ(back[0].v, 400.125);
  EXPECT_DOUBLE_EQ(back[0].area, 42.0);
  EXPECT_DOUBLE_EQ(back[0].weight, 30.5);
  EXPECT_FLOAT_EQ(static_cast<float>(back[0].quality), 0.75f);
}

TEST(Conversions, TrackedInstrumentTakesRollAndJawFromTheSensors) {
  InstrumentEstimate est;
  est.slot = "right";
  est.valid = true;
  est.trocar = Eigen::Vector3d(0.0073485, 0.0042426, 0.0084853);
  est.tip = Eigen::Vector3d(0.001, 0.0, -0.005);
  est.insertion_depth = (est.tip - est.trocar).norm();
  est.shaft_axis = (est.tip - est.trocar) / est.insertion_depth;
  est.quality = 0.9;
  vrm_msgs::InstrumentState sensors;
  sensors.type = vrm_msgs::InstrumentState::FORCEPS;
  sensors.roll = 0.7;
  sensors.jaw_angle = 0.3;
  vrm_msgs::InstrumentState msg;
  toMsg(est, &sensors, &msg);
  EXPECT_EQ(msg.type, vrm_msgs::InstrumentState::FORCEPS);
  EXPECT_DOUBLE_EQ(msg.roll, 0.7);
  EXPECT_DOUBLE_EQ(msg.jaw_angle, 0.3);
  EXPECT_TRUE(msg.valid);
  // The message's trocar constraint (tip - depth * axis) recovers the trocar.
  const InstrumentSample s = fromMsg(msg);
  EXPECT_LT((s.trocar - est.trocar).norm(), 1e-12);
  EXPECT_LT((s.orientation * Eigen::Vector3d::UnitZ() - est.shaft_axis).norm(), 1e-9);
}

}  // namespace
}  // namespace vrm_tracking
