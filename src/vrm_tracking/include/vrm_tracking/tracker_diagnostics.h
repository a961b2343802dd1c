#pragma once
// Health of the tracker's inputs and outputs (issue 5, issue 14, issue 20), for /diagnostics: per camera the age of
// its newest markers, the frames it missed and its last recovery; per period the frames, held frames, cameras per
// marker, reprojection residuals and eye/instrument validity — judged OK / WARN / ERROR. Also why a camera is missing
// from a frame (so the warning tells a fault from load). ROS-free, no clock: wall times are the caller's (s, any
// epoch, one time base); the conversions turn a DiagnosticReport into a diagnostic_msgs/DiagnosticStatus.

#include <cstddef>
#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "vrm_tracking/camera_watchdog.h"
#include "vrm_tracking/frame_sync.h"
#include "vrm_tracking/pose_tracker.h"

namespace vrm_tracking {

// Values as diagnostic_msgs/DiagnosticStatus's levels.
enum class HealthLevel : std::uint8_t { kOk = 0, kWarn = 1, kError = 2 };

struct DiagnosticReport {
  HealthLevel level = HealthLevel::kOk;
  std::string message;
  std::vector<std::pair<std::string, std::string>> values;  // key, value; in display order
};

// What the tracker takes from the running scene, as key/values for its status (so a test or an operator sees which
// geometry the poses rest on after a scene switch): "scene" (its name), "eye_centre" (world, m, "x y z") and per
// instrument slot "trocar_SLOT" (eye frame, m, "x y z") and "trocar_SLOT_azimuth_deg" (atan2(y, x) about the optical
// axis in [0, 360), as scene files write trocars). Metres with 6 decimals (1 um), degrees with 2.
std::vector<std::pair<std::string, std::string>> sceneGeometryValues(const std::string& scene_name,
                                                                     const MarkerLayout& layout);

class TrackerDiagnostics {
 public:
  // `stale_timeout` (s): how long cameras may take to deliver their first markers after `start_wall`.
  TrackerDiagnostics(std::vector<std::string> camera_names, double stale_timeout, double start_wall);

  // Markers of `camera` arrived at wall time `now` (whether or not its frame was still open).
  void onCameraMarkers(std::size_t camera, double now);
  // A frame was reconstructed from `frame` with `result`.
  void onFrame(const SyncedFrame& frame, const TrackingResult& result);
  // Held poses were published (no camera delivering).
  void onHeldFrame() { ++held_; }
  // A camera's recovery (CameraWatchdog::recoveries), shown with that camera until the next one.
  void onRecovery(const CameraRecovery& recovery);

  // The status of the period since the previous report (or the start) at wall time `now`; resets the period's
  // counters. `watchdog` tells whether poses are being held and each camera's timeout.
  DiagnosticReport report(double now, const CameraWatchdog& watchdog);

  // Why each camera absent from `frame` is missing at wall time `now`: no frame yet; silent (dropped out); late (its
  // frames came after their frame was reconstructed: detection runs behind, e.g. a saturated CPU); or its frame
  // missed the sync window. "; "-separated, one clause per missing camera.
  std::string whyMissing(const SyncedFrame& frame, double now, const FrameSynchronizer& sync) const;

 private:
  void resetPeriod(double now);

  std::vector<std::string> names_;
  double stale_timeout_;
  double start_wall_;
  double last_report_wall_;
  std::vector<std::optional<double>> last_wall_;  // per camera: arrival of its newest markers
  std::map<std::size_t, std::string> last_recovery_;
  // The period's counters.
  std::vector<int> missing_;  // per camera: frames reconstructed without it
  int frames_ = 0, no_reconstruction_ = 0, partial_ = 0, markers_ = 0, cameras_used_ = 0;
  int eye_valid_ = 0, instruments_ = 0, instruments_valid_ = 0, held_ = 0;
  double residual_sum_ = 0.0, residual_max_ = 0.0;
};

}  // namespace vrm_tracking
