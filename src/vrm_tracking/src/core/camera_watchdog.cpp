#include "vrm_tracking/camera_watchdog.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace vrm_tracking {

CameraWatchdog::CameraWatchdog(std::size_t cameras, CameraWatchdogConfig config)
    : cameras_(cameras), config_(config), last_wall_(cameras), recovering_(cameras) {
  if (config_.period_ns <= 0) throw std::invalid_argument("camera watchdog: the camera period must be positive");
  if (!(config_.timeout > 0.0)) throw std::invalid_argument("camera watchdog: the timeout must be positive");
}

void CameraWatchdog::onCameraFrame(std::size_t camera, StampNs stamp, double now) {
  if (camera >= cameras_ || !std::isfinite(now)) return;
  std::optional<double>& last = last_wall_[camera];
  if (last && now - *last > config_.timeout) {
    CameraRecovery recovery;
    recovery.camera = camera;
    recovery.returned = stamp;
    recovery.silent_s = now - *last;
    recovering_[camera] = recovery;  // a camera that drops out again before recovering starts over
  }
  last = now;
  newest_wall_ = newest_wall_ ? std::max(*newest_wall_, now) : now;
  newest_stamp_ = newest_stamp_ ? std::max(*newest_stamp_, stamp) : stamp;
}

void CameraWatchdog::onFrameReconstructed(StampNs stamp, std::size_t cameras_used) {
  last_output_ = last_output_ ? std::max(*last_output_, stamp) : stamp;
  for (std::optional<CameraRecovery>& recovery : recovering_) {
    if (!recovery || stamp < recovery->returned) continue;
    ++recovery->frames;
    if (cameras_used >= cameras_) {
      recoveries_.push_back(*recovery);
      recovery.reset();
    }
  }
}

void CameraWatchdog::onHeldFrame(StampNs stamp) {
  last_output_ = last_output_ ? std::max(*last_output_, stamp) : stamp;
  ++held_frames_;
}

std::vector<std::size_t> CameraWatchdog::missing(double now) const {
  std::vector<std::size_t> result;
  if (!newest_wall_) return result;  // nothing delivered yet: start-up, not a dropout
  for (std::size_t c = 0; c < cameras_; ++c) {
    if (!last_wall_[c] || now - *last_wall_[c] > config_.timeout) result.push_back(c);
  }
  return result;
}

bool CameraWatchdog::holding(double now) const {
  return last_output_ && newest_wall_ && now - *newest_wall_ > config_.timeout;
}

double CameraWatchdog::silence(double now) const { return newest_wall_ ? std::max(0.0, now - *newest_wall_) : 0.0; }

std::optional<StampNs> CameraWatchdog::nextHoldStamp(double now) const {
  if (!holding(now) || !newest_stamp_) return std::nullopt;
  // Rounded, not floored: a watchdog timer ticking at the camera rate with a few ms of jitter then yields one
  // stamp per tick instead of skipping a period whenever a tick comes early.
  const double periods = std::round((now - *newest_wall_) * 1e9 / static_cast<double>(config_.period_ns));
  const StampNs stamp = *newest_stamp_ + static_cast<StampNs>(periods) * config_.period_ns;
  if (stamp <= *last_output_) return std::nullopt;
  return stamp;
}

}  // namespace vrm_tracking
