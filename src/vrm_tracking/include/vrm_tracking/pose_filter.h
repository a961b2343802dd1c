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
// is no filter: at the rig's ~5 µm static noise, 1 ms of lag at 10 mm/s already costs 10 µm.

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
  // alpha-beta gains (0 < alpha < 1, 0 < beta_ab < 4 - 2 alpha); 0.5 / 0.15: critically damped-ish at 50 Hz.
  double alpha = 0.5;
  double beta_ab = 0.15;
  // A gap longer than this (s) or a non-increasing stamp restarts the filter at the new measurement.
  double max_gap = 0.2;
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
};

// Measured steady-state lag (s) of a filter on a ramp at `speed` (m/s) sampled at `rate` (Hz): the ramp's
// position error after `duration` seconds, divided by the speed. The filter's stated latency.
double measureRampLag(const PoseFilterConfig& config, double speed, double rate, double duration = 2.0);

}  // namespace vrm_tracking
