#include "vrm_sim/result/session_result.h"

#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>

namespace vrm_sim {
namespace result {
namespace {

using Json = nlohmann::ordered_json;  // keys in the order they are written, as the hand-written writer had them

bool sameNumber(double a, double b) { return a == b || (std::isnan(a) && std::isnan(b)); }

// JSON has no NaN or infinity: a metric without samples is null. Integral values are written as integers ("7", not
// "7.0") and others to 15 significant digits, the text the hand-written writer produced (so records keyed by a
// stamp's text, and scripts comparing it, are unchanged).
Json number(double value) {
  if (!std::isfinite(value)) return nullptr;
  if (std::fabs(value) < 9007199254740992.0 && value == std::trunc(value)) return static_cast<std::int64_t>(value);
  char text[32];
  std::snprintf(text, sizeof(text), "%.15g", value);
  return std::strtod(text, nullptr);  // nlohmann prints the shortest text that reads back as this double
}

Json optionalString(const std::optional<std::string>& value) { return value ? Json(*value) : Json(nullptr); }

// nlohmann's dump() knows no ", " / ": " separators; the scalars are its own (escaping, shortest round-trip numbers).
void write(const Json& value, std::string& out) {
  if (value.is_object()) {
    out += '{';
    bool first = true;
    for (const auto& [key, member] : value.items()) {
      if (!first) out += ", ";
      first = false;
      out += Json(key).dump(-1, ' ', false, Json::error_handler_t::replace);
      out += ": ";
      write(member, out);
    }
    out += '}';
  } else if (value.is_array()) {
    out += '[';
    for (std::size_t i = 0; i < value.size(); ++i) {
      if (i) out += ", ";
      write(value[i], out);
    }
    out += ']';
  } else {
    // Invalid UTF-8 in a scene name or message is replaced, not an exception in the middle of writing a result.
    out += value.dump(-1, ' ', false, Json::error_handler_t::replace);
  }
}

// Absent and null read as the default (the writer writes null for what it does not know); any other type mismatch
// is an error naming the source and the key, so a wrong file is reported instead of read as zeros.
class Fields {
 public:
  Fields(const nlohmann::json& object, const std::string& source, std::string where)
      : object_(object), source_(source), where_(std::move(where)) {}

  [[noreturn]] void fail(const std::string& key, const std::string& what) const {
    throw ResultError(source_ + ": result field " + where_ + "\"" + key + "\" " + what);
  }

  const nlohmann::json* find(const std::string& key) const {
    const auto it = object_.find(key);
    if (it == object_.end() || it->is_null()) return nullptr;
    return &*it;
  }

  bool present(const std::string& key) const { return object_.find(key) != object_.end(); }

  std::optional<std::string> optionalString(const std::string& key) const {
    const nlohmann::json* value = find(key);
    if (value == nullptr) return std::nullopt;
    if (!value->is_string()) fail(key, "is not a string");
    return value->get<std::string>();
  }

  std::string string(const std::string& key) const { return optionalString(key).value_or(""); }

  std::string required(const std::string& key) const {
    if (!present(key)) fail(key, "is missing (required)");
    const std::optional<std::string> value = optionalString(key);
    if (!value || value->empty()) fail(key, "is null or empty (required)");
    return *value;
  }

  bool boolean(const std::string& key) const {
    const nlohmann::json* value = find(key);
    if (value == nullptr) return false;
    if (!value->is_boolean()) fail(key, "is not true or false");
    return value->get<bool>();
  }

  double number(const std::string& key, double absent) const {
    const auto it = object_.find(key);
    if (it == object_.end()) return absent;
    if (it->is_null()) return kUnknown;  // written for NaN / infinity
    if (!it->is_number()) fail(key, "is not a number");
    return it->get<double>();
  }

  std::uint64_t count(const std::string& key, std::uint64_t max) const {
    const nlohmann::json* value = find(key);
    if (value == nullptr) return 0;
    // nlohmann reads "-0" as a signed integer: still a count (as in Python).
    if (value->is_number_unsigned() || (value->is_number_integer() && value->get<std::int64_t>() >= 0)) {
      const auto n = value->get<std::uint64_t>();
      if (n <= max) return n;
      fail(key, "is out of range");
    }
    // 7.0 written by a float formatter is still a count; 7.5 or -1 is not.
    if (value->is_number_float()) {
      const double d = value->get<double>();
      if (d >= 0.0 && d <= static_cast<double>(max) && d == std::trunc(d)) return static_cast<std::uint64_t>(d);
    }
    if (value->is_number()) fail(key, "is not a non-negative integer in range");
    fail(key, "is not a number");
  }

 private:
  const nlohmann::json& object_;
  const std::string& source_;
  std::string where_;
};

constexpr std::uint64_t kMaxCount = static_cast<std::uint64_t>(std::numeric_limits<std::int64_t>::max());

}  // namespace

bool ScoreItem::operator==(const ScoreItem& o) const {
  return name == o.name && sameNumber(value, o.value) && unit == o.unit && sameNumber(weight, o.weight) &&
         sameNumber(points, o.points);
}

bool GroupScore::operator==(const GroupScore& o) const {
  return name == o.name && sameNumber(points, o.points) && sameNumber(weight, o.weight);
}

bool PenaltyEvent::operator==(const PenaltyEvent& o) const {
  return sameNumber(time, o.time) && kind == o.kind && item == o.item && slot == o.slot && instrument == o.instrument &&
         sameNumber(position[0], o.position[0]) && sameNumber(position[1], o.position[1]) &&
         sameNumber(position[2], o.position[2]) && sameNumber(points, o.points);
}

bool SessionResult::operator==(const SessionResult& o) const {
  return scene == o.scene && scene_file == o.scene_file && scenario == o.scenario && difficulty == o.difficulty &&
         seed == o.seed && state == o.state && session_ended == o.session_ended && timed_out == o.timed_out &&
         message == o.message && sameNumber(start_stamp, o.start_stamp) && sameNumber(end_stamp, o.end_stamp) &&
         sameNumber(elapsed, o.elapsed) && sameNumber(total, o.total) && items == o.items && groups == o.groups &&
         events == o.events && events_dropped == o.events_dropped && final_state_hash == o.final_state_hash &&
         frames == o.frames && simulated_frames == o.simulated_frames && late_inputs == o.late_inputs &&
         frames_without_source == o.frames_without_source && input_frames == o.input_frames &&
         sameNumber(last_frame_stamp, o.last_frame_stamp) && software_version == o.software_version && bag == o.bag &&
         user == o.user && station == o.station && in_progress == o.in_progress && interrupted == o.interrupted;
}

std::string toJson(const SessionResult& r) {
  Json j;
  j["scene"] = r.scene;
  j["scene_file"] = r.scene_file;
  j["scenario"] = optionalString(r.scenario);
  j["difficulty"] = optionalString(r.difficulty);
  j["seed"] = r.seed;
  j["state"] = optionalString(r.state);
  j["session_ended"] = r.session_ended;
  if (r.scenario) {
    j["timed_out"] = r.timed_out;
    j["message"] = r.message;
    j["start_stamp"] = number(r.start_stamp);
    j["end_stamp"] = number(r.end_stamp);
    j["elapsed"] = number(r.elapsed);
    j["total"] = number(r.total);
    Json items = Json::array();
    for (const ScoreItem& item : r.items) {
      Json row;
      row["name"] = item.name;
      row["value"] = number(item.value);
      row["unit"] = item.unit;
      row["weight"] = number(item.weight);
      row["points"] = number(item.points);
      items.push_back(std::move(row));
    }
    j["items"] = std::move(items);
    Json groups = Json::array();
    for (const GroupScore& group : r.groups) {
      Json row;
      row["name"] = group.name;
      row["points"] = number(group.points);
      row["weight"] = number(group.weight);
      groups.push_back(std::move(row));
    }
    j["groups"] = std::move(groups);
    Json events = Json::array();
    for (const PenaltyEvent& event : r.events) {
      Json row;
      row["time"] = number(event.time);
      row["kind"] = event.kind;
      row["item"] = event.item;
      row["slot"] = event.slot;
      row["instrument"] = event.instrument;
      row["position"] = Json::array({number(event.position[0]), number(event.position[1]), number(event.position[2])});
      row["points"] = number(event.points);
      events.push_back(std::move(row));
    }
    j["events"] = std::move(events);
    j["events_dropped"] = r.events_dropped;
  } else {
    j["total"] = nullptr;
  }
  j["final_state_hash"] = r.final_state_hash;
  j["frames"] = r.frames;
  j["simulated_frames"] = r.simulated_frames;
  j["late_inputs"] = r.late_inputs;
  j["frames_without_source"] = r.frames_without_source;
  j["input_frames"] = r.input_frames;
  j["last_frame_stamp"] = number(r.last_frame_stamp);
  j["software_version"] = r.software_version;
  j["bag"] = optionalString(r.bag);
  j["user"] = optionalString(r.user);
  j["station"] = r.station;
  j["in_progress"] = r.in_progress;
  if (r.interrupted) j["interrupted"] = true;
  std::string out;
  write(j, out);
  return out + "\n";
}

SessionResult resultFromJson(const std::string& json_text, const std::string& source) {
  nlohmann::json root;
  try {
    root = nlohmann::json::parse(json_text);
  } catch (const nlohmann::json::exception& error) {
    // parse_error, and out_of_range for a number beyond a double (1e400): both are text that is no result.
    throw ResultError(source + ": malformed result JSON: " + error.what());
  }
  if (!root.is_object()) throw ResultError(source + ": the result JSON is not an object");

  const Fields field(root, source, "");
  SessionResult r;
  r.scene = field.required("scene");
  r.final_state_hash = field.required("final_state_hash");
  if (!field.present("frames") || root["frames"].is_null()) field.fail("frames", "is missing (required)");
  r.frames = field.count("frames", kMaxCount);
  r.scene_file = field.string("scene_file");
  r.scenario = field.optionalString("scenario");
  r.difficulty = field.optionalString("difficulty");
  r.seed = static_cast<std::uint32_t>(field.count("seed", std::numeric_limits<std::uint32_t>::max()));
  r.state = field.optionalString("state");
  r.session_ended = field.boolean("session_ended");
  r.timed_out = field.boolean("timed_out");
  r.message = field.string("message");
  r.start_stamp = field.number("start_stamp", 0.0);
  r.end_stamp = field.number("end_stamp", 0.0);
  r.elapsed = field.number("elapsed", kUnknown);
  r.total = field.number("total", kUnknown);
  if (const nlohmann::json* items = field.find("items")) {
    if (!items->is_array()) field.fail("items", "is not an array");
    for (std::size_t i = 0; i < items->size(); ++i) {
      const nlohmann::json& row = (*items)[i];
      const std::string where = "items[" + std::to_string(i) + "].";
      if (!row.is_object()) field.fail("items", "has an element that is not an object (" + where + ")");
      const Fields item_field(row, source, where);
      ScoreItem item;
      item.name = item_field.string("name");
      if (item.name.empty()) item_field.fail("name", "is missing or empty");
      item.value = item_field.number("value", kUnknown);
      item.unit = item_field.string("unit");
      item.weight = item_field.number("weight", 0.0);
      item.points = item_field.number("points", kUnknown);
      r.items.push_back(std::move(item));
    }
  }
  if (const nlohmann::json* groups = field.find("groups")) {
    if (!groups->is_array()) field.fail("groups", "is not an array");
    for (std::size_t i = 0; i < groups->size(); ++i) {
      const nlohmann::json& row = (*groups)[i];
      const std::string where = "groups[" + std::to_string(i) + "].";
      if (!row.is_object()) field.fail("groups", "has an element that is not an object (" + where + ")");
      const Fields group_field(row, source, where);
      GroupScore group;
      group.name = group_field.string("name");
      if (group.name.empty()) group_field.fail("name", "is missing or empty");
      group.points = group_field.number("points", kUnknown);
      group.weight = group_field.number("weight", 0.0);
      r.groups.push_back(std::move(group));
    }
  }
  if (const nlohmann::json* events = field.find("events")) {
    if (!events->is_array()) field.fail("events", "is not an array");
    for (std::size_t i = 0; i < events->size(); ++i) {
      const nlohmann::json& row = (*events)[i];
      const std::string where = "events[" + std::to_string(i) + "].";
      if (!row.is_object()) field.fail("events", "has an element that is not an object (" + where + ")");
      const Fields event_field(row, source, where);
      PenaltyEvent event;
      event.time = event_field.number("time", kUnknown);
      event.kind = event_field.string("kind");
      if (event.kind.empty()) event_field.fail("kind", "is missing or empty");
      event.item = event_field.string("item");
      event.slot = event_field.string("slot");
      event.instrument = event_field.string("instrument");
      if (const nlohmann::json* position = event_field.find("position")) {
        if (!position->is_array() || position->size() != 3) event_field.fail("position", "is not an array of 3");
        for (std::size_t axis = 0; axis < 3; ++axis) {
          const nlohmann::json& coordinate = (*position)[axis];
          if (coordinate.is_null()) continue;
          if (!coordinate.is_number()) event_field.fail("position", "has an element that is not a number or null");
          event.position[axis] = coordinate.get<double>();
        }
      }
      event.points = event_field.number("points", kUnknown);
      r.events.push_back(std::move(event));
    }
  }
  r.events_dropped = field.count("events_dropped", kMaxCount);
  r.simulated_frames = field.count("simulated_frames", kMaxCount);
  r.late_inputs = field.count("late_inputs", kMaxCount);
  r.frames_without_source = field.count("frames_without_source", kMaxCount);
  r.input_frames = field.count("input_frames", kMaxCount);
  r.last_frame_stamp = field.number("last_frame_stamp", 0.0);
  r.software_version = field.string("software_version");
  r.bag = field.optionalString("bag");
  r.user = field.optionalString("user");
  r.station = field.string("station");
  r.in_progress = field.boolean("in_progress");
  r.interrupted = field.boolean("interrupted");
  return r;
}

SessionResult readResultFile(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw ResultError(path + ": cannot read the result file: " + std::strerror(errno));
  std::ostringstream text;
  text << in.rdbuf();
  return resultFromJson(text.str(), path);
}

void writeResultFile(const std::string& path, const SessionResult& result) {
  const std::string temporary = path + ".tmp";
  {
    std::ofstream file(temporary, std::ios::binary | std::ios::trunc);
    file << toJson(result);
    file.flush();
    if (!file) throw ResultError(temporary + ": cannot write the result file");
  }
  if (std::rename(temporary.c_str(), path.c_str()) != 0) {
    const std::string reason = std::strerror(errno);
    std::remove(temporary.c_str());
    throw ResultError(path + ": cannot write the result file: " + reason);
  }
}

SessionResult interrupted(SessionResult provisional) {
  provisional.in_progress = false;
  provisional.interrupted = true;
  if (provisional.state == std::string("running")) provisional.state = "interrupted";
  return provisional;
}

std::string interruptedPath(const std::string& path) {
  const std::string suffix = ".result.json";
  const std::string stem =
      path.size() > suffix.size() && path.compare(path.size() - suffix.size(), suffix.size(), suffix) == 0
          ? path.substr(0, path.size() - suffix.size())
          : path;
  std::string kept = stem + ".interrupted.result.json";
  std::error_code error;
  for (int n = 2; std::filesystem::exists(kept, error); ++n) {
    kept = stem + ".interrupted-" + std::to_string(n) + ".result.json";
  }
  return kept;
}

}  // namespace result
}  // namespace vrm_sim
