#pragma once
// Colour-marker detection (thesis §7.3.2: each marker has a colour class; the EyeSi FPGA computes sub-pixel blob
// centroids per class and sends only those). One fused pass classifies a pixel through a 6-bit-per-channel lookup
// table built from the per-class HSV ranges (no colour conversion of the frame), grows 8-connected components of
// one class, and takes the chroma-weighted centroid: chroma (max − min channel) of a marker blended over a grey
// background is proportional to its coverage, so the weighted centroid is the coverage centroid — sub-pixel and
// unbiased by the symmetric edge blur. Area and roundness reject distractors (streaks, large patches, specks).
// RoiTracker searches a small window around each class's predicted position and falls back to the full frame.

#include <cstdint>
#include <opencv2/core.hpp>
#include <vector>

#include "vrm_tracking/marker_layout.h"

namespace vrm_tracking {

struct Blob {
  int class_id = 0;
  double u = 0.0;  // px, pixel centres at integers
  double v = 0.0;
  double area = 0.0;       // px²
  double roundness = 0.0;  // sqrt(λmin/λmax) of the weighted second moments, 1 = round
  double quality = 0.0;    // 0..1: roundness, exposure (mean chroma), saturation, clean surroundings
  // Fraction of a ring just outside the blob (1.5..3 px beyond its equivalent radius) that is coloured: a marker
  // over a coloured distractor blends with it, so its chroma-weighted centroid is biased (distractor rejection).
  double contamination = 0.0;
  bool touches_region_border = false;
};

class MarkerDetector {
 public:
  explicit MarkerDetector(std::vector<ColourClass> classes);

  // Accepted blobs of every class inside `region` (clipped to the image), best quality first per class.
  // only_class >= 0 restricts to that class. Throws std::invalid_argument unless the image is CV_8UC3 (BGR).
  std::vector<Blob> detect(const cv::Mat& bgr, cv::Rect region, int only_class = -1) const;
  // The whole image, coarse to fine: every second pixel of every second row is classified, and the full-resolution
  // components run only in boxes around what that found (a blob the gate accepts, >= 6 px² and round, always covers
  // one of those pixels). The same blobs as detect(bgr, whole image) at about a third of its cost: a class lost in a
  // camera (a marker merged with a distractor) costs a full-frame pass every few frames.
  std::vector<Blob> detect(const cv::Mat& bgr) const;
  // Components of the colour classes before the area/roundness gate (for diagnostics and tests).
  std::vector<Blob> components(const cv::Mat& bgr, cv::Rect region, int only_class = -1) const;

  // Fraction of coloured pixels on a ring around (u, v) just outside a blob of this equivalent radius.
  double ringContamination(const cv::Mat& bgr, double u, double v, double radius) const;
  // Class of one BGR pixel per the table, or -1.
  int classify(std::uint8_t b, std::uint8_t g, std::uint8_t r) const;
  const std::vector<ColourClass>& classes() const { return classes_; }

 private:
  std::vector<ColourClass> classes_;
  std::vector<std::int8_t> lut_;  // 64³ entries, class index or -1
  int min_chroma_ = 255;          // below it no class can match: skips most background pixels cheaply
};

struct RoiTrackerConfig {
  int roi_half = 20;             // px: window half size around the prediction (a 41×41 search)
  int lost_search_interval = 5;  // frames between full-frame searches for a class not found anywhere
  int max_candidates = 3;        // per class in full-frame mode (the reconstruction picks the consistent one)
  int lost_roi_frames = 25;      // frames a lost class is still searched around its last position (0.5 s at 50 Hz)
  bool use_roi = true;
};

struct DetectionStats {
  bool full_frame = false;  // at least one full-frame pass ran
  int roi_searches = 0;
  int found_classes = 0;
};

// Per-camera detector state: a constant-velocity 2D prediction per class from the last two detections.
class RoiTracker {
 public:
  RoiTracker(const MarkerDetector* detector, RoiTrackerConfig config);
  std::vector<Blob> process(const cv::Mat& bgr, DetectionStats* stats = nullptr);
  void reset();

 private:
  struct ClassState {
    bool valid = false;
    bool has_velocity = false;
    bool seen = false;  // u, v hold a last position
    double u = 0.0, v = 0.0, du = 0.0, dv = 0.0;
    int lost_frames = 0;
  };
  void update(int class_id, const Blob* blob);

  const MarkerDetector* detector_;
  RoiTrackerConfig config_;
  std::vector<ClassState> state_;
  std::uint64_t frame_ = 0;
};

}  // namespace vrm_tracking
