// Courses (issue 35): the course reader (the shipped course against the shipped scenes, malformed files with
// file:line:column), the progress from stored sessions (pass, fail, unlock, battery) and the assignment in the records
// store across a restart and from a version-2 database.
#include <gtest/gtest.h>
#include <sqlite3.h>

#include <filesystem>
#include <fstream>
#include <random>

#include "eyesi_gui/records/course.h"
#include "eyesi_gui/records/schema.h"
#include "vrm_scene/scene_loader.h"

namespace eyesi_gui::records {
namespace {
namespace fs = std::filesystem;

const std::string kBasicCourse = std::string(EYESI_COURSES_DIR) + "/basic_vitreoretinal.yaml";

class TempDir {
 public:
  TempDir() {
    std::random_device random;
    path_ = fs::temp_directory_path() / ("test_course_" + std::to_string(random()));
    fs::create_directories(path_);
  }
  ~TempDir() {
    std::error_code ec;
    fs::remove_all(path_, ec);
  }
  std::string file(const std::string& name) const { return (path_ / name).string(); }

 private:
  fs::path path_;
};

// What exists, from vrm_sim's own scene loader: every shipped scene with its levels, and scene files by path.
SceneLevels levelsOf(const std::string& name_or_path) {
  const vrm_sim::scene::SceneDescription scene = vrm_sim::scene::loadScene(name_or_path);
  return {scene.name, scene.scenario ? scene.scenario->difficulty_levels : std::vector<std::string>{}};
}

SceneCatalogue shippedCatalogue() {
  vrm_sim::scene::setPackageDirectory(VRM_SIM_DIR);
  SceneCatalogue catalogue;
  for (const std::string& name : vrm_sim::scene::shippedScenes()) catalogue.scenes.push_back(levelsOf(name));
  catalogue.scene_file = [](const std::string& path) -> std::optional<SceneLevels> {
    if (!fs::is_regular_file(path)) return std::nullopt;
    return levelsOf(path);
  };
  return catalogue;
}

// The error's message, or "" when the course was read.
std::string readError(const std::string& text, const SceneCatalogue* catalogue) {
  try {
    readCourseText(text, "course.yaml", catalogue);
  } catch (const CourseError& error) {
    return error.what();
  }
  return "";
}

TEST(CourseReader, TheShippedCourseNamesShippedScenesAndLevels) {
  const SceneCatalogue catalogue = shippedCatalogue();
  ASSERT_GE(catalogue.scenes.size(), 7u);
  const Course course = readCourseFile(kBasicCourse, &catalogue);
  EXPECT_EQ(course.name, "Basic vitreoretinal course");
  ASSERT_EQ(course.steps.size(), 9u);
  EXPECT_EQ(course.steps[0].scene, "navigation");
  EXPECT_EQ(course.steps[0].level, "easy");
  EXPECT_DOUBLE_EQ(course.steps[0].pass_mark, 93);  // chosen by bench_validity (the course file says how)
  EXPECT_EQ(course.steps[1].scene, "steady_hold");
  EXPECT_EQ(course.steps[2].scene, "trajectory");
  EXPECT_EQ(course.steps[3].scene, "pick_and_place");
  EXPECT_EQ(course.steps[8].scene, "ilm_peeling");
  ASSERT_TRUE(course.battery_pass_mark);
  EXPECT_DOUBLE_EQ(*course.battery_pass_mark, 698);
  // The battery asks for more than the sum of the step marks: scraping past each step is not a pass.
  double sum = 0;
  for (const CourseStep& step : course.steps) sum += step.pass_mark;
  EXPECT_GT(*course.battery_pass_mark, sum);
}

TEST(CourseReader, AModuleByPathIsTheSceneInThatFile) {
  const SceneCatalogue catalogue = shippedCatalogue();
  TempDir dir;
  const std::string scenes = fs::path(VRM_SIM_DIR) / "config" / "scenes";
  const std::string text =
      "name: by path\nsteps:\n  - {module: " + scenes + "/steady_hold.yaml, level: hard, " + "pass_mark: 90}\n";
  const Course course = readCourseText(text, dir.file("c.yaml"), &catalogue);
  ASSERT_EQ(course.steps.size(), 1u);
  EXPECT_EQ(course.steps[0].scene, "steady_hold");
  EXPECT_EQ(course.steps[0].module, scenes + "/steady_hold.yaml");
  // Relative to the course file; a file that is not there is an error naming the resolved path.
  const std::string missing = "name: x\nsteps:\n  - {module: nowhere/scene.yaml, level: easy, pass_mark: 50}\n";
  try {
    readCourseText(missing, dir.file("c.yaml"), &catalogue);
    FAIL() << "a missing scene file was accepted";
  } catch (const CourseError& error) {
    EXPECT_NE(
        std::string(error.what())
            .find(dir.file("c.yaml") + ":3:14: steps[0].module: no scene file at " + dir.file("nowhere/scene.yaml")),
        std::string::npos)
        << error.what();
  }
}

TEST(CourseReader, MalformedCoursesNameFileLineColumnAndField) {
  const SceneCatalogue catalogue = shippedCatalogue();
  struct Case {
    std::string text;
    std::vector<std::string> expected;  // substrings of the message
  };
  const std::string head = "name: c\nsteps:\n";
  const std::vector<Case> cases = {
      // An unknown scene: the scenes that exist, with a typo hint.
      {head + "  - module: navigaton\n    level: easy\n    pass_mark: 80\n",
       {"course.yaml:3:13: steps[0].module: expected one of ", "ilm_peeling", "vitrectomy", "navigation"}},
      // An unknown level: the scene's levels.
      {head + "  - module: navigation\n    level: extreme\n    pass_mark: 80\n",
       {"course.yaml:4:12: steps[0].level: expected one of easy, medium, hard, got 'extreme'"}},
      {head + "  - module: navigation\n    pass_mark: 80\n",
       {"course.yaml:3:5: steps[0]: missing level: scene navigation has the levels easy, medium, hard"}},
      {head + "  - module: navigation\n    level: easy\n    pass_mark: 120\n",
       {"course.yaml:5:16: steps[0].pass_mark: expected a pass mark in [0, 100], got '120'"}},
      {head + "  - module: navigation\n    level: easy\n    pass_mark: lots\n",
       {"course.yaml:5:16: steps[0].pass_mark: expected a pass mark in [0, 100], got 'lots'"}},
      // A misspelt key is unknown (with the hint), not a silently missing pass mark.
      {head + "  - module: navigation\n    level: easy\n    pass_mrak: 80\n",
       {"course.yaml:5:5: steps[0].pass_mrak: unknown key", "pass_mark"}},
      {head + "  - module: navigation\n    level: easy\n",
       {"course.yaml:3:5: steps[0]: missing required key 'pass_mark'"}},
      {head + "  - {module: navigation, level: easy, pass_mark: 80}\n  - {module: navigation, level: easy, pass_mark: "
              "90}\n",
       {"course.yaml:4:5: steps[1]: the same scene and level as step 1 (navigation easy)"}},
      {"name: c\nbattery_pass_mark: 250\nsteps:\n  - {module: navigation, level: easy, pass_mark: 80}\n"
       "  - {module: trajectory, level: easy, pass_mark: 80}\n",
       {"course.yaml:2:20: battery_pass_mark: expected a battery pass mark in [0, 200] (100 per step), got '250'"}},
      {"name: c\nsteps: []\n", {"course.yaml:2:8: steps: expected at least one step"}},
      {"name: c\n", {"course.yaml:1:1: missing required key 'steps'"}},
      {"name: c\nstep:\n  - {module: navigation, level: easy, pass_mark: 80}\n",
       {"course.yaml:2:1: step: unknown key", "steps"}},
      {"name: c\nsteps:\n  - {module: navigation, level: easy, pass_mark: 80\n", {"course.yaml:", "YAML syntax error"}},
      {"- just a list\n", {"course.yaml:1:1: expected a course (a map with name and steps), got a list"}},
  };
  for (const Case& c : cases) {
    const std::string message = readError(c.text, &catalogue);
    ASSERT_FALSE(message.empty()) << "accepted:\n" << c.text;
    for (const std::string& part : c.expected) EXPECT_NE(message.find(part), std::string::npos) << message;
  }
  EXPECT_EQ(readError(head + "  - {module: navigation, level: easy, pass_mark: 80}\n", &catalogue), "");
}

TEST(CourseReader, WithoutACatalogueOnlyTheShapeIsChecked) {
  const Course course =
      readCourseText("name: c\nsteps:\n  - {module: some_scene, level: odd, pass_mark: 10}\n", "course.yaml");
  ASSERT_EQ(course.steps.size(), 1u);
  EXPECT_EQ(course.steps[0].scene, "some_scene");
  EXPECT_EQ(course.steps[0].level, "odd");
  EXPECT_FALSE(course.battery_pass_mark);
  try {
    readCourseFile("/nonexistent/course.yaml");
    ADD_FAILURE() << "a missing file was read";
  } catch (const CourseError& error) {
    EXPECT_EQ(std::string(error.what()), "/nonexistent/course.yaml: course file not found");
  }
  EXPECT_NE(readError("name: c\nsteps:\n  - {module: s, pass_mark: 101}\n", nullptr).find("course.yaml:3:"),
            std::string::npos);
}

// ---- progress -----------------------------------------------------------------------------------------------------

const char* kTwoStepCourse = R"(name: Two steps
battery_pass_mark: 170
steps:
  - {module: navigation, level: easy, pass_mark: 80}
  - {module: trajectory, level: medium, pass_mark: 75}
)";

SessionRecord session(const std::string& user, const std::string& scene, const std::string& level, double total,
                      const std::string& state, double start) {
  SessionRecord s;
  s.user = user;
  s.scene = s.scenario = scene;
  s.difficulty = level;
  s.total = total;
  s.state = state;
  s.passed = state == "finished";
  s.start_stamp = start;
  s.end_stamp = start + 30;
  s.final_state_hash = "0x" + std::to_string(static_cast<long long>(start));
  return s;
}

TEST(CourseProgress, PassingAStepUnlocksTheNextAndTheBatteryDecidesTheCourse) {
  const Course course = readCourseText(kTwoStepCourse, "two.yaml");
  std::vector<SessionRecord> sessions;

  CourseProgress p = courseProgress(course, sessions);
  ASSERT_EQ(p.steps.size(), 2u);
  EXPECT_TRUE(p.steps[0].unlocked && p.steps[0].current && !p.steps[0].passed);
  EXPECT_FALSE(p.steps[1].unlocked);
  EXPECT_EQ(p.current, 0u);
  EXPECT_FALSE(mayStart(course, p, "trajectory", "medium"));
  EXPECT_TRUE(mayStart(course, p, "trajectory", "hard")) << "no step of the course: free practice";

  // Failing: below the mark, a high total of a failed session, the right scene at another level.
  sessions.push_back(session("anna", "navigation", "easy", 60, "finished", 1));
  sessions.push_back(session("anna", "navigation", "easy", 95, "failed", 2));
  sessions.push_back(session("anna", "navigation", "hard", 99, "finished", 3));
  p = courseProgress(course, sessions);
  EXPECT_FALSE(p.steps[0].passed);
  EXPECT_EQ(p.steps[0].attempts, 2);
  ASSERT_TRUE(p.steps[0].best);
  EXPECT_DOUBLE_EQ(*p.steps[0].best, 60);
  EXPECT_FALSE(p.steps[1].unlocked);
  EXPECT_DOUBLE_EQ(p.battery, 60);

  // Passing the first step (exactly the pass mark is a pass) unlocks the second, which becomes current.
  sessions.push_back(session("anna", "navigation", "easy", 80, "finished", 4));
  p = courseProgress(course, sessions);
  EXPECT_TRUE(p.steps[0].passed);
  EXPECT_FALSE(p.steps[0].current);
  EXPECT_TRUE(p.steps[1].unlocked && p.steps[1].current);
  EXPECT_EQ(p.current, 1u);
  EXPECT_TRUE(mayStart(course, p, "trajectory", "medium"));
  EXPECT_FALSE(p.passed);

  // Every step passed (80 + 76 = 156), but under the battery's 170: not passed.
  sessions.push_back(session("anna", "trajectory", "medium", 76, "finished", 5));
  p = courseProgress(course, sessions);
  EXPECT_TRUE(p.steps[1].passed);
  EXPECT_FALSE(p.current);
  EXPECT_DOUBLE_EQ(p.battery, 156);
  EXPECT_DOUBLE_EQ(p.battery_maximum, 200);
  EXPECT_FALSE(p.battery_passed);
  EXPECT_FALSE(p.passed);

  // A better session lifts the battery (the best per step counts, not the last): 96 + 76 = 172.
  sessions.push_back(session("anna", "navigation", "easy", 96, "finished", 6));
  sessions.push_back(session("anna", "navigation", "easy", 70, "finished", 7));
  p = courseProgress(course, sessions);
  EXPECT_DOUBLE_EQ(p.battery, 172);
  EXPECT_TRUE(p.battery_passed);
  EXPECT_TRUE(p.passed);
}

TEST(CourseProgress, AStepPassedOutOfOrderIsOpenAndUnlocksItsSuccessor) {
  const Course course = readCourseText(
      "name: three\nsteps:\n  - {module: a, pass_mark: 50}\n  - {module: b, pass_mark: 50}\n"
      "  - {module: c, pass_mark: 50}\n",
      "three.yaml");
  const CourseProgress p = courseProgress(course, {session("x", "b", "", 60, "finished", 1)});
  EXPECT_TRUE(p.steps[0].current);
  EXPECT_TRUE(p.steps[1].passed && p.steps[1].unlocked);
  EXPECT_TRUE(p.steps[2].unlocked);
  EXPECT_FALSE(p.steps[2].current);
  EXPECT_EQ(p.current, 0u);
}

// ---- the store --------------------------------------------------------------------------------------------------

CourseAssignment assignment(const std::string& trainee, const std::string& by, const std::string& text) {
  CourseAssignment a;
  a.user = trainee;
  a.assigned_by = by;
  a.course_text = text;
  a.course_name = readCourseText(text, "two.yaml").name;
  a.course_file = "/courses/two.yaml";
  return a;
}

TEST(CourseStore, AssignmentAndProgressSurviveARestart) {
  TempDir dir;
  const std::string path = dir.file("records.sqlite");
  CourseProgress before;
  {
    Store store(path);
    store.addUser("anna", Role::kTrainee, "1357");
    store.addUser("ines", Role::kInstructor, "2468");
    EXPECT_FALSE(store.courseAssignment("anna"));
    store.assignCourse(assignment("anna", "ines", kTwoStepCourse));
    store.recordSession(session("anna", "navigation", "easy", 88, "finished", 10));
    store.recordSession(session("anna", "trajectory", "medium", 40, "finished", 20));
    store.recordSession(session("guest", "trajectory", "medium", 99, "finished", 30));  // someone else's
    const auto a = store.courseAssignment("anna");
    ASSERT_TRUE(a);
    before = courseProgress(readCourseText(a->course_text, a->course_file), store.sessions({"anna", ""}));
    EXPECT_TRUE(before.steps[0].passed);
    EXPECT_FALSE(before.steps[1].passed);
    EXPECT_EQ(before.current, 1u);
  }
  Store store(path);  // the console restarted
  const auto a = store.courseAssignment("anna");
  ASSERT_TRUE(a);
  EXPECT_EQ(a->course_name, "Two steps");
  EXPECT_EQ(a->course_file, "/courses/two.yaml");
  EXPECT_EQ(a->assigned_by, "ines");
  EXPECT_EQ(a->course_text, kTwoStepCourse);
  EXPECT_FALSE(a->assigned_at.empty());
  const CourseProgress after =
      courseProgress(readCourseText(a->course_text, a->course_file), store.sessions({"anna", ""}));
  ASSERT_EQ(after.steps.size(), before.steps.size());
  for (std::size_t i = 0; i < after.steps.size(); ++i) {
    EXPECT_EQ(after.steps[i].passed, before.steps[i].passed) << i;
    EXPECT_EQ(after.steps[i].unlocked, before.steps[i].unlocked) << i;
    EXPECT_EQ(after.steps[i].best, before.steps[i].best) << i;
  }
  EXPECT_EQ(after.current, before.current);
  EXPECT_DOUBLE_EQ(after.battery, 128);

  // Assigning another course replaces the first.
  const std::string other = "name: Other\nsteps:\n  - {module: vitrectomy, level: easy, pass_mark: 70}\n";
  store.assignCourse(assignment("anna", "ines", other));
  EXPECT_EQ(store.courseAssignment("anna")->course_name, "Other");
}

TEST(CourseStore, OnlyAnInstructorAssignsAndOnlyToATrainee) {
  TempDir dir;
  Store store(dir.file("records.sqlite"));
  store.addUser("anna", Role::kTrainee, "");
  store.addUser("ines", Role::kInstructor, "");
  auto expectError = [&](const CourseAssignment& a, const std::string& part) {
    try {
      store.assignCourse(a);
      ADD_FAILURE() << "assigned: " << part;
    } catch (const StoreError& error) {
      EXPECT_NE(std::string(error.what()).find(part), std::string::npos) << error.what();
    }
  };
  expectError(assignment("anna", "anna", kTwoStepCourse), "\"anna\" is not an instructor");
  expectError(assignment("ines", "ines", kTwoStepCourse), "\"ines\" is not a trainee");
  expectError(assignment("nobody", "ines", kTwoStepCourse), "no user \"nobody\"");
  CourseAssignment empty = assignment("anna", "ines", kTwoStepCourse);
  empty.course_text = "";
  expectError(empty, "needs the course's name and text");
  EXPECT_FALSE(store.courseAssignment("anna"));
}

TEST(CourseStore, AVersion2DatabaseGetsTheCourseTableAndKeepsItsSessions) {
  TempDir dir;
  const std::string path = dir.file("v2.sqlite");
  {
    // What the version-2 release left on disk: a trainee, an instructor and a session, no course table.
    sqlite3* raw = nullptr;
    ASSERT_EQ(sqlite3_open(path.c_str(), &raw), SQLITE_OK);
    const std::string sql =
        std::string("BEGIN;") + migrationSql(1) + migrationSql(2) +
        "INSERT INTO users (name, role, iterations, created_at) VALUES ('anna', 'trainee', 0, '2026-01-01T00:00:00Z');"
        "INSERT INTO users (name, role, iterations, created_at) VALUES ('ines', 'instructor', 0, "
        "'2026-01-01T00:00:00Z');"
        "INSERT INTO sessions (session_key, user_id, scene, difficulty, state, total, passed, recorded_at) "
        "SELECT 'k1', id, 'navigation', 'easy', 'finished', 90, 1, '2026-01-02T00:00:00Z' FROM users "
        "WHERE name = 'anna';"
        "PRAGMA user_version = 2; COMMIT;";
    ASSERT_EQ(sqlite3_exec(raw, sql.c_str(), nullptr, nullptr, nullptr), SQLITE_OK) << sqlite3_errmsg(raw);
    sqlite3_close(raw);
  }
  Store store(path);
  EXPECT_EQ(store.schemaVersion(), Store::kSchemaVersion);
  EXPECT_FALSE(store.courseAssignment("anna"));
  store.assignCourse(assignment("anna", "ines", kTwoStepCourse));
  const auto a = store.courseAssignment("anna");
  ASSERT_TRUE(a);
  const CourseProgress p = courseProgress(readCourseText(a->course_text, a->course_file), store.sessions({"anna", ""}));
  EXPECT_TRUE(p.steps[0].passed) << "the version-2 session counts";
  EXPECT_EQ(p.current, 1u);
}

}  // namespace
}  // namespace eyesi_gui::records
