#include "eyesi_gui/records/course.h"

#include <algorithm>
#include <filesystem>

#include "vrm_scene/yaml/strict_reader.h"

namespace eyesi_gui::records {
namespace fs = std::filesystem;

namespace {

using vrm_sim::yaml::Field;
using vrm_sim::yaml::MapFields;

constexpr double kMaximumTotal = 100.0;  // a session's total is 0..100

// A module is a path when it could not be a bare scene name (resolveScenePath's rule in vrm_sim).
bool isPath(const std::string& module) {
  return module.find('/') != std::string::npos || module.find('.') != std::string::npos;
}

std::string resolveAgainst(const std::string& course_file, const std::string& module) {
  const fs::path path(module);
  if (path.is_absolute()) return path.lexically_normal().string();
  return (fs::path(course_file).parent_path() / path).lexically_normal().string();
}

// The scene a module names, checked against the catalogue when there is one.
SceneLevels sceneOf(const Field& module_field, const std::string& course_file, const SceneCatalogue* catalogue) {
  const std::string module = module_field.text();
  if (isPath(module)) {
    const std::string path = resolveAgainst(course_file, module);
    if (!catalogue) return {fs::path(path).stem().string(), {}};
    if (!catalogue->scene_file) module_field.fail("scene files given by path are not known here; name a scene");
    const std::optional<SceneLevels> scene = catalogue->scene_file(path);
    if (!scene) module_field.fail("no scene file at " + path);
    return *scene;
  }
  if (!catalogue) return {module, {}};
  std::vector<std::string> names;
  for (const SceneLevels& scene : catalogue->scenes) names.push_back(scene.name);
  const std::string name = module_field.name(names);  // fails naming the scenes that exist, with a typo hint
  for (const SceneLevels& scene : catalogue->scenes) {
    if (scene.name == name) return scene;
  }
  return {name, {}};  // not reached: name() accepts only names of the catalogue
}

// A present key, or "missing required key" at the map. Called after MapFields::finish, so a misspelt key is reported
// as unknown with a typo hint rather than as the correct key missing.
Field present(const std::optional<Field>& value, const Field& map, const std::string& key) {
  if (!value) map.fail("missing required key '" + key + "'");
  return *value;
}

CourseStep readStep(const Field& entry, const std::string& course_file, const SceneCatalogue* catalogue) {
  MapFields fields(entry);
  const std::optional<Field> module_field = fields.optional("module");
  const std::optional<Field> level = fields.optional("level");
  const std::optional<Field> pass_mark = fields.optional("pass_mark");
  fields.finish();
  CourseStep step;
  const Field module = present(module_field, entry, "module");
  const SceneLevels scene = sceneOf(module, course_file, catalogue);
  step.module = module.text();
  step.scene = scene.name;
  if (level) {
    if (catalogue && scene.levels.empty()) level->fail("scene " + scene.name + " has no difficulty levels");
    step.level = catalogue ? level->name(scene.levels) : level->text();
  } else if (catalogue && !scene.levels.empty()) {
    entry.fail("missing level: scene " + scene.name + " has the levels " + vrm_sim::yaml::joinNames(scene.levels));
  }
  step.pass_mark = present(pass_mark, entry, "pass_mark").number("a pass mark in [0, 100]", 0.0, kMaximumTotal);
  return step;
}

}  // namespace

Course readCourseText(const std::string& yaml_text, const std::string& file, const SceneCatalogue* catalogue) {
  const Field root = vrm_sim::yaml::parseText(yaml_text, file);
  if (!root.node().IsMap()) root.fail("expected a course (a map with name and steps), got " + root.shown());
  MapFields fields(root);
  const std::optional<Field> name = fields.optional("name");
  const std::optional<Field> description = fields.optional("description");
  const std::optional<Field> steps_field = fields.optional("steps");
  const std::optional<Field> battery = fields.optional("battery_pass_mark");
  fields.finish();
  Course course;
  course.file = file;
  course.name = present(name, root, "name").text();
  if (description) course.description = description->text();
  const Field steps = present(steps_field, root, "steps");
  for (const Field& entry : steps.items()) {
    CourseStep step = readStep(entry, file, catalogue);
    for (std::size_t i = 0; i < course.steps.size(); ++i) {
      // Two steps at one scene and level would share their sessions: passing one would pass both.
      if (course.steps[i].scene == step.scene && course.steps[i].level == step.level) {
        entry.fail("the same scene and level as step " + std::to_string(i + 1) + " (" + step.scene +
                   (step.level.empty() ? "" : " " + step.level) + ")");
      }
    }
    course.steps.push_back(step);
  }
  if (course.steps.empty()) steps.fail("expected at least one step");
  if (battery) {
    const double maximum = kMaximumTotal * static_cast<double>(course.steps.size());
    course.battery_pass_mark = battery->number(
        "a battery pass mark in [0, " + std::to_string(static_cast<int>(maximum)) + "] (100 per step)", 0.0, maximum);
  }
  return course;
}

Course readCourseFile(const std::string& path, const SceneCatalogue* catalogue) {
  return readCourseText(vrm_sim::yaml::readFile(path, "course file"), path, catalogue);
}

CourseProgress courseProgress(const Course& course, const std::vector<SessionRecord>& sessions) {
  CourseProgress progress;
  progress.steps.resize(course.steps.size());
  progress.battery_maximum = kMaximumTotal * static_cast<double>(course.steps.size());
  for (std::size_t i = 0; i < course.steps.size(); ++i) {
    const CourseStep& step = course.steps[i];
    StepProgress& state = progress.steps[i];
    for (const SessionRecord& session : sessions) {
      if (session.scene != step.scene || session.difficulty != step.level) continue;
      ++state.attempts;
      if (session.state != "finished") continue;
      state.best = std::max(state.best.value_or(session.total), session.total);
    }
    state.passed = state.best && *state.best >= step.pass_mark;
    progress.battery += state.best.value_or(0.0);
  }
  bool all_passed = true;
  for (std::size_t i = 0; i < progress.steps.size(); ++i) {
    StepProgress& state = progress.steps[i];
    state.unlocked = i == 0 || progress.steps[i - 1].passed || state.passed;
    if (!state.passed && !progress.current) {
      progress.current = i;
      state.current = true;
    }
    all_passed = all_passed && state.passed;
  }
  progress.battery_passed = !course.battery_pass_mark || progress.battery >= *course.battery_pass_mark;
  progress.passed = all_passed && progress.battery_passed;
  return progress;
}

bool mayStart(const Course& course, const CourseProgress& progress, const std::string& scene,
              const std::string& level) {
  for (std::size_t i = 0; i < course.steps.size() && i < progress.steps.size(); ++i) {
    if (course.steps[i].scene == scene && course.steps[i].level == level) return progress.steps[i].unlocked;
  }
  return true;
}

}  // namespace eyesi_gui::records
