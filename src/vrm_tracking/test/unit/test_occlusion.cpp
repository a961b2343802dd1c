// Issue 43 §2: markers partly hidden by a shaft or another marker. The cut centroid's shift against a numerical
// reference, the weighted triangulation against exact projections, and the tracker on the shipped demo with a camera
// stopped (the shaft of one instrument slowly covering the other's tip marker).

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <opencv2/imgproc.hpp>

#include "vrm_scene/scene_loader.h"
#include "vrm_tracking/evaluation.h"
#include "vrm_tracking/marker_detector.h"
#include "vrm_tracking/marker_layout.h"
#include "vrm_tracking/pose_tracker.h"
#include "vrm_tracking/scene_trocars.h"
#include "vrm_tracking/triangulation.h"

namespace vrm_tracking {
namespace {

// A unit disc whose part below y = edge is hidden, sampled on a fine grid: the hidden area fraction and the centroid
// shift of the visible part (radii).
void cutDiscByGrid(double edge, double* missing, double* shift) {
  const int n = 2000;
  double visible = 0.0, total = 0.0, sum_y = 0.0;
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < n; ++j) {
      const double x = -1.0 + (i + 0.5) * 2.0 / n, y = -1.0 + (j + 0.5) * 2.0 / n;
      if (x * x + y * y > 1.0) continue;
      total += 1.0;
      if (y < edge) continue;
      visible += 1.0;
      sum_y += y;
    }
  }
  *missing = 1.0 - visible / total;
  *shift = sum_y / visible;
}

TEST(CutDisc, CentroidShiftMatchesANumericalReference) {
  for (double edge : {-0.9, -0.6, -0.3, 0.0, 0.3, 0.5}) {
    double missing = 0.0, shift = 0.0;
    cutDiscByGrid(edge, &missing, &shift);
    EXPECT_NEAR(cutDiscCentroidShift(missing), shift, 2e-3) << "edge at " << edge << " radii";
  }
  EXPECT_EQ(cutDiscCentroidShift(0.0), 0.0);
  EXPECT_EQ(cutDiscCentroidShift(-0.2), 0.0);  // a blob larger than expected is not cut
  EXPECT_EQ(cutDiscCentroidShift(std::numeric_limits<double>::quiet_NaN()), 0.0);
  EXPECT_TRUE(std::isfinite(cutDiscCentroidShift(1.0)));  // clamped: a sliver gives a large but finite shift
}

std::vector<PixelObservation> exactObservations(const CameraRig& rig, const Eigen::Vector3d& p,
                                                const std::vector<std::size_t>& cameras) {
  std::vector<PixelObservation> obs;
  for (std::size_t c : cameras) {
    PixelObservation o;
    o.camera = c;
    EXPECT_TRUE(rig.cameras[c].project(p, &o.pixel));
    obs.push_back(o);
  }
  return obs;
}

// The image direction in camera `to` along which the point moves when it slides along camera `from`'s ray: the
// epipolar line, where two cameras cannot see a bias.
Eigen::Vector2d epipolarDirection(const CameraRig& rig, const Eigen::Vector3d& p, std::size_t from, std::size_t to) {
  const Eigen::Vector3d ray = (p - rig.cameras[from].centreInWorld()).normalized();
  Eigen::Vector2d a, b;
  rig.cameras[to].project(p, &a);
  rig.cameras[to].project(p + 1e-3 * ray, &b);
  return (b - a).normalized();
}

// Two tip markers of different colours side by side, rendered (4 x 4 rays per pixel, blurred as the optics do) with
// the second in front where they overlap; the first alone gives its unoccluded blob.
cv::Mat twoMarkers(const ColourClass& back, const ColourClass& front, double separation_px, bool with_front) {
  constexpr double kRadius = 4.5, kBlur = 0.8;
  const Eigen::Vector2d a(24.0, 20.0), b = a + Eigen::Vector2d(separation_px, 0.3 * separation_px);
  cv::Mat image(40, 56, CV_32FC3, cv::Scalar(40, 40, 40));
  for (int y = 0; y < image.rows; ++y) {
    for (int x = 0; x < image.cols; ++x) {
      cv::Vec3f sum(0, 0, 0);
      for (int sy = 0; sy < 4; ++sy) {
        for (int sx = 0; sx < 4; ++sx) {
          const Eigen::Vector2d p(x - 0.5 + (sx + 0.5) / 4, y - 0.5 + (sy + 0.5) / 4);
          cv::Vec3f c(40, 40, 40);
          if ((p - a).norm() <= kRadius) c = cv::Vec3f(back.bgr[0], back.bgr[1], back.bgr[2]);
          if (with_front && (p - b).norm() <= kRadius) c = cv::Vec3f(front.bgr[0], front.bgr[1], front.bgr[2]);
          sum += c / 16.0f;
        }
      }
      image.at<cv::Vec3f>(y, x) = sum;
    }
  }
  cv::GaussianBlur(image, image, cv::Size(0, 0), kBlur);
  cv::Mat bgr;
  image.convertTo(bgr, CV_8UC3);
  return bgr;
}

// Where two markers' blurred edges meet, the back one loses its fringe, whose pixels have little chroma: its
// chroma-weighted centroid moves less than the missing *area* says (that over-corrected the demo with camera_1
// stopped by 0.34 px); the missing *weight* (Blob::weight) gives the shift.
TEST(CutDisc, ABlobLosingItsFringeToANeighbourShiftsAsItsMissingWeightSays) {
  const MarkerLayout layout = makeDefaultLayout();
  const MarkerDetector detector(layout.classes);
  const ColourClass& back = layout.classes[layout.classes.size() - 2];
  const ColourClass& front = layout.classes[layout.classes.size() - 1];
  auto blobOf = [&](const cv::Mat& image) {
    for (const Blob& b : detector.components(image, cv::Rect(0, 0, image.cols, image.rows), -1)) {
      if (b.class_id == back.id) return b;
    }
    return Blob{};
  };
  int tried = 0;
  for (double separation : {8.0, 7.0, 6.0}) {
    const Blob full = blobOf(twoMarkers(back, front, separation, false));
    const Blob cut = blobOf(twoMarkers(back, front, separation, true));
    ASSERT_GT(full.area, 0.0);
    if (!(cut.area > 0.0) || cut.area >= full.area) continue;
    ++tried;
    const double measured = std::hypot(cut.u - full.u, cut.v - full.v);
    const double radius = std::sqrt(full.area / M_PI);
    const double by_area = cutDiscCentroidShift(1.0 - cut.area / full.area) * radius;
    const double by_weight = cutDiscCentroidShift(1.0 - cut.weight / full.weight) * radius;
    SCOPED_TRACE("separation " + std::to_string(separation) + " px: measured " + std::to_string(measured) +
                 ", by area " + std::to_string(by_area) + ", by weight " + std::to_string(by_weight));
    EXPECT_LT(std::abs(by_weight - measured), std::abs(by_area - measured));
    EXPECT_LT(std::abs(by_weight - measured), 0.25 * measured + 0.05);
  }
  EXPECT_GE(tried, 2);
}

TEST(TriangulateWeighted, IdentityWeightsAreTheOrdinarySolution) {
  const CameraRig rig = makeDefaultRig();
  const Eigen::Vector3d p(0.002, -0.003, 0.004);
  std::vector<PixelObservation> obs = exactObservations(rig, p, {0, 1, 2});
  obs[0].pixel += Eigen::Vector2d(0.3, -0.2);  // an ordinary (isotropic) error
  const std::vector<Eigen::Matrix2d> identity(3, Eigen::Matrix2d::Identity() / (0.05 * 0.05));
  const Triangulation plain = triangulate(rig, obs), weighted = triangulateWeighted(rig, obs, identity);
  ASSERT_TRUE(plain.valid && weighted.valid);
  EXPECT_LT((plain.point - weighted.point).norm(), 1e-10);
  EXPECT_NEAR(plain.rms_px, weighted.rms_px, 1e-9);
  EXPECT_NEAR(plain.max_px, weighted.max_px, 1e-9);
}

TEST(TriangulateWeighted, ACutCentroidWeighedAlongItsEdgeOnlyLeavesNoBias) {
  const CameraRig rig = makeDefaultRig();
  const Eigen::Vector3d p(-0.001, 0.002, -0.009);
  std::vector<PixelObservation> obs = exactObservations(rig, p, {0, 1, 2});
  const Eigen::Vector2d across(0.6, 0.8);  // the cut's normal in camera 2's image
  obs[2].pixel += 1.5 * across;            // what a shaft covering 40 % of the blob does
  const double sigma = 0.05, cut_sigma = 2.0;
  std::vector<Eigen::Matrix2d> information(3, Eigen::Matrix2d::Identity() / (sigma * sigma));
  const Eigen::Vector2d along(-across.y(), across.x());
  information[2] = along * along.transpose() / (sigma * sigma) + across * across.transpose() / (cut_sigma * cut_sigma);
  const Triangulation plain = triangulate(rig, obs), weighted = triangulateWeighted(rig, obs, information);
  ASSERT_TRUE(plain.valid && weighted.valid);
  EXPECT_GT((plain.point - p).norm(), 20e-6);      // the ordinary solution takes the bias
  EXPECT_LT((weighted.point - p).norm(), 0.5e-6);  // three rays fix the point without the biased direction
  // The residual in the reliable directions shows no inconsistency (what is left is the 1.5 px across the cut at its
  // relative weight, (0.05 / 2)²: 0.0375 px); the ordinary one does.
  EXPECT_LT(weighted.max_px, 0.05);
  EXPECT_GT(plain.max_px, 0.5);
}

TEST(TriangulateWeighted, APairCutAlongItsEpipolarLineNeedsThePrior) {
  const CameraRig rig = makeDefaultRig();
  const Eigen::Vector3d p(0.001, 0.001, -0.008);
  std::vector<PixelObservation> obs = exactObservations(rig, p, {0, 2});
  const Eigen::Vector2d across = epipolarDirection(rig, p, 0, 2);
  obs[1].pixel += 1.5 * across;
  const double sigma = 0.05, cut_sigma = 2.0;
  std::vector<Eigen::Matrix2d> information(2, Eigen::Matrix2d::Identity() / (sigma * sigma));
  const Eigen::Vector2d along(-across.y(), across.x());
  information[1] = along * along.transpose() / (sigma * sigma) + across * across.transpose() / (cut_sigma * cut_sigma);
  // The weights alone cannot help: the cut direction is the only one that fixes the depth along camera 0's ray.
  const Triangulation without = triangulateWeighted(rig, obs, information);
  ASSERT_TRUE(without.valid);
  EXPECT_GT((without.point - p).norm(), 50e-6);
  // The prediction, 8 µm off, as a prior of 10 µm.
  PointPrior prior;
  prior.point = p + Eigen::Vector3d(5e-6, -5e-6, 4e-6);
  prior.sigma = 10e-6;
  const Triangulation with = triangulateWeighted(rig, obs, information, &prior);
  ASSERT_TRUE(with.valid);
  EXPECT_LT((with.point - p).norm(), 12e-6);
}

TEST(TriangulateWeighted, BadWeightsAreInvalidNotThrown) {
  const CameraRig rig = makeDefaultRig();
  const std::vector<PixelObservation> obs = exactObservations(rig, Eigen::Vector3d(0, 0, -0.005), {0, 1});
  std::vector<Eigen::Matrix2d> information(2, Eigen::Matrix2d::Identity());
  information[1](0, 1) = std::numeric_limits<double>::quiet_NaN();
  EXPECT_FALSE(triangulateWeighted(rig, obs, information).valid);
  EXPECT_FALSE(triangulateWeighted(rig, obs, {Eigen::Matrix2d::Identity()}).valid);  // one weight for two
  PointPrior nan_prior;
  nan_prior.point = Eigen::Vector3d::Constant(std::numeric_limits<double>::quiet_NaN());
  nan_prior.sigma = 1e-5;
  const Triangulation t = triangulateWeighted(rig, obs, {Eigen::Matrix2d::Identity(), Eigen::Matrix2d::Identity()},
                                              &nan_prior);  // a non-finite prior is ignored
  ASSERT_TRUE(t.valid);
  EXPECT_LT((t.point - Eigen::Vector3d(0, 0, -0.005)).norm(), 1e-9);
}

// The shipped demo (the simulator's scripted surgeon) in the default scene, rendered as the bench does, camera_1
// stopped after 2 s: from 2.4 s to 3.3 s the right instrument's shaft covers the left tip marker in camera_2 (its
// blob shrinks from 64 to 29 px², the centroid moving 2 px across the shaft), so the pair of cameras 0 and 2 sees a
// biased marker for 40 frames.
EvalResult demoWithCameraOneStopped(bool occlusion_model) {
  const vrm_sim::scene::SceneDescription scene = vrm_sim::scene::loadScene(vrm_sim::scene::kDefaultSceneName);
  MarkerLayout layout = makeDefaultLayout();
  applySceneTrocars(scene, &layout);
  SurgeonScript demo = playInScene(scene, loadSession("", scene));
  demo.setPlayback(Playback::kOnce);
  std::vector<double> times;
  for (int f = 0; f < 175; ++f) times.push_back(f / 50.0);
  EvalOptions opt;
  opt.rendered = true;
  opt.occluded_camera = 1;
  opt.occlusion_start_frame = 100;
  opt.seed = 14;
  opt.tracker.occlusion_model = occlusion_model;
  return evaluate(
      makeDefaultRig(), layout, [&demo](double t) { return demo.sample(t); }, times, opt);
}

TEST(OcclusionModel, TheDemosShaftCutPairStaysWithinTheTarget) {
  const EvalResult with = demoWithCameraOneStopped(true), without = demoWithCameraOneStopped(false);
  // Without the model the cut blob goes into the pair as it is (the bench's before: 198 µm over the whole demo).
  EXPECT_GT(without.tip_max_um, 100.0);
  EXPECT_LE(with.tip_max_um, 60.0);
  EXPECT_LT(with.tip_rms_um, 0.5 * without.tip_rms_um);
  EXPECT_GE(with.track_rate, without.track_rate);
}

}  // namespace
}  // namespace vrm_tracking
