#include "vrm_scene/package_data.h"

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <regex>
#include <sstream>
#include <system_error>

#include "vrm_scene/scene_loader.h"

namespace vrm_sim {
namespace {

namespace fs = std::filesystem;

// The <name> of a package manifest, "" when there is none.
std::string manifestName(const fs::path& manifest) {
  std::ifstream file(manifest);
  std::stringstream text;
  text << file.rdbuf();
  static const std::regex name_tag(R"(<name>\s*([^<\s]+)\s*</name>)");
  std::smatch match;
  const std::string content = text.str();
  return std::regex_search(content, match, name_tag) ? match[1].str() : "";
}

// rospack's crawl, depth-first in directory order, bounded so a path entry of "/" cannot walk the disk.
std::string crawl(const fs::path& directory, const std::string& name, int depth) {
  std::error_code error;
  if (fs::exists(directory / "package.xml", error)) {
    return manifestName(directory / "package.xml") == name ? directory.string() : "";
  }
  if (depth == 0 || fs::exists(directory / "CATKIN_IGNORE", error)) return "";
  fs::directory_iterator entries(directory, fs::directory_options::skip_permission_denied, error);
  if (error) return "";
  for (const fs::directory_entry& entry : entries) {
    const std::string leaf = entry.path().filename().string();
    if (leaf.empty() || leaf[0] == '.' || !entry.is_directory(error)) continue;
    std::string found = crawl(entry.path(), name, depth - 1);
    if (!found.empty()) return found;
  }
  return "";
}

}  // namespace

std::string findPackageOnPath(const std::string& name) {
  const char* path = std::getenv("ROS_PACKAGE_PATH");
  if (path == nullptr) return "";
  std::stringstream entries(path);
  std::string entry;
  while (std::getline(entries, entry, ':')) {
    if (entry.empty()) continue;
    std::string found = crawl(entry, name, 6);
    if (!found.empty()) return found;
  }
  return "";
}

std::string usePackageData() {
  static std::mutex mutex;
  std::lock_guard<std::mutex> lock(mutex);
  std::string directory = scene::packageDirectory();
  if (!directory.empty()) return directory;
  directory = findPackageOnPath(kSceneDataPackage);
  if (!directory.empty()) scene::setPackageDirectory(directory);
  return directory;
}

}  // namespace vrm_sim
