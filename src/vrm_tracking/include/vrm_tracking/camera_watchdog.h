#pragma once
// Camera dropout handling of the tracker (issue 14): which of the rig's cameras went silent, when no camera
// delivers and the last poses must be held, the stamps of those held frames, and how many frames a camera that came
// back needs until the tracker uses every camera again. ROS-free, no clock: liveness is judged on the wall times the
// caller passes (s), stamps are the cameras' exposure stamps in integer nanoseconds (exact on the camera period
// grid, which seconds as double are not at epoch magnitudes).

#include <cstddef>
#include <cstdint>
#include <optional>
#include <vector>

namespace vrm_tracking {

using StampNs = std::int64_t;

struct CameraWatchdogConfig {
  StampNs period_ns = 20'000'000;  // nominal camera period (50 Hz)
  double timeout = 0.06;           // s of wall time without a frame after which a camera counts as missing
};

struct CameraRecovery {
  std::size_t camera = 0;
  StampNs returned = 0;   // stamp of its first frame after the silence
  double silent_s = 0.0;  // wall time it had been silent
  // Frames reconstructed from its return on until one used every camera, that one included: 1 = the first frame
  // after the return already had all cameras.
  int frames = 0;
};

class CameraWatchdog {
 public:
  CameraWatchdog(std::size_t cameras, CameraWatchdogConfig config = CameraWatchdogConfig());

  // A frame of `camera` with exposure `stamp` arrived at wall time `now`. Out-of-range cameras are ignored.
  void onCameraFrame(std::size_t camera, StampNs stamp, double now);
  // The tracker reconstructed (and published) the frame `stamp` with `cameras_used` cameras.
  void onFrameReconstructed(StampNs stamp, std::size_t cameras_used);
  // Held poses were published at `stamp` (from nextHoldStamp).
  void onHeldFrame(StampNs stamp);

  // Cameras silent for longer than the timeout at `now` (never-seen cameras included once any camera delivered).
  std::vector<std::size_t> missing(double now) const;
  // No camera delivered for longer than the timeout, after at least one frame was output (so there is a pose).
  bool holding(double now) const;
  // Wall seconds since the newest camera frame (0 before any).
  double silence(double now) const;
  // The stamp of the held frame due at `now`, if one is: the newest camera stamp advanced by the wall time elapsed
  // since it arrived, rounded to the camera period grid, and strictly after every frame output so far.
  std::optional<StampNs> nextHoldStamp(double now) const;
  // A camera frame whose stamp is not after the last output (normal or held) would break the outputs' monotonic
  // stamps: the tracker drops it (a held frame already stood for that exposure).
  bool accepts(StampNs stamp) const { return !last_output_ || stamp > *last_output_; }

  std::optional<StampNs> lastOutput() const { return last_output_; }
  // Completed recoveries, oldest first; pending ones are not listed until a frame used every camera.
  const std::vector<CameraRecovery>& recoveries() const { return recoveries_; }
  std::size_t heldFrames() const { return held_frames_; }
  const CameraWatchdogConfig& config() const { return config_; }

 private:
  std::size_t cameras_;
  CameraWatchdogConfig config_;
  std::vector<std::optional<double>> last_wall_;  // per camera
  std::optional<double> newest_wall_;             // arrival of the newest frame of any camera
  std::optional<StampNs> newest_stamp_;
  std::optional<StampNs> last_output_;
  std::vector<std::optional<CameraRecovery>> recovering_;  // per camera
  std::vector<CameraRecovery> recoveries_;
  std::size_t held_frames_ = 0;
};

}  // namespace vrm_tracking
