// Which blobs make a marker (issue 43 §2, §3, §5): a reconstruction must agree with the rig geometry (three rays
// within TrackerConfig::consistent_px) and, for a pair, with the marker's predicted position. Each case is one that
// the earlier rule (the loose 3 px gate, clean blobs first, the most cameras first, then the lowest residual) got
// wrong: a distractor on the epipolar line of the only other camera, a blob pulled 1 px by a distractor next to it
// (clean by its quality), a distractor in the remaining camera with one camera occluded, and a tip marker cut by a
// shaft during a fast eye roll with a reversal (rendered).

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <opencv2/imgproc.hpp>

#include "vrm_tracking/evaluation.h"
#include "vrm_tracking/pose_tracker.h"

namespace vrm_tracking {
namespace {

constexpr double kRate = 50.0;

Blob blobAt(const CameraModel& camera, const Eigen::Vector3d& p, int class_id, double du = 0.0, double dv = 0.0) {
  Eigen::Vector2d px;
  EXPECT_TRUE(camera.project(p, &px));
  Blob b;
  b.class_id = class_id;
  b.u = px.x() + du;
  b.v = px.y() + dv;
  b.quality = 0.9;
  return b;
}

// A tip marker moving at 10 mm/s through the vitreous.
Eigen::Vector3d tipAt(const MarkerLayout& layout, int frame) {
  return layout.rotation_center + Eigen::Vector3d(0.002, 0.001 + 0.010 * frame / kRate, -0.006);
}

// Five frames with every camera seeing the marker: the tracker's prediction of frame 5.
void warmUp(PoseTracker* tracker, const CameraRig& rig, const MarkerLayout& layout, int cls,
            const std::vector<std::size_t>& cameras) {
  for (int f = 0; f < 5; ++f) {
    std::vector<CameraObservations> frame;
    for (std::size_t c : cameras) frame.push_back({c, {blobAt(rig.cameras[c], tipAt(layout, f), cls)}});
    ASSERT_TRUE(tracker->update(frame, f / kRate).markers[cls].valid);
  }
}

TEST(MarkerConsistency, DistractorOnTheEpipolarLineOfTheOnlyPairIsNotTaken) {
  const CameraRig rig = makeDefaultRig();
  const MarkerLayout layout = makeDefaultLayout();
  const int cls = layout.instruments[0].class_id;
  PoseTracker tracker(rig, layout);
  warmUp(&tracker, rig, layout, cls, {0, 1, 2});
  // Frame 5: camera 0 misses the marker (hidden), camera 1 sees only a distractor of its colour that lies on the
  // epipolar line of camera 2's true blob, 3.5 mm along camera 2's ray: the pair 1-2 meets exactly, 3.5 mm off.
  const Eigen::Vector3d p = tipAt(layout, 5);
  const Eigen::Vector3d ray = (p - rig.cameras[2].centreInWorld()).normalized();
  const Eigen::Vector3d ghost = p + 0.0035 * ray;
  const std::vector<CameraObservations> frame = {{1, {blobAt(rig.cameras[1], ghost, cls)}},
                                                 {2, {blobAt(rig.cameras[2], p, cls)}}};
  const MarkerEstimate m = tracker.update(frame, 5 / kRate).markers[cls];
  // Not seen this frame is right (the instrument holds its last pose); a position 3.5 mm off is not.
  if (m.valid) EXPECT_LT((m.position - p).norm(), 60e-6);
  // The same frame without the history: nothing tells the ghost from the marker, so it is taken (the test's premise).
  const MarkerEstimate fresh = PoseTracker(rig, layout).reconstruct(cls, frame);
  ASSERT_TRUE(fresh.valid);
  EXPECT_GT((fresh.position - p).norm(), 3e-3);
}

TEST(MarkerConsistency, BlobPulledByADistractorNextToItIsOutvotedByTheOtherTwo) {
  const CameraRig rig = makeDefaultRig();
  const MarkerLayout layout = makeDefaultLayout();
  const int cls = layout.instruments[1].class_id;
  const Eigen::Vector3d p = tipAt(layout, 0);
  // Camera 1's blob has merged with a small distractor just beside the marker: its centroid moves 1 px, its quality
  // stays that of a clean blob (round, bright, nothing coloured around the merged blob), so quality tiering cannot
  // see it. The three rays then miss each other by ~0.4 px: within the loose 3 px gate, not within consistent_px.
  std::vector<CameraObservations> frame;
  for (std::size_t c = 0; c < rig.size(); ++c) {
    frame.push_back({c, {blobAt(rig.cameras[c], p, cls, c == 1 ? 0.7 : 0.0, c == 1 ? 0.7 : 0.0)}});
  }
  const MarkerEstimate m = PoseTracker(rig, layout).reconstruct(cls, frame);
  ASSERT_TRUE(m.valid);
  EXPECT_EQ(m.cameras, 2);
  EXPECT_LT((m.position - p).norm(), 1e-6);
}

TEST(MarkerConsistency, OneCameraOccludedTheRemainingPairTakesTheCandidateNearestThePrediction) {
  const CameraRig rig = makeDefaultRig();
  const MarkerLayout layout = makeDefaultLayout();
  const int cls = layout.instruments[0].class_id;
  PoseTracker tracker(rig, layout);
  warmUp(&tracker, rig, layout, cls, {0, 1});  // camera 2 occluded throughout
  // Frame 5: camera 1 reports the marker (0.05 px of centroid noise) and, listed first and as clean, a distractor of
  // its colour on camera 0's epipolar line 1.5 mm away, which meets camera 0's ray exactly: the lower residual.
  const Eigen::Vector3d p = tipAt(layout, 5);
  const Eigen::Vector3d ray = (p - rig.cameras[0].centreInWorld()).normalized();
  const std::vector<CameraObservations> frame = {
      {0, {blobAt(rig.cameras[0], p, cls)}},
      {1, {blobAt(rig.cameras[1], p + 0.0015 * ray, cls), blobAt(rig.cameras[1], p, cls, 0.05, -0.05)}}};
  const MarkerEstimate m = tracker.update(frame, 5 / kRate).markers[cls];
  ASSERT_TRUE(m.valid);
  EXPECT_EQ(m.cameras, 2);
  EXPECT_LT((m.position - p).norm(), 15e-6);
}

TEST(MarkerConsistency, OneCameraOccludedAPairWithAShaftCutBlobIsNotTaken) {
  const CameraRig rig = makeDefaultRig();
  const MarkerLayout layout = makeDefaultLayout();
  const int cls = layout.instruments[1].class_id;
  PoseTracker tracker(rig, layout);
  warmUp(&tracker, rig, layout, cls, {0, 1});  // camera 2 occluded throughout
  // Frame 5: a shaft crosses the marker in camera 1: the blob is flagged (a third of its ring coloured) and its
  // centroid has moved 1 px along the epipolar line of camera 0's blob, so the pair still meets exactly, ~0.1 mm off.
  const Eigen::Vector3d p = tipAt(layout, 5);
  const Eigen::Vector3d ray = (p - rig.cameras[0].centreInWorld()).normalized();
  Blob cut = blobAt(rig.cameras[1], p + 0.0001 * ray, cls);
  cut.contamination = 0.3;
  const std::vector<CameraObservations> frame = {{0, {blobAt(rig.cameras[0], p, cls)}}, {1, {cut}}};
  const MarkerEstimate m = tracker.update(frame, 5 / kRate).markers[cls];
  if (m.valid) EXPECT_LT((m.position - p).norm(), 15e-6);
}

TEST(MarkerConsistency, CameraStoppedAfterACleanThreeCameraHistoryThePairsOfRealBlobsAreTaken) {
  // camera_dropout.test: a camera stops after seconds of three-camera tracking. The remaining pair's residuals are a
  // pair's, not the three cameras': rendered at 640x480 the pairs of the real marker blobs reach 0.49 px on the
  // built-in demo and 0.55 px on the random fast trajectory 4304 (a shaft cutting the blob in one camera), against
  // ~0.02 px for three cameras. A pair threshold taken from the three-camera noise (0.25 px) dropped such frames:
  // 5-24 % of the frames of the stopped camera in the graph test. Here camera 1's blob is 1 px off the epipolar line
  // of camera 0's (a pair residual of ~0.5 px) in every frame after camera 2 stops.
  const CameraRig rig = makeDefaultRig();
  const MarkerLayout layout = makeDefaultLayout();
  const int cls = layout.instruments[0].class_id;
  PoseTracker tracker(rig, layout);
  auto at = [&layout](int f) -> Eigen::Vector3d {  // 10 mm/s about a point: 70 frames stay in the vitreous
    const double a = 2.0 * M_PI * f / 60.0;
    return layout.rotation_center + Eigen::Vector3d(0.002 + 0.0019 * std::cos(a), 0.0019 * std::sin(a), -0.006);
  };
  for (int f = 0; f < 50; ++f) {
    std::vector<CameraObservations> frame;
    for (std::size_t c : {0, 1, 2}) frame.push_back({c, {blobAt(rig.cameras[c], at(f), cls)}});
    ASSERT_TRUE(tracker.update(frame, f / kRate).markers[cls].valid);
  }
  EXPECT_EQ(tracker.consistentPx(), TrackerConfig().consistent_px);  // a clean history: the floor
  int valid = 0;
  for (int f = 50; f < 70; ++f) {
    const Eigen::Vector3d p = at(f);
    const Eigen::Vector3d ray = (p - rig.cameras[0].centreInWorld()).normalized();
    Eigen::Vector2d a, b;
    ASSERT_TRUE(rig.cameras[1].project(p, &a) && rig.cameras[1].project(p + 0.001 * ray, &b));
    const Eigen::Vector2d across = Eigen::Vector2d(a.y() - b.y(), b.x() - a.x()).normalized();  // off the line
    const std::vector<CameraObservations> frame = {{0, {blobAt(rig.cameras[0], p, cls)}},
                                                   {1, {blobAt(rig.cameras[1], p, cls, across.x(), across.y())}}};
    const double residual = triangulate(rig, {{0, Eigen::Vector2d(frame[0].blobs[0].u, frame[0].blobs[0].v)},
                                              {1, Eigen::Vector2d(frame[1].blobs[0].u, frame[1].blobs[0].v)}})
                                .max_px;
    EXPECT_GT(residual, 0.4);
    EXPECT_LT(residual, 0.6);
    const MarkerEstimate m = tracker.update(frame, f / kRate).markers[cls];
    if (!m.valid) continue;
    ++valid;
    EXPECT_EQ(m.cameras, 2);
    EXPECT_LT((m.position - p).norm(), 60e-6);  // the pair's own solution: ~50 um for 1 px across its epipolar line
  }
  EXPECT_EQ(valid, 20) << "frames of the remaining pair taken";
}

TEST(MarkerConsistency, ThresholdFollowsTheCentroidNoiseSoNoisyRigsKeepThreeCameras) {
  // 0.3 px of centroid noise (the FPGA path of the benchmark): three-camera residuals are often above 0.25 px, so
  // the threshold must follow the measured noise, or the tracker would fall back to pairs (~1.3x the error).
  const CameraRig rig = makeDefaultRig();
  const MarkerLayout layout = makeDefaultLayout();
  const auto truth = circlingSurgeon(layout, 0.010);
  std::vector<double> times;
  for (int f = 0; f < 200; ++f) times.push_back(f / kRate);
  EvalOptions opt;
  opt.noise_px = 0.3;
  opt.seed = 13;
  const EvalResult r = evaluate(rig, layout, truth, times, opt);
  std::vector<Eigen::Vector3d> points;
  for (std::size_t i = 0; i < times.size(); i += 10) {
    const SurgeonSnapshot s = truth(times[i]);
    for (const InstrumentSample& inst : s.instruments) points.push_back(s.rotation_center + s.eye_rotation * inst.tip);
  }
  const double floor = idealFloorUm(rig, points, 0.3, {0, 1, 2}, 50, 99);
  EXPECT_LT(r.tip_rms_um, 1.1 * floor);
  EXPECT_EQ(r.track_rate, 1.0);
}

TEST(MarkerConsistency, RenderedDistractorTouchingATipMarker) {
  // Rendered cameras (the rig twin), the right tip 2 mm from the left one; in camera 1 a small distractor of the tip's
  // colour touches the marker's disc, so the detector returns one merged blob whose centroid is pulled towards it.
  const CameraRig rig = makeDefaultRig();
  const MarkerLayout layout = makeDefaultLayout();
  const int cls = layout.instruments[1].class_id;
  const WorldScene scene = worldSceneFromSnapshot(circlingSurgeon(layout, 0.0)(0.0), layout);
  RenderConfig render;
  render.seed = 43;
  const RigRenderer renderer(rig, layout, render);
  const MarkerDetector detector(layout.classes);
  const ColourClass& colour = layout.classes[cls];
  std::vector<CameraObservations> frame;
  Eigen::Vector3d truth = Eigen::Vector3d::Zero();
  for (const WorldMarker& m : scene.markers) {
    if (m.class_id == cls) truth = m.position;
  }
  for (std::size_t c = 0; c < rig.size(); ++c) {
    cv::Mat image;
    std::vector<ProjectedMarker> projected;
    renderer.render(c, scene, 0, &image, &projected);
    for (const ProjectedMarker& p : projected) {
      if (c != 1 || p.class_id != cls) continue;
      ASSERT_TRUE(p.visible);
      const cv::Point at(static_cast<int>(std::lround(p.pixel.x() + p.radius_px + 1.0)),
                         static_cast<int>(std::lround(p.pixel.y())));
      cv::circle(image, at, 2, cv::Scalar(colour.bgr[0], colour.bgr[1], colour.bgr[2]), cv::FILLED, cv::LINE_AA);
    }
    frame.push_back({c, detector.detect(image)});
  }
  const MarkerEstimate m = PoseTracker(rig, layout).reconstruct(cls, frame);
  ASSERT_TRUE(m.valid);
  std::printf("merged blob in camera 1: %d cameras, %.1f um off\n", m.cameras, 1e6 * (m.position - truth).norm());
  EXPECT_LT((m.position - truth).norm(), 15e-6);
}

TEST(MarkerConsistency, FastEyeRollWithReversalsAndTipsTurningAtTheirTopSpeed) {
  // Random fast trajectory 4304 of the benchmark (randomFastSurgeon: the eye up to 1 rad/s with reversals, the tips
  // up to 60 mm/s with abrupt turns near the posterior pole), its last 0.6 s (30 rendered frames): the right tip's
  // blob in camera 1 is cut by a shaft there (centroid ~1 px off), which the loose gate takes into a three-camera
  // solution: 35 µm off over these frames with the earlier rule, 16 µm now.
  const CameraRig rig = makeDefaultRig();
  const MarkerLayout layout = makeDefaultLayout();
  const auto truth = randomFastSurgeon(layout, 4304);
  std::vector<double> times;
  for (int f = 470; f < 500; ++f) times.push_back(f / kRate);
  EvalOptions opt;
  opt.rendered = true;
  opt.seed = 43;
  const EvalResult r = evaluate(rig, layout, truth, times, opt);
  std::printf("random fast 4304, frames 470-499: tip RMS %.2f um, max %.2f um\n", r.tip_rms_um, r.tip_max_um);
  EXPECT_GT(r.track_rate, 0.95);
  EXPECT_LT(r.tip_rms_um, 15.0);
  EXPECT_LT(r.tip_max_um, 30.0);
}

}  // namespace
}  // namespace vrm_tracking
