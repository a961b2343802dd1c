#pragma once
// Offline evaluation of the tracking pipeline against ground truth (the `tracking` benchmark and tracking_eval):
// sample a ground-truth trajectory, feed the pipeline either exact projected centroids plus Gaussian noise (the
// FPGA path) or rendered images (renderer → RoiTracker detector), and compare the reconstructed eye rotation and
// instrument tips with the truth. No ROS, no master; time is measured only through the clock the caller passes.

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "vrm_tracking/camera_rig.h"
#include "vrm_tracking/marker_detector.h"
#include "vrm_tracking/marker_layout.h"
#include "vrm_tracking/pose_tracker.h"
#include "vrm_tracking/rig_renderer.h"
#include "vrm_tracking/surgeon_script.h"

namespace vrm_tracking {

struct EvalOptions {
  bool rendered = false;  // false: exact centroids + noise_px Gaussian noise per coordinate
  double noise_px = 0.0;
  int occluded_camera = -1;  // this camera delivers nothing (-1: none)
  // A camera that stops mid-run (camera_dropout.test): the occluded camera delivers up to this frame index and
  // nothing from it on; the frames before it are tracked with every camera but not scored. 0: occluded throughout.
  int occlusion_start_frame = 0;
  RenderConfig render;   // rendered mode
  RoiTrackerConfig roi;  // rendered mode
  TrackerConfig tracker;
  std::uint32_t seed = 1;
  bool motion = true;  // pass marker velocities to the renderer (motion blur)
  // Rendered mode: camera c exposes at t + camera_time_offset[c] (s) while the tracker takes the frame as one instant
  // t (an unsynchronised rig); missing entries are 0. The accuracy is still judged against the truth at t.
  std::vector<double> camera_time_offset;
  std::function<double()> clock;  // seconds, monotonic; empty: no timing
  // The rig the tracker reconstructs with (e.g. one estimated by calibrate_rig, calibration.h); null: the rig the
  // images or centroids come from (a perfectly calibrated tracker). Not owned; must outlive evaluate().
  const CameraRig* tracker_rig = nullptr;
};

struct EvalResult {
  int frames = 0;
  double tip_rms_um = 0.0;  // world-frame tip marker error (what triangulation determines)
  double tip_max_um = 0.0;
  // Issue 43 §4: the part of the world-frame tip error that changes from frame to frame: RMS of the error vector
  // about its mean per instrument over the run. At rest (a frozen truth) it is the jitter a filter should remove; the
  // mean is the static bias (calibration, centroid bias) no filter can.
  double tip_jitter_um = 0.0;
  double tip_eye_rms_um = 0.0;  // eye-frame tip error (adds the eye-rotation error)
  double tip_eye_max_um = 0.0;
  double eye_err_deg = 0.0;  // RMS angular error of the eye rotation
  double eye_err_max_deg = 0.0;
  double detect_rate = 0.0;  // visible (marker, camera) pairs with a centroid within 3 px
  double track_rate = 0.0;   // instrument-frames with a valid pose
  // Scored instrument-frames without a valid pose although at least two delivering cameras reported a blob of the
  // tip marker's class (camera_dropout.test's count: what two cameras could have reconstructed), and all of them.
  int tips_invalid_seen = 0;
  int tips_scored = 0;
  double ms_detect = 0.0;       // per camera triple
  double ms_reconstruct = 0.0;  // per frame (all markers, eye and instruments)
  double ms_render = 0.0;       // rendered mode: the synthetic rig's cost per camera triple (not the pipeline's)
  double ms_render_p99 = 0.0;   // rendered mode: 99th percentile and worst over the frames (per triple)
  double ms_render_max = 0.0;
  double ms_detect_p99 = 0.0;
  double full_frame_rate = 0.0;  // fraction of camera frames that needed a full-frame pass
};

// times: sample instants (s); truth(t) gives the ground truth. Velocities for motion blur come from truth(t ± 1 ms).
EvalResult evaluate(const CameraRig& rig, const MarkerLayout& layout,
                    const std::function<SurgeonSnapshot(double)>& truth, const std::vector<double>& times,
                    const EvalOptions& options);

// Ideal floor: RMS error (µm) of the optimal least-squares (Gauss-Newton from the true point) triangulation of the
// given points with isotropic Gaussian centroid noise noise_px, by Monte Carlo over `trials` draws per point.
// cameras: indices used. Also the Cramér-Rao bound of the same configuration (crlb_um).
double idealFloorUm(const CameraRig& rig, const std::vector<Eigen::Vector3d>& points, double noise_px,
                    const std::vector<std::size_t>& cameras, int trials, std::uint32_t seed, double* crlb_um = nullptr);

// The benchmark's parametric surgeon: tips circling at `speed` (m/s) on 3 mm circles in the vitreous, the eye
// rotating a few degrees. speed 0: the tips jump to a new static position every sample (no motion blur).
std::function<SurgeonSnapshot(double)> circlingSurgeon(const MarkerLayout& layout, double speed);

// The benchmark's hard case (issue 15): everything fast at once, with the tips at the back of the eye.
//   * eye: tilted by ±eye_amplitude about x and about y in quadrature (a cone), so its angular speed is
//     eye_amplitude · 2π · eye_frequency at every instant instead of passing through zero at the turning points;
//   * tips: 1.5 mm either side of the optical axis at eye-frame z = tip_depth, 1.6–2 mm in front of the 12 mm retina
//     at the posterior pole (the longest shafts, the tips farthest from the trocars; with the cameras below the eye
//     the pole faces them), sweeping ±sweep_half_length along y in antiphase at a constant `sweep_speed` (m/s, a
//     triangle wave). With the default leg the reversals fall half a 50 Hz frame from the sample instants: the
//     renderer smears a marker along its velocity at the stamp, which a reversal inside the exposure is not.
struct FastSurgeonConfig {
  double eye_amplitude = 12.0 * 3.14159265358979323846 / 180.0;  // rad, per axis
  double eye_frequency = 0.65;                                   // Hz
  double sweep_speed = 0.050;                                    // m/s
  double sweep_half_length = 0.0025;                             // m: a 100 ms leg, five 50 Hz frames
  double tip_depth = -0.010;                                     // m, eye frame z of the tips
};
std::function<SurgeonSnapshot(double)> fastPosteriorSurgeon(const MarkerLayout& layout,
                                                            const FastSurgeonConfig& config = FastSurgeonConfig());
// Issue 43 §5: seeded random fast trajectories, generated outside the bench's fixed rows, to test that the fixes are
// not tuned to them.
//   * eye: about x, y and z (the roll about the optical axis) a slow and a quick sinusoid per axis with random
//     frequencies and phases, so the rotation reverses (quickly, on the 1.5-3 Hz component) and its direction changes;
//     scaled so that the peak angular speed over [0, duration] is a random fraction in [0.85, 1] of max_eye_speed;
//   * tips: straight sweeps between random waypoints near the posterior pole (eye frame: |x| 0.5-3 mm on the
//     instrument's side, |y| <= 3 mm, z -10.5 to -8 mm: 1.5-4 mm in front of the 12 mm retina), each leg at a random
//     speed in [0.5, 1] · max_tip_speed, legs of >= 1.5 mm; the velocity changes at once at a waypoint (an abrupt
//     reversal when the next waypoint lies behind), at instants that fall anywhere between the 50 Hz samples.
struct RandomFastConfig {
  double max_eye_speed = 1.0;    // rad/s
  double max_tip_speed = 0.060;  // m/s
  double duration = 10.0;        // s: the eye's scaling and the tips' legs cover [0, duration]
};
std::function<SurgeonSnapshot(double)> randomFastSurgeon(const MarkerLayout& layout, std::uint32_t seed,
                                                         const RandomFastConfig& config = RandomFastConfig());
// Peak tip speed (m/s, eye frame) of a surgeon over the samples `times`, by central differences over ±dt.
double peakTipSpeed(const std::function<SurgeonSnapshot(double)>& truth, const std::vector<double>& times,
                    double dt = 1e-4);
// Angular speed (rad/s) of a surgeon's eye rotation at t, by a central difference over ±dt.
double eyeAngularSpeed(const std::function<SurgeonSnapshot(double)>& truth, double t, double dt = 1e-4);

}  // namespace vrm_tracking
