// Camera dropout logic (issue 14) without ROS: missing cameras, the hold when none delivers, held stamps on the
// camera period grid and monotonic, and the recovery count of a camera that comes back.

#include <gtest/gtest.h>

#include "vrm_tracking/camera_watchdog.h"

namespace vrm_tracking {
namespace {

constexpr StampNs kPeriod = 20'000'000;  // 50 Hz
constexpr StampNs kT0 = 1'700'000'000'000'000'000;

// Three cameras deliver ticks [first, last) at 50 Hz, frames arriving `latency` s after their exposure; every tick
// is reconstructed with the cameras that delivered it.
struct Rig {
  CameraWatchdog watchdog{3, CameraWatchdogConfig{kPeriod, 0.06}};
  double wall(int tick, double latency = 0.005) const { return tick * 0.02 + latency; }
  StampNs stamp(int tick) const { return kT0 + tick * kPeriod; }
  void run(int first, int last, const std::vector<std::size_t>& cameras) {
    for (int t = first; t < last; ++t) {
      for (std::size_t c : cameras) watchdog.onCameraFrame(c, stamp(t), wall(t));
      if (watchdog.accepts(stamp(t))) watchdog.onFrameReconstructed(stamp(t), cameras.size());
    }
  }
};

TEST(CameraWatchdog, RejectsABadConfiguration) {
  EXPECT_THROW(CameraWatchdog(3, CameraWatchdogConfig{0, 0.06}), std::invalid_argument);
  EXPECT_THROW(CameraWatchdog(3, CameraWatchdogConfig{kPeriod, 0.0}), std::invalid_argument);
}

TEST(CameraWatchdog, NothingMissingOrHeldBeforeTheFirstFrame) {
  CameraWatchdog w(3);
  EXPECT_TRUE(w.missing(10.0).empty());
  EXPECT_FALSE(w.holding(10.0));
  EXPECT_FALSE(w.nextHoldStamp(10.0));
  EXPECT_TRUE(w.accepts(kT0));
}

TEST(CameraWatchdog, OneCameraStoppedIsMissingButNotAHold) {
  Rig r;
  r.run(0, 50, {0, 1, 2});
  r.run(50, 150, {0, 2});  // camera 1 stops for 2 s
  const double now = r.wall(149) + 0.001;
  EXPECT_EQ(r.watchdog.missing(now), std::vector<std::size_t>{1});
  EXPECT_FALSE(r.watchdog.holding(now));
  EXPECT_FALSE(r.watchdog.nextHoldStamp(now + 0.01));
  EXPECT_TRUE(r.watchdog.recoveries().empty());

  r.run(150, 160, {0, 1, 2});  // it returns: its first frame is a three-camera frame
  ASSERT_EQ(r.watchdog.recoveries().size(), 1u);
  const CameraRecovery& rec = r.watchdog.recoveries().front();
  EXPECT_EQ(rec.camera, 1u);
  EXPECT_EQ(rec.returned, r.stamp(150));
  EXPECT_EQ(rec.frames, 1);
  EXPECT_NEAR(rec.silent_s, 2.02, 1e-9);
  EXPECT_TRUE(r.watchdog.missing(r.wall(159) + 0.001).empty());
}

TEST(CameraWatchdog, RecoveryCountsTheFramesUntilEveryCameraIsUsed) {
  Rig r;
  r.run(0, 10, {0, 1, 2});
  r.run(10, 20, {0, 2});
  // Camera 1's first two frames back arrive too late for their frames (reconstructed with two cameras).
  for (int t = 20; t < 22; ++t) {
    r.watchdog.onCameraFrame(1, r.stamp(t), r.wall(t));
    r.watchdog.onFrameReconstructed(r.stamp(t), 2);
  }
  EXPECT_TRUE(r.watchdog.recoveries().empty());
  r.run(22, 25, {0, 1, 2});
  ASSERT_EQ(r.watchdog.recoveries().size(), 1u);
  EXPECT_EQ(r.watchdog.recoveries().front().frames, 3);
  // Older frames flushed after the return do not count.
  r.watchdog.onFrameReconstructed(r.stamp(5), 2);
  EXPECT_EQ(r.watchdog.recoveries().size(), 1u);
}

TEST(CameraWatchdog, AllStoppedHoldsOnThePeriodGridWithMonotonicStamps) {
  Rig r;
  r.run(0, 50, {0, 1, 2});
  const double last_arrival = r.wall(49);
  // Within the timeout: no hold.
  EXPECT_FALSE(r.watchdog.holding(last_arrival + 0.05));
  EXPECT_FALSE(r.watchdog.nextHoldStamp(last_arrival + 0.05));
  EXPECT_EQ(r.watchdog.missing(last_arrival + 0.05).size(), 0u);
  EXPECT_EQ(r.watchdog.missing(last_arrival + 0.07).size(), 3u);
  // A watchdog tick every 20 ms (with jitter) from there on for 2 s.
  StampNs previous = r.stamp(49);
  int held = 0;
  for (int k = 4; k < 104; ++k) {
    const double now = last_arrival + k * 0.02 + 0.002 * ((k % 3) - 1) + 0.001;
    ASSERT_TRUE(r.watchdog.holding(now));
    const auto stamp = r.watchdog.nextHoldStamp(now);
    if (!stamp) continue;
    EXPECT_GT(*stamp, previous);
    EXPECT_EQ((*stamp - r.stamp(0)) % kPeriod, 0) << "off the camera period grid";
    // Never more than half a period ahead of the elapsed time.
    EXPECT_LE(static_cast<double>(*stamp - r.stamp(49)) * 1e-9, now - last_arrival + 0.01 + 1e-9);
    r.watchdog.onHeldFrame(*stamp);
    EXPECT_FALSE(r.watchdog.nextHoldStamp(now)) << "the same tick twice";
    previous = *stamp;
    ++held;
  }
  EXPECT_EQ(held, 100) << "one held frame per watchdog tick";
  EXPECT_EQ(r.watchdog.heldFrames(), static_cast<std::size_t>(held));

  // The cameras come back: frames exposed at or before the last held stamp are not accepted, newer ones are.
  EXPECT_FALSE(r.watchdog.accepts(previous));
  EXPECT_TRUE(r.watchdog.accepts(previous + kPeriod));
  const int back = static_cast<int>((previous - kT0) / kPeriod) + 1;
  r.run(back, back + 5, {0, 1, 2});
  EXPECT_FALSE(r.watchdog.holding(r.wall(back + 4) + 0.001));
  ASSERT_EQ(r.watchdog.recoveries().size(), 3u);
  for (const CameraRecovery& rec : r.watchdog.recoveries()) EXPECT_EQ(rec.frames, 1);
}

TEST(CameraWatchdog, AReturningFrameCoveredByAHoldIsDroppedAndCountsAgainstRecovery) {
  Rig r;
  r.run(0, 10, {0, 1, 2});
  const double now = r.wall(9) + 0.101;  // 100 ms of silence: 5 periods
  const auto stamp = r.watchdog.nextHoldStamp(now);
  ASSERT_TRUE(stamp);
  EXPECT_EQ(*stamp, r.stamp(14));
  r.watchdog.onHeldFrame(*stamp);
  // Frame 14 arrives late (slow pipeline): dropped; frame 15 is reconstructed with all cameras.
  r.run(14, 16, {0, 1, 2});
  ASSERT_EQ(r.watchdog.recoveries().size(), 3u);
  EXPECT_EQ(r.watchdog.recoveries().front().returned, r.stamp(14));
  EXPECT_EQ(r.watchdog.recoveries().front().frames, 1);
  EXPECT_EQ(*r.watchdog.lastOutput(), r.stamp(15));
}

TEST(CameraWatchdog, IgnoresUnknownCamerasAndNonFiniteTimes) {
  CameraWatchdog w(2);
  w.onCameraFrame(5, kT0, 1.0);
  w.onCameraFrame(0, kT0, std::numeric_limits<double>::quiet_NaN());
  EXPECT_TRUE(w.missing(2.0).empty());
  EXPECT_DOUBLE_EQ(w.silence(2.0), 0.0);
}

}  // namespace
}  // namespace vrm_tracking
