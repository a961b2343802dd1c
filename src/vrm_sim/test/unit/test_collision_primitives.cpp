// Exact primitives beyond sphere/capsule/box: cylinder and cone against points, lines and triangles, every
// primitive pair (GJK on support mappings, half-space planes in closed form) against analytic truth, the geometric
// detector with a cone, and degenerate / NaN input.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <limits>

#include "vrm_scene/meshes/primitive_meshes.h"
#include "vrm_sim/collision/collision_detector.h"
#include "vrm_sim/collision/primitives.h"

namespace vrm_sim {
namespace collision {
namespace {

using Eigen::Vector3d;
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

double rnd() { return 2.0 * std::rand() / RAND_MAX - 1.0; }
Vector3d rndVector() { return Vector3d(rnd(), rnd(), rnd()); }

TEST(ExactPrimitives, CylinderAndConeDistancesAndIntervals) {
  const Primitive cylinder = Primitive::cylinder(Vector3d(0, 0, 0), Vector3d(0, 0, 2), 0.5);
  EXPECT_NEAR(signedDistance(cylinder, Vector3d(0, 0, 1)), -0.5, 1e-12);    // on the axis: radius is nearest
  EXPECT_NEAR(signedDistance(cylinder, Vector3d(0, 0, 0.2)), -0.2, 1e-12);  // near the cap
  EXPECT_NEAR(signedDistance(cylinder, Vector3d(1.5, 0, 1)), 1.0, 1e-12);   // beside the mantle
  EXPECT_NEAR(signedDistance(cylinder, Vector3d(0, 0, 3)), 1.0, 1e-12);     // above the cap
  EXPECT_NEAR(signedDistance(cylinder, Vector3d(3.5, 0, 6)), 5.0, 1e-12);   // off the rim: (3, 4) -> 5
  // Cone: apex (0,0,0), base centre (0,0,1), base radius 1 (45° half angle).
  const Primitive cone = Primitive::cone(Vector3d(0, 0, 0), Vector3d(0, 0, 1), 1.0);
  EXPECT_NEAR(signedDistance(cone, Vector3d(0, 0, -1)), 1.0, 1e-12);            // below the apex
  EXPECT_NEAR(signedDistance(cone, Vector3d(0, 0, 0.9)), -0.1, 1e-12);          // near the base
  EXPECT_NEAR(signedDistance(cone, Vector3d(1, 0, 0)), std::sqrt(0.5), 1e-12);  // beside the apex, off the side
  EXPECT_NEAR(signedDistance(cone, Vector3d(0, 0, 0.5)), -0.5 * std::sqrt(0.5), 1e-12);
  EXPECT_NEAR(signedDistance(cone, Vector3d(2, 0, 2)), std::sqrt(2.0), 1e-12);  // nearest: the rim (1, 1)

  auto interval = lineInterval(cylinder, Vector3d(0.3, 0, -5), Vector3d::UnitZ());
  ASSERT_TRUE(interval);
  EXPECT_NEAR((*interval)[0], 5.0, 1e-12);
  EXPECT_NEAR((*interval)[1], 7.0, 1e-12);
  interval = lineInterval(cylinder, Vector3d(-5, 0.3, 1), Vector3d::UnitX());
  ASSERT_TRUE(interval);
  EXPECT_NEAR((*interval)[0], 5.0 - 0.4, 1e-12);
  EXPECT_NEAR((*interval)[1], 5.0 + 0.4, 1e-12);
  EXPECT_FALSE(lineInterval(cylinder, Vector3d(0.6, 0, -5), Vector3d::UnitZ()));
  // Along the cone's axis: from the apex to the base.
  interval = lineInterval(cone, Vector3d(0, 0, -5), Vector3d::UnitZ());
  ASSERT_TRUE(interval);
  EXPECT_NEAR((*interval)[0], 5.0, 1e-12);
  EXPECT_NEAR((*interval)[1], 6.0, 1e-12);
  // Parallel to the axis at radius 0.5: enters the side at h = 0.5, leaves through the base.
  interval = lineInterval(cone, Vector3d(0.5, 0, -5), Vector3d::UnitZ());
  ASSERT_TRUE(interval);
  EXPECT_NEAR((*interval)[0], 5.5, 1e-12);
  EXPECT_NEAR((*interval)[1], 6.0, 1e-12);
  // Across at h = 0.5: |x| <= 0.5.
  interval = lineInterval(cone, Vector3d(-3, 0, 0.5), Vector3d::UnitX());
  ASSERT_TRUE(interval);
  EXPECT_NEAR((*interval)[0], 2.5, 1e-12);
  EXPECT_NEAR((*interval)[1], 3.5, 1e-12);
  // The other nappe of the double cone (below the apex) is not part of the solid.
  EXPECT_FALSE(lineInterval(cone, Vector3d(-3, 0, -0.5), Vector3d::UnitX()));
  // Random lines: the interval ends lie on the surface, its midpoint inside.
  std::srand(3);
  for (int trial = 0; trial < 200; ++trial) {
    const Vector3d origin = 2.0 * rndVector();
    const Vector3d direction = rndVector().normalized();
    for (const Primitive& solid : {cylinder, cone}) {
      const auto i = lineInterval(solid, origin, direction);
      if (!i) continue;
      EXPECT_NEAR(signedDistance(solid, origin + (*i)[0] * direction), 0.0, 1e-9) << trial;
      EXPECT_NEAR(signedDistance(solid, origin + (*i)[1] * direction), 0.0, 1e-9) << trial;
      EXPECT_LE(signedDistance(solid, origin + 0.5 * ((*i)[0] + (*i)[1]) * direction), 1e-12) << trial;
    }
  }
}

TEST(ExactPrimitives, CylinderAndConeTriangleOverlapAgreesWithDenseSampling) {
  std::srand(11);
  const std::vector<Primitive> solids = {Primitive::cylinder(Vector3d(-0.3, 0, 0), Vector3d(0.3, 0.2, 0.1), 0.25),
                                         Primitive::cone(Vector3d(0, -0.4, 0.1), Vector3d(0.1, 0.3, 0), 0.35),
                                         Primitive::cylinder(Vector3d(0, 0, -0.4), Vector3d(0, 0, 0.4), 0.0)};
  int overlaps = 0, separated = 0;
  for (int trial = 0; trial < 300; ++trial) {
    const Vector3d a = rndVector(), b = rndVector(), c = rndVector();
    for (std::size_t k = 0; k < solids.size(); ++k) {
      const Primitive& s = solids[k];
      double min_distance = 1e9;
      const int n = 40;
      for (int i = 0; i <= n; ++i) {
        for (int j = 0; i + j <= n; ++j) {
          min_distance = std::min(min_distance, signedDistance(s, a + (b - a) * i / n + (c - a) * j / n));
        }
      }
      const bool overlap = overlapsTriangle(s, a, b, c);
      overlaps += overlap;
      separated += !overlap;
      if (min_distance < 0.0) EXPECT_TRUE(overlap) << trial << " solid " << k;
      if (overlap) EXPECT_LT(min_distance, 0.06) << trial << " solid " << k;
      if (min_distance > 0.06) EXPECT_FALSE(overlap) << trial << " solid " << k;
      // The tolerance is a Minkowski sum with a ball: overlap within t iff the distance is at most t.
      if (min_distance > 0.1 && min_distance < 0.5) {
        EXPECT_TRUE(overlapsTriangle(s, a, b, c, min_distance + 1e-9)) << trial << " solid " << k;
        EXPECT_FALSE(overlapsTriangle(s, a, b, c, min_distance - 0.06)) << trial << " solid " << k;
      }
    }
  }
  EXPECT_GT(overlaps, 50);
  EXPECT_GT(separated, 50);
}

// All pairs against closed-form truth: a sphere overlaps X iff X's exact signed distance at its centre is at most
// its radius; a half-space overlaps X iff X's lowest point along the normal is in it; capsule pairs by segment
// distance; parallel cylinders by axis distance and axial overlap.
TEST(ExactPrimitives, PrimitivePairsAgreeWithAnalyticTruth) {
  std::srand(5);
  auto random_primitive = [](int type) {
    const Vector3d a = 0.5 * rndVector(), b = a + 0.6 * rndVector();
    const double r = 0.05 + 0.3 * std::abs(rnd());
    switch (type) {
      case 0:
        return Primitive::sphere(a, r);
      case 1:
        return Primitive::capsule(a, b, r);
      case 2:
        return Primitive::box(a, Vector3d(0.1, 0.2, 0.3) + 0.1 * rndVector().cwiseAbs(),
                              Eigen::AngleAxisd(rnd() * 3.0, rndVector().normalized()).toRotationMatrix());
      case 3:
        return Primitive::cylinder(a, b, r);
      default:
        return Primitive::cone(a, b, r);
    }
  };
  auto lowest = [](const Primitive& p, const Vector3d& n) {  // min over the solid of n . x
    const Vector3d u = (p.b - p.a).normalized();
    const double across = std::sqrt(std::max(0.0, 1.0 - std::pow(n.dot(u), 2)));
    switch (p.type) {
      case Primitive::Type::kSphere:
        return n.dot(p.a) - p.radius;
      case Primitive::Type::kCapsule:
        return std::min(n.dot(p.a), n.dot(p.b)) - p.radius;
      case Primitive::Type::kBox:
        return n.dot(p.a) - (p.rotation.transpose() * n).cwiseAbs().dot(p.half_extents);
      case Primitive::Type::kCylinder:
        return std::min(n.dot(p.a), n.dot(p.b)) - p.radius * across;
      default:
        return std::min(n.dot(p.a), n.dot(p.b) - p.radius * across);
    }
  };
  int hits = 0, misses = 0;
  for (int trial = 0; trial < 400; ++trial) {
    for (int type = 0; type < 5; ++type) {
      const Primitive x = random_primitive(type);
      const Primitive sphere = Primitive::sphere(0.8 * rndVector(), 0.05 + 0.3 * std::abs(rnd()));
      const double sd = signedDistance(x, sphere.a);
      if (std::abs(sd - sphere.radius) > 1e-9) {
        const bool truth = sd <= sphere.radius;
        EXPECT_EQ(overlaps(sphere, x), truth) << "sphere vs type " << type << " trial " << trial;
        EXPECT_EQ(overlaps(x, sphere), truth) << "type " << type << " vs sphere, trial " << trial;
        hits += truth;
        misses += !truth;
      }
      const Primitive plane = Primitive::plane(0.5 * rndVector(), rndVector().normalized());
      const double low = lowest(x, plane.normal) - plane.normal.dot(plane.a);
      if (std::abs(low) > 1e-9) {
        EXPECT_EQ(overlaps(plane, x), low <= 0.0) << "plane vs type " << type << " trial " << trial;
        EXPECT_EQ(overlaps(x, plane), low <= 0.0);
      }
    }
    const Primitive c1 = random_primitive(1), c2 = random_primitive(1);
    const double gap = std::sqrt(segmentSegmentDistanceSquared(c1.a, c1.b, c2.a, c2.b)) - c1.radius - c2.radius;
    if (std::abs(gap) > 1e-9) EXPECT_EQ(overlaps(c1, c2), gap <= 0.0) << "capsules, trial " << trial;
    if (gap > 1e-3) {
      EXPECT_TRUE(overlaps(c1, c2, gap + 1e-9)) << gap;
      EXPECT_FALSE(overlaps(c1, c2, gap - 1e-6));
    }
    // Parallel cylinders along z.
    const Vector3d p1 = 0.5 * rndVector(), p2 = 0.5 * rndVector();
    const double h1 = 0.1 + 0.3 * std::abs(rnd()), h2 = 0.1 + 0.3 * std::abs(rnd());
    const double r1 = 0.05 + 0.2 * std::abs(rnd()), r2 = 0.05 + 0.2 * std::abs(rnd());
    const Primitive z1 = Primitive::cylinder(p1, p1 + Vector3d(0, 0, h1), r1);
    const Primitive z2 = Primitive::cylinder(p2, p2 + Vector3d(0, 0, h2), r2);
    const double radial = (p1 - p2).head<2>().norm() - r1 - r2;
    const double axial = std::max(p2.z() - (p1.z() + h1), p1.z() - (p2.z() + h2));
    if (std::abs(radial) > 1e-9 && std::abs(axial) > 1e-9) {
      EXPECT_EQ(overlaps(z1, z2), radial <= 0.0 && axial <= 0.0) << "cylinders, trial " << trial;
    }
  }
  EXPECT_GT(hits, 200);
  EXPECT_GT(misses, 200);
  // Half-spaces: disjoint only when opposite with a gap.
  const Primitive up = Primitive::plane(Vector3d::Zero(), Vector3d::UnitZ());
  EXPECT_TRUE(overlaps(up, Primitive::plane(Vector3d(0, 0, 5), Vector3d::UnitX())));
  EXPECT_TRUE(overlaps(up, Primitive::plane(Vector3d(0, 0, -1), -Vector3d::UnitZ())));
  EXPECT_FALSE(overlaps(up, Primitive::plane(Vector3d(0, 0, 1), -Vector3d::UnitZ())));
  EXPECT_TRUE(overlaps(up, Primitive::plane(Vector3d(0, 0, 1), -Vector3d::UnitZ()), 1.0));
}

TEST(ExactPrimitives, DegenerateAndNanInputNeverOverlap) {
  const Vector3d a(-1, -1, 0), b(1, -1, 0), c(0, 1, 0);
  const Primitive nan_cylinder = Primitive::cylinder(Vector3d(kNaN, 0, 0), Vector3d(0, 0, 1), 0.5);
  const Primitive flat_cylinder = Primitive::cylinder(Vector3d::Zero(), Vector3d::Zero(), 0.5);  // no axis
  const Primitive flat_cone = Primitive::cone(Vector3d::Zero(), Vector3d::Zero(), 0.5);
  const Primitive negative = Primitive::cone(Vector3d(0, 0, -1), Vector3d(0, 0, 1), -0.5);
  const Primitive nan_plane = Primitive::plane(Vector3d::Zero(), Vector3d(kNaN, 0, 1));
  for (const Primitive& p : {nan_cylinder, flat_cylinder, flat_cone, negative, nan_plane}) {
    EXPECT_FALSE(isValid(p));
    EXPECT_FALSE(overlapsTriangle(p, a, b, c));
    EXPECT_FALSE(overlaps(p, Primitive::sphere(Vector3d::Zero(), 10.0)));
    EXPECT_FALSE(overlaps(Primitive::sphere(Vector3d::Zero(), 10.0), p));
  }
  EXPECT_EQ(signedDistance(flat_cylinder, Vector3d::Zero()), std::numeric_limits<double>::infinity());
  // Zero radius is a segment, not an error.
  const Primitive wire = Primitive::cylinder(Vector3d(0, 0, -1), Vector3d(0, 0, 1), 0.0);
  EXPECT_TRUE(isValid(wire));
  EXPECT_TRUE(overlapsTriangle(wire, a, b, c));
  EXPECT_FALSE(overlapsTriangle(wire, a + Vector3d(5, 0, 0), b + Vector3d(5, 0, 0), c + Vector3d(5, 0, 0)));
  // NaN triangles, a NaN tolerance, a degenerate (collinear) triangle.
  const Primitive cone = Primitive::cone(Vector3d(0, 0, -1), Vector3d(0, 0, 1), 0.5);
  EXPECT_FALSE(overlapsTriangle(cone, Vector3d(kNaN, 0, 0), b, c));
  EXPECT_FALSE(overlaps(cone, Primitive::sphere(Vector3d::Zero(), 1.0), kNaN));
  EXPECT_TRUE(overlapsTriangle(cone, Vector3d(-1, 0, 0), Vector3d(0, 0, 0), Vector3d(1, 0, 0)));
  EXPECT_FALSE(overlapsTriangle(cone, Vector3d(-1, 5, 0), Vector3d(0, 5, 0), Vector3d(1, 5, 0)));
  // Identical solids and a point-sized sphere inside.
  EXPECT_TRUE(overlaps(cone, cone));
  EXPECT_TRUE(overlaps(cone, Primitive::sphere(Vector3d(0, 0, 0.5), 0.0)));
}

// The geometric detector with a cone tip (apex down, half angle atan(k)) pressed 0.2 mm into a plane: exactly the
// nodes within the cross-section are pushed down onto the cone, by 0.2 mm - rho / k.
TEST(ExactPrimitives, GeometricDetectorWithConeTip) {
  const double height = 0.001, base = 0.0004, k = base / height, depth = 0.0002;
  InstrumentModel model;
  model.primitives = {Primitive::cone(Vector3d(0, 0, 0), Vector3d(0, 0, -height), base)};
  scene::PlaneParams params;
  params.size_x = params.size_y = 0.002;
  params.subdivisions = 40;
  const TriangleMesh surface = scene::makePlane(params);
  Eigen::Isometry3d pose(Eigen::AngleAxisd(M_PI, Vector3d::UnitX()));  // instrument +z = surface -z
  pose.translation() = Vector3d(0, 0, -depth);
  auto detector = makeCollisionDetector("geometric");
  detector->setInstrument(model);
  const CollisionResult result = detector->collide(pose, SurfaceView::of(surface));
  ASSERT_EQ(result.status, CollisionStatus::kOk);
  ASSERT_TRUE(result.colliding);
  std::size_t expected_nodes = 0;
  for (const Vector3d& v : surface.vertices) expected_nodes += v.head<2>().norm() < depth * k;
  EXPECT_EQ(result.nodes.size(), expected_nodes);
  for (std::size_t i = 0; i < result.nodes.size(); ++i) {
    const double rho = surface.vertices[result.nodes[i]].head<2>().norm();
    EXPECT_NEAR(result.deformations[i].z(), -(depth - rho / k), 1e-12);
    EXPECT_NEAR(result.deformations[i].head<2>().norm(), 0.0, 1e-15);
  }
}

}  // namespace
}  // namespace collision
}  // namespace vrm_sim
