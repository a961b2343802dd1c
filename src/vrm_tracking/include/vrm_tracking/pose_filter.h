#pragma once
// Optional light filtering of the tracked marker positions (issue 5: "constant-velocity or One Euro, with its
// latency stated"). Two filters on a 3D point with explicit timestamps (the camera stamps, never a clock):
//   * One Euro (Casiez, Roussel & Vogel, CHI 2012): a first-order low-pass whose cutoff rises with the filtered
//     speed, fc = min_cutoff + beta·|v|. Strong smoothing at rest, less when moving — but a first-order low-pass
//     always lags a ramp by τ = 1/(2π fc) in steady state.
//   * alpha-beta (constant velocity; Kalata 1984): predicts with the estimated velocity and corrects position and
//     velocity by fixed gains. No steady-state lag on a ramp (a type-2 loop); it lags only under acceleration and
//     removes less noise than One Euro at rest.
// Latency and noise reduction are measured in test_pose_filter and the `tracking` benchmark (README). The default
// is no filter: at the rig's ~5 µm static noise, 1 ms of lag at 10 mm/s already costs 10 µm. Both filters have a
// motion gate (issue 43, PoseFilterConfig::noise_sigma): they smooth what the measured noise can explain and pass
// motion through, so they are never less accurate than no filter at speed.

#include <Eigen/Core>
#include <string>

namespace vrm_tracking {

enum class FilterType { kNone, kOneEuro, kAlphaBeta };

struct PoseFilterConfig {
  FilterType type = FilterType::kNone;
  // One Euro. min_cutoff in Hz, beta in Hz per (m/s), d_cutoff in Hz (of the speed estimate).
  double min_cutoff = 1.0;
  double beta = 2000.0;  // +20 Hz at 10 mm/s
  double d_cutoff = 1.0;
  // alpha-beta gains (0 < alpha < 1, 0 < beta_ab < 4 - 2 alpha). 0.2 / 0.02 (issue 43): position noise × 0.39 at rest
  // (σ_out²/σ² = (2α² + 2β − 3αβ) / (α(4 − 2α − β)) = 0.15; the earlier 0.5 / 0.15 gave × 0.59); the slow
  // acceleration bias these low gains bring (a·T²·(1 − α)/β) is capped by the motion gate.
  double alpha = 0.2;
  double beta_ab = 0.02;
  // A gap longer than this (s) or a non-increasing stamp restarts the filter at the new measurement.
  double max_gap = 0.2;
  // Issue 43 §4, the motion gate: noise_sigma is the measured per-axis σ (m) of the positions being filtered (the
  // tracker's jitter at rest). A measurement farther than gate_sigmas·noise_sigma from the filter's prediction cannot
  // be noise (at 4σ in 3D a false alarm is 1 in ~600 frames at rest), so it is motion: the filter restarts there and
  // passes it through unchanged. Either filter then smooths only what the noise can explain — it removes the jitter
  // at rest and cannot add more than ~gate_sigmas·σ of lag error at any speed. noise_sigma 0: no gate (the plain
  // filters, which lag: 5.9 ms for One Euro on a 10 mm/s ramp). Default 1.9 µm per axis: the 640x480 rendered
  // pipeline's frame-to-frame error while moving (3.0-3.4 µm in 3D), a conservative bound on its jitter at rest
  // (1.1 µm per axis, which the benchmark measures and uses).
  double noise_sigma = 1.9e-6;
  double gate_sigmas = 4.0;
  // After motion the filter keeps passing measurements through until they have stayed within the gate for this long
  // (s): where the frame-to-frame motion is only a few σ (10 mm/s is 200 µm a frame, 4σ of the 0.3 px centroid
  // path), one sample that happens to fall inside the gate must not restart the smoothing, and its lag, mid-motion.
  double motion_hold = 0.1;
};

// "none", "one_euro", "alpha_beta"; throws std::invalid_argument for anything else.
FilterType filterTypeFromString(const std::string& name);
std::string toString(FilterType type);

class PointFilter {
 public:
  explicit PointFilter(PoseFilterConfig config = PoseFilterConfig()) : config_(config) {}
  // Filtered position for measurement x at time t (s). The first call (and after reset or a gap) returns x.
  Eigen::Vector3d filter(const Eigen::Vector3d& x, double t);
  void reset() { initialised_ = false; }
  const PoseFilterConfig& config() const { return config_; }

 private:
  PoseFilterConfig config_;
  bool initialised_ = false;
  double t_ = 0.0;
  Eigen::Vector3d x_ = Eigen::Vector3d::Zero();
  Eigen::Vector3d v_ = Eigen::Vector3d::Zero();
  double quiet_since_ = -1e300;  // stamp of the last measurement outside the motion gate
};

// Measured steady-state lag (s) of a filter on a ramp at `speed` (m/s) sampled at `rate` (Hz): the ramp's
// position error after `duration` seconds, divided by the speed. The filter's stated latency.
double measureRampLag(const PoseFilterConfig& config, double speed, double rate, double duration = 2.0);

}  // namespace vrm_tracking
