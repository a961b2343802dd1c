// Building blocks of the image-space detectors: rasterizer fill rule, volume fitting, readback reductions (§4.2.5)
// and the z-convexity check (§4.1.4).
#include <gtest/gtest.h>

#include "vrm_scene/meshes/mesh_utils.h"
#include "vrm_scene/meshes/primitive_meshes.h"
#include "vrm_sim/collision/image_space.h"
#include "vrm_sim/collision/primitives.h"

namespace vrm_sim {
namespace collision {
namespace {

using Eigen::Vector3d;

TEST(CollisionRasterizer, SharedEdgesCoverEveryPixelCentreExactlyOnce) {
  // A 10 x 10 pixel square split into many triangles whose vertices lie on pixel centres and edges.
  scene::PlaneParams params;
  params.size_x = 10.0;
  params.size_y = 10.0;
  params.subdivisions = 5;
  TriangleMesh plane = scene::makePlane(params);
  std::vector<int> count(100, 0);
  const PixelRect clip{0, 0, 10, 10};
  for (const auto& t : plane.triangles) {
    Vector3d v[3];
    for (int k = 0; k < 3; ++k) v[k] = plane.vertices[t[k]] + Vector3d(5.0, 5.0, 1.0);
    rasterizeTriangle(v[0], v[1], v[2], clip, 10.0, [&](int x, int y, double depth) {
      EXPECT_NEAR(depth, 1.0, 1e-12);
      ++count[y * 10 + x];
    });
  }
  for (int c : count) EXPECT_EQ(c, 1);
}

TEST(CollisionRasterizer, ClipsDepthAndWindowAndSkipsDegenerate) {
  int fragments = 0;
  auto count = [&](int, int, double) { ++fragments; };
  const PixelRect clip{0, 0, 4, 4};
  rasterizeTriangle(Vector3d(0, 0, 5), Vector3d(8, 0, 5), Vector3d(0, 8, 5), clip, 2.0, count);
  EXPECT_EQ(fragments, 0);  // beyond the far plane
  rasterizeTriangle(Vector3d(0, 0, 1), Vector3d(1, 1, 1), Vector3d(2, 2, 1), clip, 2.0, count);
  EXPECT_EQ(fragments, 0);  // degenerate
  const double nan = std::numeric_limits<double>::quiet_NaN();
  rasterizeTriangle(Vector3d(nan, 0, 1), Vector3d(8, 0, 1), Vector3d(0, 8, 1), clip, 2.0, count);
  EXPECT_EQ(fragments, 0);
  rasterizeTriangle(Vector3d(-100, -100, 1), Vector3d(100, -100, 1), Vector3d(0, 100, 1), clip, 2.0, count);
  EXPECT_EQ(fragments, 16);  // clipped to the 4 x 4 window
}

TEST(CollisionVolume, FitsTipRegionWithSquarePixels) {
  // A long capsule along z with its tip at the origin: only the tip region defines the lateral extent.
  const TriangleMesh mesh = primitiveMesh(Primitive::capsule(Vector3d(0, 0, -0.0103), Vector3d(0, 0, -0.0003), 0.0003));
  const ProjectionVolume v = fitProjectionVolume(mesh, Vector3d::UnitZ(), 32, 0.002);
  ASSERT_EQ(v.resolution, 32);
  EXPECT_NEAR(v.pixel_size, 0.0006 / 30, 0.0006 / 30 * 0.01);
  const Vector3d tip = v.toPixel(Vector3d::Zero());
  EXPECT_NEAR(tip.x(), 16.0, 0.5);
  EXPECT_NEAR(tip.y(), 16.0, 0.5);
  EXPECT_NEAR(tip.z(), 0.5 * v.pixel_size, 1e-12);
  EXPECT_TRUE(fitProjectionVolume(TriangleMesh{}, Vector3d::UnitZ(), 32, 0.002).resolution == 0);
  // A round trip through pixel space.
  const Vector3d p = v.fromPixel(3, 7, 0.001);
  const Vector3d q = v.toPixel(p);
  EXPECT_NEAR(q.x(), 3.5, 1e-9);
  EXPECT_NEAR(q.y(), 7.5, 1e-9);
  EXPECT_NEAR(q.z(), 0.001, 1e-12);
}

TEST(CollisionReductions, OrFoldingFindsSinglePixelAndRoi) {
  for (int size : {1, 7, 30, 64, 100}) {
    std::vector<std::uint8_t> mask(size * size, 0);
    EXPECT_FALSE(orFoldYesNo(mask, size, size));
    EXPECT_TRUE(orFoldRoi(mask, size, size).empty());
    const int x = size - 1, y = size / 3;
    mask[y * size + x] = 1;
    EXPECT_TRUE(orFoldYesNo(mask, size, size)) << size;
    const PixelRect roi = orFoldRoi(mask, size, size);
    EXPECT_EQ(roi.x0, x);
    EXPECT_EQ(roi.x1, x + 1);
    EXPECT_EQ(roi.y0, y);
    EXPECT_EQ(roi.y1, y + 1);
  }
}

TEST(CollisionReductions, ZConvexityByAdditiveStencil) {
  scene::PlaneParams params;
  params.size_x = params.size_y = 0.002;
  params.subdivisions = 10;
  TriangleMesh sheet = scene::makePlane(params);
  // The instrument-fixed volume looks along +z; put the sheet 1 mm behind the tip.
  scene::transformMesh(sheet, Eigen::Isometry3d(Eigen::Translation3d(0, 0, -0.001)));
  const ProjectionVolume v = fitProjectionVolume(sheet, Vector3d::UnitZ(), 40, 0.002);
  EXPECT_EQ(maxCoverage(sheet, v), 1);
  TriangleMesh folded = sheet;
  TriangleMesh second = sheet;
  scene::transformMesh(second, Eigen::Isometry3d(Eigen::Translation3d(0, 0, -0.0005)));
  scene::appendMesh(folded, second);
  EXPECT_EQ(maxCoverage(folded, v), 2);  // two layers: not z-convex, ZCOLL sees only the front one
}

TEST(CollisionPrimitives, ExactDistancesAndIntervals) {
  const Primitive sphere = Primitive::sphere(Vector3d(0, 0, 1), 0.5);
  EXPECT_NEAR(signedDistance(sphere, Vector3d(0, 0, 0)), 0.5, 1e-12);
  const auto i = lineInterval(sphere, Vector3d(0, 0, -1), Vector3d::UnitZ());
  ASSERT_TRUE(i);
  EXPECT_NEAR((*i)[0], 1.5, 1e-12);
  EXPECT_NEAR((*i)[1], 2.5, 1e-12);
  const Primitive capsule = Primitive::capsule(Vector3d(0, 0, 0), Vector3d(0, 0, 2), 0.5);
  const auto j = lineInterval(capsule, Vector3d(0.3, 0, -5), Vector3d::UnitZ());
  ASSERT_TRUE(j);
  EXPECT_NEAR((*j)[0], 5.0 - 0.4, 1e-9);
  EXPECT_NEAR((*j)[1], 7.0 + 0.4, 1e-9);
  const auto k = lineInterval(capsule, Vector3d(-5, 0, 1), Vector3d::UnitX());
  ASSERT_TRUE(k);
  EXPECT_NEAR((*k)[0], 4.5, 1e-9);
  EXPECT_NEAR((*k)[1], 5.5, 1e-9);
  const Primitive box = Primitive::box(Vector3d(1, 1, 1), Vector3d(0.5, 1, 2));
  EXPECT_NEAR(signedDistance(box, Vector3d(1, 1, 1)), -0.5, 1e-12);
  EXPECT_NEAR(signedDistance(box, Vector3d(2, 1, 1)), 0.5, 1e-12);
  const Vector3d a(-1, -1, 0), b(1, -1, 0), c(0, 1, 0);
  EXPECT_TRUE(overlapsTriangle(sphere, a, b, c, 0.0) == false);
  EXPECT_TRUE(overlapsTriangle(Primitive::sphere(Vector3d(0, 0, 0.4), 0.5), a, b, c));
  EXPECT_TRUE(overlapsTriangle(capsule, a, b, c));
  EXPECT_TRUE(overlapsTriangle(Primitive::box(Vector3d(0, 0, 0.4), Vector3d(0.1, 0.1, 0.5)), a, b, c));
  EXPECT_FALSE(overlapsTriangle(Primitive::box(Vector3d(0, 0, 0.7), Vector3d(0.1, 0.1, 0.5)), a, b, c));
  EXPECT_NEAR(
      segmentSegmentDistanceSquared(Vector3d(0, 0, 0), Vector3d(1, 0, 0), Vector3d(0.5, 1, -1), Vector3d(0.5, 1, 1)),
      1.0, 1e-12);
  EXPECT_NEAR(segmentTriangleDistanceSquared(Vector3d(0, 0, -1), Vector3d(0, 0, 1), a, b, c), 0.0, 1e-12);
  EXPECT_NEAR(segmentTriangleDistanceSquared(Vector3d(0, 0, 0.5), Vector3d(0, 0, 1), a, b, c), 0.25, 1e-12);
}

TEST(CollisionPrimitives, OverlapAgreesWithDenseSampling) {
  // Random triangles vs the three primitives: if a dense sample of the triangle lies inside, overlap must be true;
  // if overlap is true, the triangle's closest sample lies within the sampling distance.
  std::srand(7);
  auto rnd = [] { return 2.0 * std::rand() / RAND_MAX - 1.0; };
  const Eigen::Matrix3d rot = Eigen::AngleAxisd(0.5, Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  const std::vector<Primitive> solids = {Primitive::sphere(Vector3d(0.1, 0, 0), 0.4),
                                         Primitive::capsule(Vector3d(-0.3, 0, 0), Vector3d(0.3, 0.2, 0.1), 0.25),
                                         Primitive::box(Vector3d(0, 0.1, 0), Vector3d(0.3, 0.2, 0.4), rot)};
  int overlaps = 0;
  for (int trial = 0; trial < 300; ++trial) {
    const Vector3d a(rnd(), rnd(), rnd()), b(rnd(), rnd(), rnd()), c(rnd(), rnd(), rnd());
    for (const Primitive& s : solids) {
      double min_distance = 1e9;
      const int n = 40;
      for (int i = 0; i <= n; ++i) {
        for (int j = 0; i + j <= n; ++j) {
          const Vector3d p = a + (b - a) * i / n + (c - a) * j / n;
          min_distance = std::min(min_distance, signedDistance(s, p));
        }
      }
      const bool overlap = overlapsTriangle(s, a, b, c);
      overlaps += overlap;
      if (min_distance < 0.0) EXPECT_TRUE(overlap) << trial;
      if (overlap) EXPECT_LT(min_distance, 0.06) << trial;
      if (min_distance > 0.06) EXPECT_FALSE(overlap) << trial;
    }
  }
  EXPECT_GT(overlaps, 50);
}

}  // namespace
}  // namespace collision
}  // namespace vrm_sim
