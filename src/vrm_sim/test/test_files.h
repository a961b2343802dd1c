#pragma once
// Reading what the tools and launch files wrote (result files, JSON lines), shared by the unit and graph tests.
#include <filesystem>
#include <fstream>
#include <iterator>
#include <regex>
#include <string>

namespace vrm_sim {
namespace test {

inline std::string readText(const std::filesystem::path& path) {
  std::ifstream file(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(file), {});
}

// The value of "key" in a flat JSON object (a string without its quotes, or a number / literal as written); "" if
// absent.
inline std::string jsonField(const std::string& json, const std::string& key) {
  const std::regex pattern("\"" + key + "\": *(\"[^\"]*\"|[^,}\\s]+)");
  std::smatch match;
  if (!std::regex_search(json, match, pattern)) return "";
  std::string value = match[1];
  if (value.size() >= 2 && value.front() == '"') value = value.substr(1, value.size() - 2);
  return value;
}

}  // namespace test
}  // namespace vrm_sim
