#include "eyesi_gui/records/trajectory.h"

#include <nlohmann/json.hpp>

#include "eyesi_gui/records/store.h"

namespace eyesi_gui::records {

std::string trajectoryJson(const std::vector<TrajectorySample>& samples, const std::string& source_bag) {
  nlohmann::json rows = nlohmann::json::array();
  for (const TrajectorySample& s : samples) {
    rows.push_back({s.frame, s.time, s.source, s.frame_id, s.position[0], s.position[1], s.position[2],
                    s.orientation[0], s.orientation[1], s.orientation[2], s.orientation[3], s.valid});
  }
  return nlohmann::json{{"format", kTrajectoryFormat}, {"source_bag", source_bag}, {"samples", rows}}.dump();
}

std::vector<TrajectorySample> parseTrajectoryJson(const std::string& text, const std::string& origin) {
  const nlohmann::json document = nlohmann::json::parse(text, nullptr, false);
  if (document.is_discarded() || !document.is_object()) throw StoreError(origin + ": not a JSON object");
  if (document.value("format", std::string()) != kTrajectoryFormat) {
    throw StoreError(origin + ": not a trajectory file (format is not \"" + std::string(kTrajectoryFormat) + "\")");
  }
  const auto samples = document.find("samples");
  if (samples == document.end() || !samples->is_array()) throw StoreError(origin + ": no \"samples\" array");
  std::vector<TrajectorySample> result;
  result.reserve(samples->size());
  for (std::size_t i = 0; i < samples->size(); ++i) {
    const nlohmann::json& row = (*samples)[i];
    const auto bad = [&](const std::string& why) {
      return StoreError(origin + ": sample " + std::to_string(i) + ": " + why);
    };
    if (!row.is_array() || row.size() != 12) throw bad("not an array of 12 values");
    if (!row[0].is_number_unsigned() || !row[2].is_string() || !row[3].is_string() || !row[11].is_boolean()) {
      throw bad("frame, source, frame_id or valid of the wrong type");
    }
    TrajectorySample s;
    s.frame = row[0].get<std::uint64_t>();
    s.source = row[2].get<std::string>();
    s.frame_id = row[3].get<std::string>();
    s.valid = row[11].get<bool>();
    double* numbers[] = {&s.time,           &s.position[0],    &s.position[1],    &s.position[2],
                         &s.orientation[0], &s.orientation[1], &s.orientation[2], &s.orientation[3]};
    const int columns[] = {1, 4, 5, 6, 7, 8, 9, 10};
    for (int k = 0; k < 8; ++k) {
      if (!row[columns[k]].is_number()) throw bad("value " + std::to_string(columns[k]) + " is not a number");
      *numbers[k] = row[columns[k]].get<double>();
    }
    result.push_back(std::move(s));
  }
  return result;
}

std::string trajectoryPathFor(const std::string& result_path) {
  const std::string suffix = ".result.json";
  if (result_path.size() > suffix.size() &&
      result_path.compare(result_path.size() - suffix.size(), suffix.size(), suffix) == 0) {
    return result_path.substr(0, result_path.size() - suffix.size()) + ".trajectory.json";
  }
  return result_path + ".trajectory.json";
}

}  // namespace eyesi_gui::records
