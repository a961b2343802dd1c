#pragma once
// Where a process finds the shipped data (scenes, scripts, mesh assets): the package directory that ROS_PACKAGE_PATH
// names, so a devel space reads the source package and an install space <prefix>/share/<package>; never a path
// compiled in (issue 18: a deployed machine has no source tree). ROS-free: the crawl follows rospack's rules (a
// directory with a package.xml is a package, its subdirectories are not searched; CATKIN_IGNORE and hidden
// directories are skipped), so the floor links no roslib.

#include <string>

namespace vrm_sim {

// The package whose share directory holds the shipped scene library (config/scenes, config/scripts).
constexpr const char* kSceneDataPackage = "vrm_sim";

// The directory of the package named `name` on ROS_PACKAGE_PATH (the first entry that has it, as rospack finds it),
// or "" when no entry has it (or the variable is unset).
std::string findPackageOnPath(const std::string& name);

// Finds kSceneDataPackage and hands its directory to the scene library (scene::setPackageDirectory), once per
// process; later calls return the same directory. Returns it, or "" when it is not on ROS_PACKAGE_PATH (no
// setup.bash sourced): then a shipped scene's name is a SceneError that says so, while scene files given by path
// still load.
std::string usePackageData();

}  // namespace vrm_sim
