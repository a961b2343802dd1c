#include <gtest/gtest.h>

#include <cmath>

#include "vrm_render/conversions.h"

namespace vrm_render {
namespace {

TEST(Conversions, PoseRoundTripsThroughTransform) {
  geometry_msgs::Pose pose;
  pose.position.x = 0.001;
  pose.position.y = -0.002;
  pose.position.z = 0.003;
  // Not normalised on purpose: toIsometry normalises.
  pose.orientation.w = 2.0;
  pose.orientation.z = 2.0;
  const Eigen::Isometry3f t = toIsometry(pose);
  EXPECT_NEAR((t.linear() * Eigen::Vector3f::UnitX() - Eigen::Vector3f::UnitY()).norm(), 0.0f, 1e-6f);
  const geometry_msgs::Transform msg = toTransformMsg(t);
  EXPECT_NEAR(msg.translation.y, -0.002, 1e-9);
  EXPECT_NEAR(std::abs(msg.rotation.w), std::sqrt(0.5), 1e-6);
  EXPECT_NEAR(std::abs(msg.rotation.z), std::sqrt(0.5), 1e-6);
}

TEST(Conversions, ZeroQuaternionIsIdentity) {
  geometry_msgs::Pose pose;  // all zero
  EXPECT_TRUE(toIsometry(pose).isApprox(Eigen::Isometry3f::Identity()));
  vrm_msgs::EyeState eye;
  eye.rotation_center.z = 0.5;
  EXPECT_FLOAT_EQ(worldFromEye(eye).translation().z(), 0.5f);
}

// Ghosts of a bag recorded before input frames: the raw state as if applied, its type constant by name.
TEST(Conversions, InstrumentStateBecomesAnAppliedInstrument) {
  vrm_msgs::InstrumentState state;
  state.header.frame_id = "eye";
  state.instrument_id = "right";
  state.type = vrm_msgs::InstrumentState::VITRECTOR;
  state.tip_pose.position.z = -0.008;
  state.jaw_angle = 0.25;
  state.valid = true;
  const vrm_msgs::AppliedInstrument applied = toAppliedInstrument(state);
  EXPECT_EQ(applied.slot, "right");
  EXPECT_EQ(applied.type, "vitrector");
  EXPECT_EQ(applied.header.frame_id, "eye");
  EXPECT_DOUBLE_EQ(applied.pose.position.z, -0.008);
  EXPECT_DOUBLE_EQ(applied.jaw_angle, 0.25);
  EXPECT_TRUE(applied.valid);
  state.type = 200;  // no such instrument
  state.valid = false;
  EXPECT_EQ(toAppliedInstrument(state).type, "");
  EXPECT_FALSE(toAppliedInstrument(state).valid);
}

TEST(Conversions, MeshViewUsesOnlyArraysOfMatchingSize) {
  vrm_msgs::TissueMesh mesh;
  mesh.positions = {0, 0, 0, 1, 0, 0, 0, 1, 0};
  mesh.triangles = {0, 1, 2};
  mesh.normals = {0, 0, 1};         // one normal for three vertices: ignored
  mesh.colors.assign(3 * 4, 0.5f);  // matches
  mesh.injury = {0.0f, 1.0f};       // too short: ignored
  const MeshView view = toMeshView(mesh);
  EXPECT_EQ(view.vertex_count, 3u);
  EXPECT_EQ(view.triangle_count, 1u);
  EXPECT_EQ(view.positions, mesh.positions.data()) << "a view, not a copy";
  EXPECT_EQ(view.normals, nullptr);
  EXPECT_EQ(view.colors, mesh.colors.data());
  EXPECT_EQ(view.injury, nullptr);
}

TEST(Conversions, MicroscopeKnobs) {
  vrm_msgs::MicroscopeSettings settings;
  settings.focus_distance = 0.21;
  settings.zoom = 2.0;
  settings.ambient_light = 0.4;
  settings.disparity_scale = 0.5;
  const MicroscopeState state = toMicroscopeState(settings);
  EXPECT_EQ(state.focus_distance, 0.21);
  EXPECT_EQ(state.zoom, 2.0);
  EXPECT_EQ(state.ambient_light, 0.4);
  EXPECT_EQ(state.disparity_scale, 0.5);
}

TEST(Conversions, OpticalFrameLooksAlongTheOpticalAxisAndObjectiveIsRep103Body) {
  const MicroscopeRig rig;
  const CameraView left = microscopeCamera(rig, MicroscopeState(), 800, 600, Eye::kLeft, true);
  const Eigen::Isometry3f optical = worldFromOptical(left);
  // z forward (down into the eye), y down in the image (= -rig.up).
  EXPECT_NEAR((optical.linear().col(2) - left.forward.normalized()).norm(), 0.0f, 1e-5f);
  EXPECT_LT(optical.linear().col(1).dot(rig.up), -0.99f);
  const Eigen::Isometry3f objective = worldFromObjective(rig);
  EXPECT_NEAR((objective.linear().col(0) - rig.view_direction).norm(), 0.0f, 1e-6f);
  EXPECT_NEAR((objective.linear().col(2) - rig.up).norm(), 0.0f, 1e-6f);
  EXPECT_NEAR(objective.linear().determinant(), 1.0f, 1e-6f) << "right-handed";
}

TEST(Conversions, CameraInfoCarriesIntrinsicsAndTheStereoBaseline) {
  const MicroscopeRig rig;
  const CameraView left = microscopeCamera(rig, MicroscopeState(), 800, 600, Eye::kLeft, true);
  const CameraView right = microscopeCamera(rig, MicroscopeState(), 800, 600, Eye::kRight, true);
  const sensor_msgs::CameraInfo l = toCameraInfo(left, left, 800, 600);
  const sensor_msgs::CameraInfo r = toCameraInfo(right, left, 800, 600);
  EXPECT_EQ(l.width, 800u);
  EXPECT_EQ(l.height, 600u);
  EXPECT_EQ(l.distortion_model, "plumb_bob");
  EXPECT_GT(l.K[0], 0.0);
  EXPECT_EQ(l.K[0], l.P[0]);
  EXPECT_EQ(l.P[3], 0.0) << "the left camera is the reference";
  EXPECT_NEAR(r.P[3], -r.K[0] * (right.position - left.position).norm(), 1e-9);
  EXPECT_LT(r.P[3], 0.0);
}

}  // namespace
}  // namespace vrm_render
