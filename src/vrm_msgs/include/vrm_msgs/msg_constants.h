// The integer constants of a .msg file (`uint8 LOAD=0  # comment`), read from the file itself: what tests compare the
// hand-kept mirrors of message constants with (the console's lists, vrm_sim's instrument types), so that a constant
// added to a message cannot go unnoticed. ROS-free; throws std::runtime_error naming the file.
#pragma once

#include <fstream>
#include <regex>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace vrm_msgs {

struct MsgConstant {
  std::string name;
  long long value = 0;
};

inline std::vector<MsgConstant> readMsgConstants(const std::string& path) {
  std::ifstream file(path);
  if (!file) throw std::runtime_error(path + ": cannot open the message file");
  static const std::regex kInteger(R"(^\s*u?int(8|16|32|64)\s+([A-Za-z_][A-Za-z0-9_]*)\s*=\s*(-?[0-9]+)\s*(#.*)?$)");
  std::vector<MsgConstant> constants;
  std::string line;
  while (std::getline(file, line)) {
    std::smatch match;
    // String and float constants are not what the mirrors hold; fields have no '='.
    if (std::regex_match(line, match, kInteger)) constants.push_back({match[2].str(), std::stoll(match[3].str())});
  }
  return constants;
}

}  // namespace vrm_msgs
