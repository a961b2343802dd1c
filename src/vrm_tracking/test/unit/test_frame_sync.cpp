// Frame assembly of the tracker (frame_sync.h), without ROS.
#include <gtest/gtest.h>

#include <vector>

#include "vrm_tracking/frame_sync.h"

namespace vrm_tracking {
namespace {

constexpr StampNs kMs = 1'000'000;

std::vector<Blob> oneBlob(int class_id) {
  Blob b;
  b.class_id = class_id;
  return {b};
}

TEST(FrameSync, CompleteFrameComesOutWhenTheLastCameraReports) {
  FrameSynchronizer sync(3, 30 * kMs);
  std::vector<SyncedFrame> ready;
  EXPECT_EQ(sync.add(0, 100 * kMs, 7, oneBlob(0), &ready), FrameSynchronizer::Verdict::kAccepted);
  EXPECT_EQ(sync.add(2, 100 * kMs, 8, oneBlob(2), &ready), FrameSynchronizer::Verdict::kAccepted);
  EXPECT_TRUE(ready.empty());
  EXPECT_EQ(sync.add(1, 100 * kMs, 9, oneBlob(1), &ready), FrameSynchronizer::Verdict::kAccepted);
  ASSERT_EQ(ready.size(), 1u);
  EXPECT_EQ(ready[0].stamp, 100 * kMs);
  EXPECT_EQ(ready[0].seq, 9u);  // the newest message's
  const std::vector<CameraObservations> obs = ready[0].observations();
  ASSERT_EQ(obs.size(), 3u);
  for (std::size_t c = 0; c < 3; ++c) {
    EXPECT_EQ(obs[c].camera, c);
    EXPECT_EQ(obs[c].blobs.at(0).class_id, static_cast<int>(c));
  }
}

TEST(FrameSync, IncompleteFrameIsGivenUpOnceANewerStampIsPastTheWindow) {
  FrameSynchronizer sync(3, 30 * kMs);
  std::vector<SyncedFrame> ready;
  sync.add(0, 100 * kMs, 0, {}, &ready);
  sync.add(1, 100 * kMs, 0, {}, &ready);
  sync.add(0, 120 * kMs, 0, {}, &ready);
  sync.add(0, 130 * kMs, 0, {}, &ready);  // 100 + 30 is not < 130: still waiting
  EXPECT_TRUE(ready.empty());
  sync.add(0, 140 * kMs, 0, {}, &ready);
  ASSERT_EQ(ready.size(), 1u);
  EXPECT_EQ(ready[0].stamp, 100 * kMs);
  EXPECT_EQ(ready[0].cameras.size(), 2u);
}

TEST(FrameSync, ACompleteFrameFlushesTheOlderOnesFirstInStampOrder) {
  FrameSynchronizer sync(2, 30 * kMs);
  std::vector<SyncedFrame> ready;
  sync.add(0, 100 * kMs, 0, {}, &ready);
  sync.add(0, 110 * kMs, 0, {}, &ready);
  sync.add(1, 110 * kMs, 0, {}, &ready);
  ASSERT_EQ(ready.size(), 2u);
  EXPECT_EQ(ready[0].stamp, 100 * kMs);
  EXPECT_EQ(ready[1].stamp, 110 * kMs);
}

TEST(FrameSync, LateCamerasAreDroppedAndCounted) {
  FrameSynchronizer sync(2, 30 * kMs);
  std::vector<SyncedFrame> ready;
  sync.add(0, 100 * kMs, 0, {}, &ready);
  sync.add(1, 100 * kMs, 0, {}, &ready);
  ready.clear();
  EXPECT_EQ(sync.add(1, 100 * kMs, 0, {}, &ready), FrameSynchronizer::Verdict::kLate);
  EXPECT_EQ(sync.add(1, 90 * kMs, 0, {}, &ready), FrameSynchronizer::Verdict::kLate);
  EXPECT_TRUE(ready.empty());
  EXPECT_EQ(sync.lateFrames(1), 2u);
  EXPECT_EQ(sync.lateFrames(0), 0u);
}

TEST(FrameSync, FramesExposedDuringAHoldAreDroppedWithoutCounting) {
  FrameSynchronizer sync(2, 30 * kMs);
  std::vector<SyncedFrame> ready;
  sync.add(0, 100 * kMs, 0, {}, &ready);
  const std::vector<SyncedFrame> flushed = sync.flushAll();
  ASSERT_EQ(flushed.size(), 1u);
  EXPECT_EQ(flushed[0].cameras.size(), 1u);
  sync.onHeldFrame(200 * kMs);
  EXPECT_EQ(sync.add(1, 180 * kMs, 0, {}, &ready), FrameSynchronizer::Verdict::kDuringHold);
  EXPECT_EQ(sync.add(1, 200 * kMs, 0, {}, &ready), FrameSynchronizer::Verdict::kDuringHold);
  EXPECT_EQ(sync.lateFrames(1), 0u);
  EXPECT_EQ(sync.add(1, 220 * kMs, 0, {}, &ready), FrameSynchronizer::Verdict::kAccepted);
  EXPECT_TRUE(sync.flushAll().size() == 1u);
}

}  // namespace
}  // namespace vrm_tracking
