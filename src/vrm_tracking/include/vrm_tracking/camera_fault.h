#pragma once
// Runtime fault injection of the camera rig twin (issue 14, camera dropout tests): a command on
// camera_rig_sim/fault (std_msgs/String) stops cameras for a wall duration or resumes them.
//   stop CAMERAS [SECONDS]   CAMERAS: "all" or a comma-separated list of names (camera_1) or indices (1);
//                            SECONDS > 0, omitted = until resumed
//   resume [CAMERAS]         omitted = all
// ROS-free so the grammar is tested without a master.

#include <string>
#include <vector>

namespace vrm_tracking {

struct CameraFault {
  enum class Action { kStop, kResume };
  Action action = Action::kStop;
  std::vector<std::size_t> cameras;  // indices into the rig, sorted, unique
  double seconds = 0.0;              // stop only; 0 = until resumed
};

// Throws std::invalid_argument (naming the problem) for an unknown verb or camera, or a bad duration.
CameraFault parseCameraFault(const std::string& command, const std::vector<std::string>& camera_names);

}  // namespace vrm_tracking
