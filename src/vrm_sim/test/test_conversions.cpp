#include <gtest/gtest.h>

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

}  // namespace
}  // namespace vrm_sim
