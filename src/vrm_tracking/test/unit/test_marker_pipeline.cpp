// Renderer → detector → pose tracker: centroids of rendered blobs against the exact projections, distractor
// rejection, ROI tracking with full-frame fallback, and bad input (empty image, wrong encoding, NaN, a camera
// missing).

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <opencv2/imgproc.hpp>
#include <tuple>

#include "vrm_scene/yaml/yaml_error.h"
#include "vrm_tracking/marker_detector.h"
#include "vrm_tracking/pose_tracker.h"
#include "vrm_tracking/rig_renderer.h"

namespace vrm_tracking {
namespace {

SurgeonSnapshot snapshot(double angle, const Eigen::Vector3d& left_tip, const Eigen::Vector3d& right_tip) {
  const MarkerLayout layout = makeDefaultLayout();
  SurgeonSnapshot s;
  s.eye_rotation = Eigen::Quaterniond(Eigen::AngleAxisd(angle, Eigen::Vector3d(1, -1, 0).normalized()));
  for (const auto& [slot, tip] :
       {std::make_pair(std::string("left"), left_tip), std::make_pair(std::string("right"), right_tip)}) {
    InstrumentSample i;
    i.slot = slot;
    i.trocar = layout.findSlot(slot)->trocar;
    i.tip = tip;
    i.shaft_axis = (tip - i.trocar).normalized();
    i.insertion_depth = (tip - i.trocar).norm();
    s.instruments.push_back(i);
  }
  return s;
}

class Pipeline : public testing::Test {
 protected:
  Pipeline()
      : rig_(makeDefaultRig()),
        layout_(makeDefaultLayout()),
        detector_(layout_.classes),
        snap_(snapshot(0.05, Eigen::Vector3d(-0.002, 0.001, -0.005), Eigen::Vector3d(0.003, -0.002, -0.008))),
        scene_(worldSceneFromSnapshot(snap_, layout_)) {}

  RenderConfig quiet() const {
    RenderConfig c;
    c.read_noise = 0.0;
    c.shot_gain = 0.0;
    return c;
  }

  CameraRig rig_;
  MarkerLayout layout_;
  MarkerDetector detector_;
  SurgeonSnapshot snap_;
  WorldScene scene_;
};

TEST_F(Pipeline, CentroidsOfNoiselessRenderingsAreSubPixelExact) {
  RigRenderer renderer(rig_, layout_, quiet());
  for (std::size_t c = 0; c < rig_.size(); ++c) {
    cv::Mat image;
    std::vector<ProjectedMarker> truth;
    renderer.render(c, scene_, 0, &image, &truth);
    const std::vector<Blob> blobs = detector_.detect(image);
    for (const ProjectedMarker& t : truth) {
      if (!t.visible) continue;
      int matches = 0;
      for (const Blob& b : blobs) {
        if (b.class_id != t.class_id) continue;
        ++matches;
        // 8-bit quantisation, the chroma threshold and the tinted background leave a few hundredths of a pixel.
        EXPECT_LT(std::hypot(b.u - t.pixel.x(), b.v - t.pixel.y()), 0.1) << "camera " << c << " class " << t.class_id;
        EXPECT_GT(b.quality, 0.5);
      }
      EXPECT_EQ(matches, 1) << "camera " << c << " class " << t.class_id;
    }
  }
}

// The whole-image search is coarse to fine (MarkerDetector::detect(bgr)): it must find exactly the blobs of the plain
// search over the whole image, with noise, shafts, 12 distractors, markers at the image's edge and a noise image.
TEST_F(Pipeline, CoarseToFineWholeImageSearchFindsTheSameBlobs) {
  RenderConfig config;
  config.distractors = 12;
  RigRenderer renderer(rig_, layout_, config);
  auto key = [](const Blob& b) { return std::make_tuple(b.class_id, b.area, b.u, b.v); };
  auto same = [&](const cv::Mat& image, const std::string& what) {
    std::vector<Blob> fast = detector_.detect(image),
                      plain = detector_.detect(image, cv::Rect(0, 0, image.cols, image.rows));
    auto order = [&](const Blob& a, const Blob& b) { return key(a) < key(b); };
    std::sort(fast.begin(), fast.end(), order);
    std::sort(plain.begin(), plain.end(), order);
    ASSERT_EQ(fast.size(), plain.size()) << what;
    // The moments are summed from each search region's corner, so the last bits of a centroid may differ.
    for (std::size_t i = 0; i < fast.size(); ++i) {
      EXPECT_EQ(fast[i].class_id, plain[i].class_id) << what << " blob " << i;
      EXPECT_EQ(fast[i].area, plain[i].area) << what << " blob " << i;
      EXPECT_NEAR(fast[i].u, plain[i].u, 1e-9) << what << " blob " << i;
      EXPECT_NEAR(fast[i].v, plain[i].v, 1e-9) << what << " blob " << i;
      EXPECT_NEAR(fast[i].quality, plain[i].quality, 1e-9) << what << " blob " << i;
      EXPECT_NEAR(fast[i].roundness, plain[i].roundness, 1e-9) << what << " blob " << i;
      EXPECT_EQ(fast[i].contamination, plain[i].contamination) << what << " blob " << i;
      EXPECT_EQ(fast[i].touches_region_border, plain[i].touches_region_border) << what << " blob " << i;
    }
  };
  int blobs = 0;
  for (std::uint64_t frame = 0; frame < 20; ++frame) {
    const WorldScene scene =
        worldSceneFromSnapshot(snapshot(0.02 * frame, Eigen::Vector3d(-0.002 + 3e-4 * frame, 0.001, -0.005),
                                        Eigen::Vector3d(0.003, -0.002 + 2e-4 * frame, -0.008)),
                               layout_);
    for (std::size_t c = 0; c < rig_.size(); ++c) {
      cv::Mat image;
      renderer.render(c, scene, frame, &image);
      same(image, "camera " + std::to_string(c) + " frame " + std::to_string(frame));
      blobs += static_cast<int>(detector_.detect(image).size());
      // A marker cut by the image's edge, and the image shifted by one pixel (the coarse grid's other phase).
      same(image(cv::Rect(image.cols / 3, 0, image.cols - image.cols / 3, image.rows)).clone(), "cropped");
      same(image(cv::Rect(1, 1, image.cols - 1, image.rows - 1)).clone(), "shifted");
    }
  }
  EXPECT_GT(blobs, 20 * 3 * 4);  // the markers and the distractors that match a class
  cv::Mat noise(97, 131, CV_8UC3);
  cv::randu(noise, 0, 256);
  same(noise, "uniform noise");
  EXPECT_TRUE(detector_.detect(cv::Mat()).empty());
  EXPECT_THROW(detector_.detect(cv::Mat(4, 4, CV_8UC1, cv::Scalar(0))), std::invalid_argument);
}

TEST_F(Pipeline, RenderedFramesTrackWithinTensOfMicrometres) {
  RenderConfig config;  // default noise, blur, clutter, shafts
  RigRenderer renderer(rig_, layout_, config);
  PoseTracker tracker(rig_, layout_);
  std::vector<CameraObservations> frame;
  for (std::size_t c = 0; c < rig_.size(); ++c) {
    cv::Mat image;
    renderer.render(c, scene_, 3, &image);
    frame.push_back({c, detector_.detect(image)});
  }
  const TrackingResult r = tracker.update(frame);
  ASSERT_TRUE(r.eye.valid);
  EXPECT_LT(r.eye.rotation.angularDistance(snap_.eye_rotation) * 180.0 / M_PI, 0.5);
  ASSERT_EQ(r.instruments.size(), 2u);
  for (std::size_t i = 0; i < 2; ++i) {
    ASSERT_TRUE(r.instruments[i].valid) << r.instruments[i].slot;
    EXPECT_LT((r.instruments[i].tip - snap_.instruments[i].tip).norm(), 60e-6) << r.instruments[i].slot;
    EXPECT_LT((r.instruments[i].shaft_axis - snap_.instruments[i].shaft_axis).norm(), 0.05);
  }
}

TEST_F(Pipeline, ExactCentroidsGiveExactPoses) {
  // The FPGA path with perfect centroids: projected → reconstructed exactly.
  RigRenderer renderer(rig_, layout_, quiet());
  PoseTracker tracker(rig_, layout_);
  std::vector<CameraObservations> frame;
  for (std::size_t c = 0; c < rig_.size(); ++c) {
    CameraObservations obs{c, {}};
    for (const ProjectedMarker& p : renderer.project(c, scene_)) {
      Blob b;
      b.class_id = p.class_id;
      b.u = p.pixel.x();
      b.v = p.pixel.y();
      obs.blobs.push_back(b);
    }
    frame.push_back(obs);
  }
  const TrackingResult r = tracker.update(frame);
  ASSERT_TRUE(r.eye.valid);
  EXPECT_LT(r.eye.rotation.angularDistance(snap_.eye_rotation), 1e-9);
  for (std::size_t i = 0; i < 2; ++i) {
    ASSERT_TRUE(r.instruments[i].valid);
    EXPECT_LT((r.instruments[i].tip - snap_.instruments[i].tip).norm(), 1e-9);
    EXPECT_NEAR(r.instruments[i].insertion_depth, snap_.instruments[i].insertion_depth, 1e-9);
  }
  for (const MarkerEstimate& m : r.markers) EXPECT_EQ(m.cameras, 3);

  // One camera missing: two-camera fallback, still exact.
  frame.erase(frame.begin() + 1);
  const TrackingResult two = tracker.update(frame);
  ASSERT_TRUE(two.instruments[0].valid);
  EXPECT_LT((two.instruments[0].tip - snap_.instruments[0].tip).norm(), 1e-9);
  for (const MarkerEstimate& m : two.markers) EXPECT_EQ(m.cameras, 2);

  // Only one camera: nothing valid, the eye rotation and the instrument poses are held from the last valid frame
  // (issue 14: the VR part keeps them where they were and stops their interaction), with quality 0.
  frame.resize(1);
  const TrackingResult one = tracker.update(frame);
  EXPECT_FALSE(one.eye.valid);
  EXPECT_LT(one.eye.rotation.angularDistance(snap_.eye_rotation), 1e-9);
  for (std::size_t i = 0; i < 2; ++i) {
    EXPECT_FALSE(one.instruments[i].valid);
    EXPECT_EQ(one.instruments[i].quality, 0.0);
    EXPECT_EQ(one.instruments[i].tip, two.instruments[i].tip);
    EXPECT_EQ(one.instruments[i].shaft_axis, two.instruments[i].shaft_axis);
    EXPECT_EQ(one.instruments[i].insertion_depth, two.instruments[i].insertion_depth);
  }
  // No camera at all: still the held poses; after reset() nothing is held.
  EXPECT_EQ(tracker.update({}).instruments[1].tip, two.instruments[1].tip);
  tracker.reset();
  EXPECT_EQ(tracker.update({}).instruments[1].tip, Eigen::Vector3d::Zero());
}

TEST_F(Pipeline, DistractorsAreRejectedOrOutvoted) {
  RenderConfig config;
  config.distractors = 12;
  RigRenderer renderer(rig_, layout_, config);
  PoseTracker tracker(rig_, layout_);
  for (std::uint64_t frame_index = 0; frame_index < 5; ++frame_index) {
    std::vector<CameraObservations> frame;
    for (std::size_t c = 0; c < rig_.size(); ++c) {
      cv::Mat image;
      renderer.render(c, scene_, frame_index, &image);
      frame.push_back({c, detector_.detect(image)});
    }
    const TrackingResult r = tracker.update(frame);
    for (std::size_t i = 0; i < 2; ++i) {
      ASSERT_TRUE(r.instruments[i].valid) << "frame " << frame_index;
      EXPECT_LT((r.instruments[i].tip - snap_.instruments[i].tip).norm(), 80e-6) << "frame " << frame_index;
    }
  }
}

TEST_F(Pipeline, RoiTrackerMatchesFullFrameAndFallsBack) {
  RigRenderer renderer(rig_, layout_, quiet());
  RoiTracker roi(&detector_, RoiTrackerConfig());
  cv::Mat image;
  renderer.render(0, scene_, 0, &image);
  DetectionStats stats;
  const std::vector<Blob> first = roi.process(image, &stats);
  EXPECT_TRUE(stats.full_frame);  // nothing predicted yet
  const std::vector<Blob> second = roi.process(image, &stats);
  EXPECT_FALSE(stats.full_frame);
  EXPECT_EQ(stats.found_classes, 4);
  ASSERT_EQ(first.size(), second.size());
  for (std::size_t i = 0; i < first.size(); ++i) {
    bool same = false;
    for (const Blob& b : second)
      same |= b.class_id == first[i].class_id && std::hypot(b.u - first[i].u, b.v - first[i].v) < 1e-9;
    EXPECT_TRUE(same);
  }
  // A jump far outside the window: the full-frame fallback finds the markers again.
  WorldScene moved = scene_;
  for (WorldMarker& m : moved.markers) m.position += Eigen::Vector3d(0.006, 0.0, 0.0);
  cv::Mat jumped;
  renderer.render(0, moved, 1, &jumped);
  const std::vector<Blob> third = roi.process(jumped, &stats);
  EXPECT_TRUE(stats.full_frame);
  EXPECT_EQ(stats.found_classes, 4);
}

TEST_F(Pipeline, BadImagesAreHandled) {
  EXPECT_TRUE(detector_.detect(cv::Mat()).empty());  // empty image: no blobs, no throw
  EXPECT_THROW(detector_.detect(cv::Mat(480, 640, CV_8UC1, cv::Scalar(0))), std::invalid_argument);
  EXPECT_THROW(detector_.detect(cv::Mat(480, 640, CV_16UC3, cv::Scalar(0))), std::invalid_argument);
  // Uniform and saturated images: nothing to find.
  EXPECT_TRUE(detector_.detect(cv::Mat(480, 640, CV_8UC3, cv::Scalar(255, 255, 255))).empty());
  EXPECT_TRUE(detector_.detect(cv::Mat(480, 640, CV_8UC3, cv::Scalar(0, 0, 0))).empty());
  // A region outside the image.
  cv::Mat image(480, 640, CV_8UC3, cv::Scalar(40, 40, 40));
  EXPECT_TRUE(detector_.detect(image, cv::Rect(700, 500, 20, 20)).empty());
  // NaN centroids in pre-extracted observations are ignored.
  PoseTracker tracker(rig_, layout_);
  Blob nan;
  nan.u = std::numeric_limits<double>::quiet_NaN();
  const TrackingResult r = tracker.update({{0, {nan}}, {1, {nan}}, {9, {nan}}});
  EXPECT_FALSE(r.eye.valid);
}

TEST(MarkerDetector, ClassifiesTheLayoutColours) {
  const MarkerLayout layout = makeDefaultLayout();
  const MarkerDetector detector(layout.classes);
  for (const ColourClass& c : layout.classes)
    EXPECT_EQ(detector.classify(c.bgr[0], c.bgr[1], c.bgr[2]), c.id) << c.name;
  EXPECT_EQ(detector.classify(220, 40, 220), -1);  // magenta distractor
  EXPECT_EQ(detector.classify(90, 92, 95), -1);    // grey
}

TEST(MarkerLayout, YamlOverridesAndErrors) {
  const MarkerLayout l = layoutFromYamlString(R"(
eye_markers:
  - {class: eye_a, position: [0.01, 0, -0.005]}
  - {class: eye_b, position: [0, 0.01, -0.005]}
instruments:
  - {slot: only, class: tip_right, trocar: [0, 0.008, 0.008]}
)");
  ASSERT_EQ(l.instruments.size(), 1u);
  EXPECT_EQ(l.instruments[0].class_id, 3);
  EXPECT_THROW(layoutFromYamlString("instruments:\n  - {slot: x, class: nope, trocar: [0, 0, 0]}"), std::runtime_error);
  EXPECT_THROW(layoutFromYamlString("eye_markers:\n  - {class: eye_a, position: [0, 0, 0]}"), std::runtime_error);
}

// The strict reader's contract (vrm_scene/yaml/strict_reader.h), as for scenes: file:line:col, the field, a typo hint;
// a key the format does not have is an error (a layout that relied on one being ignored now names it).
std::string layoutError(const std::string& text) {
  try {
    layoutFromYamlString(text, "layout.yaml");
  } catch (const vrm_sim::YamlError& error) {
    return error.what();
  }
  return "no error";
}

TEST(MarkerLayout, StrictReaderNamesFileLineColumnAndTypos) {
  EXPECT_EQ(layoutError("eye_marker_radius: 0.0005\ntip_marker_radus: 0.0004\n"),
            "layout.yaml:2:1: tip_marker_radus: unknown key (did you mean 'tip_marker_radius'?); allowed keys: "
            "classes, eye_markers, instruments, rotation_center, eye_marker_radius, tip_marker_radius, shaft_radius, "
            "shaft_length");
  EXPECT_EQ(layoutError("instruments:\n  - {slot: left, class: tip_lft}\n"),
            "layout.yaml:2:25: instruments[0].class: expected one of eye_a, eye_b, tip_left, tip_right, got "
            "'tip_lft' (did you mean 'tip_left'?)");
  EXPECT_EQ(layoutError("instruments:\n  - {slot: left, class: tip_left, colour: green}\n"),
            "layout.yaml:2:35: instruments[0].colour: unknown key; allowed keys: slot, class, trocar");
  EXPECT_EQ(layoutError("instruments:\n  - {slot: left, class: tip_left}\n  - {slot: left, class: tip_right}\n"),
            "layout.yaml:3:5: instruments[1]: a second marker for slot 'left'");
  EXPECT_EQ(layoutError("eye_marker_radius: -1\n"),
            "layout.yaml:1:20: eye_marker_radius: expected a positive number, got '-1'");
  EXPECT_EQ(layoutError("rotation_center: [0, 0, .nan]\n"),
            "layout.yaml:1:25: rotation_center[2]: expected a finite number, got '.nan'");
  EXPECT_EQ(layoutError("classes: [{name: a, area_min: 10, area_max: 5}]\n"),
            "layout.yaml:1:11: classes[0]: area_max must be larger than area_min");
  EXPECT_EQ(layoutError("classes: [{name: a}]\n"),
            "layout.yaml:1:1: the default eye markers' classes are gone: give eye_markers too");
  EXPECT_NE(
      layoutError("eye_markers: [{class: eye_a, position: [0, 0, 1]\n").find("layout.yaml:2:1: YAML syntax error"),
      std::string::npos)
      << layoutError("eye_markers: [{class: eye_a, position: [0, 0, 1]\n");
  EXPECT_THROW(loadLayoutYaml("/nonexistent/layout.yaml"), vrm_sim::YamlError);
}

TEST(MarkerLayout, ShippedConfigIsTheDefaultLayout) {
  const MarkerLayout file = loadLayoutYaml(std::string(VRM_TRACKING_SOURCE_DIR) + "/config/markers_default.yaml");
  const MarkerLayout def = makeDefaultLayout();
  ASSERT_EQ(file.classes.size(), def.classes.size());
  for (std::size_t i = 0; i < def.classes.size(); ++i) {
    EXPECT_EQ(file.classes[i].name, def.classes[i].name);
    EXPECT_EQ(file.classes[i].bgr, def.classes[i].bgr);
    EXPECT_EQ(file.classes[i].h_min, def.classes[i].h_min);
    EXPECT_EQ(file.classes[i].h_max, def.classes[i].h_max);
  }
  ASSERT_EQ(file.eye_markers.size(), 2u);
  for (std::size_t i = 0; i < 2; ++i) {
    EXPECT_LT((file.eye_markers[i].position - def.eye_markers[i].position).norm(), 1e-15);
  }
  ASSERT_EQ(file.instruments.size(), def.instruments.size());
  for (std::size_t i = 0; i < def.instruments.size(); ++i) {
    EXPECT_EQ(file.instruments[i].slot, def.instruments[i].slot);
    EXPECT_EQ(file.instruments[i].class_id, def.instruments[i].class_id);
    // The file leaves the trocars to the scene (test_scene_trocars checks the nodelets' default scene gives them).
    EXPECT_TRUE(file.instruments[i].trocar_from_scene);
    EXPECT_FALSE(def.instruments[i].trocar_from_scene);
  }
  // Until a scene filled them in, a tracker refuses the layout (it would pivot the shafts at the eye centre).
  EXPECT_THROW(PoseTracker(makeDefaultRig(), file), std::invalid_argument);
}

}  // namespace
}  // namespace vrm_tracking
