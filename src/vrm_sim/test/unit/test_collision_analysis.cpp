// analyzeCollisionMask (Alg. 4.2 l. 14-17 / Alg. 4.3 l. 9-12) on synthetic buffers: the branch-free footprint pass of
// issue 15 must give what the thesis' per-pixel loop gives — triangles, per-node max and mean, contact at the first
// deepest pixel in scan order — whatever ROI it scans and whatever ids lie outside the mask.

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <array>
#include <cstdint>
#include <vector>

#include "../../src/core/collision/detector_internals.h"
#include "vrm_sim/collision/image_space.h"

namespace vrm_sim {
namespace collision {
namespace internal {
namespace {

constexpr int kR = 12;

struct Buffers {
  std::vector<std::uint8_t> mask = std::vector<std::uint8_t>(kR * kR, 0);
  std::vector<float> a = std::vector<float>(kR * kR, 5.0f);
  std::vector<float> b = std::vector<float>(kR * kR, 7.0f);  // b > a: no collision where the mask is 0 anyway
  std::vector<std::int32_t> ids = std::vector<std::int32_t>(kR * kR, -1);
  void collide(int x, int y, std::int32_t id, float penetration) {
    const int i = y * kR + x;
    mask[i] = 1;
    ids[i] = id;
    b[i] = a[i] - penetration;
  }
};

CollisionResult analyze(const Buffers& buffers, const PixelRect& roi, DeformationReduction reduction,
                        AnalysisScratch& scratch) {
  static const std::vector<Eigen::Vector3d> positions(6, Eigen::Vector3d::Zero());
  static const std::vector<std::array<std::uint32_t, 3>> triangles = {{0, 1, 2}, {1, 2, 3}, {3, 4, 5}, {0, 4, 5}};
  SurfaceView surface;
  surface.positions = positions.data();
  surface.node_count = positions.size();
  surface.triangles = triangles.data();
  surface.triangle_count = triangles.size();
  ProjectionVolume volume;
  volume.resolution = kR;
  volume.pixel_size = 1.0;
  CollisionOptions options;
  options.reduction = reduction;
  CollisionResult result;
  analyzeCollisionMask(volume, buffers.mask, roi, buffers.a.data(), buffers.ids.data(), buffers.b.data(),
                       Eigen::Isometry3d::Identity(), surface, options, scratch, result);
  return result;
}

Buffers scene() {
  Buffers buffers;
  // Triangle 1: a tie of its deepest penetration at (6, 3) and (2, 4): the first in scan order (row 3) wins.
  buffers.collide(4, 3, 1, 0.25f);
  buffers.collide(6, 3, 1, 0.5f);
  buffers.collide(7, 3, 1, 0.125f);
  buffers.collide(2, 4, 1, 0.5f);
  // Triangle 2: one pixel.
  buffers.collide(8, 8, 2, 0.75f);
  // Colliding pixels with a corrupt id (one past the last triangle, negative): ignored.
  buffers.collide(9, 8, 4, 1.0f);
  buffers.collide(10, 8, -7, 1.0f);
  // Ids outside the mask, as a GL colour buffer holds them: ignored.
  buffers.ids[0] = 0;
  buffers.ids[5 * kR + 5] = 3;
  return buffers;
}

TEST(ZcollAnalysis, TrianglesDeepestPixelAndReductionsMatchThePerPixelDefinition) {
  const Buffers buffers = scene();
  AnalysisScratch scratch;
  const CollisionResult max = analyze(buffers, PixelRect{0, 0, kR, kR}, DeformationReduction::kMax, scratch);
  EXPECT_EQ(max.triangles, (std::vector<std::uint32_t>{1, 2}));
  ASSERT_EQ(max.contact_points.size(), 2u);
  EXPECT_EQ(max.contact_points[0].head<2>(), Eigen::Vector2d(6.5, 3.5));  // pixel centre of the first deepest pixel
  EXPECT_EQ(max.contact_points[1].head<2>(), Eigen::Vector2d(8.5, 8.5));
  // Nodes 1..5: max over the pixels of the triangles around them (Eq. 4.2, |d| = a - b).
  EXPECT_EQ(max.nodes, (std::vector<std::uint32_t>{1, 2, 3, 4, 5}));
  const std::vector<double> expected_max = {0.5, 0.5, 0.75, 0.75, 0.75};
  for (std::size_t k = 0; k < max.nodes.size(); ++k) EXPECT_EQ(max.deformations[k].norm(), expected_max[k]) << k;

  const CollisionResult mean = analyze(buffers, PixelRect{0, 0, kR, kR}, DeformationReduction::kMean, scratch);
  ASSERT_EQ(mean.nodes, max.nodes);
  const double triangle1 = (0.25 + 0.5 + 0.125 + 0.5) / 4.0;
  const std::vector<double> expected_mean = {triangle1, triangle1, (1.375 + 0.75) / 5.0, 0.75, 0.75};
  for (std::size_t k = 0; k < mean.nodes.size(); ++k) EXPECT_EQ(mean.deformations[k].norm(), expected_mean[k]) << k;
}

TEST(ZcollAnalysis, ResultDoesNotDependOnTheScannedRoiAndScratchIsClean) {
  const Buffers buffers = scene();
  AnalysisScratch scratch;
  // The colliding ROI (what orFoldRoi gives) and the whole buffer (the CPU detector passes B's footprint), twice
  // each with the same scratch: the second query must not see the first one's pixels.
  const PixelRect tight{2, 3, 11, 9};
  const CollisionResult reference = analyze(buffers, tight, DeformationReduction::kMean, scratch);
  for (const PixelRect& roi : {PixelRect{0, 0, kR, kR}, tight, PixelRect{0, 0, kR, kR}}) {
    const CollisionResult result = analyze(buffers, roi, DeformationReduction::kMean, scratch);
    EXPECT_EQ(result.triangles, reference.triangles);
    EXPECT_EQ(result.nodes, reference.nodes);
    ASSERT_EQ(result.deformations.size(), reference.deformations.size());
    for (std::size_t k = 0; k < result.deformations.size(); ++k) {
      EXPECT_EQ(result.deformations[k], reference.deformations[k]);
    }
    EXPECT_EQ(result.contact_points, reference.contact_points);
  }
}

}  // namespace
}  // namespace internal
}  // namespace collision
}  // namespace vrm_sim
