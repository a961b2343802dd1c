// The rig twin's span renderer against its reference (issue 30 item 4): without noise both draw the same image;
// with noise the untouched background has the same mean and σ, no correlation between frames or neighbours, the
// markers the same centroids; determinism per (seed, camera, frame); hard cases (a marker cut by the image edge,
// one half hidden by a shaft, fast motion blur, a non-finite pose) agree between the paths.

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <opencv2/core.hpp>

#include "vrm_tracking/marker_detector.h"
#include "vrm_tracking/rig_renderer.h"

namespace vrm_tracking {
namespace {

class RendererPaths : public testing::Test {
 protected:
  RendererPaths() : rig_(makeDefaultRig()), layout_(makeDefaultLayout()), detector_(layout_.classes) {}

  RenderConfig config(bool reference, bool noise = true) const {
    RenderConfig c;
    c.reference_path = reference;
    if (!noise) {
      c.read_noise = 0.0;
      c.shot_gain = 0.0;
    }
    return c;
  }

  // A world point that camera `c` sees at pixel (u, v), `depth` metres in front of it (the default rig has no
  // distortion).
  Eigen::Vector3d worldAt(std::size_t c, double u, double v, double depth) const {
    const CameraModel& cam = rig_.cameras[c];
    const Eigen::Vector3d p((u - cam.K(0, 2)) / cam.K(0, 0) * depth, (v - cam.K(1, 2)) / cam.K(1, 1) * depth, depth);
    return cam.world_to_camera.inverse() * p;
  }

  WorldMarker marker(std::size_t c, double u, double v, int class_index = 0) const {
    WorldMarker m;
    m.class_id = layout_.classes.at(class_index).id;
    m.position = worldAt(c, u, v, 0.1);
    m.radius = 0.0005;
    return m;
  }

  // Largest per-byte difference of two images inside `region`, and the fraction of bytes that differ by more
  // than one DN.
  static std::pair<int, double> difference(const cv::Mat& a, const cv::Mat& b, cv::Rect region) {
    region &= cv::Rect(0, 0, a.cols, a.rows);
    int worst = 0;
    long over = 0, n = 0;
    for (int y = region.y; y < region.br().y; ++y) {
      const std::uint8_t* pa = a.ptr<std::uint8_t>(y) + 3 * region.x;
      const std::uint8_t* pb = b.ptr<std::uint8_t>(y) + 3 * region.x;
      for (int i = 0; i < 3 * region.width; ++i, ++n) {
        const int d = std::abs(pa[i] - pb[i]);
        worst = std::max(worst, d);
        over += d > 1;
      }
    }
    return {worst, n ? static_cast<double>(over) / n : 0.0};
  }

  CameraRig rig_;
  MarkerLayout layout_;
  MarkerDetector detector_;
};

// Without noise the two paths differ only by the coverage table (< 1e-6 of full coverage) and the reach of the
// boxes (coverage < 5e-6 beyond the reference's): at most 1 DN where a value sits on a rounding edge.
TEST_F(RendererPaths, NoiselessImagesAgreeWithTheReference) {
  const RigRenderer reference(rig_, layout_, config(true, false)), spans(rig_, layout_, config(false, false));
  for (std::size_t c = 0; c < rig_.size(); ++c) {
    WorldScene scene;
    scene.markers = {marker(c, 320.3, 240.6, 0), marker(c, 120.7, 400.2, 1), marker(c, 500.1, 90.9, 2)};
    scene.markers[1].velocity = Eigen::Vector3d(0.02, -0.01, 0.0);
    WorldSegment shaft;
    shaft.a = worldAt(c, 50, 60, 0.095);
    shaft.b = worldAt(c, 600, 300, 0.098);
    scene.shafts = {shaft};
    cv::Mat a, b;
    std::vector<ProjectedMarker> ta, tb;
    reference.render(c, scene, 7, &a, &ta);
    spans.render(c, scene, 7, &b, &tb);
    const auto [worst, over] = difference(a, b, cv::Rect(0, 0, a.cols, a.rows));
    EXPECT_LE(worst, 1) << "camera " << c;
    EXPECT_EQ(over, 0.0) << "camera " << c;
    ASSERT_EQ(ta.size(), tb.size());
    for (std::size_t i = 0; i < ta.size(); ++i) EXPECT_EQ(ta[i].visible, tb[i].visible);
    const std::vector<Blob> ba = detector_.detect(a), bb = detector_.detect(b);
    ASSERT_EQ(ba.size(), bb.size()) << "camera " << c;
    for (std::size_t i = 0; i < ba.size(); ++i) {
      EXPECT_EQ(ba[i].class_id, bb[i].class_id);
      EXPECT_NEAR(ba[i].u, bb[i].u, 0.005);
      EXPECT_NEAR(ba[i].v, bb[i].v, 0.005);
      EXPECT_NEAR(ba[i].area, bb[i].area, 2.0);
    }
  }
}

// Residual of a flat-background frame (no clutter: every row has one level per channel) against its row means.
std::vector<double> residual(const cv::Mat& image) {
  std::vector<double> r;
  r.reserve(image.total() * 3);
  for (int y = 0; y < image.rows; ++y) {
    const std::uint8_t* p = image.ptr<std::uint8_t>(y);
    double mean[3] = {0, 0, 0};
    for (int x = 0; x < image.cols; ++x)
      for (int ch = 0; ch < 3; ++ch) mean[ch] += p[3 * x + ch];
    for (double& m : mean) m /= image.cols;
    for (int x = 0; x < image.cols; ++x)
      for (int ch = 0; ch < 3; ++ch) r.push_back(p[3 * x + ch] - mean[ch]);
  }
  return r;
}

double correlation(const std::vector<double>& a, const std::vector<double>& b, std::size_t shift = 0) {
  double ab = 0, aa = 0, bb = 0;
  for (std::size_t i = 0; i + shift < a.size(); ++i) {
    ab += a[i] * b[i + shift];
    aa += a[i] * a[i];
    bb += b[i + shift] * b[i + shift];
  }
  return ab / std::sqrt(aa * bb);
}

double stddev(const std::vector<double>& v) {
  double s = 0, s2 = 0;
  for (double x : v) {
    s += x;
    s2 += x * x;
  }
  return std::sqrt(s2 / v.size() - (s / v.size()) * (s / v.size()));
}

TEST_F(RendererPaths, BackgroundNoiseHasTheReferenceStatisticsAndNoFixedPattern) {
  for (const auto& [read_noise, shot_gain] : {std::make_pair(2.0, 0.05), std::make_pair(6.0, 0.2)}) {
    RenderConfig ref = config(true), fast = config(false);
    for (RenderConfig* c : {&ref, &fast}) {
      c->clutter = 0;
      c->read_noise = read_noise;
      c->shot_gain = shot_gain;
    }
    const RigRenderer reference(rig_, layout_, ref), spans(rig_, layout_, fast);
    const WorldScene empty;
    cv::Mat image;
    std::vector<std::vector<double>> rs, fs;
    cv::Scalar mean_ref, mean_fast;
    for (std::uint64_t f = 0; f < 4; ++f) {
      reference.render(1, empty, f, &image);
      mean_ref += cv::mean(image);
      rs.push_back(residual(image));
      spans.render(1, empty, f, &image);
      mean_fast += cv::mean(image);
      fs.push_back(residual(image));
    }
    for (int ch = 0; ch < 3; ++ch) EXPECT_NEAR(mean_fast[ch] / 4, mean_ref[ch] / 4, 0.05);
    // σ of read + shot noise at the background levels (31..59 DN): the same within 2 %.
    const double sigma_ref = stddev(rs[0]), sigma_fast = stddev(fs[0]);
    EXPECT_NEAR(sigma_fast / sigma_ref, 1.0, 0.02) << "read noise " << read_noise;
    EXPECT_GT(sigma_fast, read_noise);
    // Consecutive and nearby frames: uncorrelated (921,600 samples: σ of a zero correlation is 0.001).
    for (std::size_t g = 1; g < fs.size(); ++g) EXPECT_LT(std::abs(correlation(fs[0], fs[g])), 0.006) << "frame " << g;
    // Neighbours in a frame: the next channel, pixel and row.
    for (std::size_t shift : {1, 3, 3 * 640}) EXPECT_LT(std::abs(correlation(fs[0], fs[0], shift)), 0.006) << shift;
  }
}

TEST_F(RendererPaths, DeterministicPerSeedCameraAndFrame) {
  RenderConfig c = config(false);
  c.distractors = 6;
  const RigRenderer one(rig_, layout_, c), two(rig_, layout_, c);
  WorldScene scene;
  scene.markers = {marker(0, 300.2, 200.7, 0)};
  cv::Mat a, b, next, other_camera;
  one.render(0, scene, 11, &a);
  two.render(0, scene, 11, &b);
  EXPECT_EQ(cv::norm(a, b, cv::NORM_INF), 0.0);  // bit-identical
  one.render(0, scene, 12, &next);
  one.render(1, scene, 11, &other_camera);
  const auto [worst, over] = difference(a, next, cv::Rect(0, 0, a.cols, a.rows));
  EXPECT_GT(over, 0.3);  // fresh noise: about half the bytes move by more than 1 DN at σ ≈ 2.5
  EXPECT_GT(worst, 5);
  c.seed = 2;
  const RigRenderer reseeded(rig_, layout_, c);
  cv::Mat d;
  reseeded.render(0, scene, 11, &d);
  EXPECT_GT(difference(a, d, cv::Rect(0, 0, a.cols, a.rows)).second, 0.3);
}

TEST_F(RendererPaths, NoisyMarkerCentroidsMatchTheReference) {
  const RigRenderer reference(rig_, layout_, config(true)), spans(rig_, layout_, config(false));
  for (std::size_t c = 0; c < rig_.size(); ++c) {
    WorldScene scene;
    scene.markers = {marker(c, 320.3, 240.6, 0), marker(c, 150.7, 380.2, 1)};
    for (const RigRenderer* r : {&reference, &spans}) {
      double err2 = 0;
      int n = 0;
      for (std::uint64_t f = 0; f < 20; ++f) {
        cv::Mat image;
        std::vector<ProjectedMarker> truth;
        r->render(c, scene, f, &image, &truth);
        for (const Blob& b : detector_.detect(image)) {
          for (const ProjectedMarker& t : truth) {
            if (t.class_id != b.class_id || !t.visible) continue;
            err2 += std::pow(b.u - t.pixel.x(), 2) + std::pow(b.v - t.pixel.y(), 2);
            ++n;
          }
        }
      }
      EXPECT_EQ(n, 40) << "camera " << c;
      EXPECT_LT(std::sqrt(err2 / n), 0.06) << "camera " << c << (r == &spans ? " spans" : " reference");
    }
  }
}

TEST_F(RendererPaths, MarkerCutByTheImageEdge) {
  const RigRenderer reference(rig_, layout_, config(true, false)), spans(rig_, layout_, config(false, false));
  for (const Eigen::Vector2d& px : {Eigen::Vector2d(1.2, 240.0), Eigen::Vector2d(-3.0, 2.0),
                                    Eigen::Vector2d(639.4, 479.6), Eigen::Vector2d(645.0, 100.0)}) {
    WorldScene scene;
    scene.markers = {marker(0, px.x(), px.y(), 1)};
    cv::Mat a, b;
    std::vector<ProjectedMarker> ta, tb;
    reference.render(0, scene, 3, &a, &ta);
    spans.render(0, scene, 3, &b, &tb);
    const auto [worst, over] = difference(a, b, cv::Rect(0, 0, a.cols, a.rows));
    EXPECT_LE(worst, 1) << px.transpose();
    EXPECT_EQ(over, 0.0);
    EXPECT_EQ(ta[0].visible, tb[0].visible);
  }
}

TEST_F(RendererPaths, MarkerHalfHiddenByANearerShaft) {
  const RigRenderer reference(rig_, layout_, config(true, false)), spans(rig_, layout_, config(false, false));
  WorldScene scene;
  scene.markers = {marker(2, 300.0, 250.0, 0)};
  WorldSegment shaft;  // 10 mm nearer the camera, its edge across the marker's centre
  shaft.a = worldAt(2, 200.0, 245.0, 0.09);
  shaft.b = worldAt(2, 420.0, 245.0, 0.09);
  scene.shafts = {shaft};
  cv::Mat a, b;
  std::vector<ProjectedMarker> ta, tb;
  reference.render(2, scene, 5, &a, &ta);
  spans.render(2, scene, 5, &b, &tb);
  const auto [worst, over] = difference(a, b, cv::Rect(180, 220, 260, 60));
  EXPECT_LE(worst, 1);
  EXPECT_EQ(over, 0.0);
  EXPECT_EQ(ta[0].visible, tb[0].visible);
  // The shaft is in front: the marker's lower half only (less area than unoccluded, centroid pushed down).
  const std::vector<Blob> ba = detector_.components(a, cv::Rect(0, 0, a.cols, a.rows)),
                          bb = detector_.components(b, cv::Rect(0, 0, b.cols, b.rows));
  ASSERT_EQ(ba.size(), 1u);
  ASSERT_EQ(bb.size(), 1u);
  EXPECT_GT(bb[0].v, 250.5);
  EXPECT_NEAR(ba[0].u, bb[0].u, 0.01);
  EXPECT_NEAR(ba[0].v, bb[0].v, 0.01);
}

TEST_F(RendererPaths, FastMotionBlurAgrees) {
  const RigRenderer reference(rig_, layout_, config(true, false)), spans(rig_, layout_, config(false, false));
  WorldScene scene;
  scene.markers = {marker(1, 320.0, 240.0, 2)};
  // 0.5 m/s across the view: a 2 mm (~25 px) smear over the 4 ms exposure.
  scene.markers[0].velocity = rig_.cameras[1].world_to_camera.linear().transpose() * Eigen::Vector3d(0.5, 0.1, 0.0);
  cv::Mat a, b;
  reference.render(1, scene, 9, &a);
  spans.render(1, scene, 9, &b);
  const auto [worst, over] = difference(a, b, cv::Rect(0, 0, a.cols, a.rows));
  EXPECT_LE(worst, 1);
  EXPECT_EQ(over, 0.0);
  const std::vector<Blob> ba = detector_.components(a, cv::Rect(0, 0, a.cols, a.rows)),
                          bb = detector_.components(b, cv::Rect(0, 0, b.cols, b.rows));
  ASSERT_EQ(ba.size(), 1u);
  ASSERT_EQ(bb.size(), 1u);
  EXPECT_GT(bb[0].area, 120.0);  // smeared (a still marker: ~80 px)
  EXPECT_NEAR(ba[0].u, bb[0].u, 0.01);
  EXPECT_NEAR(ba[0].v, bb[0].v, 0.01);
}

TEST_F(RendererPaths, NonFinitePoseIsSkippedAsByTheReference) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  for (bool reference_path : {true, false}) {
    const RigRenderer renderer(rig_, layout_, config(reference_path, false));
    WorldScene clean;
    clean.markers = {marker(0, 320.0, 240.0, 0)};
    WorldScene broken = clean;
    WorldMarker bad = marker(0, 200.0, 200.0, 1);
    bad.position.x() = nan;
    broken.markers.push_back(bad);
    WorldMarker smeared = marker(0, 400.0, 300.0, 2);
    smeared.velocity = Eigen::Vector3d(nan, 0, 0);  // every sub-frame position non-finite: not drawn
    broken.markers.push_back(smeared);
    WorldSegment shaft;
    shaft.a = Eigen::Vector3d(nan, 0, 0);
    broken.shafts = {shaft};
    cv::Mat a, b;
    std::vector<ProjectedMarker> truth;
    renderer.render(0, clean, 4, &a);
    ASSERT_NO_THROW(renderer.render(0, broken, 4, &b, &truth));
    EXPECT_EQ(cv::norm(a, b, cv::NORM_INF), 0.0) << (reference_path ? "reference" : "spans");
    ASSERT_EQ(truth.size(), 3u);
    EXPECT_TRUE(truth[0].visible);
    EXPECT_FALSE(truth[1].visible);
  }
}

}  // namespace
}  // namespace vrm_tracking
