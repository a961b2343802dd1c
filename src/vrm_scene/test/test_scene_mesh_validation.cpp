// validateMesh() counts every problem class; cleanupMesh() repairs the fixable ones.

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "vrm_scene/meshes/mesh_utils.h"
#include "vrm_scene/meshes/mesh_validation.h"
#include "vrm_scene/meshes/primitive_meshes.h"

namespace vrm_sim {
namespace scene {
namespace {

TriangleMesh unitSquare() {
  TriangleMesh mesh;
  mesh.name = "square";
  mesh.vertices = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}};
  mesh.triangles = {{0, 1, 2}, {0, 2, 3}};
  return mesh;
}

TEST(MeshValidation, CleanClosedMesh) {
  const MeshReport report = validateMesh(makeBox({}));
  EXPECT_TRUE(report.isUsable());
  EXPECT_TRUE(report.isClean());
  EXPECT_TRUE(report.isClosed());
  EXPECT_EQ(report.summary(), "8 vertices, 12 triangles");
}

TEST(MeshValidation, OpenSquareHasFourBoundaryEdges) {
  const MeshReport report = validateMesh(unitSquare());
  EXPECT_TRUE(report.isClean());
  EXPECT_FALSE(report.isClosed());
  EXPECT_EQ(report.boundary_edges, 4u);
}

TEST(MeshValidation, CountsEachProblem) {
  TriangleMesh mesh = unitSquare();
  mesh.vertices.push_back({1, 0, 0});   // 4: duplicate of 1
  mesh.vertices.push_back({2, 0, 0});   // 5: collinear with 0 and 1
  mesh.vertices.push_back({5, 5, 5});   // 6: unreferenced
  mesh.triangles.push_back({0, 1, 5});  // zero area
  mesh.triangles.push_back({2, 2, 3});  // repeated index
  const MeshReport report = validateMesh(mesh);
  EXPECT_TRUE(report.isUsable());
  EXPECT_FALSE(report.isClean());
  EXPECT_EQ(report.degenerate_triangles, 2u);
  EXPECT_EQ(report.duplicate_vertices, 1u);
  EXPECT_EQ(report.unreferenced_vertices, 2u);  // 4 and 6
  EXPECT_NE(report.summary().find("2 degenerate triangles"), std::string::npos) << report.summary();
}

TEST(MeshValidation, NonFiniteAndOutOfRangeAreUnusable) {
  TriangleMesh with_nan = unitSquare();
  with_nan.vertices[2].x() = std::numeric_limits<double>::quiet_NaN();
  EXPECT_EQ(validateMesh(with_nan).non_finite_vertices, 1u);
  EXPECT_FALSE(validateMesh(with_nan).isUsable());

  TriangleMesh bad_index = unitSquare();
  bad_index.triangles.push_back({0, 3, 17});
  EXPECT_EQ(validateMesh(bad_index).out_of_range_triangles, 1u);
  EXPECT_FALSE(validateMesh(bad_index).isUsable());

  TriangleMesh bad_fixed = unitSquare();
  bad_fixed.fixed_vertices = {9};
  EXPECT_EQ(validateMesh(bad_fixed).out_of_range_fixed_vertices, 1u);

  EXPECT_FALSE(validateMesh(TriangleMesh{}).isUsable());
  EXPECT_THROW(cleanupMesh(with_nan), std::invalid_argument);
}

TEST(MeshValidation, NonManifoldAndInconsistentEdges) {
  TriangleMesh fin = unitSquare();
  fin.vertices.push_back({0.5, 0.5, 1.0});
  fin.triangles.push_back({0, 2, 4});  // a third triangle on edge 0-2
  EXPECT_EQ(validateMesh(fin).non_manifold_edges, 1u);

  TriangleMesh flipped = unitSquare();
  std::swap(flipped.triangles[1][1], flipped.triangles[1][2]);  // both triangles now traverse 0 -> 2
  EXPECT_EQ(validateMesh(flipped).inconsistent_edges, 1u);
  EXPECT_FALSE(validateMesh(flipped).isClean());
}

TEST(MeshCleanup, JoinsRemovesAndKeepsFixedVertices) {
  TriangleMesh mesh = unitSquare();
  mesh.vertices.push_back({1, 0, 0});  // 4: duplicate of 1
  mesh.vertices.push_back({2, 0, 0});  // 5
  mesh.vertices.push_back({5, 5, 5});  // 6: unreferenced
  mesh.triangles = {{0, 4, 2}, {0, 2, 3}, {0, 1, 5}};
  mesh.fixed_vertices = {4, 3};
  const MeshCleanupResult result = cleanupMesh(mesh);
  EXPECT_EQ(result.joined_vertices, 1u);
  EXPECT_EQ(result.removed_triangles, 1u);
  EXPECT_EQ(result.removed_vertices, 2u);  // 5 (only in the removed triangle) and 6
  EXPECT_EQ(mesh.vertexCount(), 4u);
  EXPECT_EQ(mesh.triangleCount(), 2u);
  EXPECT_TRUE(validateMesh(mesh).isClean()) << validateMesh(mesh).summary();
  ASSERT_EQ(mesh.fixed_vertices.size(), 2u);
  EXPECT_TRUE(mesh.vertices[mesh.fixed_vertices[0]].isApprox(Eigen::Vector3d(1, 0, 0)));
  EXPECT_TRUE(mesh.vertices[mesh.fixed_vertices[1]].isApprox(Eigen::Vector3d(0, 1, 0)));
}

TEST(MeshCleanup, JoinDistanceMergesNearDuplicates) {
  TriangleMesh mesh = unitSquare();
  mesh.triangles = {{0, 1, 2}};
  mesh.vertices.push_back({1.0 + 1e-9, 1.0, 0.0});  // 4: almost vertex 2
  mesh.triangles.push_back({0, 4, 3});
  MeshCleanupOptions options;
  options.join_distance = 1e-6;
  const MeshCleanupResult result = cleanupMesh(mesh, options);
  EXPECT_EQ(result.joined_vertices, 1u);
  EXPECT_EQ(mesh.vertexCount(), 4u);
  EXPECT_EQ(validateMesh(mesh).boundary_edges, 4u);  // the two triangles share their diagonal again
}

TEST(MeshUtils, TransformKeepsOrientationAndVolume) {
  TriangleMesh box = makeBox({});
  const double volume = signedVolume(box);
  Eigen::Isometry3d transform = Eigen::Isometry3d::Identity();
  transform.linear() = rotationFromRpy(Eigen::Vector3d(0.3, -1.1, 2.0));
  transform.translation() = Eigen::Vector3d(0.01, -0.02, 0.03);
  transformMesh(box, transform);
  EXPECT_NEAR(signedVolume(box), volume, 1e-18);
  flipOrientation(box);
  EXPECT_NEAR(signedVolume(box), -volume, 1e-18);
}

TEST(MeshUtils, RpyMatchesRosConvention) {
  // Yaw of 90 deg turns x into y.
  EXPECT_TRUE(
      (rotationFromRpy(Eigen::Vector3d(0, 0, M_PI / 2)) * Eigen::Vector3d::UnitX()).isApprox(Eigen::Vector3d::UnitY()));
  // Roll is applied first (about the fixed x axis), then pitch, then yaw.
  const Eigen::Matrix3d rotation = rotationFromRpy(Eigen::Vector3d(0.1, 0.2, 0.3));
  const Eigen::Matrix3d expected =
      (Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitZ()) * Eigen::AngleAxisd(0.2, Eigen::Vector3d::UnitY()) *
       Eigen::AngleAxisd(0.1, Eigen::Vector3d::UnitX()))
          .toRotationMatrix();
  EXPECT_TRUE(rotation.isApprox(expected));
}

TEST(MeshUtils, AppendAndNormals) {
  TriangleMesh mesh = unitSquare();
  mesh.fixed_vertices = {1};
  TriangleMesh other = unitSquare();
  other.fixed_vertices = {2};
  appendMesh(mesh, other);
  EXPECT_EQ(mesh.vertexCount(), 8u);
  EXPECT_EQ(mesh.triangles[2][0], 4u);
  EXPECT_EQ(mesh.fixed_vertices, (std::vector<std::uint32_t>{1, 6}));
  computeVertexNormals(mesh);
  for (const auto& normal : mesh.normals) EXPECT_TRUE(normal.isApprox(Eigen::Vector3d::UnitZ()));
}

}  // namespace
}  // namespace scene
}  // namespace vrm_sim
