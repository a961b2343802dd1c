// The geometric (exact primitive) detector and the FCL facade: exact answers on simple scenes, BVH refit after a
// deformation equals a rebuild, all bounding volume types agree.
#include <gtest/gtest.h>

#include <set>

#include "vrm_scene/meshes/mesh_utils.h"
#include "vrm_scene/meshes/primitive_meshes.h"
#include "vrm_sim/collision/collision_detector.h"
#include "vrm_sim/collision/primitives.h"

namespace vrm_sim {
namespace collision {
namespace {

using Eigen::Vector3d;
constexpr double kPi = 3.14159265358979323846;

Eigen::Isometry3d pointingDown(const Vector3d& tip) {
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.linear() = Eigen::AngleAxisd(kPi, Vector3d::UnitX()).toRotationMatrix();
  pose.translation() = tip;
  return pose;
}

TriangleMesh plane(double size, int subdivisions) {
  scene::PlaneParams params;
  params.size_x = params.size_y = size;
  params.subdivisions = subdivisions;
  return scene::makePlane(params);
}

InstrumentModel sphereInstrument(double radius) {
  InstrumentModel model;
  model.primitives = {Primitive::sphere(Vector3d(0, 0, -radius), radius)};
  model.mesh = primitiveMesh(model.primitives[0], 48);
  return model;
}

TEST(GeometricDetector, SphereOnPlaneIsExact) {
  const double radius = 0.0005, depth = 0.0002;
  const TriangleMesh surface = plane(0.004, 40);
  auto detector = makeCollisionDetector("geometric");
  detector->setInstrument(sphereInstrument(radius));
  const Eigen::Isometry3d pose = pointingDown(Vector3d(0.00003, 0, -depth));
  const CollisionResult r = detector->collide(pose, SurfaceView::of(surface));
  ASSERT_TRUE(r.colliding);
  const Vector3d centre(0.00003, 0, radius - depth);
  // Exactly the triangles within `radius` of the centre.
  for (std::size_t t = 0; t < surface.triangles.size(); ++t) {
    const auto& tri = surface.triangles[t];
    const double distance =
        (closestPointOnTriangle(centre, surface.vertices[tri[0]], surface.vertices[tri[1]], surface.vertices[tri[2]]) -
         centre)
            .norm();
    EXPECT_EQ(std::binary_search(r.triangles.begin(), r.triangles.end(), t), distance <= radius) << t;
  }
  // Nodes inside the sphere move along -z exactly onto the front (lower) surface.
  ASSERT_FALSE(r.nodes.empty());
  for (std::size_t i = 0; i < r.nodes.size(); ++i) {
    const Vector3d moved = surface.vertices[r.nodes[i]] + r.deformations[i];
    EXPECT_NEAR((moved - centre).norm(), radius, 1e-12);
    EXPECT_LT(moved.z(), centre.z());
    EXPECT_NEAR(r.deformations[i].normalized().z(), -1.0, 1e-12);
  }
  for (std::size_t i = 0; i < r.contact_points.size(); ++i) {
    EXPECT_LE((r.contact_points[i] - centre).norm(), radius + 1e-12);
    EXPECT_NEAR(r.contact_normals[i].norm(), 1.0, 1e-12);
  }
}

TEST(GeometricDetector, CapsuleAndBoxAgreeWithSampling) {
  TriangleMesh surface = plane(0.004, 30);
  scene::transformMesh(surface, Eigen::Isometry3d(Eigen::AngleAxisd(0.3, Vector3d(1, 1, 0).normalized())));
  const std::vector<Primitive> solids = {Primitive::capsule(Vector3d(0, 0, -0.0025), Vector3d(0, 0, -0.0004), 0.0004),
                                         Primitive::box(Vector3d(0, 0, -0.0005), Vector3d(0.0003, 0.0006, 0.0005),
                                                        Eigen::AngleAxisd(0.4, Vector3d::UnitZ()).toRotationMatrix())};
  for (const Primitive& solid : solids) {
    InstrumentModel model;
    model.primitives = {solid};
    auto detector = makeCollisionDetector("geometric");
    detector->setInstrument(model);
    const Eigen::Isometry3d pose = pointingDown(Vector3d(0.0001, -0.0002, -0.00015));
    const CollisionResult r = detector->collide(pose, SurfaceView::of(surface));
    ASSERT_TRUE(r.colliding);
    const Primitive world = transformed(solid, pose);
    for (std::size_t t = 0; t < surface.triangles.size(); ++t) {
      const auto& tri = surface.triangles[t];
      const Vector3d& a = surface.vertices[tri[0]];
      const Vector3d& b = surface.vertices[tri[1]];
      const Vector3d& c = surface.vertices[tri[2]];
      double min_distance = 1e9;
      for (int i = 0; i <= 20; ++i) {
        for (int j = 0; i + j <= 20; ++j) {
          min_distance = std::min(min_distance, signedDistance(world, a + (b - a) * i / 20.0 + (c - a) * j / 20.0));
        }
      }
      const bool found = std::binary_search(r.triangles.begin(), r.triangles.end(), t);
      if (min_distance < 0.0) EXPECT_TRUE(found) << t;
      if (min_distance > 0.00002) EXPECT_FALSE(found) << t;
    }
    for (std::size_t i = 0; i < r.nodes.size(); ++i) {
      EXPECT_LT(signedDistance(world, surface.vertices[r.nodes[i]]), 0.0);
      EXPECT_NEAR(signedDistance(world, surface.vertices[r.nodes[i]] + r.deformations[i]), 0.0, 1e-12);
    }
  }
}

TEST(FclDetector, FindsSurfaceCrossingTrianglesAndRefitEqualsRebuild) {
  const double radius = 0.0005;
  const InstrumentModel sphere = sphereInstrument(radius);
  TriangleMesh surface = plane(0.004, 40);
  const Eigen::Isometry3d pose = pointingDown(Vector3d(0.00002, 0.00001, -0.0002));
  auto geometric = makeCollisionDetector("geometric");
  geometric->setInstrument(sphere);
  const CollisionResult exact = geometric->collide(pose, SurfaceView::of(surface));
  std::vector<CollisionResult> results;
  for (const std::string name : {"fcl_aabb", "fcl_obbrss", "fcl_kios"}) {
    SCOPED_TRACE(name);
    auto detector = makeCollisionDetector(name);
    detector->setInstrument(sphere);
    const CollisionResult r = detector->collide(pose, SurfaceView::of(surface));
    ASSERT_TRUE(r.colliding);
    // FCL sees the tessellated sphere: every triangle it reports touches the exact sphere.
    for (std::uint32_t t : r.triangles) {
      EXPECT_TRUE(std::binary_search(exact.triangles.begin(), exact.triangles.end(), t));
    }
    // Mesh-mesh: triangles entirely inside the instrument are not reported.
    EXPECT_LT(r.triangles.size(), exact.triangles.size());
    EXPECT_FALSE(r.contact_points.empty());
    results.push_back(r);

    // Deform the surface (a dent), refit, and compare with a freshly built BVH.
    TriangleMesh dented = surface;
    for (Vector3d& v : dented.vertices) v.z() -= 0.0001 * std::exp(-v.head<2>().squaredNorm() / 1e-6);
    SurfaceView view = SurfaceView::of(surface);
    std::vector<Vector3d> positions = dented.vertices;
    view.positions = positions.data();
    const CollisionResult refit = detector->collide(pose, view);
    auto fresh = makeCollisionDetector(name);
    fresh->setInstrument(sphere);
    const CollisionResult rebuilt = fresh->collide(pose, view);
    EXPECT_EQ(refit.triangles, rebuilt.triangles);
    EXPECT_NE(refit.triangles, r.triangles);
  }
  EXPECT_EQ(results[0].triangles, results[1].triangles);
  EXPECT_EQ(results[0].triangles, results[2].triangles);
}

}  // namespace
}  // namespace collision
}  // namespace vrm_sim
