#pragma once
// Where the ROS layer (nodelets, nodes, rosrun tools) finds vrm_sim's shipped data: the package directory that
// ROS_PACKAGE_PATH names, so a devel space reads the source package and an install space <prefix>/share/vrm_sim;
// never a path compiled in (issue 18: a deployed machine has no source tree).

#include <string>

namespace vrm_sim {

// Finds the vrm_sim package (ros::package::getPath, no master needed) and hands its directory to the ROS-free core
// (scene::setPackageDirectory), once per process; later calls return the same directory. Returns it, or "" when
// vrm_sim is not on ROS_PACKAGE_PATH (no setup.bash sourced): then a shipped scene's name is a SceneError that says
// so, while scene files given by path still load.
std::string usePackageData();

}  // namespace vrm_sim
