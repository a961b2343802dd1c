#pragma once
// The one strict YAML reader of the project's own file formats (scenes, marker layouts, camera rigs): every problem is
// reported as "<file>:<line>:<column>: <field>: <problem>", a misspelt key or name gets a "did you mean" hint, and a
// key nobody asked for is an error (MapFields::finish), so a typo never silently leaves a default in place.
// ROS-free; only yaml-cpp and Eigen, so the tracking and rendering libraries read their files without linking the
// simulation.

#include <yaml-cpp/yaml.h>

#include <Eigen/Core>
#include <map>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "vrm_scene/yaml/yaml_error.h"

namespace vrm_sim {

namespace yaml {

// "a, b, c", for the lists of allowed names in messages.
std::string joinNames(const std::vector<std::string>& names);

// One YAML node together with its field path and file, so every check can report where it failed.
class Field {
 public:
  Field(YAML::Node node, std::string path, std::string file)
      : node_(std::move(node)), path_(std::move(path)), file_(std::move(file)) {}

  const YAML::Node& node() const { return node_; }
  const std::string& path() const { return path_; }
  const std::string& file() const { return file_; }
  SourceLocation location() const;
  [[noreturn]] void fail(const std::string& problem) const;

  Field child(const YAML::Node& node, const std::string& key) const;
  Field item(const YAML::Node& node, std::size_t index) const;
  // What the user wrote, for "got ..." in messages.
  std::string shown() const;

  std::string text() const;  // a non-empty scalar
  // `expectation` names the accepted range in messages, e.g. "a positive number". Non-finite values never pass.
  double number(const std::string& expectation, double minimum, double maximum, bool minimum_inclusive = true,
                bool maximum_inclusive = true) const;
  double finite() const;
  double positive() const;
  double nonNegative() const;
  int integer(int minimum, int maximum) const;
  bool boolean() const;

  template <typename Enum>
  Enum choice(const std::vector<std::pair<std::string, Enum>>& options) const {
    std::vector<std::string> names;
    for (const auto& option : options) names.push_back(option.first);
    if (node_.IsScalar()) {
      for (const auto& option : options) {
        if (option.first == node_.Scalar()) return option.second;
      }
    }
    failChoice(names);
  }
  // One of `allowed` (a registry's or the file's own names), with a typo hint when it is not.
  std::string name(const std::vector<std::string>& allowed) const;

  std::vector<Field> items() const;  // a list
  std::vector<double> numbers(std::size_t count, const std::string& element_expectation, double minimum,
                              double maximum) const;
  Eigen::Vector3d vector3() const;

 private:
  [[noreturn]] void failChoice(const std::vector<std::string>& names) const;
  bool parseNumber(double* value) const;

  YAML::Node node_;
  std::string path_;
  std::string file_;
};

// The keys of one YAML map. Every key the parser asks for is allowed; finish() rejects the rest (with a typo hint and
// the allowed keys), so a misspelt key fails instead of silently leaving a default in place. Duplicate keys fail.
class MapFields {
 public:
  explicit MapFields(const Field& field);

  std::optional<Field> optional(const std::string& key);
  Field required(const std::string& key);
  bool has(const std::string& key) const { return entries_.count(key) > 0; }
  void finish() const;
  const Field& field() const { return field_; }

 private:
  struct Entry {
    YAML::Node key;
    YAML::Node value;
  };
  Field field_;
  std::map<std::string, Entry> entries_;
  std::vector<std::string> order_;
  std::vector<std::string> known_;
};

// The root of a document: a YAML syntax error is a YamlError at its line and column ("YAML syntax error: ...").
Field parseText(const std::string& text, const std::string& file);
// The file's text; YamlError naming the file when it does not exist or cannot be read. `what` names the kind of file
// in the message ("marker layout not found").
std::string readFile(const std::string& path, const std::string& what);

}  // namespace yaml
}  // namespace vrm_sim
