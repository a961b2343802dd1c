// Triangulation and pose recovery against exact references: projected → triangulated is exact at zero noise.

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "vrm_tracking/pose_tracker.h"
#include "vrm_tracking/triangulation.h"

namespace vrm_tracking {
namespace {

std::vector<PixelObservation> projectAll(const CameraRig& rig, const Eigen::Vector3d& p) {
  std::vector<PixelObservation> obs;
  for (std::size_t c = 0; c < rig.size(); ++c) {
    PixelObservation o;
    o.camera = c;
    EXPECT_TRUE(rig.cameras[c].project(p, &o.pixel));
    obs.push_back(o);
  }
  return obs;
}

TEST(Triangulation, ExactAtZeroNoiseWithThreeAndTwoCameras) {
  CameraRig rig = makeDefaultRig();
  rig.cameras[1].distortion = {-0.1, 0.02, 0.0, 0.0, 0.0};  // the refinement handles distortion too
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-0.015, 0.015);
  for (int i = 0; i < 200; ++i) {
    const Eigen::Vector3d p(u(rng), u(rng), u(rng));
    const auto obs = projectAll(rig, p);
    const Triangulation t = triangulate(rig, obs);
    ASSERT_TRUE(t.valid);
    EXPECT_LT((t.point - p).norm(), 1e-9);
    EXPECT_LT(t.rms_px, 1e-6);
    EXPECT_EQ(t.cameras.size(), 3u);
    for (const Triangulation& pair : triangulatePairs(rig, obs)) {
      ASSERT_TRUE(pair.valid);
      EXPECT_LT((pair.point - p).norm(), 1e-9);
    }
  }
}

TEST(Triangulation, DltAloneIsExactWithoutDistortion) {
  const CameraRig rig = makeDefaultRig();
  const Eigen::Vector3d p(0.004, -0.007, 0.011);
  const Triangulation t = triangulateDlt(rig, projectAll(rig, p));
  ASSERT_TRUE(t.valid);
  EXPECT_LT((t.point - p).norm(), 1e-10);
}

TEST(Triangulation, ResidualReportsAnInconsistentCamera) {
  const CameraRig rig = makeDefaultRig();
  auto obs = projectAll(rig, Eigen::Vector3d(0.001, 0.002, -0.003));
  obs[2].pixel += Eigen::Vector2d(8.0, 0.0);
  const Triangulation t = triangulate(rig, obs);
  ASSERT_TRUE(t.valid);
  EXPECT_GT(t.rms_px, 1.0);
}

TEST(Triangulation, BadInputIsInvalidNotAThrow) {
  const CameraRig rig = makeDefaultRig();
  auto obs = projectAll(rig, Eigen::Vector3d::Zero());
  EXPECT_FALSE(triangulate(rig, {obs[0]}).valid);               // one camera
  EXPECT_FALSE(triangulate(rig, {}).valid);                     // none
  obs[1].pixel.x() = std::numeric_limits<double>::quiet_NaN();  // NaN centroid
  EXPECT_FALSE(triangulate(rig, obs).valid);
  obs[1].camera = 7;  // unknown camera
  EXPECT_FALSE(triangulate(rig, obs).valid);
}

TEST(Triangulation, NoiseGivesTheExpectedErrorScale) {
  // 0.1 px centroid noise at ~105 µm/px: the error must be a fraction of a pixel footprint, not pixels.
  const CameraRig rig = makeDefaultRig();
  std::mt19937 rng(5);
  std::normal_distribution<double> noise(0.0, 0.1);
  double sum2 = 0.0;
  const int n = 500;
  for (int i = 0; i < n; ++i) {
    const Eigen::Vector3d p(0.002, -0.003, -0.004);
    auto obs = projectAll(rig, p);
    for (auto& o : obs) o.pixel += Eigen::Vector2d(noise(rng), noise(rng));
    sum2 += (triangulate(rig, obs).point - p).squaredNorm();
  }
  const double rms_um = std::sqrt(sum2 / n) * 1e6;
  EXPECT_GT(rms_um, 3.0);
  EXPECT_LT(rms_um, 30.0);
}

TEST(EyeRotation, KabschRecoversTheRotationExactly) {
  const MarkerLayout layout = makeDefaultLayout();
  const Eigen::Vector3d a0 = layout.eye_markers[0].position, b0 = layout.eye_markers[1].position;
  for (const Eigen::Quaterniond q : {Eigen::Quaterniond::Identity(),
                                     Eigen::Quaterniond(Eigen::AngleAxisd(0.2, Eigen::Vector3d(1, 2, 3).normalized())),
                                     Eigen::Quaterniond(Eigen::AngleAxisd(-0.4, Eigen::Vector3d::UnitX()))}) {
    const Eigen::Quaterniond r = eyeRotationFromMarkers(a0, b0, q * a0, q * b0);
    EXPECT_LT(r.angularDistance(q), 1e-12);
  }
}

}  // namespace
}  // namespace vrm_tracking
