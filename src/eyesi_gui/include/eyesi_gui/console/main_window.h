// The trainee and instructor console (thesis §2.4, §7.3): login, scenario choice, the live session, its result,
// the history of sessions and the instructor's tools, as touch-sized screens in one window. It talks to the
// simulator only through a SimulatorLink and keeps the training records in a records::Store.
#pragma once

#include <QFutureWatcher>
#include <QMainWindow>
#include <QMap>
#include <QPointer>
#include <functional>
#include <memory>
#include <optional>

#include "eyesi_gui/console/simulator_link.h"
#include "eyesi_gui/records/centre.h"
#include "eyesi_gui/records/store.h"

class QComboBox;
class QLabel;
class QLineEdit;
class QListWidget;
class QPlainTextEdit;
class QProgressBar;
class QPushButton;
class QSlider;
class QStackedWidget;
class QTableWidget;
class QCheckBox;
class QTimer;

namespace QtCharts {
class QChartView;
}

namespace eyesi_gui {

class StereoView;
class CoursePanel;
class CourseAssigner;

struct ConsoleOptions {
  QString database;                    // the records store (opened by the caller)
  QString import_dir;                  // result files to import at start (a crashed or absent console's sessions)
  QString export_dir;                  // where CSV exports go ("" = ask with a file dialog)
  QString view_mode = "side_by_side";  // or "anaglyph"
  // Autopilot (demos, README screenshots and the real-window test): log in, load the scene, press START, wait for
  // the result, visit every screen, save a screenshot of each into screenshot_dir, then quit (exit status 0 only if
  // the session's result reached the records store).
  QString autopilot_scene;
  QString autopilot_user = "guest";
  QString autopilot_pin;
  QString screenshot_dir;
  double autopilot_timeout = 240.0;  // s
  QString course_dir;                // the course files an instructor can assign (*.yaml; "" = none)
};

class MainWindow : public QMainWindow {
  Q_OBJECT

 public:
  enum Screen { kLogin = 0, kScenarios, kSession, kResult, kHistory, kInstructor, kCentre };

  // The whole centre (issue 41): where the centre screen gets its data. The console's default (main.cpp, with the
  // ~centre_server parameter) asks the records server as the signed-in instructor with the password typed on that
  // screen (records::fetchCentre); tests give a fake. Without a source the screen says there is no records server.
  using CentreSource = std::function<records::CentreData(const QString& user, const QString& password,
                                                         const records::CentreFilter& filter)>;
  void setCentreSource(CentreSource source) { centre_source_ = std::move(source); }
  // Signing in for the centre on this station (records_sign_in as the person, with their server password): from then
  // on the station may upload their sessions. A user that came down from the server and has no PIN here logs in
  // only this way (then the PIN typed is set for this station); others may add it to a PIN login. Throws on failure.
  using CentreSignIn = std::function<void(const QString& user, const QString& password)>;
  void setCentreSignIn(CentreSignIn sign_in);

  MainWindow(SimulatorLink* link, records::Store* store, ConsoleOptions options, QWidget* parent = nullptr);
  ~MainWindow() override;

  Screen screen() const;
  QString currentUser() const { return user_ ? QString::fromStdString(user_->name) : QString(); }
  std::int64_t lastStoredSession() const { return last_stored_session_; }
  // Saves what the window shows (the X server's framebuffer under a real display, the widget under offscreen).
  bool saveScreenshot(const QString& path);

 public slots:
  void showScreen(eyesi_gui::MainWindow::Screen screen);
  void startOrPause();  // Space
  void stopSession();   // Esc

 signals:
  void autopilotFinished(int exit_code);

 private slots:
  void onScenes(const QVector<eyesi_gui::SceneInfo>& scenes, const QStringList& errors);
  void onStationStatus(const eyesi_gui::StationState& state);
  void onScenarioStatus(const eyesi_gui::ScenarioState& state);
  void onSessionResult(const QString& json);
  void onLoadAnswered(bool accepted, const QString& message, quint32 seed);
  void onLinkProblem(const QString& message);
  void autopilotStep();

 private:
  QWidget* buildTopBar();
  QWidget* buildLogin();
  QWidget* buildScenarios();
  QWidget* buildSession();
  QWidget* buildResult();
  QWidget* buildHistory();
  QWidget* buildInstructor();
  QWidget* buildCentre();

  void refreshUsers();
  void login(const records::User& user);
  void logout();
  void refreshScenarioList();
  void showSceneDetails();
  const SceneInfo* selectedScene() const;
  const SceneInfo* sceneNamed(const QString& name) const;
  void loadSelectedScene(bool record);
  void loadSession(const SessionRequest& request);
  void updateSessionControls();
  void rebuildInstrumentChoices(const SceneInfo* scene);
  void sendMicroscope();
  void showResult(std::int64_t session_id);
  void refreshHistory();
  void refreshInstructor();
  void refreshCentre();
  void exportCsv();
  void importFolderInBackground(const QString& folder);
  void replaySelected();
  void note(const QString& message);

  SimulatorLink* link_;
  records::Store* store_;
  ConsoleOptions options_;
  std::optional<records::User> user_;
  QVector<SceneInfo> scenes_;
  StationState station_;
  ScenarioState scenario_;
  SessionRequest current_request_;
  QString pending_difficulty_override_;
  std::int64_t last_stored_session_ = 0;
  QString replay_expected_hash_;
  QStringList result_jsons_seen_;
  int stereo_frames_ = 0;
  QTimer* start_retry_timer_ = nullptr;
  int start_retries_ = 0;

  // Widgets (object names are the tests' handles).
  QStackedWidget* stack_ = nullptr;
  QLabel* top_label_ = nullptr;
  QPushButton *nav_scenarios_ = nullptr, *nav_history_ = nullptr, *nav_instructor_ = nullptr, *nav_logout_ = nullptr;
  QPushButton* nav_centre_ = nullptr;
  QLabel* status_line_ = nullptr;
  // login
  QListWidget* user_list_ = nullptr;
  QLineEdit* pin_edit_ = nullptr;
  QLineEdit* new_user_edit_ = nullptr;
  QLineEdit* centre_login_password_ = nullptr;  // issue 41: the server password (shown with a centre sign-in)
  CentreSignIn centre_sign_in_;
  // scenarios
  QListWidget* scenario_list_ = nullptr;
  QLabel* scenario_details_ = nullptr;
  QComboBox* difficulty_box_ = nullptr;
  QCheckBox* record_check_ = nullptr;
  QPushButton* load_button_ = nullptr;
  CoursePanel* course_panel_ = nullptr;  // the trainee's assigned course
  // session
  StereoView* stereo_view_ = nullptr;
  QComboBox* view_mode_box_ = nullptr;
  QLabel* session_title_ = nullptr;
  QLabel* session_state_ = nullptr;
  QLabel* session_clock_ = nullptr;
  QLabel* session_message_ = nullptr;
  QProgressBar* progress_bar_ = nullptr;
  QPushButton *start_button_ = nullptr, *pause_button_ = nullptr, *stop_button_ = nullptr, *reset_button_ = nullptr;
  QCheckBox* session_record_check_ = nullptr;
  QMap<QString, QComboBox*> instrument_boxes_;
  QWidget* instrument_panel_ = nullptr;
  QSlider *zoom_slider_ = nullptr, *focus_slider_ = nullptr, *light_slider_ = nullptr;
  // result
  QLabel* result_title_ = nullptr;
  QLabel* result_total_ = nullptr;
  QTableWidget* result_table_ = nullptr;
  QTableWidget* result_groups_ = nullptr;  // the five factor groups (issue 35)
  QTableWidget* result_events_ = nullptr;  // the penalty events: why points were lost
  QLabel* result_events_note_ = nullptr;
  QLabel* result_comparison_ = nullptr;
  // history
  QComboBox* history_scene_box_ = nullptr;
  QtCharts::QChartView* history_chart_ = nullptr;
  QTableWidget* history_table_ = nullptr;
  QProgressBar* history_progress_ = nullptr;
  // instructor
  QTableWidget* instructor_table_ = nullptr;
  QComboBox* override_box_ = nullptr;
  QPlainTextEdit* annotation_edit_ = nullptr;
  CourseAssigner* course_assigner_ = nullptr;
  QFutureWatcher<QString> background_;
  // centre (issue 41)
  CentreSource centre_source_;
  QLineEdit *centre_password_ = nullptr, *centre_station_ = nullptr, *centre_trainee_ = nullptr;
  QLineEdit *centre_scene_ = nullptr, *centre_from_ = nullptr, *centre_to_ = nullptr;
  QTableWidget* centre_table_ = nullptr;
  QtCharts::QChartView* centre_chart_ = nullptr;
  QTableWidget* centre_progress_ = nullptr;
  QLabel* centre_summary_ = nullptr;
  // The server is asked off the UI thread (an unreachable one takes up to its 5 s connect timeout).
  struct CentreAnswer {
    records::CentreData data;
    std::vector<records::SessionRecord> sessions;  // filtered
    QString error;
  };
  QFutureWatcher<CentreAnswer>* centre_watcher_ = nullptr;
  void showCentre(const CentreAnswer& answer);

  // autopilot
  int autopilot_stage_ = -1;
  double autopilot_elapsed_ = 0.0;
  QTimer* autopilot_timer_ = nullptr;
};

}  // namespace eyesi_gui
