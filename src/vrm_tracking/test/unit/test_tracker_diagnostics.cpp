// The tracker's health report (tracker_diagnostics.h), without ROS: wall times are plain seconds.
#include <gtest/gtest.h>

#include <string>

#include "vrm_tracking/tracker_diagnostics.h"

namespace vrm_tracking {
namespace {

std::string value(const DiagnosticReport& report, const std::string& key) {
  for (const auto& [k, v] : report.values) {
    if (k == key) return v;
  }
  return "<missing>";
}

SyncedFrame frameWith(std::initializer_list<std::size_t> cameras) {
  SyncedFrame frame;
  for (std::size_t c : cameras) frame.cameras[c] = CameraObservations{c, {}};
  return frame;
}

TrackingResult validResult() {
  TrackingResult result;
  MarkerEstimate m;
  m.valid = true;
  m.cameras = 3;
  m.rms_px = 0.2;
  result.markers = {m, m};
  result.eye.valid = true;
  InstrumentEstimate est;
  est.valid = true;
  result.instruments = {est};
  return result;
}

class TrackerDiagnosticsTest : public ::testing::Test {
 protected:
  CameraWatchdogConfig config() {
    CameraWatchdogConfig c;
    c.timeout = 0.25;
    return c;
  }
  CameraWatchdog watchdog_{3, config()};
  TrackerDiagnostics diagnostics_{{"camera_0", "camera_1", "camera_2"}, 1.0, 100.0};
};

TEST_F(TrackerDiagnosticsTest, NoMarkersYetWarnsThenErrsAfterTheStaleTimeout) {
  DiagnosticReport early = diagnostics_.report(100.5, watchdog_);
  EXPECT_EQ(early.level, HealthLevel::kWarn);
  EXPECT_EQ(early.message, "no marker frames yet");
  EXPECT_EQ(value(early, "camera_0 last markers age s"), "never");
  EXPECT_EQ(diagnostics_.report(101.5, watchdog_).level, HealthLevel::kError);
}

TEST_F(TrackerDiagnosticsTest, AllCamerasLiveIsOkAndTheCountersCoverOnePeriod) {
  for (std::size_t c = 0; c < 3; ++c) {
    watchdog_.onCameraFrame(c, 1'000'000'000, 100.9);
    diagnostics_.onCameraMarkers(c, 100.9);
  }
  diagnostics_.onFrame(frameWith({0, 1, 2}), validResult());
  diagnostics_.onFrame(frameWith({0, 1, 2}), validResult());
  const DiagnosticReport report = diagnostics_.report(101.0, watchdog_);
  EXPECT_EQ(report.level, HealthLevel::kOk) << report.message;
  EXPECT_EQ(report.message, "tracking with 3 cameras");
  EXPECT_EQ(value(report, "frames"), "2");
  EXPECT_EQ(value(report, "rate hz"), "2");
  EXPECT_EQ(value(report, "cameras used per marker (mean)"), "3");
  EXPECT_EQ(value(report, "reprojection rms px (max)"), "0.2");
  EXPECT_EQ(value(report, "instruments valid"), "2 of 2");
  EXPECT_EQ(value(diagnostics_.report(101.1, watchdog_), "frames"), "0");  // reset
}

TEST_F(TrackerDiagnosticsTest, AMissingCameraIsAWarningNamingIt) {
  for (std::size_t c = 0; c < 3; ++c) diagnostics_.onCameraMarkers(c, 100.1);
  for (std::size_t c = 0; c < 2; ++c) diagnostics_.onCameraMarkers(c, 101.0);
  diagnostics_.onFrame(frameWith({0, 1}), validResult());
  const DiagnosticReport report = diagnostics_.report(101.0, watchdog_);
  EXPECT_EQ(report.level, HealthLevel::kWarn);
  EXPECT_NE(report.message.find("camera_2 missing for 0.9 s"), std::string::npos) << report.message;
  EXPECT_NE(report.message.find("1 of 1 frames with a camera missing (camera_2)"), std::string::npos) << report.message;
  EXPECT_EQ(value(report, "camera_2 frames missing"), "1");
}

TEST_F(TrackerDiagnosticsTest, WhyMissingTellsNoFrameSilentLateAndWindow) {
  FrameSynchronizer sync(3, 30'000'000);
  std::vector<SyncedFrame> ready;
  sync.add(2, 100, 0, {}, &ready);
  sync.add(0, 100, 0, {}, &ready);
  sync.add(1, 100, 0, {}, &ready);
  sync.add(2, 100, 0, {}, &ready);  // late
  diagnostics_.onCameraMarkers(1, 100.0);
  diagnostics_.onCameraMarkers(2, 100.9);
  EXPECT_EQ(diagnostics_.whyMissing(frameWith({}), 101.0, sync),
            "camera_0: no frame yet; camera_1: silent for 1.0 s, the camera dropped out; camera_2: late, 1 of its "
            "frames came after the 30 ms sync window so far: its detection runs behind, e.g. on a saturated CPU");
  diagnostics_.onCameraMarkers(0, 100.95);
  EXPECT_EQ(diagnostics_.whyMissing(frameWith({1, 2}), 101.0, sync), "camera_0: no frame within the 30 ms sync window");
}

TEST_F(TrackerDiagnosticsTest, HoldingIsAnErrorAndTheRecoveryIsShown) {
  watchdog_.onCameraFrame(0, 1'000'000'000, 100.0);
  diagnostics_.onCameraMarkers(0, 100.0);
  watchdog_.onFrameReconstructed(1'000'000'000, 1);
  diagnostics_.onHeldFrame();
  const DiagnosticReport holding = diagnostics_.report(101.0, watchdog_);
  ASSERT_TRUE(watchdog_.holding(101.0));
  EXPECT_EQ(holding.level, HealthLevel::kError);
  EXPECT_NE(holding.message.find("holding the last poses"), std::string::npos) << holding.message;
  CameraRecovery recovery;
  recovery.camera = 1;
  recovery.frames = 2;
  recovery.silent_s = 1.5;
  recovery.returned = 3'000'000'000;
  diagnostics_.onRecovery(recovery);
  EXPECT_EQ(value(diagnostics_.report(101.1, watchdog_), "camera_1 last recovery"),
            "2 frame(s) after 1.50 s silent (back at 3.000)");
}

}  // namespace
}  // namespace vrm_tracking
