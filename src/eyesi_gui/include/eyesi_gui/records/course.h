// Courses (issue 35): an ordered list of steps, each a module (scene) at a difficulty level with a pass mark on the
// session's total, optionally a pass mark over the whole battery (the sum of the steps' best totals; published EyeSi
// programmes use e.g. 596 of 700 over seven modules, Jaud 2021). Passing a step unlocks the next.
//
// The file is YAML read through the project's one strict reader (vrm_scene/yaml/strict_reader.h), so every problem is
// a YamlError "<file>:<line>:<column>: <field>: <problem>" and a misspelt key is an error:
//
//   name: Basic vitreoretinal course       # required
//   description: ...                       # optional
//   battery_pass_mark: 560                 # optional, 0 .. 100 x steps
//   steps:                                 # required, at least one
//     - module: navigation                 # a shipped scene's name, or a scene file's path (relative: to this file)
//       level: easy                        # the scene's difficulty level (omitted only for a scene without levels)
//       pass_mark: 70                      # 0..100, on the session's total
//
// Progress is computed, never stored: it follows from the trainee's sessions in the records store, so it survives a
// restart and cannot disagree with them. ROS-free and Qt-free.
#pragma once

#include <cstddef>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "eyesi_gui/records/store.h"
#include "vrm_scene/yaml/yaml_error.h"

namespace eyesi_gui::records {

using CourseError = vrm_sim::YamlError;

struct CourseStep {
  std::string module;      // as written in the file: a scene name or a scene file's path
  std::string scene;       // the scene name its sessions are filed under
  std::string level;       // "" = the scene has no levels
  double pass_mark = 0.0;  // 0..100, on the session's total
};

struct Course {
  std::string name;
  std::string description;
  std::string file;  // where it was read from
  std::vector<CourseStep> steps;
  std::optional<double> battery_pass_mark;  // on the sum of the steps' best totals (0 .. 100 x steps)
};

// A scene a course may name, with its difficulty levels in file order.
struct SceneLevels {
  std::string name;
  std::vector<std::string> levels;
};

// What exists, to check a course against: the scenes by name, and (optional) what a scene file given by path holds
// (nullopt: no scene there). The console fills it from the station's scene list, the tests from vrm_sim's loader.
struct SceneCatalogue {
  std::vector<SceneLevels> scenes;
  std::function<std::optional<SceneLevels>(const std::string& path)> scene_file;
};

// Reads a course. With a catalogue, an unknown scene or level is an error naming the scenes or levels that exist;
// without one only the file's shape is checked (a module given by path is then filed under its file's stem).
// Throws CourseError.
Course readCourseText(const std::string& yaml_text, const std::string& file, const SceneCatalogue* catalogue = nullptr);
Course readCourseFile(const std::string& path, const SceneCatalogue* catalogue = nullptr);

struct StepProgress {
  std::optional<double> best;  // best total of a finished session at the step's scene and level
  int attempts = 0;            // sessions at the step's scene and level, in any state
  bool passed = false;         // best >= pass mark
  bool unlocked = false;       // the first step, a step whose predecessor is passed, or a passed step (to improve it)
  bool current = false;        // the first step not passed
};

struct CourseProgress {
  std::vector<StepProgress> steps;     // one per course step, in course order
  std::optional<std::size_t> current;  // index of the first step not passed; none when every step is passed
  double battery = 0.0;                // sum of the steps' best totals (a step never finished counts 0)
  double battery_maximum = 0.0;        // 100 x steps
  bool battery_passed = false;         // true when the course has no battery pass mark
  bool passed = false;                 // every step passed and the battery passed
};

// One trainee's progress from their sessions (the caller passes that trainee's, e.g. Store::sessions({user, ""})).
// Only sessions whose state is "finished" count towards a step: a failed or stopped session has a total, but the task
// was not done.
CourseProgress courseProgress(const Course& course, const std::vector<SessionRecord>& sessions);

// Whether `course` lets a trainee with `progress` start `scene` at `level`: a scene and level that is no step of the
// course is free practice (allowed); a course step must be unlocked.
bool mayStart(const Course& course, const CourseProgress& progress, const std::string& scene, const std::string& level);

}  // namespace eyesi_gui::records
