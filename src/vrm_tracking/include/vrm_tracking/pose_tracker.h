#pragma once
// From per-camera marker centroids to the poses of the eye and the instruments (thesis §7.3.2):
//   * each colour class is reconstructed from every camera that saw it (3-camera least squares, or the best
//     consistent pair when a camera is occluded or saw a distractor);
//   * the eye rotation about its fixed rotation centre from the two peripheral markers (a 2-vector Kabsch fit);
//   * the instrument tip from its marker, moved into the eye frame; the shaft from the trocar (fixed in the eye)
//     to the tip. Roll (magnetic sensor) and jaw angle (instrument input) are not optical: the caller adds them.
// ROS-free; the tracker nodelet and the offline tools share it.

#include <Eigen/Geometry>
#include <limits>
#include <string>
#include <vector>

#include "vrm_tracking/camera_rig.h"
#include "vrm_tracking/marker_detector.h"
#include "vrm_tracking/marker_layout.h"
#include "vrm_tracking/pose_filter.h"
#include "vrm_tracking/triangulation.h"

namespace vrm_tracking {

// One camera's centroids for one frame (from the detector or pre-extracted: the FPGA path).
struct CameraObservations {
  std::size_t camera = 0;
  std::vector<Blob> blobs;  // class_id, u, v, area, quality are used
};

struct TrackerConfig {
  double gate_px = 3.0;                  // accept a reconstruction whose RMS reprojection residual is below this
  double max_radius = 0.03;              // m: reject points farther than this from the rotation centre
  double eye_marker_tolerance = 0.0015;  // m: |marker − centre| must match the layout within this
  // Blobs below this fraction of the best quality of their class in the frame are used only if the others do not
  // reconstruct (distractor rejection; 0 = off).
  double clean_quality_ratio = 0.5;
  // Issue 43 §3: which blobs make a marker. A solution is "consistent" when every camera's reprojection residual is
  // within consistent_px: 5x the largest residual of a clean three-camera solution on the rendered bench (0.05 px),
  // well below the ~0.5-1 px bias of a blob merged with a distractor or cut by a shaft. A consistent solution
  // of three or more cameras is taken first (three rays meeting within half a pixel do not happen by chance); then a
  // consistent pair; the loose gate_px only as the last resort.
  double consistent_px = 0.25;
  // ... or, when the centroids are noisier than the rendered ones (the FPGA path, a worse calibration), this many
  // times the median of the recent three-camera residuals (each frame's smallest max residual of a three-camera
  // solution per marker, the last consistent_window of them): the threshold follows the measured noise, and a blob
  // biased by a distractor or a shaft is an outlier against that noise. A residual the whole rig shares (noise,
  // calibration) raises the median; a rare biased blob does not. While a marker is predicted, only a consistent
  // solution is taken (else the marker is missing that frame); without a prediction the loose gate_px is the last
  // resort.
  double consistent_noise_factor = 4.0;
  int consistent_window = 64;
  // A pair is consistent against its own threshold, never the three-camera one: pair_consistent_px, or
  // consistent_noise_factor times the median of the residuals of the pairs taken recently (the last
  // consistent_window of them). Two rays always nearly meet, so a pair's residual says little about a wrong blob
  // (that is the prediction gate's job, below); what it must not do is reject the real blobs. Rendered at 640x480,
  // the pairs of real marker blobs (shaft-cut ones included) reach 0.49 px on the built-in demo and 0.55 px on the
  // random fast trajectory 4304, blobs of markers half behind a shaft 0.63 px, while three-camera residuals are
  // ~0.02 px: the three-camera threshold (0.25 px) made 5-24 % of the frames of a stopped camera invalid
  // (camera_dropout.test). 1 px admits them with a margin and is still a third of gate_px. This applies when only two
  // cameras report the marker's class; when a third one reports it as well and disagrees with every pair (no
  // consistent three-camera solution), a blob is biased and a pair is held to the three-camera threshold (with 1 px
  // there, 12 distractors reached 93 um and the demo's three-camera max 196 um, against 33 and 96 um).
  double pair_consistent_px = 1.0;
  // A pair has a single epipolar check, which a distractor anywhere along the epipolar line passes. So a pair solution
  // must lie within prediction_margin + (|v| + max_marker_speed) dt of the marker's constant-velocity prediction (v
  // from its last two positions, dt since the last: the velocity can turn into any other up to max_marker_speed,
  // e.g. a full reversal; without a velocity yet, |v| = max_marker_speed), and among the clean pairs the one nearest
  // the prediction wins. The prediction expires after prediction_max_age s without the marker
  // (then pairs are taken on their residual alone and the loose gate is allowed, so a marker is found again).
  double prediction_margin = 0.0005;  // m
  double max_marker_speed = 0.075;    // m/s: above the 60 mm/s tip sweeps the simulator is specified for
  double prediction_max_age = 0.1;    // s
  // A pair whose blobs include one with more than this fraction of its surrounding ring coloured (Blob::
  // contamination: a shaft crossing the marker or a distractor touching it; clean blobs read 0-0.05, cut ones
  // 0.2-0.3) is not taken while the marker is predicted: cut by a shaft, a centroid moves up to ~1 px, and along the
  // pair's epipolar line no residual shows it (76 and 103 µm on the random fast trajectory 4304 with one camera
  // occluded).
  double pair_contamination_max = 0.15;
  // Issue 43 §2: predicted occlusion. While the markers are predicted the tracker knows where every marker and every
  // shaft will be (a shaft from its tip's prediction out through its trocar, fixed in the eye whose rotation the eye
  // markers' predictions give). A blob whose marker the prediction puts within occlusion_margin_px of a nearer shaft
  // or marker in that camera is cut: its centroid is exact along the occluder's edge and may be off by up to
  // cut_sigma_px across it (a shaft slowly covering a tip marker over 40 frames of the built-in demo moved the
  // centroid 2 px across the shaft and 0.02 px along it; with one camera stopped that pair was 198 µm off). Such a
  // blob enters the solution weighted accordingly (triangulateWeighted), with the marker's prediction as a prior of
  // the recent prediction error (at least prior_sigma_min) for the one direction two rays cannot fix when the cut
  // runs along it. centroid_sigma_px: the floor of the centroid noise the weights are relative to (the median
  // three-camera residual raises it). The margin covers the blob's blur (~1 px) and the prediction's error.
  bool occlusion_model = true;
  double occlusion_margin_px = 1.5;
  double cut_sigma_px = 2.0;
  double centroid_sigma_px = 0.02;
  double prior_sigma_min = 0.00001;  // m
  // A blob cut from one side is corrected by the shift a straight edge gives a disc that lost the blob's missing area
  // (against the area the marker's unoccluded blobs had at its projected size), along the predicted direction; what
  // remains uncertain across the edge is this fraction of that shift. Measured on the demo: a shaft's cut 1.98 px
  // predicted against 1.92 px (3 %); a neighbour marker's blurred colours, no straight edge, 1.22 against 0.88 px
  // (40 %). 0.15 on the demo's stopped-camera rows: max 47 / 37 / 28 µm; 0.3: 82 / 53 / 25 µm; 0.1 made its
  // three-camera row worse (3.45 -> 3.77 µm RMS).
  double cut_shift_uncertainty = 0.15;
  // The model applies to markers (as targets and as occluders) whose recent prediction error is below this (m): the
  // geometry must be known to a fraction of a marker's radius (0.05 mm is half a pixel at the eye).
  double occlusion_max_prediction_error = 0.00005;
  // Optional filter of every reconstructed marker position (so of the eye rotation and the tips); off by default.
  PoseFilterConfig filter;
};

struct MarkerEstimate {
  int class_id = 0;
  bool valid = false;
  Eigen::Vector3d position = Eigen::Vector3d::Zero();      // world, m (filtered if a filter is configured)
  Eigen::Vector3d raw_position = Eigen::Vector3d::Zero();  // world, m, as triangulated
  double rms_px = 0.0;
  double max_px = 0.0;  // the largest camera's reprojection residual
  int cameras = 0;
  double quality = 0.0;  // 0..1
};

struct EyeEstimate {
  bool valid = false;  // false: the rotation is held from the last valid frame (or identity)
  Eigen::Quaterniond rotation = Eigen::Quaterniond::Identity();  // world -> eye
  Eigen::Vector3d rotation_center = Eigen::Vector3d::Zero();
  double quality = 0.0;
};

struct InstrumentEstimate {
  std::string slot;
  bool valid = false;  // false: the pose is held from the last valid frame (or zeros before the first)
  Eigen::Vector3d tip = Eigen::Vector3d::Zero();     // eye frame, m
  Eigen::Vector3d trocar = Eigen::Vector3d::Zero();  // eye frame, m
  Eigen::Vector3d shaft_axis = Eigen::Vector3d::UnitZ();
  double insertion_depth = 0.0;
  double quality = 0.0;
};

struct TrackingResult {
  std::vector<MarkerEstimate> markers;  // one per class of the layout
  EyeEstimate eye;
  std::vector<InstrumentEstimate> instruments;  // in layout order
};

class PoseTracker {
 public:
  PoseTracker(CameraRig rig, MarkerLayout layout, TrackerConfig config = TrackerConfig());

  // Observations of unknown cameras and non-finite centroids are ignored (never thrown on). stamp (s, the camera
  // exposure time) drives the optional filter; NaN: 20 ms after the previous frame.
  TrackingResult update(const std::vector<CameraObservations>& frame,
                        double stamp = std::numeric_limits<double>::quiet_NaN());
  // One marker from one frame without a prediction (a first frame, or a tracker that just lost it).
  MarkerEstimate reconstruct(int class_id, const std::vector<CameraObservations>& frame) const;
  // Where a marker is expected (world, m) and how far from it a pair solution may lie (m); see TrackerConfig.
  struct Prediction {
    Eigen::Vector3d position = Eigen::Vector3d::Zero();
    double gate = 0.0;
  };
  MarkerEstimate reconstruct(int class_id, const std::vector<CameraObservations>& frame,
                             const Prediction* prediction) const;
  // The consistency thresholds (px) the next update() uses for solutions of three or more cameras and for pairs:
  // each its floor or the measured noise of its kind (see TrackerConfig).
  double consistentPx() const;
  double pairConsistentPx() const;
  void reset();

  const CameraRig& rig() const { return rig_; }
  const MarkerLayout& layout() const { return layout_; }

 private:
  CameraRig rig_;
  MarkerLayout layout_;
  TrackerConfig config_;
  EyeEstimate last_eye_;
  std::vector<InstrumentEstimate> last_instruments_;  // last valid estimate per layout instrument
  std::vector<PointFilter> filters_;                  // per colour class (index as layout_.classes)
  // Per colour class: its last two raw positions and their stamps (the prediction of issue 43 §3).
  struct ClassHistory {
    int count = 0;  // 0, 1 or 2 positions held
    Eigen::Vector3d position = Eigen::Vector3d::Zero(), previous = Eigen::Vector3d::Zero();
    double stamp = 0.0, previous_stamp = 0.0;
  };
  std::vector<ClassHistory> history_;
  bool predictionFor(std::size_t k, double stamp, Prediction* prediction) const;
  // Per colour class: the recent error of its prediction against clean (uncut) solutions, m (the prior's sigma).
  std::vector<double> prediction_error_;
  // Per colour class and camera: the blob area of the unoccluded marker over its projected radius squared (EMA;
  // < 0 unknown), so a cut blob's missing area, hence its centroid's shift, can be told (see TrackerConfig).
  std::vector<std::vector<double>> area_ratio_;
  // Predicted occlusion of one class in every camera: the weight of a blob's pixel residual relative to an ordinary
  // centroid's (identity: not cut; eigenvalue (centroid σ / cut_sigma_px)² across a predicted cut).
  struct Occlusion {
    std::vector<Eigen::Matrix2d> relative_information;  // per rig camera
    // Per rig camera: the unit image vector from the one occluder towards the marker (zero: no occluder, or several)
    // and the area (px²) the blob would have unoccluded (0: not known yet).
    std::vector<Eigen::Vector2d> away;
    std::vector<double> full_area;
    bool any = false;
    double centroid_sigma_px = 0.0;
    PointPrior prior;
    // Whether rig camera `camera` sees the marker partly hidden (its weight is not the identity).
    bool cutIn(std::size_t camera) const {
      return any && camera < relative_information.size() && !relative_information[camera].isIdentity(1e-12);
    }
  };
  // The occlusion of every class this frame from the predictions (classes without a prediction: none).
  double markerRadius(int class_id) const;  // m: an eye marker's or a tip marker's
  // Learns the unoccluded blob size of class index k from this frame's blobs of it (cameras not predicted cut).
  void learnBlobArea(std::size_t k, const Eigen::Vector3d& position, const std::vector<CameraObservations>& frame,
                     const Occlusion& occlusion);
  std::vector<Occlusion> predictOcclusions(const std::vector<Prediction>& predictions,
                                           const std::vector<bool>& predicted) const;
  // Consistency thresholds (px) of one update(): three or more cameras, and pairs.
  struct Thresholds {
    double multi_px = 0.0;
    double pair_px = 0.0;
  };
  // reconstruct() with given thresholds; *multi_sample_px: the smallest max residual of a solution of three or more
  // cameras (infinity without one).
  MarkerEstimate reconstructWith(int class_id, const std::vector<CameraObservations>& frame,
                                 const Prediction* prediction, const Thresholds& thresholds, double* multi_sample_px,
                                 const Occlusion* occlusion = nullptr, bool* used_cut = nullptr) const;
  // A ring of the last consistent_window residual samples (px) and its median.
  struct ResidualWindow {
    std::vector<double> samples;
    std::size_t next = 0;
    void add(double px, int window);
    double median() const;
  };
  ResidualWindow multi_residuals_;  // three-camera solutions: each frame's best per marker
  ResidualWindow pair_residuals_;   // the pairs taken
  double last_stamp_ = 0.0;
};

// The centroid shift, in disc radii, of a disc that lost `missing` (0..1; clamped to 0.9) of its area to a straight
// edge, away from the edge (issue 43 §2: a marker blob cut by a shaft). 0 for 0 or a non-finite fraction.
double cutDiscCentroidShift(double missing);

// Rotation R (world -> eye) that best maps the layout's eye-frame marker positions a0, b0 onto the measured
// a, b (world, relative to the rotation centre): Kabsch on {a, b, a×b}.
Eigen::Quaterniond eyeRotationFromMarkers(const Eigen::Vector3d& a0, const Eigen::Vector3d& b0,
                                          const Eigen::Vector3d& a, const Eigen::Vector3d& b);

}  // namespace vrm_tracking
