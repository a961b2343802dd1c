#include "vrm_tracking/tracker_diagnostics.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace vrm_tracking {

namespace {

std::string formatNumber(double v) {
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%.3g", v);
  return std::string(buf);
}

std::string formatPoint(const Eigen::Vector3d& p) {
  char buf[96];
  std::snprintf(buf, sizeof(buf), "%.6f %.6f %.6f", p.x(), p.y(), p.z());
  return std::string(buf);
}

}  // namespace

std::vector<std::pair<std::string, std::string>> sceneGeometryValues(const std::string& scene_name,
                                                                     const MarkerLayout& layout) {
  constexpr double kRadToDeg = 180.0 / 3.14159265358979323846;
  std::vector<std::pair<std::string, std::string>> values;
  values.emplace_back("scene", scene_name);
  values.emplace_back("eye_centre", formatPoint(layout.rotation_center));
  for (const InstrumentMarker& marker : layout.instruments) {
    values.emplace_back("trocar_" + marker.slot, formatPoint(marker.trocar));
    double degrees = std::atan2(marker.trocar.y(), marker.trocar.x()) * kRadToDeg;
    if (degrees < 0.0) degrees += 360.0;
    char azimuth[32];
    std::snprintf(azimuth, sizeof(azimuth), "%.2f", degrees);
    values.emplace_back("trocar_" + marker.slot + "_azimuth_deg", azimuth);
  }
  return values;
}

TrackerDiagnostics::TrackerDiagnostics(std::vector<std::string> camera_names, double stale_timeout, double start_wall)
    : names_(std::move(camera_names)),
      stale_timeout_(stale_timeout),
      start_wall_(start_wall),
      last_report_wall_(start_wall),
      last_wall_(names_.size()),
      missing_(names_.size(), 0) {}

void TrackerDiagnostics::onCameraMarkers(std::size_t camera, double now) { last_wall_.at(camera) = now; }

void TrackerDiagnostics::onFrame(const SyncedFrame& frame, const TrackingResult& result) {
  ++frames_;
  const std::size_t n = names_.size();
  if (frame.cameras.size() < 2) {
    ++no_reconstruction_;
  } else if (frame.cameras.size() < n) {
    ++partial_;
  }
  for (std::size_t c = 0; c < n; ++c) missing_[c] += frame.cameras.count(c) ? 0 : 1;
  for (const MarkerEstimate& m : result.markers) {
    if (!m.valid) continue;
    ++markers_;
    cameras_used_ += m.cameras;
    residual_sum_ += m.rms_px;
    residual_max_ = std::max(residual_max_, m.rms_px);
  }
  eye_valid_ += result.eye.valid;
  for (const InstrumentEstimate& est : result.instruments) {
    ++instruments_;
    instruments_valid_ += est.valid;
  }
}

void TrackerDiagnostics::onRecovery(const CameraRecovery& r) {
  char text[128];
  std::snprintf(text, sizeof(text), "%d frame(s) after %.2f s silent (back at %.3f)", r.frames, r.silent_s,
                1e-9 * static_cast<double>(r.returned));
  last_recovery_[r.camera] = text;
}

std::string TrackerDiagnostics::whyMissing(const SyncedFrame& frame, double now, const FrameSynchronizer& sync) const {
  const double window_ms = 1e-6 * static_cast<double>(sync.syncWindow());
  std::string why;
  for (std::size_t c = 0; c < names_.size(); ++c) {
    if (frame.cameras.count(c)) continue;
    const std::string& name = names_[c];
    char reason[200];
    if (!last_wall_[c]) {
      std::snprintf(reason, sizeof reason, "%s: no frame yet", name.c_str());
    } else if (const double silent = now - *last_wall_[c]; silent > 0.2) {
      std::snprintf(reason, sizeof reason, "%s: silent for %.1f s, the camera dropped out", name.c_str(), silent);
    } else if (sync.lateFrames(c) > 0) {
      std::snprintf(reason, sizeof reason,
                    "%s: late, %zu of its frames came after the %.0f ms sync window so far: its detection runs "
                    "behind, e.g. on a saturated CPU",
                    name.c_str(), sync.lateFrames(c), window_ms);
    } else {
      std::snprintf(reason, sizeof reason, "%s: no frame within the %.0f ms sync window", name.c_str(), window_ms);
    }
    why += (why.empty() ? "" : "; ") + std::string(reason);
  }
  return why;
}

DiagnosticReport TrackerDiagnostics::report(double now, const CameraWatchdog& watchdog) {
  DiagnosticReport status;
  auto kv = [&status](const std::string& key, const std::string& value) { status.values.emplace_back(key, value); };
  std::vector<std::string> problems;
  auto raise = [&status, &problems](HealthLevel level, const std::string& what) {
    status.level = std::max(status.level, level);
    problems.push_back(what);
  };
  const double period = std::max(1e-3, now - last_report_wall_);
  const bool started = std::any_of(last_wall_.begin(), last_wall_.end(), [](const auto& t) { return t.has_value(); });
  const std::size_t n = names_.size();
  int cameras_live = 0;
  const bool holding = watchdog.holding(now);
  for (std::size_t c = 0; c < n; ++c) {
    const std::string& name = names_[c];
    const double age = last_wall_[c] ? now - *last_wall_[c] : now - start_wall_;
    kv(name + " last markers age s", last_wall_[c] ? formatNumber(age) : "never");
    kv(name + " frames missing", std::to_string(missing_[c]));
    if (last_recovery_.count(c)) kv(name + " last recovery", last_recovery_.at(c));
    if (!last_wall_[c]) {
      // Start-up: cameras connect one by one; a camera that never delivered is reported after stale_timeout.
      if (started && age > stale_timeout_) raise(HealthLevel::kWarn, name + " never delivered markers");
    } else if (age > watchdog.config().timeout) {
      if (!holding)
        raise(HealthLevel::kWarn, name + " missing for " + formatNumber(age) + " s (tracking with the others)");
    } else {
      ++cameras_live;
    }
  }
  if (holding) {
    raise(HealthLevel::kError,
          "no camera frame for " + formatNumber(watchdog.silence(now)) + " s: holding the last poses, marked invalid");
  } else if (!started) {
    raise(now - start_wall_ > stale_timeout_ ? HealthLevel::kError : HealthLevel::kWarn, "no marker frames yet");
  } else if (cameras_live < 2) {
    raise(HealthLevel::kError, std::to_string(cameras_live) + " camera(s) live: no reconstruction possible");
  }
  if (held_ > 0 && !holding) {
    raise(HealthLevel::kWarn, std::to_string(held_) + " frames held (no camera), now tracking again");
  }
  if (frames_ > 0) {
    if (no_reconstruction_ > 0) {
      // A few under load are frames whose other cameras arrived late; most of them means no tracking.
      raise(2 * no_reconstruction_ > frames_ ? HealthLevel::kError : HealthLevel::kWarn,
            std::to_string(no_reconstruction_) + " of " + std::to_string(frames_) +
                " frames with fewer than 2 cameras (late or missing)");
    }
    if (partial_ > 0) {
      std::string which;
      for (std::size_t c = 0; c < n; ++c) {
        if (missing_[c] > 0) which += (which.empty() ? " (" : ", ") + names_[c];
      }
      raise(HealthLevel::kWarn, std::to_string(partial_) + " of " + std::to_string(frames_) +
                                    " frames with a camera missing" + (which.empty() ? "" : which + ")") +
                                    ", continuing with the others");
    }
    if (eye_valid_ < 0.9 * frames_) {
      raise(HealthLevel::kWarn, "eye markers reconstructed in " + std::to_string(eye_valid_) + " of " +
                                    std::to_string(frames_) + " frames");
    }
  }
  kv("frames", std::to_string(frames_));
  kv("held frames", std::to_string(held_));
  kv("rate hz", formatNumber(frames_ / period));
  kv("cameras live", std::to_string(cameras_live) + " of " + std::to_string(n));
  kv("cameras used per marker (mean)", markers_ ? formatNumber(static_cast<double>(cameras_used_) / markers_) : "-");
  kv("reprojection rms px (mean)", markers_ ? formatNumber(residual_sum_ / markers_) : "-");
  kv("reprojection rms px (max)", markers_ ? formatNumber(residual_max_) : "-");
  kv("eye valid", std::to_string(eye_valid_) + " of " + std::to_string(frames_));
  kv("instruments valid", std::to_string(instruments_valid_) + " of " + std::to_string(instruments_));
  if (problems.empty()) {
    status.message = "tracking with " + std::to_string(cameras_live) + " cameras";
  } else {
    for (std::size_t i = 0; i < problems.size(); ++i) status.message += (i ? "; " : "") + problems[i];
  }
  resetPeriod(now);
  return status;
}

void TrackerDiagnostics::resetPeriod(double now) {
  last_report_wall_ = now;
  frames_ = no_reconstruction_ = partial_ = markers_ = cameras_used_ = 0;
  eye_valid_ = instruments_ = instruments_valid_ = held_ = 0;
  residual_sum_ = residual_max_ = 0.0;
  std::fill(missing_.begin(), missing_.end(), 0);
}

}  // namespace vrm_tracking
