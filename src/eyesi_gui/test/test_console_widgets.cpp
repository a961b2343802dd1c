// The console's widgets, offscreen (QT_QPA_PLATFORM=offscreen) with a fake simulator link and a real records store:
// log in → choose a scenario → load → START is sent → a scenario_status and the session's result arrive → the result
// screen shows the items → the row is in the database; plus PINs, keyboard shortcuts, the stereo view and export.
#include <gtest/gtest.h>

#include <QApplication>
#include <QCheckBox>
#include <QComboBox>
#include <QDir>
#include <QFile>
#include <QLabel>
#include <QLineEdit>
#include <QListWidget>
#include <QPushButton>
#include <QSpinBox>
#include <QTableWidget>
#include <QTemporaryDir>
#include <QtCharts/QChartView>
#include <QtTest/QTest>
#include <fstream>

#include "../src/console/stereo_view.h"
#include "eyesi_gui/console/main_window.h"
#include "offscreen_application.h"

namespace eyesi_gui {
namespace {

class FakeLink : public SimulatorLink {
 public:
  QString stationName() const override { return "fake"; }
  void requestScenes() override {
    SceneInfo scene;
    scene.name = "membrane_peeling";
    scene.description = "Peel an epiretinal membrane";
    scene.scenario = "membrane_peeling";
    scene.scenario_description = "Grasp the edge and peel";
    scene.difficulties = QStringList{"easy", "medium", "hard"};
    scene.default_difficulty = "medium";
    scene.time_limit = 120;
    scene.score_items = QStringList{"completed", "time"};
    scene.score_weights = {3, 1};
    scene.instruments = {InstrumentSlotInfo{"left", "light_pipe", {}},
                         InstrumentSlotInfo{"right", "forceps", {"vitrector", "laser_probe"}}};
    SceneInfo plain;
    plain.name = "viewer";  // no scenario: not listed
    emit scenesListed({scene, plain}, {});
  }
  void loadSession(const SessionRequest& request) override { loads.push_back(request); }
  void endSession() override { ++ends; }
  void playGhost(const QString& bag, double) override { ghosts << bag; }
  void sendCommand(Command command, const QString& argument) override { commands.push_back({command, argument}); }
  void setMicroscope(const MicroscopeSetting& setting) override { microscope.push_back(setting); }

  void station(int state, double progress = 0.0) {
    StationState status;
    status.state = state;
    status.progress = progress;
    status.station = "fake";
    status.mode = "session";
    status.scene = "membrane_peeling";
    status.recording = true;
    emit stationStatus(status);
  }
  void scenario(int state, double elapsed, const QString& message) {
    ScenarioState status;
    status.scenario = "membrane_peeling";
    status.difficulty = "hard";
    status.state = state;
    status.elapsed = elapsed;
    status.message = message;
    emit scenarioStatus(status);
  }

  std::vector<SessionRequest> loads;
  std::vector<std::pair<Command, QString>> commands;
  std::vector<MicroscopeSetting> microscope;
  QStringList ghosts;
  int ends = 0;
};

const char* kResult = R"({"scene": "membrane_peeling", "scene_file": "/x.yaml", "scenario": "membrane_peeling",
  "difficulty": "hard", "seed": 7, "state": "finished", "session_ended": true, "timed_out": false,
  "message": "membrane peeled", "start_stamp": 100.5, "end_stamp": 130.25, "elapsed": 29.75, "total": 87.5,
  "items": [{"name": "completed", "value": 1, "unit": "", "weight": 3, "points": 100},
            {"name": "time", "value": 29.75, "unit": "s", "weight": 1, "points": 50}],
  "final_state_hash": "0x00000000deadbeef", "frames": 1500, "simulated_frames": 1480, "late_inputs": 0,
  "last_frame_stamp": 130.25, "software_version": "vrm_sim 0.1.0", "bag": "/records/s.bag", "user": "anna",
  "station": "fake"})";

template <typename T>
T* child(QWidget& window, const char* name) {
  T* widget = window.findChild<T*>(name);
  EXPECT_NE(widget, nullptr) << name;
  return widget;
}

class ConsoleTest : public ::testing::Test {
 protected:
  void SetUp() override {
    ASSERT_TRUE(dir_.isValid());
    store_ = std::make_unique<records::Store>(dir_.filePath("records.sqlite").toStdString());
    store_->addUser("anna", records::Role::kTrainee, "1357");
    options_.export_dir = dir_.path();
  }
  std::unique_ptr<MainWindow> makeWindow() {
    auto window = std::make_unique<MainWindow>(&link_, store_.get(), options_);
    window->show();
    return window;
  }
  void loginAnna(MainWindow& window) {
    auto* users = child<QListWidget>(window, "userList");
    for (int i = 0; i < users->count(); ++i)
      if (users->item(i)->data(Qt::UserRole).toString() == "anna") users->setCurrentRow(i);
    child<QLineEdit>(window, "pinEdit")->setText("1357");
    child<QPushButton>(window, "loginButton")->click();
  }

  QTemporaryDir dir_;
  std::unique_ptr<records::Store> store_;
  ConsoleOptions options_;
  FakeLink link_;
};

TEST_F(ConsoleTest, WholeSessionFromLoginToTheStoredResult) {
  auto window = makeWindow();
  EXPECT_EQ(window->screen(), MainWindow::kLogin);
  loginAnna(*window);
  ASSERT_EQ(window->screen(), MainWindow::kScenarios);
  EXPECT_EQ(window->currentUser(), "anna");

  auto* scenarios = child<QListWidget>(*window, "scenarioList");
  ASSERT_EQ(scenarios->count(), 1);  // the scene without a scenario is not offered
  scenarios->setCurrentRow(0);
  auto* difficulty = child<QComboBox>(*window, "difficultyBox");
  EXPECT_EQ(difficulty->currentText(), "medium");  // the scenario's default
  difficulty->setCurrentText("hard");
  child<QPushButton>(*window, "loadButton")->click();
  ASSERT_EQ(link_.loads.size(), 1u);
  EXPECT_EQ(link_.loads[0].scene, "membrane_peeling");
  EXPECT_EQ(link_.loads[0].difficulty, "hard");
  EXPECT_EQ(link_.loads[0].user, "anna");
  EXPECT_TRUE(link_.loads[0].record);
  EXPECT_EQ(window->screen(), MainWindow::kSession);

  auto* start = child<QPushButton>(*window, "startButton");
  link_.station(StationState::kLoading, 0.4);
  EXPECT_FALSE(start->isEnabled()) << "START before the station is ready";
  link_.station(StationState::kReady, 1.0);
  link_.scenario(ScenarioState::kIdle, 0.0, "press START");
  ASSERT_TRUE(start->isEnabled());
  start->click();
  ASSERT_EQ(link_.commands.size(), 1u);
  EXPECT_EQ(link_.commands[0].first, SimulatorLink::kStart);

  // Instrument choice per hand from the scene's alternatives.
  auto* right = child<QComboBox>(*window, "instrument_right");
  right->setCurrentText("vitrector");
  ASSERT_EQ(link_.commands.size(), 2u);
  EXPECT_EQ(link_.commands[1].first, SimulatorLink::kSelectInstrument);
  EXPECT_EQ(link_.commands[1].second, "right:vitrector");
  EXPECT_FALSE(child<QComboBox>(*window, "instrument_left")->isEnabled()) << "no alternatives for the light pipe";
  // Issue 37: types are labelled by their message constants; a slot that can hold the laser probe has the laser
  // console's power and exposure, sent as the probe's settings.
  EXPECT_EQ(right->itemText(2), "laser probe");
  EXPECT_EQ(child<QComboBox>(*window, "instrument_left")->itemText(0), "light pipe");
  child<QSpinBox>(*window, "laser_power_right")->setValue(250);
  ASSERT_EQ(link_.commands.size(), 3u);
  EXPECT_EQ(link_.commands[2].first, SimulatorLink::kSelectInstrument);
  EXPECT_EQ(link_.commands[2].second, "right:laser_probe:power_mw=250,duration_ms=100");
  EXPECT_EQ(window->findChild<QSpinBox*>("laser_power_left"), nullptr) << "the light pipe's slot has no laser";
  link_.commands.resize(2);

  link_.scenario(ScenarioState::kRunning, 12.0, "3 of 7 adhesion points detached");
  EXPECT_EQ(child<QLabel>(*window, "sessionClock")->text(), "0:12");
  EXPECT_TRUE(child<QLabel>(*window, "sessionMessage")->text().contains("3 of 7"));
  link_.scenario(ScenarioState::kFinished, 29.75, "membrane peeled");
  emit link_.sessionResult(kResult);
  ASSERT_EQ(window->screen(), MainWindow::kResult);

  auto* table = child<QTableWidget>(*window, "resultTable");
  ASSERT_EQ(table->rowCount(), 2);
  EXPECT_EQ(table->item(0, 0)->text(), "completed");
  EXPECT_EQ(table->item(1, 0)->text(), "time");
  EXPECT_EQ(table->item(1, 1)->text(), "29.75");
  EXPECT_EQ(table->item(1, 3)->text(), "1");
  EXPECT_EQ(table->item(1, 4)->text(), "50 / 100");
  EXPECT_TRUE(child<QLabel>(*window, "resultTotal")->text().startsWith("87.5 / 100"));
  EXPECT_TRUE(child<QLabel>(*window, "resultTotal")->text().contains("PASSED"));

  const auto sessions = store_->sessions({"anna", "membrane_peeling"});
  ASSERT_EQ(sessions.size(), 1u);
  EXPECT_EQ(sessions[0].id, window->lastStoredSession());
  EXPECT_DOUBLE_EQ(sessions[0].total, 87.5);
  EXPECT_EQ(sessions[0].difficulty, "hard");
  EXPECT_EQ(sessions[0].bag_path, "/records/s.bag");
  EXPECT_EQ(sessions[0].items.size(), 2u);

  // The latched result again (a reconnect): still one row.
  emit link_.sessionResult(kResult);
  EXPECT_EQ(store_->sessions({"anna", ""}).size(), 1u);

  // History: the session in the table; the scenario list shows best/last.
  window->showScreen(MainWindow::kHistory);
  EXPECT_EQ(child<QTableWidget>(*window, "historyTable")->rowCount(), 1);
  window->showScreen(MainWindow::kScenarios);
  EXPECT_TRUE(scenarios->item(0)->text().contains("best 87.5"));
}

TEST_F(ConsoleTest, WrongPinKeepsTheLoginScreenAndGuestNeedsNone) {
  auto window = makeWindow();
  auto* users = child<QListWidget>(*window, "userList");
  for (int i = 0; i < users->count(); ++i)
    if (users->item(i)->data(Qt::UserRole).toString() == "anna") users->setCurrentRow(i);
  child<QLineEdit>(*window, "pinEdit")->setText("0000");
  child<QPushButton>(*window, "loginButton")->click();
  EXPECT_EQ(window->screen(), MainWindow::kLogin);
  EXPECT_TRUE(child<QLineEdit>(*window, "pinEdit")->text().isEmpty());
  child<QPushButton>(*window, "guestButton")->click();
  EXPECT_EQ(window->screen(), MainWindow::kScenarios);
  EXPECT_EQ(window->currentUser(), "guest");
  // A trainee is not an instructor: that screen stays closed.
  window->showScreen(MainWindow::kInstructor);
  EXPECT_EQ(window->screen(), MainWindow::kScenarios);
}

TEST_F(ConsoleTest, SpaceStartsAndPausesEscapeStops) {
  auto window = makeWindow();
  loginAnna(*window);
  child<QPushButton>(*window, "loadButton")->click();
  link_.station(StationState::kReady, 1.0);
  link_.scenario(ScenarioState::kIdle, 0.0, "");
  window->activateWindow();
  ASSERT_TRUE(QTest::qWaitForWindowActive(window.get()));
  QTest::keyClick(window.get(), Qt::Key_Space);
  ASSERT_EQ(link_.commands.size(), 1u);
  EXPECT_EQ(link_.commands.back().first, SimulatorLink::kStart);
  link_.scenario(ScenarioState::kRunning, 1.0, "");
  QTest::keyClick(window.get(), Qt::Key_Space);
  EXPECT_EQ(link_.commands.back().first, SimulatorLink::kPause);
  link_.scenario(ScenarioState::kPaused, 1.0, "");
  QTest::keyClick(window.get(), Qt::Key_Space);
  EXPECT_EQ(link_.commands.back().first, SimulatorLink::kResume);
  link_.scenario(ScenarioState::kRunning, 2.0, "");
  QTest::keyClick(window.get(), Qt::Key_Escape);
  EXPECT_EQ(link_.commands.back().first, SimulatorLink::kStop);
  EXPECT_EQ(link_.commands.size(), 4u);
}

TEST_F(ConsoleTest, AStartThatIsNotAcknowledgedIsSentAgain) {
  auto window = makeWindow();
  loginAnna(*window);
  child<QPushButton>(*window, "loadButton")->click();
  link_.station(StationState::kReady, 1.0);
  link_.scenario(ScenarioState::kIdle, 0.0, "");
  child<QPushButton>(*window, "startButton")->click();
  ASSERT_EQ(link_.commands.size(), 1u);
  ASSERT_TRUE(QTest::qWaitFor([&] { return link_.commands.size() == 2u; }, 5000)) << "no second START";
  EXPECT_EQ(link_.commands.back().first, SimulatorLink::kStart);
  link_.scenario(ScenarioState::kRunning, 0.5, "");  // acknowledged: no more
  QTest::qWait(3500);
  EXPECT_EQ(link_.commands.size(), 2u);
}

TEST_F(ConsoleTest, ExportWritesTheUsersCsvWithoutBlockingTheUi) {
  store_->importResultJson(kResult, "test", "anna");
  auto window = makeWindow();
  loginAnna(*window);
  window->showScreen(MainWindow::kHistory);
  child<QPushButton>(*window, "exportButton")->click();
  const QString path = QDir(dir_.path()).filePath("eyesi_anna.csv");
  ASSERT_TRUE(QTest::qWaitFor([&] { return QFile::exists(path) && QFile(path).size() > 0; }, 5000));
  QTest::qWait(100);
  QFile file(path);
  ASSERT_TRUE(file.open(QIODevice::ReadOnly));
  const QStringList lines = QString::fromUtf8(file.readAll()).split('\n', Qt::SkipEmptyParts);
  ASSERT_EQ(lines.size(), 3);  // header + two items
  EXPECT_TRUE(lines[1].contains("membrane_peeling"));
}

// Issue 35: the result screen shows the factor groups and every penalty (when, what, which instrument, where, the
// points it cost); the export writes them beside the items.
const char* kResultWithPenalties = R"({"scene": "membrane_peeling", "scenario": "membrane_peeling",
  "difficulty": "medium", "seed": 8, "state": "failed", "session_ended": true, "message": "failed: retina_contacts",
  "start_stamp": 200.5, "end_stamp": 230.25, "elapsed": 29.75, "total": 40.5,
  "items": [{"name": "retina_contacts", "value": 2, "unit": "1", "weight": 2, "points": 50}],
  "groups": [{"name": "tissue_treatment", "points": 50, "weight": 2}, {"name": "efficiency", "points": 20, "weight": 1}],
  "events": [{"time": 65.25, "kind": "retina_touched", "item": "retina_contacts", "slot": "right",
              "instrument": "forceps", "position": [0.0012, -0.0003, -0.0118], "points": 6.3},
             {"time": 70, "kind": "bleeding", "item": "bleeding_area", "slot": "", "instrument": "",
              "position": [null, null, null], "points": 1.5}],
  "events_dropped": 1, "final_state_hash": "0x00000000feedbeef", "frames": 1500, "user": "anna"})";

TEST_F(ConsoleTest, ResultScreenListsTheGroupsAndWhyPointsWereLost) {
  auto window = makeWindow();
  loginAnna(*window);
  auto* scenarios = child<QListWidget>(*window, "scenarioList");
  scenarios->setCurrentRow(0);
  child<QPushButton>(*window, "loadButton")->click();
  link_.station(StationState::kReady, 1.0);
  link_.scenario(ScenarioState::kFailed, 29.75, "failed: retina_contacts");
  emit link_.sessionResult(kResultWithPenalties);
  ASSERT_EQ(window->screen(), MainWindow::kResult);

  auto* groups = child<QTableWidget>(*window, "resultGroups");
  ASSERT_EQ(groups->rowCount(), 2);
  EXPECT_EQ(groups->item(0, 0)->text(), "tissue treatment");
  EXPECT_EQ(groups->item(0, 1)->text(), "50 / 100");
  EXPECT_EQ(groups->item(1, 0)->text(), "efficiency");
  auto* events = child<QTableWidget>(*window, "resultEvents");
  ASSERT_EQ(events->rowCount(), 2);
  EXPECT_EQ(events->item(0, 0)->text(), "1:05.2");
  EXPECT_EQ(events->item(0, 1)->text(), "retina touched");
  EXPECT_EQ(events->item(0, 2)->text(), "forceps (right)");
  EXPECT_EQ(events->item(0, 3)->text(), "1.2, -0.3, -11.8");
  EXPECT_EQ(events->item(0, 4)->text(), "-6.3");
  EXPECT_EQ(events->item(1, 2)->text(), "-");
  EXPECT_EQ(events->item(1, 3)->text(), "-");
  const QString note = child<QLabel>(*window, "resultEventsNote")->text();
  EXPECT_TRUE(note.contains("3 penalties cost 7.8 points")) << note.toStdString();
  EXPECT_TRUE(note.contains("1 not listed")) << note.toStdString();

  window->showScreen(MainWindow::kHistory);
  child<QPushButton>(*window, "exportButton")->click();
  const QString path = QDir(dir_.path()).filePath("eyesi_anna_events.csv");
  ASSERT_TRUE(QTest::qWaitFor([&] { return QFile::exists(path) && QFile(path).size() > 0; }, 5000));
  QTest::qWait(100);
  QFile file(path);
  ASSERT_TRUE(file.open(QIODevice::ReadOnly));
  const QStringList lines = QString::fromUtf8(file.readAll()).split('\n', Qt::SkipEmptyParts);
  ASSERT_EQ(lines.size(), 3);  // header + two events
  EXPECT_TRUE(lines[1].contains("retina_touched"));
  EXPECT_TRUE(QFile::exists(QDir(dir_.path()).filePath("eyesi_anna_groups.csv")));
}

TEST_F(ConsoleTest, CentreScreenShowsTheServersSessionsCurvesAndTheGroupsProgress) {
  store_->addUser("weber", records::Role::kInstructor, "2468");
  auto window = makeWindow();
  std::vector<records::CentreFilter> asked;
  QString password_seen;
  window->setCentreSource([&](const QString& user, const QString& password, const records::CentreFilter& filter) {
    EXPECT_EQ(user, "weber");
    password_seen = password;
    asked.push_back(filter);
    records::CentreData data;
    const char* stations[] = {"station_or1", "station_or2"};
    for (int i = 0; i < 6; ++i) {
      records::SessionRecord s;
      s.user = i % 2 ? "ben" : "anna";
      s.scene = i < 4 ? "membrane_peeling" : "navigation";
      s.difficulty = "medium";
      s.station = stations[i % 2];
      s.total = 40 + 10 * i;
      s.state = "finished";
      s.passed = true;
      s.start_stamp = 100 + i;
      s.recorded_at = "2026-11-2" + std::to_string(i) + "T10:00:00Z";
      data.sessions.push_back(s);
    }
    data.trainees = {"anna", "ben", "cleo"};
    data.assignments = {{"anna", "Basics", "basics.yaml",
                         "name: Basics\nsteps:\n  - module: membrane_peeling\n    level: medium\n    pass_mark: 50\n",
                         "weber", ""}};
    return data;
  });
  auto* users = child<QListWidget>(*window, "userList");
  for (int i = 0; i < users->count(); ++i)
    if (users->item(i)->data(Qt::UserRole).toString() == "weber") users->setCurrentRow(i);
  child<QLineEdit>(*window, "pinEdit")->setText("2468");
  child<QPushButton>(*window, "loginButton")->click();
  ASSERT_TRUE(child<QPushButton>(*window, "navCentre")->isVisible());
  window->showScreen(MainWindow::kCentre);
  ASSERT_EQ(window->screen(), MainWindow::kCentre);
  child<QLineEdit>(*window, "centrePassword")->setText("server-secret-1");
  child<QLineEdit>(*window, "centreStation")->setText("station_or1");
  child<QPushButton>(*window, "centreShowButton")->click();
  // Asked off the UI thread: the screen fills in when the answer is there.
  ASSERT_TRUE(QTest::qWaitFor([&] { return child<QTableWidget>(*window, "centreTable")->rowCount() > 0; }, 5000));
  ASSERT_EQ(asked.size(), 1u);
  EXPECT_EQ(asked[0].station, "station_or1");
  EXPECT_EQ(password_seen, "server-secret-1");
  auto* table = child<QTableWidget>(*window, "centreTable");
  ASSERT_EQ(table->rowCount(), 3);  // anna's three sessions on station_or1
  for (int row = 0; row < 3; ++row) EXPECT_EQ(table->item(row, 1)->text(), "station_or1");
  auto* chart = child<QtCharts::QChartView>(*window, "centreChart");
  EXPECT_EQ(chart->chart()->series().size(), 2);  // anna in two modules
  auto* progress = child<QTableWidget>(*window, "centreProgress");
  ASSERT_EQ(progress->rowCount(), 3);  // the whole group, cleo without a course included
  EXPECT_EQ(progress->item(0, 1)->text(), "Basics");
  EXPECT_EQ(progress->item(0, 2)->text(), "1 / 1");  // from all of anna's sessions, not only the filtered ones
  EXPECT_EQ(progress->item(2, 1)->text(), "(none)");
  // A filter the server cannot take is reported on the screen, not thrown.
  child<QLineEdit>(*window, "centreFrom")->setText("30.11.2026");
  child<QPushButton>(*window, "centreShowButton")->click();
  EXPECT_TRUE(
      QTest::qWaitFor([&] { return child<QLabel>(*window, "centreSummary")->text().contains("YYYY-MM-DD"); }, 5000));
  EXPECT_EQ(asked.size(), 1u);  // nothing was asked for it
  // A trainee never reaches the centre screen.
  child<QPushButton>(*window, "navLogout")->click();
  loginAnna(*window);
  EXPECT_FALSE(child<QPushButton>(*window, "navCentre")->isVisible());
  window->showScreen(MainWindow::kCentre);
  EXPECT_EQ(window->screen(), MainWindow::kScenarios);
}

TEST_F(ConsoleTest, ACentreUserWithoutAPinHereSignsInWithTheServerPasswordNeverAnEmptyPin) {
  store_->applyServerUsers({{"anna", "trainee", false}, {"carla", "trainee", false}});  // carla: from the server
  auto window = makeWindow();
  auto chooseCarla = [&] {
    auto* users = child<QListWidget>(*window, "userList");
    for (int i = 0; i < users->count(); ++i)
      if (users->item(i)->data(Qt::UserRole).toString() == "carla") users->setCurrentRow(i);
  };
  // Without a centre sign-in (a station on its own) carla cannot log in with an empty PIN.
  chooseCarla();
  child<QPushButton>(*window, "loginButton")->click();
  EXPECT_EQ(window->screen(), MainWindow::kLogin);
  QStringList signed_in;
  window->setCentreSignIn([&](const QString& user, const QString& password) {
    if (password != "carla-server-secret") throw std::runtime_error("password authentication failed");
    signed_in << user;
  });
  EXPECT_TRUE(child<QLineEdit>(*window, "centreLoginPassword")->isVisible());
  chooseCarla();
  child<QLineEdit>(*window, "centreLoginPassword")->setText("wrong-password-1");
  child<QPushButton>(*window, "loginButton")->click();
  EXPECT_EQ(window->screen(), MainWindow::kLogin);
  chooseCarla();
  child<QLineEdit>(*window, "pinEdit")->setText("8642");
  child<QLineEdit>(*window, "centreLoginPassword")->setText("carla-server-secret");
  child<QPushButton>(*window, "loginButton")->click();
  EXPECT_EQ(window->screen(), MainWindow::kScenarios);
  EXPECT_EQ(signed_in, QStringList{"carla"});
  EXPECT_TRUE(store_->checkPin("carla", "8642"));  // the PIN she chose, for this station only
  EXPECT_FALSE(store_->checkPin("carla", ""));
  // anna (a PIN of her own here) still logs in with it; a failed centre sign-in does not stop her (offline first).
  child<QPushButton>(*window, "navLogout")->click();
  child<QLineEdit>(*window, "centreLoginPassword")->setText("not-it");
  loginAnna(*window);
  EXPECT_EQ(window->screen(), MainWindow::kScenarios);
  EXPECT_EQ(window->currentUser(), "anna");
}

TEST(StereoView, AnaglyphTakesRedFromTheLeftEyeAndCyanFromTheRight) {
  QImage left(4, 2, QImage::Format_RGB888), right(4, 2, QImage::Format_RGB888);
  left.fill(QColor(200, 10, 20));
  right.fill(QColor(30, 150, 250));
  const QImage composed = StereoView::anaglyph(left, right);
  ASSERT_EQ(composed.size(), left.size());
  EXPECT_EQ(composed.pixelColor(1, 1), QColor(200, 150, 250));
}

}  // namespace
}  // namespace eyesi_gui

int main(int argc, char** argv) {
  const auto app = eyesi_gui::testing::offscreenApplication(argc, argv);
  ::testing::InitGoogleTest(&argc, argv);
  return RUN_ALL_TESTS();
}
