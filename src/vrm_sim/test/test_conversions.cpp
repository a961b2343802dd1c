#include <gtest/gtest.h>

#include <algorithm>
#include <cctype>
#include <map>
#include <set>
#include <string>

#include "vrm_msgs/InstrumentTypes.h"
#include "vrm_msgs/msg_constants.h"
#include "vrm_scene/scene_description.h"
#include "vrm_sim/conversions.h"

namespace vrm_sim {
namespace {

TEST(Conversions, PoseRoundTrip) {
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.translation() = Eigen::Vector3d(0.001, -0.002, 0.012);
  pose.linear() = Eigen::AngleAxisd(0.3, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  const Eigen::Isometry3d back = toEigen(toPoseMsg(pose));
  EXPECT_TRUE(back.isApprox(pose, 1e-12));
}

TEST(Conversions, ZeroQuaternionIsIdentityNotSingular) {
  geometry_msgs::Pose pose;  // all zeros, as a default-constructed message
  EXPECT_TRUE(toEigen(pose).linear().isApprox(Eigen::Matrix3d::Identity()));
}

TEST(Conversions, TissueMeshPacksPositionsTrianglesAndNormals) {
  TriangleMesh square;
  square.vertices = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}};
  square.triangles = {{0, 1, 2}, {0, 2, 3}};
  vrm_msgs::TissueMesh message;
  fillTissueMesh(square, message);
  ASSERT_EQ(message.positions.size(), 12u);
  ASSERT_EQ(message.triangles.size(), 6u);
  EXPECT_FLOAT_EQ(message.positions[3 * 2 + 1], 1.0f);
  EXPECT_EQ(message.triangles[5], 3u);
  for (std::size_t vertex = 0; vertex < 4; ++vertex) {
    EXPECT_FLOAT_EQ(message.normals[3 * vertex + 2], 1.0f) << "counter-clockwise triangles face +z";
  }

  visualization_msgs::Marker marker;
  fillTriangleListMarker(message, {1, 0, 0, 1}, marker);
  ASSERT_EQ(marker.points.size(), 6u);
  EXPECT_DOUBLE_EQ(marker.points[5].y, 1.0);
}

// A TissueMesh off the wire may lie about its sizes (found by fuzzing, src/vrm_fuzz/regressions/sim_messages).
TEST(Conversions, TriangleListMarkerLeavesOutTrianglesThatIndexBeyondThePositions) {
  vrm_msgs::TissueMesh message;
  message.positions = {0, 0, 0, 1, 0, 0, 0, 1, 0};
  message.triangles = {0, 1, 2, 0, 1, 4000000000u, 2, 1};  // one good, one out of range, one partial
  visualization_msgs::Marker marker;
  fillTriangleListMarker(message, {1, 0, 0, 1}, marker);
  ASSERT_EQ(marker.points.size(), 3u);
  EXPECT_DOUBLE_EQ(marker.points[2].y, 1.0);
}

TEST(Conversions, SelectedTrianglesMarkerHasOnlyThoseTriangles) {
  const std::vector<Eigen::Vector3d> positions = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}};
  const std::vector<std::array<std::uint32_t, 3>> triangles = {{0, 1, 2}, {0, 2, 3}};
  visualization_msgs::Marker marker;
  fillTriangleListMarker(positions.data(), triangles.data(), {1}, {1, 0, 0, 1}, marker);
  ASSERT_EQ(marker.points.size(), 3u);
  EXPECT_DOUBLE_EQ(marker.points[2].x, 0.0);  // node 3
  EXPECT_DOUBLE_EQ(marker.points[2].y, 1.0);
  EXPECT_EQ(marker.type, visualization_msgs::Marker::TRIANGLE_LIST);
}

TEST(Conversions, EyeStateIsARotationAboutTheCentre) {
  vrm_msgs::EyeState eye;
  eye.rotation_center.x = 0.01;
  const Eigen::Quaterniond q(Eigen::AngleAxisd(0.5, Eigen::Vector3d::UnitX()));
  eye.rotation.w = q.w();
  eye.rotation.x = q.x();
  const Eigen::Isometry3d world_from_eye = worldFromEye(eye);
  EXPECT_TRUE(world_from_eye.translation().isApprox(Eigen::Vector3d(0.01, 0, 0)));
  EXPECT_TRUE(world_from_eye.linear().isApprox(q.toRotationMatrix()));
}

TEST(Conversions, CollisionReportCopiesTheResult) {
  collision::CollisionResult result;
  result.colliding = true;
  result.triangles = {3, 7};
  result.nodes = {1};
  result.deformations = {Eigen::Vector3d(0, 0, -2e-4)};
  result.contact_points = {Eigen::Vector3d(1, 2, 3)};
  result.contact_normals = {Eigen::Vector3d::UnitZ()};
  result.pixel_size = 1e-5;
  result.timing.ms_total = 0.5;
  vrm_msgs::CollisionReport report;
  fillCollisionReport(result, report);
  EXPECT_TRUE(report.colliding);
  EXPECT_EQ(report.triangles, result.triangles);
  EXPECT_EQ(report.nodes, result.nodes);
  ASSERT_EQ(report.deformations.size(), 1u);
  EXPECT_DOUBLE_EQ(report.deformations[0].z, -2e-4);
  ASSERT_EQ(report.contact_points.size(), 1u);
  EXPECT_DOUBLE_EQ(report.contact_points[0].y, 2.0);
  EXPECT_DOUBLE_EQ(report.contact_normals[0].z, 1.0);
  EXPECT_DOUBLE_EQ(report.pixel_size, 1e-5);
  EXPECT_DOUBLE_EQ(report.ms_total, 0.5);
}

TEST(Conversions, InstrumentTypeConstantsRoundTripAndUnknownIsNone) {
  const std::pair<scene::InstrumentType, std::uint8_t> expected[] = {
      {scene::InstrumentType::kLightPipe, vrm_msgs::InstrumentState::LIGHT_PIPE},
      {scene::InstrumentType::kForceps, vrm_msgs::InstrumentState::FORCEPS},
      {scene::InstrumentType::kVitrector, vrm_msgs::InstrumentState::VITRECTOR},
      {scene::InstrumentType::kNeedle, vrm_msgs::InstrumentState::NEEDLE},
      {scene::InstrumentType::kHook, vrm_msgs::InstrumentState::HOOK},
      {scene::InstrumentType::kLaserProbe, vrm_msgs::InstrumentTypes::LASER_PROBE}};
  for (const auto& [type, constant] : expected) {
    EXPECT_EQ(toMsgType(type), constant);
    ASSERT_TRUE(instrumentTypeFromMsg(constant).has_value());
    EXPECT_EQ(*instrumentTypeFromMsg(constant), type);
  }
  EXPECT_FALSE(instrumentTypeFromMsg(vrm_msgs::InstrumentTypes::LASER_PROBE + 1).has_value());
  EXPECT_FALSE(instrumentTypeFromMsg(255).has_value());
  EXPECT_EQ(toMsgType(std::nullopt), 255);
  vrm_msgs::InstrumentState message;
  message.type = 200;  // a constant this build does not know: the slot keeps its type
  EXPECT_FALSE(toWorld(message).type.has_value());
}

}  // namespace
}  // namespace vrm_sim

// vrm_msgs/InstrumentTypes' constants against the instrument type registry, read from the .msg file itself: every
// constant maps to the type of the same name (LIGHT_PIPE <-> "light_pipe") and back, and every registered type has a
// constant, so a type added on one side only fails here instead of arriving as "unknown" in a graph.
TEST(Conversions, InstrumentTypeConstantsMatchTheMessageAndTheRegistry) {
  const std::string path = std::string(VRM_MSGS_MSG_DIR) + "/InstrumentTypes.msg";
  const std::vector<vrm_msgs::MsgConstant> constants = vrm_msgs::readMsgConstants(path);
  ASSERT_FALSE(constants.empty()) << path;
  std::set<std::string> constant_names;
  for (const vrm_msgs::MsgConstant& constant : constants) {
    std::string name = constant.name;
    std::transform(name.begin(), name.end(), name.begin(), [](unsigned char c) { return std::tolower(c); });
    constant_names.insert(name);
    const auto type = vrm_sim::instrumentTypeFromMsg(static_cast<std::uint8_t>(constant.value));
    ASSERT_TRUE(type.has_value()) << "InstrumentState." << constant.name << " = " << constant.value
                                  << " has no instrument type in vrm_sim's conversions";
    EXPECT_EQ(vrm_sim::scene::toString(*type), name) << "InstrumentState." << constant.name;
    EXPECT_EQ(vrm_sim::toMsgType(type), constant.value) << name;
  }
  for (const auto& entry : vrm_sim::scene::instrumentTypeRegistry().entries()) {
    EXPECT_EQ(constant_names.count(entry.name), 1u)
        << "instrument type '" << entry.name << "' has no constant in vrm_msgs/InstrumentState.msg";
  }
}

// Issue 37: a new type goes into InstrumentTypes.msg only. InstrumentState.msg's constants are those of its first
// five types, equal to InstrumentTypes' ones, and its md5 is the one every committed session bag was recorded with.
TEST(Conversions, InstrumentStateKeepsItsConstantsAndItsMd5) {
  std::map<std::string, long long> all;
  for (const vrm_msgs::MsgConstant& constant :
       vrm_msgs::readMsgConstants(std::string(VRM_MSGS_MSG_DIR) + "/InstrumentTypes.msg")) {
    all[constant.name] = constant.value;
  }
  const std::vector<vrm_msgs::MsgConstant> state_constants =
      vrm_msgs::readMsgConstants(std::string(VRM_MSGS_MSG_DIR) + "/InstrumentState.msg");
  ASSERT_EQ(state_constants.size(), 5u);
  for (const vrm_msgs::MsgConstant& constant : state_constants) {
    ASSERT_EQ(all.count(constant.name), 1u) << constant.name;
    EXPECT_EQ(all[constant.name], constant.value) << constant.name;
  }
  EXPECT_STREQ(ros::message_traits::MD5Sum<vrm_msgs::InstrumentState>::value(), "a47fb64b46b0c64d5e61e8fcd269622b");
}
