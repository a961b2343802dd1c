#include "vrm_sim/package_data.h"

#include <ros/package.h>

#include <mutex>

#include "vrm_sim/scene/scene_loader.h"

namespace vrm_sim {

std::string usePackageData() {
  static std::mutex mutex;
  std::lock_guard<std::mutex> lock(mutex);
  std::string directory = scene::packageDirectory();
  if (!directory.empty()) return directory;
  directory = ros::package::getPath("vrm_sim");
  if (!directory.empty()) scene::setPackageDirectory(directory);
  return directory;
}

}  // namespace vrm_sim
