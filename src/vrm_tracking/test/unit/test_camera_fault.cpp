// The fault-injection grammar of camera_rig_sim (camera_rig_sim/fault), without ROS.

#include <gtest/gtest.h>

#include "vrm_tracking/camera_fault.h"

namespace vrm_tracking {
namespace {

const std::vector<std::string> kNames{"camera_0", "camera_1", "camera_2"};

TEST(CameraFault, StopsNamedOrIndexedCamerasForADuration) {
  CameraFault f = parseCameraFault("stop camera_1 2.0", kNames);
  EXPECT_EQ(f.action, CameraFault::Action::kStop);
  EXPECT_EQ(f.cameras, std::vector<std::size_t>{1});
  EXPECT_DOUBLE_EQ(f.seconds, 2.0);
  f = parseCameraFault("  stop 2,camera_0,2   0.5 ", kNames);
  EXPECT_EQ(f.cameras, (std::vector<std::size_t>{0, 2}));
  EXPECT_DOUBLE_EQ(f.seconds, 0.5);
  f = parseCameraFault("stop all", kNames);
  EXPECT_EQ(f.cameras, (std::vector<std::size_t>{0, 1, 2}));
  EXPECT_DOUBLE_EQ(f.seconds, 0.0) << "no duration: until resumed";
}

TEST(CameraFault, ResumesAllOrSome) {
  CameraFault f = parseCameraFault("resume", kNames);
  EXPECT_EQ(f.action, CameraFault::Action::kResume);
  EXPECT_EQ(f.cameras, (std::vector<std::size_t>{0, 1, 2}));
  f = parseCameraFault("resume camera_2", kNames);
  EXPECT_EQ(f.cameras, std::vector<std::size_t>{2});
}

TEST(CameraFault, RejectsBadCommandsWithAReason) {
  for (const char* bad : {"", "   ", "halt camera_1", "stop", "stop camera_9", "stop 3", "stop camera_1 -1",
                          "stop camera_1 0", "stop camera_1 nan", "stop camera_1 inf", "stop camera_1 2s",
                          "stop camera_1 2 3", "stop ,", "resume camera_1 2", "stop 99999999999999999999"}) {
    EXPECT_THROW(parseCameraFault(bad, kNames), std::invalid_argument) << "'" << bad << "'";
  }
}

}  // namespace
}  // namespace vrm_tracking
