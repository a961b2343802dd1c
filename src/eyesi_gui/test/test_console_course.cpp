// The console's course widgets (issue 35), offscreen with a fake simulator link and a real records store: an
// instructor assigns the shipped course, the trainee sees it with passed / current / locked steps and best totals,
// starts only unlocked steps (from the course panel and from the scenario list), and sees the same progress after a
// restart; a course naming a scene the station lacks is refused with file:line:column.
#include <gtest/gtest.h>

#include <QApplication>
#include <QComboBox>
#include <QFile>
#include <QLabel>
#include <QLineEdit>
#include <QListWidget>
#include <QPushButton>
#include <QStatusBar>
#include <QTableWidget>
#include <QTemporaryDir>

#include "eyesi_gui/console/main_window.h"
#include "offscreen_application.h"

namespace eyesi_gui {
namespace {

// A station with the seven shipped scenarios at three levels each.
class FakeLink : public SimulatorLink {
 public:
  QString stationName() const override { return "fake"; }
  void requestScenes() override {
    QVector<SceneInfo> scenes;
    for (const char* name : {"ilm_peeling", "membrane_peeling", "navigation", "pick_and_place", "steady_hold",
                             "trajectory", "vitrectomy"}) {
      SceneInfo scene;
      scene.name = scene.scenario = name;
      scene.difficulties = QStringList{"easy", "medium", "hard"};
      scene.default_difficulty = "medium";
      scenes.push_back(scene);
    }
    emit scenesListed(scenes, {});
  }
  void loadSession(const SessionRequest& request) override { loads.push_back(request); }
  void endSession() override {}
  void playGhost(const QString&, double) override {}
  void sendCommand(Command, const QString&) override {}
  void setMicroscope(const MicroscopeSetting&) override {}

  std::vector<SessionRequest> loads;
};

template <typename T>
T* child(QWidget& window, const char* name) {
  T* widget = window.findChild<T*>(name);
  EXPECT_NE(widget, nullptr) << name;
  return widget;
}

records::SessionRecord finished(const std::string& scene, const std::string& level, double total, double start) {
  records::SessionRecord s;
  s.user = "anna";
  s.scene = s.scenario = scene;
  s.difficulty = level;
  s.state = "finished";
  s.passed = true;
  s.total = total;
  s.start_stamp = start;
  s.end_stamp = start + 20;
  return s;
}

class CourseConsoleTest : public ::testing::Test {
 protected:
  void SetUp() override {
    ASSERT_TRUE(dir_.isValid());
    store_ = std::make_unique<records::Store>(dir_.filePath("records.sqlite").toStdString());
    store_->addUser("anna", records::Role::kTrainee, "1357");
    store_->addUser("ines", records::Role::kInstructor, "2468");
    options_.course_dir = EYESI_COURSES_DIR;
  }
  std::unique_ptr<MainWindow> makeWindow() {
    auto window = std::make_unique<MainWindow>(&link_, store_.get(), options_);
    window->show();
    return window;
  }
  void login(MainWindow& window, const QString& name, const QString& pin) {
    if (window.screen() != MainWindow::kLogin) child<QPushButton>(window, "navLogout")->click();
    auto* users = child<QListWidget>(window, "userList");
    for (int i = 0; i < users->count(); ++i)
      if (users->item(i)->data(Qt::UserRole).toString() == name) users->setCurrentRow(i);
    child<QLineEdit>(window, "pinEdit")->setText(pin);
    child<QPushButton>(window, "loginButton")->click();
    ASSERT_EQ(window.currentUser(), name);
  }
  void assign(MainWindow& window, const QString& course_file) {
    login(window, "ines", "2468");
    window.showScreen(MainWindow::kInstructor);
    ASSERT_EQ(window.screen(), MainWindow::kInstructor);
    child<QComboBox>(window, "courseTraineeBox")->setCurrentText("anna");
    auto* courses = child<QComboBox>(window, "courseFileBox");
    courses->setCurrentText(course_file);
    ASSERT_EQ(courses->currentText(), course_file);
    child<QPushButton>(window, "assignCourseButton")->click();
  }
  static QString statusLine(MainWindow& window) {
    QString text;
    for (QLabel* label : window.statusBar()->findChildren<QLabel*>()) text += label->text();
    return text;
  }
  static QString status(QTableWidget* table, int row) { return table->item(row, 5)->text(); }

  QTemporaryDir dir_;
  std::unique_ptr<records::Store> store_;
  ConsoleOptions options_;
  FakeLink link_;
};

TEST_F(CourseConsoleTest, AssignedCourseShowsProgressAndOnlyUnlockedStepsStart) {
  {
    auto window = makeWindow();
    login(*window, "guest", "");
    EXPECT_TRUE(child<QWidget>(*window, "coursePanel")->isHidden()) << "no course, no panel";

    assign(*window, "basic_vitreoretinal.yaml");
    const auto assignment = store_->courseAssignment("anna");
    ASSERT_TRUE(assignment) << statusLine(*window).toStdString();
    EXPECT_EQ(assignment->course_name, "Basic vitreoretinal course");
    EXPECT_EQ(assignment->assigned_by, "ines");
    EXPECT_TRUE(child<QLabel>(*window, "courseAssignment")->text().contains("Basic vitreoretinal course"));

    login(*window, "anna", "1357");
    ASSERT_EQ(window->screen(), MainWindow::kScenarios);
    EXPECT_FALSE(child<QWidget>(*window, "coursePanel")->isHidden());
    auto* table = child<QTableWidget>(*window, "courseTable");
    ASSERT_EQ(table->rowCount(), 9);
    EXPECT_EQ(table->item(0, 1)->text(), "navigation");
    EXPECT_EQ(table->item(0, 2)->text(), "easy");
    EXPECT_EQ(table->item(0, 3)->text(), "93");  // the shipped course's mark (chosen by bench_validity)
    EXPECT_EQ(status(table, 0), "current");
    EXPECT_EQ(status(table, 1), "locked");
    EXPECT_TRUE(child<QLabel>(*window, "courseSummary")->text().contains("step 1 of 9"));

    // A locked step cannot start, from the course panel ...
    auto* start = child<QPushButton>(*window, "courseStartButton");
    table->selectRow(1);
    EXPECT_FALSE(start->isEnabled());
    // ... nor from the scenario list at its level; another level of the same scene is free practice.
    auto* scenarios = child<QListWidget>(*window, "scenarioList");
    for (int i = 0; i < scenarios->count(); ++i)
      if (scenarios->item(i)->data(Qt::UserRole).toString() == "steady_hold") scenarios->setCurrentRow(i);
    child<QComboBox>(*window, "difficultyBox")->setCurrentText("easy");
    child<QPushButton>(*window, "loadButton")->click();
    EXPECT_TRUE(link_.loads.empty());
    EXPECT_TRUE(statusLine(*window).contains("locked in your course")) << statusLine(*window).toStdString();
    child<QComboBox>(*window, "difficultyBox")->setCurrentText("hard");
    child<QPushButton>(*window, "loadButton")->click();
    ASSERT_EQ(link_.loads.size(), 1u);
    EXPECT_EQ(link_.loads.back().difficulty, "hard");

    // The current step starts at its level.
    window->showScreen(MainWindow::kScenarios);
    table->selectRow(0);
    ASSERT_TRUE(start->isEnabled());
    start->click();
    ASSERT_EQ(link_.loads.size(), 2u);
    EXPECT_EQ(link_.loads.back().scene, "navigation");
    EXPECT_EQ(link_.loads.back().difficulty, "easy");
    EXPECT_EQ(link_.loads.back().user, "anna");

    // A pass (95 >= 93) unlocks step 2.
    store_->recordSession(finished("navigation", "easy", 95, 100));
    window->showScreen(MainWindow::kScenarios);
    EXPECT_EQ(status(table, 0), "passed");
    EXPECT_EQ(table->item(0, 4)->text(), "95.0");
    EXPECT_EQ(status(table, 1), "current");
    table->selectRow(1);
    EXPECT_TRUE(start->isEnabled());
  }
  // The console restarted: the same course, the same progress.
  auto window = makeWindow();
  login(*window, "anna", "1357");
  auto* table = child<QTableWidget>(*window, "courseTable");
  ASSERT_EQ(table->rowCount(), 9);
  EXPECT_EQ(status(table, 0), "passed");
  EXPECT_EQ(status(table, 1), "current");
  EXPECT_EQ(status(table, 2), "locked");
  EXPECT_TRUE(child<QLabel>(*window, "courseSummary")->text().contains("battery 95.0 / 900"));
}

TEST_F(CourseConsoleTest, ACourseNamingASceneTheStationLacksIsNotAssigned) {
  QTemporaryDir courses;
  ASSERT_TRUE(courses.isValid());
  QFile file(courses.filePath("typo.yaml"));
  ASSERT_TRUE(file.open(QIODevice::WriteOnly));
  file.write("name: Typo\nsteps:\n  - {module: navigaton, level: easy, pass_mark: 80}\n");
  file.close();
  options_.course_dir = courses.path();
  auto window = makeWindow();
  assign(*window, "typo.yaml");
  EXPECT_FALSE(store_->courseAssignment("anna"));
  const QString note = statusLine(*window);
  EXPECT_TRUE(note.contains("typo.yaml:3:14: steps[0].module: expected one of")) << note.toStdString();
  EXPECT_TRUE(note.contains("navigation")) << note.toStdString();
  EXPECT_EQ(child<QLabel>(*window, "courseAssignment")->text(), "now: no course");
}

}  // namespace
}  // namespace eyesi_gui

int main(int argc, char** argv) {
  const auto app = eyesi_gui::testing::offscreenApplication(argc, argv);
  ::testing::InitGoogleTest(&argc, argv);
  return RUN_ALL_TESTS();
}
