#include "eyesi_gui/records/result_json.h"

#include <limits>
#include <nlohmann/json.hpp>

namespace eyesi_gui::records {
namespace {

using nlohmann::json;

// The field readers treat absent and null alike (the scenario_manager writes null for what it does not know) and
// reject every other type mismatch, so a wrong file is reported instead of stored as zeros.
class FieldReader {
 public:
  FieldReader(const json& object, std::string origin, std::string where)
      : object_(object), origin_(std::move(origin)), where_(std::move(where)) {}

  [[noreturn]] void fail(const std::string& key, const std::string& what) const {
    throw StoreError(origin_ + ": result field " + where_ + "\"" + key + "\" " + what);
  }

  const json* find(const std::string& key) const {
    const auto it = object_.find(key);
    if (it == object_.end() || it->is_null()) return nullptr;
    return &*it;
  }

  std::string string(const std::string& key) const {
    const json* value = find(key);
    if (value == nullptr) return "";
    if (!value->is_string()) fail(key, "is not a string");
    return value->get<std::string>();
  }

  double number(const std::string& key) const {
    const json* value = find(key);
    if (value == nullptr) return 0.0;
    // The simulator writes a metric that had no samples (NaN, infinite) as null: no number, not an error.
    if (value->is_null()) return std::numeric_limits<double>::quiet_NaN();
    if (!value->is_number()) fail(key, "is not a number");
    return value->get<double>();
  }

  std::uint64_t count(const std::string& key, std::uint64_t max) const {
    const json* value = find(key);
    if (value == nullptr) return 0;
    if (value->is_number_unsigned()) {
      const auto n = value->get<std::uint64_t>();
      if (n <= max) return n;
      fail(key, "is out of range");
    }
    // 7.0 written by a float formatter is still a count; 7.5 or -1 is not.
    if (value->is_number_float()) {
      const double d = value->get<double>();
      if (d >= 0.0 && d <= static_cast<double>(max) && d == static_cast<double>(static_cast<std::uint64_t>(d))) {
        return static_cast<std::uint64_t>(d);
      }
    }
    if (value->is_number()) fail(key, "is not a non-negative integer in range");
    fail(key, "is not a number");
  }

 private:
  const json& object_;
  std::string origin_;
  std::string where_;
};

}  // namespace

SessionRecord parseResultJson(const std::string& json_text, const std::string& origin) {
  json root;
  try {
    root = json::parse(json_text);
  } catch (const json::parse_error& e) {
    throw StoreError(origin + ": malformed result JSON: " + e.what());
  }
  if (!root.is_object()) throw StoreError(origin + ": result JSON is not an object");

  const FieldReader field(root, origin, "");
  SessionRecord s;
  s.scene = field.string("scene");
  if (s.scene.empty()) field.fail("scene", "is missing or empty");
  s.scenario = field.string("scenario");
  s.difficulty = field.string("difficulty");
  s.seed = static_cast<std::uint32_t>(field.count("seed", std::numeric_limits<std::uint32_t>::max()));
  s.state = field.string("state");
  s.passed = s.state == "finished";
  s.message = field.string("message");
  s.start_stamp = field.number("start_stamp");
  s.end_stamp = field.number("end_stamp");
  s.elapsed = field.number("elapsed");
  s.total = field.number("total");
  s.final_state_hash = field.string("final_state_hash");
  s.frames = field.count("frames", static_cast<std::uint64_t>(std::numeric_limits<std::int64_t>::max()));
  s.software_version = field.string("software_version");
  s.bag_path = field.string("bag");
  s.user = field.string("user");
  s.station = field.string("station");

  if (const json* items = field.find("items")) {
    if (!items->is_array()) field.fail("items", "is not an array");
    for (std::size_t i = 0; i < items->size(); ++i) {
      const json& item = (*items)[i];
      const std::string where = "items[" + std::to_string(i) + "].";
      if (!item.is_object()) field.fail("items", "has an element that is not an object (" + where + ")");
      const FieldReader item_field(item, origin, where);
      ScoreItemRecord record;
      record.name = item_field.string("name");
      if (record.name.empty()) item_field.fail("name", "is missing or empty");
      record.value = item_field.number("value");
      record.unit = item_field.string("unit");
      record.weight = item_field.number("weight");
      record.points = item_field.number("points");
      s.items.push_back(std::move(record));
    }
  }
  return s;
}

}  // namespace eyesi_gui::records
