// The exact vertex reference of the collision benchmark (issue 19): membrane vertices inside the instrument solid by
// a point-in-solid test, and per vertex the axial penetration (displacement along the instrument axis out of the
// solid). The geometric detector resolves exactly that; ZCOLL/F moves every inside vertex (its 1-ring max may also
// move outside neighbours of colliding triangles, and by more than their own depth).
#include <gtest/gtest.h>

#include <set>

#include "vrm_scene/meshes/primitive_meshes.h"
#include "vrm_sim/collision/collision_detector.h"
#include "vrm_sim/collision/primitives.h"

using Eigen::Vector3d;
using namespace vrm_sim::collision;

namespace {

struct Scene {
  InstrumentModel sphere;
  vrm_sim::TriangleMesh membrane;
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  Scene() {
    sphere.primitives.push_back(Primitive::sphere(Vector3d(0, 0, -0.001), 0.001));
    sphere.mesh = primitiveMesh(sphere.primitives[0], 64);
    vrm_sim::scene::PlaneParams params;
    params.size_x = params.size_y = 0.004;
    params.subdivisions = 30;
    membrane = vrm_sim::scene::makePlane(params);
    // Tip (+z) pointing down (-z of the membrane frame), 0.4 mm into the plane z = 0.
    pose.linear() = Eigen::AngleAxisd(M_PI, Vector3d::UnitX()).toRotationMatrix();
    pose.translation() = Vector3d(0.00003, -0.00002, -0.0004);
  }
  // Axial penetration of vertex v (0 outside).
  double depth(std::size_t v) const {
    const Primitive s = transformed(sphere.primitives[0], pose);
    if (signedDistance(s, membrane.vertices[v]) >= 0.0) return 0.0;
    return (*lineInterval(s, membrane.vertices[v], pose.linear() * Vector3d::UnitZ()))[1];
  }
};

}  // namespace

TEST(CollisionVertexReference, GeometricDetectorMovesExactlyTheInsideVerticesByTheirAxialDepth) {
  Scene scene;
  auto detector = makeCollisionDetector("geometric");
  detector->setInstrument(scene.sphere);
  const CollisionResult r = detector->collide(scene.pose, SurfaceView::of(scene.membrane));
  std::set<std::uint32_t> moved;
  for (std::size_t i = 0; i < r.nodes.size(); ++i) {
    if (r.deformations[i].norm() == 0.0) continue;
    moved.insert(r.nodes[i]);
    EXPECT_NEAR(r.deformations[i].norm(), scene.depth(r.nodes[i]), 1e-9);
  }
  int inside = 0;
  for (std::size_t v = 0; v < scene.membrane.vertices.size(); ++v) {
    if (scene.depth(v) > 0.0) {
      ++inside;
      EXPECT_TRUE(moved.count(v)) << v;
    }
  }
  EXPECT_GT(inside, 20);
  EXPECT_EQ(static_cast<int>(moved.size()), inside);
}

TEST(CollisionVertexReference, ZcollFFindsEveryInsideVertex) {
  Scene scene;
  CollisionOptions options;
  options.resolution = 100;
  auto detector = makeCollisionDetector("zcoll_f_cpu", options);
  detector->setInstrument(scene.sphere);
  const CollisionResult r = detector->collide(scene.pose, SurfaceView::of(scene.membrane));
  const std::set<std::uint32_t> moved(r.nodes.begin(), r.nodes.end());
  int inside = 0;
  for (std::size_t v = 0; v < scene.membrane.vertices.size(); ++v) {
    if (scene.depth(v) <= 0.0) continue;
    ++inside;
    EXPECT_TRUE(moved.count(v)) << v;
  }
  EXPECT_GT(inside, 20);
  EXPECT_GE(static_cast<int>(moved.size()), inside);  // plus outside vertices of colliding triangles (1-ring)
}
