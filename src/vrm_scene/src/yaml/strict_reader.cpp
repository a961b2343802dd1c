#include "vrm_scene/yaml/strict_reader.h"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "vrm_scene/registry.h"

namespace vrm_sim {

YamlError::YamlError(const SourceLocation& location, const std::string& problem)
    : std::runtime_error([&] {
        std::string prefix = location.file;
        if (location.line > 0) prefix += ":" + std::to_string(location.line) + ":" + std::to_string(location.column);
        if (!location.field.empty()) prefix += ": " + location.field;
        return prefix + ": " + problem;
      }()),
      location_(location),
      problem_(problem) {}

namespace yaml {

std::string joinNames(const std::vector<std::string>& names) {
  std::string joined;
  for (const auto& name : names) joined += (joined.empty() ? "" : ", ") + name;
  return joined;
}

SourceLocation Field::location() const {
  SourceLocation location;
  location.file = file_;
  location.field = path_;
  const YAML::Mark mark = node_.Mark();
  if (!mark.is_null()) {
    location.line = mark.line + 1;
    location.column = mark.column + 1;
  }
  return location;
}

void Field::fail(const std::string& problem) const { throw YamlError(location(), problem); }

Field Field::child(const YAML::Node& node, const std::string& key) const {
  return Field(node, path_.empty() ? key : path_ + "." + key, file_);
}

Field Field::item(const YAML::Node& node, std::size_t index) const {
  return Field(node, path_ + "[" + std::to_string(index) + "]", file_);
}

std::string Field::shown() const {
  if (!node_.IsDefined() || node_.IsNull()) return "nothing";
  if (node_.IsScalar()) return "'" + node_.Scalar() + "'";
  if (node_.IsSequence()) return "a list";
  return "a map";
}

std::string Field::text() const {
  if (!node_.IsScalar() || node_.Scalar().empty()) fail("expected a non-empty string, got " + shown());
  return node_.Scalar();
}

double Field::number(const std::string& expectation, double minimum, double maximum, bool minimum_inclusive,
                     bool maximum_inclusive) const {
  double value = 0.0;
  if (!parseNumber(&value)) fail("expected " + expectation + ", got " + shown());
  const bool above = minimum_inclusive ? value >= minimum : value > minimum;
  const bool below = maximum_inclusive ? value <= maximum : value < maximum;
  if (!above || !below) fail("expected " + expectation + ", got " + shown());
  return value;
}

double Field::finite() const { return number("a finite number", -HUGE_VAL, HUGE_VAL, false, false); }
double Field::positive() const { return number("a positive number", 0.0, HUGE_VAL, false, false); }
double Field::nonNegative() const { return number("a non-negative number", 0.0, HUGE_VAL, true, false); }

int Field::integer(int minimum, int maximum) const {
  const std::string expectation = "an integer in [" + std::to_string(minimum) + ", " + std::to_string(maximum) + "]";
  if (!node_.IsScalar()) fail("expected " + expectation + ", got " + shown());
  const std::string& scalar = node_.Scalar();
  char* end = nullptr;
  errno = 0;
  const long value = std::strtol(scalar.c_str(), &end, 10);
  if (scalar.empty() || end != scalar.c_str() + scalar.size() || errno == ERANGE || value < minimum ||
      value > maximum) {
    fail("expected " + expectation + ", got " + shown());
  }
  return static_cast<int>(value);
}

bool Field::boolean() const {
  if (node_.IsScalar() && (node_.Scalar() == "true" || node_.Scalar() == "false")) return node_.Scalar() == "true";
  fail("expected true or false, got " + shown());
}

void Field::failChoice(const std::vector<std::string>& names) const {
  fail("expected one of " + joinNames(names) + ", got " + shown() +
       (node_.IsScalar() ? typoSuggestion(node_.Scalar(), names) : ""));
}

std::string Field::name(const std::vector<std::string>& allowed) const {
  std::vector<std::pair<std::string, std::string>> options;
  for (const auto& name : allowed) options.emplace_back(name, name);
  return choice(options);
}

std::vector<Field> Field::items() const {
  if (!node_.IsSequence()) fail("expected a list, got " + shown());
  std::vector<Field> result;
  for (std::size_t i = 0; i < node_.size(); ++i) result.push_back(item(node_[i], i));
  return result;
}

std::vector<double> Field::numbers(std::size_t count, const std::string& element_expectation, double minimum,
                                   double maximum) const {
  if (!node_.IsSequence() || node_.size() != count) {
    fail("expected a list of " + std::to_string(count) + " numbers, got " + shown() +
         (node_.IsSequence() ? " of " + std::to_string(node_.size()) : ""));
  }
  std::vector<double> values;
  for (const Field& element : items()) values.push_back(element.number(element_expectation, minimum, maximum));
  return values;
}

Eigen::Vector3d Field::vector3() const {
  const auto values = numbers(3, "a finite number", -1e300, 1e300);
  return {values[0], values[1], values[2]};
}

bool Field::parseNumber(double* value) const {
  if (!node_.IsScalar() || node_.Scalar().empty()) return false;
  const std::string& scalar = node_.Scalar();
  char* end = nullptr;
  *value = std::strtod(scalar.c_str(), &end);
  return end == scalar.c_str() + scalar.size() && std::isfinite(*value);
}

MapFields::MapFields(const Field& field) : field_(field) {
  if (!field.node().IsMap()) field.fail("expected a map, got " + field.shown());
  for (const auto& entry : field.node()) {
    const Field key_field(entry.first, field.path(), field.file());
    if (!entry.first.IsScalar()) key_field.fail("map keys must be plain names");
    const std::string key = entry.first.Scalar();
    if (entries_.count(key) > 0) key_field.child(entry.first, key).fail("duplicate key");
    entries_.emplace(key, Entry{entry.first, entry.second});
    order_.push_back(key);
  }
}

std::optional<Field> MapFields::optional(const std::string& key) {
  known_.push_back(key);
  const auto found = entries_.find(key);
  if (found == entries_.end()) return std::nullopt;
  return field_.child(found->second.value, key);
}

Field MapFields::required(const std::string& key) {
  std::optional<Field> value = optional(key);
  if (!value) field_.fail("missing required key '" + key + "'");
  return *value;
}

void MapFields::finish() const {
  for (const auto& key : order_) {
    if (std::find(known_.begin(), known_.end(), key) != known_.end()) continue;
    field_.child(entries_.at(key).key, key)
        .fail("unknown key" + typoSuggestion(key, known_) + "; allowed keys: " + joinNames(known_));
  }
}

Field parseText(const std::string& text, const std::string& file) {
  try {
    return Field(YAML::Load(text), "", file);
  } catch (const YAML::Exception& error) {
    SourceLocation location;
    location.file = file;
    if (!error.mark.is_null()) {
      location.line = error.mark.line + 1;
      location.column = error.mark.column + 1;
    }
    throw YamlError(location, "YAML syntax error: " + error.msg);
  }
}

std::string readFile(const std::string& path, const std::string& what) {
  namespace fs = std::filesystem;
  SourceLocation location;
  location.file = path;
  std::error_code error;
  if (!fs::exists(path, error)) throw YamlError(location, what + " not found");
  std::ifstream stream(path);
  if (!stream || fs::is_directory(path, error)) throw YamlError(location, "cannot read the " + what);
  std::ostringstream text;
  text << stream.rdbuf();
  return text.str();
}

}  // namespace yaml
}  // namespace vrm_sim
