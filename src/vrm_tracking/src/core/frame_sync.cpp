#include "vrm_tracking/frame_sync.h"

#include <utility>

namespace vrm_tracking {

std::vector<CameraObservations> SyncedFrame::observations() const {
  std::vector<CameraObservations> all;
  all.reserve(cameras.size());
  for (const auto& entry : cameras) all.push_back(entry.second);
  return all;
}

FrameSynchronizer::FrameSynchronizer(std::size_t cameras, StampNs sync_window_ns)
    : window_(sync_window_ns), late_frames_(cameras, 0) {}

SyncedFrame FrameSynchronizer::take(std::map<StampNs, SyncedFrame>::iterator it) {
  SyncedFrame frame = std::move(it->second);
  pending_.erase(it);
  last_processed_ = frame.stamp;
  return frame;
}

FrameSynchronizer::Verdict FrameSynchronizer::add(std::size_t camera, StampNs stamp, std::uint32_t seq,
                                                  std::vector<Blob> blobs, std::vector<SyncedFrame>* ready) {
  if (last_held_ && stamp <= *last_held_) return Verdict::kDuringHold;
  if (last_processed_ && stamp <= *last_processed_) {
    ++late_frames_.at(camera);
    return Verdict::kLate;
  }
  SyncedFrame& frame = pending_[stamp];
  frame.stamp = stamp;
  frame.seq = seq;
  frame.cameras[camera] = CameraObservations{camera, std::move(blobs)};

  // Older frames that can no longer complete: reconstructed with the cameras they have, in stamp order.
  while (!pending_.empty() && pending_.begin()->first + window_ < stamp) ready->push_back(take(pending_.begin()));
  const auto it = pending_.find(stamp);
  if (it != pending_.end() && it->second.cameras.size() == late_frames_.size()) {
    while (pending_.begin() != it) ready->push_back(take(pending_.begin()));
    ready->push_back(take(it));
  }
  return Verdict::kAccepted;
}

std::vector<SyncedFrame> FrameSynchronizer::flushAll() {
  std::vector<SyncedFrame> all;
  while (!pending_.empty()) all.push_back(take(pending_.begin()));
  return all;
}

}  // namespace vrm_tracking
