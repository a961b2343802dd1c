#pragma once
// Frame assembly of the tracker (issue 5, thesis §7.3.2): the cameras' marker observations grouped by exposure stamp.
// A frame is complete once every camera reported; an older frame is given up waiting once a newer stamp is more than
// the sync window past it, and reconstructed with the cameras it has (a camera that stops costs one frame of latency,
// not the tracking). Frames come out in stamp order, each once. Observations of a stamp at or before the last frame
// out are late (their frame is gone: dropped and counted per camera); those at or before the newest held frame
// (camera_watchdog.h) are dropped too, so the outputs stay monotonic. ROS-free, no clock: stamps are integer
// nanoseconds (exact comparisons).

#include <cstddef>
#include <cstdint>
#include <map>
#include <optional>
#include <vector>

#include "vrm_tracking/camera_watchdog.h"
#include "vrm_tracking/pose_tracker.h"

namespace vrm_tracking {

struct SyncedFrame {
  StampNs stamp = 0;
  std::uint32_t seq = 0;                                 // of the frame's newest camera message (the caller's)
  std::map<std::size_t, CameraObservations> cameras;     // by camera index
  std::vector<CameraObservations> observations() const;  // in camera order, for PoseTracker::update
};

class FrameSynchronizer {
 public:
  enum class Verdict { kAccepted, kDuringHold, kLate };

  FrameSynchronizer(std::size_t cameras, StampNs sync_window_ns);

  // Adds one camera's observations. kAccepted: taken; `ready` receives the frames that are now complete or given up
  // (oldest first, possibly none). kLate / kDuringHold: dropped, `ready` untouched.
  Verdict add(std::size_t camera, StampNs stamp, std::uint32_t seq, std::vector<Blob> blobs,
              std::vector<SyncedFrame>* ready);
  // Every frame still assembling, oldest first (no camera will complete them: a hold starts).
  std::vector<SyncedFrame> flushAll();
  // Held poses went out at `stamp`: camera frames exposed at or before it are dropped from now on.
  void onHeldFrame(StampNs stamp) { last_held_ = stamp; }

  std::size_t cameras() const { return late_frames_.size(); }
  // Per camera: its frames that came after their frame was reconstructed (detection running behind).
  std::size_t lateFrames(std::size_t camera) const { return late_frames_.at(camera); }
  StampNs syncWindow() const { return window_; }

 private:
  SyncedFrame take(std::map<StampNs, SyncedFrame>::iterator it);

  StampNs window_;
  std::map<StampNs, SyncedFrame> pending_;
  std::optional<StampNs> last_processed_;
  std::optional<StampNs> last_held_;
  std::vector<std::size_t> late_frames_;
};

}  // namespace vrm_tracking
