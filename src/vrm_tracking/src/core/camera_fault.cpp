#include "vrm_tracking/camera_fault.h"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>

namespace vrm_tracking {
namespace {

std::vector<std::size_t> parseCameras(const std::string& list, const std::vector<std::string>& names) {
  std::vector<std::size_t> cameras;
  if (list == "all") {
    for (std::size_t c = 0; c < names.size(); ++c) cameras.push_back(c);
    return cameras;
  }
  std::stringstream items(list);
  std::string item;
  while (std::getline(items, item, ',')) {
    const auto named = std::find(names.begin(), names.end(), item);
    if (named != names.end()) {
      cameras.push_back(static_cast<std::size_t>(named - names.begin()));
      continue;
    }
    const bool digits = !item.empty() && item.size() < 6 &&
                        std::all_of(item.begin(), item.end(), [](char ch) { return ch >= '0' && ch <= '9'; });
    if (!digits || std::stoul(item) >= names.size()) {
      throw std::invalid_argument("camera fault: unknown camera '" + item + "'");
    }
    cameras.push_back(std::stoul(item));
  }
  if (cameras.empty()) throw std::invalid_argument("camera fault: no camera given");
  std::sort(cameras.begin(), cameras.end());
  cameras.erase(std::unique(cameras.begin(), cameras.end()), cameras.end());
  return cameras;
}

}  // namespace

CameraFault parseCameraFault(const std::string& command, const std::vector<std::string>& camera_names) {
  std::istringstream in(command);
  std::vector<std::string> words;
  for (std::string w; in >> w;) words.push_back(w);
  if (words.empty()) throw std::invalid_argument("camera fault: empty command (stop CAMERAS [SECONDS] | resume)");
  CameraFault fault;
  if (words[0] == "resume") {
    if (words.size() > 2) throw std::invalid_argument("camera fault: resume takes at most a camera list");
    fault.action = CameraFault::Action::kResume;
    fault.cameras = parseCameras(words.size() == 2 ? words[1] : "all", camera_names);
    return fault;
  }
  if (words[0] != "stop") {
    throw std::invalid_argument("camera fault: unknown command '" + words[0] + "' (stop CAMERAS [SECONDS] | resume)");
  }
  if (words.size() < 2 || words.size() > 3) throw std::invalid_argument("camera fault: stop CAMERAS [SECONDS]");
  fault.cameras = parseCameras(words[1], camera_names);
  if (words.size() == 3) {
    std::size_t used = 0;
    try {
      fault.seconds = std::stod(words[2], &used);
    } catch (const std::exception&) {
      used = 0;
    }
    if (used != words[2].size() || !std::isfinite(fault.seconds) || fault.seconds <= 0.0) {
      throw std::invalid_argument("camera fault: bad duration '" + words[2] + "' (seconds > 0)");
    }
  }
  return fault;
}

}  // namespace vrm_tracking
