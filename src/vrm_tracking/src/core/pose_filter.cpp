#include "vrm_tracking/pose_filter.h"

#include <cmath>
#include <stdexcept>

namespace vrm_tracking {

namespace {
constexpr double kPi = 3.14159265358979323846;

// Smoothing factor of an exponential low-pass at cutoff fc (Hz) for a sample interval dt (s).
double lowPassAlpha(double cutoff, double dt) {
  const double tau = 1.0 / (2.0 * kPi * std::max(cutoff, 1e-6));
  return 1.0 / (1.0 + tau / dt);
}
}  // namespace

FilterType filterTypeFromString(const std::string& name) {
  if (name == "none" || name.empty()) return FilterType::kNone;
  if (name == "one_euro") return FilterType::kOneEuro;
  if (name == "alpha_beta") return FilterType::kAlphaBeta;
  throw std::invalid_argument("filter '" + name + "': expected none, one_euro or alpha_beta");
}

std::string toString(FilterType type) {
  switch (type) {
    case FilterType::kOneEuro:
      return "one_euro";
    case FilterType::kAlphaBeta:
      return "alpha_beta";
    default:
      return "none";
  }
}

Eigen::Vector3d PointFilter::filter(const Eigen::Vector3d& x, double t) {
  if (config_.type == FilterType::kNone || !x.allFinite() || !std::isfinite(t)) return x;
  const double dt = t - t_;
  // The motion gate: a measurement the noise cannot explain restarts the filter there, and so does every one for
  // motion_hold after it (see PoseFilterConfig).
  const bool gated = config_.noise_sigma > 0.0 && initialised_ && dt > 0.0;
  const Eigen::Vector3d predicted =
      config_.type == FilterType::kAlphaBeta && initialised_ && dt > 0.0 ? Eigen::Vector3d(x_ + v_ * dt) : x_;
  const bool motion = gated && (x - predicted).norm() > config_.gate_sigmas * config_.noise_sigma;
  if (motion) quiet_since_ = t;
  const bool holding = gated && t - quiet_since_ < config_.motion_hold;
  if (!initialised_ || dt <= 0.0 || dt > config_.max_gap || motion || holding) {
    // A (re)start knows nothing of the motion yet: it holds as after motion.
    if (!holding) quiet_since_ = t;
    initialised_ = true;
    t_ = t;
    x_ = x;
    v_.setZero();
    return x;
  }
  t_ = t;
  if (config_.type == FilterType::kOneEuro) {
    // Speed from the raw difference, low-passed at d_cutoff; its magnitude raises the position cutoff.
    const Eigen::Vector3d raw_v = (x - x_) / dt;
    v_ += lowPassAlpha(config_.d_cutoff, dt) * (raw_v - v_);
    const double cutoff = config_.min_cutoff + config_.beta * v_.norm();
    x_ += lowPassAlpha(cutoff, dt) * (x - x_);
  } else {
    const Eigen::Vector3d residual = x - predicted;
    x_ = predicted + config_.alpha * residual;
    v_ += (config_.beta_ab / dt) * residual;
  }
  return x_;
}

double measureRampLag(const PoseFilterConfig& config, double speed, double rate, double duration) {
  PointFilter filter(config);
  Eigen::Vector3d out = Eigen::Vector3d::Zero();
  double x = 0.0;
  const int n = static_cast<int>(std::round(duration * rate));
  for (int i = 0; i <= n; ++i) {
    const double t = i / rate;
    x = speed * t;
    out = filter.filter(Eigen::Vector3d(x, 0.0, 0.0), t);
  }
  return (x - out.x()) / speed;
}

}  // namespace vrm_tracking
