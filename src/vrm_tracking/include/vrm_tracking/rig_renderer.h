#pragma once
// Synthetic twin of the EyeSi tracking cameras (thesis §7.3.2): renders the ground-truth markers of a WorldScene as
// what a 640×480 colour CMOS camera sees — anti-aliased, optically blurred, motion-blurred blobs over a cluttered
// background, occluded by the instrument shafts, with exposure, Gaussian read noise, shot noise and optional
// distractor blobs. Deterministic: every random draw comes from (seed, camera, frame index).

#include <cstdint>
#include <opencv2/core.hpp>
#include <vector>

#include "vrm_tracking/camera_rig.h"
#include "vrm_tracking/marker_layout.h"

namespace vrm_tracking {

struct RenderConfig {
  double blur_px = 0.7;          // σ of the optical point spread (px)
  double read_noise = 2.0;       // σ of Gaussian read noise (DN, 8 bit)
  double shot_gain = 0.05;       // shot noise variance per DN of signal (0 = off)
  double exposure = 1.0;         // scales all radiance (1 = markers just below saturation)
  double exposure_time = 0.004;  // s; markers moving during it smear (motion blur)
  int motion_samples = 6;        // sub-frame positions averaged over the exposure
  int clutter = 25;              // static grey background shapes per camera
  int distractors = 0;           // per frame: elongated/oversized class-coloured blobs and magenta dots
  bool shafts = true;            // instrument shafts occlude markers behind them
  double background = 45.0;      // mean background level (DN)
  std::uint32_t seed = 1;
  // Issue 30 item 4: false (default) draws and exposes only the rows of pixels a marker, shaft or distractor can
  // reach and gives the rest of the frame its noise from a bank of normal draws (RigRenderer::render); true keeps
  // the earlier renderer (rectangular boxes per drawable and shaft piece, a noise-table lookup per untouched byte) as
  // the reference the benchmark and the tests compare against. Both have the same sensor model and statistics.
  bool reference_path = false;
};

// The exact centroid a perfect detector would report: the projection of the marker centre at mid-exposure.
struct ProjectedMarker {
  int class_id = 0;
  Eigen::Vector2d pixel = Eigen::Vector2d::Zero();
  double radius_px = 0.0;
  bool visible = false;  // in front of the camera, inside the image, not hidden behind a shaft
};

class RigRenderer {
 public:
  RigRenderer(CameraRig rig, MarkerLayout layout, RenderConfig config);

  // Renders camera `camera` into `image` (resized to CV_8UC3 BGR of the camera's size; may wrap a message
  // buffer). frame_index selects the noise and distractor draws. Markers whose position does not project (behind
  // the camera, non-finite) are skipped and reported invisible.
  void render(std::size_t camera, const WorldScene& scene, std::uint64_t frame_index, cv::Mat* image,
              std::vector<ProjectedMarker>* truth = nullptr) const;
  // Exact projected centroids without rendering (the FPGA path and the centroid-noise benchmark).
  std::vector<ProjectedMarker> project(std::size_t camera, const WorldScene& scene) const;

  const CameraRig& rig() const { return rig_; }
  const RenderConfig& config() const { return config_; }

 private:
  void buildBackgrounds();
  float sensorSigma(int level) const;  // read + shot noise σ (DN) at a signal level
  void renderReference(std::size_t camera, const WorldScene& scene, std::uint64_t frame_index, cv::Mat* image,
                       std::vector<ProjectedMarker>* truth) const;
  void renderSpans(std::size_t camera, const WorldScene& scene, std::uint64_t frame_index, cv::Mat* image,
                   std::vector<ProjectedMarker>* truth) const;
  // Sensor model of the pixels nothing is drawn on, for the whole frame: level + σ(level)·z with z from the
  // normal bank at a random offset per row (fixed point, one multiply per byte; see rig_renderer.cpp).
  void exposeBackground(std::size_t camera, std::uint64_t frame_key, cv::Mat* image) const;

  CameraRig rig_;
  MarkerLayout layout_;
  RenderConfig config_;
  std::vector<cv::Mat> backgrounds_;                          // CV_32FC3 per camera, static clutter
  std::vector<std::vector<std::uint8_t>> background_levels_;  // per camera: exposed background, 8 bit
  std::vector<std::uint8_t> noise_lut_;  // 256 levels × 256 noisy samples (sensor model of untouched pixels)
  // Per camera, per pixel and channel: σ of the exposed background level in Q11 (σ · 2048; the span path's
  // untouched pixels). Empty when some σ ≥ 16 DN does not fit: the span path then uses noise_lut_ too.
  std::vector<std::vector<std::int16_t>> background_sigma_q11_;
};

}  // namespace vrm_tracking
