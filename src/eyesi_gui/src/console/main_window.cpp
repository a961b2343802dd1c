#include "eyesi_gui/console/main_window.h"

#include <QApplication>
#include <QCheckBox>
#include <QComboBox>
#include <QDateTime>
#include <QDir>
#include <QFileDialog>
#include <QFileInfo>
#include <QGridLayout>
#include <QGroupBox>
#include <QHBoxLayout>
#include <QHeaderView>
#include <QLabel>
#include <QLineEdit>
#include <QListWidget>
#include <QMessageBox>
#include <QPlainTextEdit>
#include <QProgressBar>
#include <QPushButton>
#include <QScreen>
#include <QShortcut>
#include <QSlider>
#include <QSpinBox>
#include <QStackedWidget>
#include <QStatusBar>
#include <QTableWidget>
#include <QTimer>
#include <QVBoxLayout>
#include <QWindow>
#include <QtCharts/QChartView>
#include <QtCharts/QLineSeries>
#include <QtCharts/QScatterSeries>
#include <QtCharts/QValueAxis>
#include <QtConcurrent/QtConcurrent>
#include <cmath>
#include <fstream>
#include <sstream>

#include "course_panel.h"
#include "eyesi_gui/console/message_constants.h"
#include "stereo_view.h"
#include "vrm_sim/result/session_result.h"

namespace eyesi_gui {
namespace {

QString q(const std::string& text) { return QString::fromStdString(text); }

// Touch targets: at least ~1 cm on a 1280x800 panel.
QPushButton* bigButton(const QString& text, const QString& name, QWidget* parent = nullptr) {
  auto* button = new QPushButton(text, parent);
  button->setObjectName(name);
  button->setMinimumSize(150, 56);
  button->setFocusPolicy(Qt::NoFocus);  // Space/Esc belong to the session, not to the focused button
  return button;
}

// The labels come with the constants (message_constants.h), so a state added to a message cannot show as another.
QString stateName(int state) { return constantLabel(kScenarioStatusConstants, state); }

QString stationStateName(int state) { return constantLabel(kStationStatusConstants, state); }

QString clock(double seconds) {
  const int s = static_cast<int>(seconds);
  return QString("%1:%2").arg(s / 60).arg(s % 60, 2, 10, QChar('0'));
}

QTableWidgetItem* cell(const QString& text) {
  auto* item = new QTableWidgetItem(text);
  item->setFlags(item->flags() & ~Qt::ItemIsEditable);
  return item;
}

}  // namespace

MainWindow::MainWindow(SimulatorLink* link, records::Store* store, ConsoleOptions options, QWidget* parent)
    : QMainWindow(parent), link_(link), store_(store), options_(std::move(options)) {
  setWindowTitle("EyeSi console");
  setMinimumSize(1280, 800);
  setStyleSheet(
      "QWidget { font-size: 17px; } QPushButton { padding: 8px 16px; } "
      "QListWidget::item { min-height: 48px; } QLabel#title { font-size: 26px; font-weight: bold; } "
      "QComboBox { min-height: 44px; } QLineEdit { min-height: 44px; } QCheckBox::indicator { width: 28px; "
      "height: 28px; } QSlider::handle:horizontal { width: 36px; } QTableWidget { font-size: 15px; }");
  auto* central = new QWidget;
  auto* layout = new QVBoxLayout(central);
  layout->addWidget(buildTopBar());
  stack_ = new QStackedWidget;
  stack_->addWidget(buildLogin());
  stack_->addWidget(buildScenarios());
  stack_->addWidget(buildSession());
  stack_->addWidget(buildResult());
  stack_->addWidget(buildHistory());
  stack_->addWidget(buildInstructor());
  stack_->addWidget(buildCentre());
  layout->addWidget(stack_, 1);
  setCentralWidget(central);
  status_line_ = new QLabel;
  statusBar()->addWidget(status_line_, 1);

  auto* space = new QShortcut(QKeySequence(Qt::Key_Space), this);
  space->setContext(Qt::ApplicationShortcut);
  connect(space, &QShortcut::activated, this, &MainWindow::startOrPause);
  auto* escape = new QShortcut(QKeySequence(Qt::Key_Escape), this);
  escape->setContext(Qt::ApplicationShortcut);
  connect(escape, &QShortcut::activated, this, &MainWindow::stopSession);

  connect(link_, &SimulatorLink::scenesListed, this, &MainWindow::onScenes);
  connect(link_, &SimulatorLink::stationStatus, this, &MainWindow::onStationStatus);
  connect(link_, &SimulatorLink::scenarioStatus, this, &MainWindow::onScenarioStatus);
  connect(link_, &SimulatorLink::sessionResult, this, &MainWindow::onSessionResult);
  connect(link_, &SimulatorLink::sessionLoadAnswered, this, &MainWindow::onLoadAnswered);
  connect(link_, &SimulatorLink::linkProblem, this, &MainWindow::onLinkProblem);
  connect(link_, &SimulatorLink::stereoFrame, this, [this](const QImage& left, const QImage& right) {
    // Only the session screen shows the view; a hidden one is not painted.
    ++stereo_frames_;
    if (screen() == kSession) stereo_view_->setFrame(left, right);
  });
  connect(&background_, &QFutureWatcher<QString>::finished, this, [this] {
    history_progress_->hide();
    note(background_.result());
    refreshHistory();
    refreshScenarioList();
  });

  refreshUsers();
  showScreen(kLogin);
  link_->requestScenes();
  if (!options_.import_dir.isEmpty()) importFolderInBackground(options_.import_dir);
  if (!options_.autopilot_scene.isEmpty()) {
    autopilot_stage_ = 0;
    autopilot_timer_ = new QTimer(this);
    connect(autopilot_timer_, &QTimer::timeout, this, &MainWindow::autopilotStep);
    autopilot_timer_->start(250);
  }
}

MainWindow::~MainWindow() { background_.waitForFinished(); }

MainWindow::Screen MainWindow::screen() const { return static_cast<Screen>(stack_->currentIndex()); }

QWidget* MainWindow::buildTopBar() {
  auto* bar = new QWidget;
  auto* layout = new QHBoxLayout(bar);
  top_label_ = new QLabel("EyeSi console");
  top_label_->setObjectName("title");
  layout->addWidget(top_label_, 1);
  nav_scenarios_ = bigButton("Scenarios", "navScenarios");
  nav_history_ = bigButton("History", "navHistory");
  nav_instructor_ = bigButton("Instructor", "navInstructor");
  nav_centre_ = bigButton("Centre", "navCentre");
  nav_logout_ = bigButton("Log out", "navLogout");
  for (QPushButton* button : {nav_scenarios_, nav_history_, nav_instructor_, nav_centre_, nav_logout_}) {
    layout->addWidget(button);
  }
  connect(nav_centre_, &QPushButton::clicked, this, [this] { showScreen(kCentre); });
  connect(nav_scenarios_, &QPushButton::clicked, this, [this] { showScreen(kScenarios); });
  connect(nav_history_, &QPushButton::clicked, this, [this] { showScreen(kHistory); });
  connect(nav_instructor_, &QPushButton::clicked, this, [this] { showScreen(kInstructor); });
  connect(nav_logout_, &QPushButton::clicked, this, &MainWindow::logout);
  return bar;
}

// ---- login -------------------------------------------------------------------------------------------------------

void MainWindow::setCentreSignIn(CentreSignIn sign_in) {
  centre_sign_in_ = std::move(sign_in);
  centre_login_password_->setVisible(static_cast<bool>(centre_sign_in_));
}

QWidget* MainWindow::buildLogin() {
  auto* page = new QWidget;
  auto* layout = new QHBoxLayout(page);
  auto* left = new QVBoxLayout;
  left->addWidget(new QLabel("Who is training?"));
  user_list_ = new QListWidget;
  user_list_->setObjectName("userList");
  left->addWidget(user_list_, 1);
  layout->addLayout(left, 1);

  auto* right = new QVBoxLayout;
  pin_edit_ = new QLineEdit;
  pin_edit_->setObjectName("pinEdit");
  pin_edit_->setEchoMode(QLineEdit::Password);
  pin_edit_->setPlaceholderText("PIN");
  right->addWidget(pin_edit_);
  auto* pad = new QGridLayout;
  const QStringList keys = {"1", "2", "3", "4", "5", "6", "7", "8", "9", "⌫", "0", "✓"};
  for (int i = 0; i < keys.size(); ++i) {
    auto* key = bigButton(keys[i], "pin_" + QString::number(i));
    pad->addWidget(key, i / 3, i % 3);
    connect(key, &QPushButton::clicked, this, [this, text = keys[i]] {
      if (text == "⌫") {
        pin_edit_->backspace();
      } else if (text == "✓") {
        findChild<QPushButton*>("loginButton")->click();
      } else {
        pin_edit_->insert(text);
      }
    });
  }
  right->addLayout(pad);
  centre_login_password_ = new QLineEdit;
  centre_login_password_->setObjectName("centreLoginPassword");
  centre_login_password_->setEchoMode(QLineEdit::Password);
  centre_login_password_->setPlaceholderText("centre password (to sign in for the centre on this station)");
  centre_login_password_->hide();  // until setCentreSignIn
  right->addWidget(centre_login_password_);
  auto* login_button = bigButton("Log in", "loginButton");
  connect(login_button, &QPushButton::clicked, this, [this] {
    auto* item = user_list_->currentItem();
    if (!item) return note("choose your name in the list first");
    const std::string name = item->data(Qt::UserRole).toString().toStdString();
    const std::optional<records::User> user = store_->findUser(name);
    if (!user) return;
    const QString server_password = centre_login_password_->text();
    centre_login_password_->clear();
    // A centre user without a PIN on this station proves who they are to the server, never with an empty PIN.
    const bool needs_server = user->from_server && !user->has_pin;
    if (needs_server && (!centre_sign_in_ || server_password.isEmpty())) {
      pin_edit_->clear();
      return note("first time on this station: sign in with your centre password (and choose a PIN)");
    }
    if (!needs_server && !store_->checkPin(name, pin_edit_->text().toStdString())) {
      pin_edit_->clear();
      return note("wrong PIN for " + q(name));
    }
    if (centre_sign_in_ && !server_password.isEmpty()) {
      try {
        centre_sign_in_(q(name), server_password);
        if (needs_server && !pin_edit_->text().isEmpty()) store_->setPin(name, pin_edit_->text().toStdString());
        note("signed in for the centre: this station uploads your sessions");
      } catch (const std::exception& error) {
        pin_edit_->clear();
        if (needs_server) return note(QString("centre sign-in failed: %1").arg(error.what()));
        note(QString("centre sign-in failed (your sessions stay on this station until you sign in): %1")
                 .arg(error.what()));
      }
    }
    login(*store_->findUser(name));
  });
  right->addWidget(login_button);
  auto* guest = bigButton("Continue as guest", "guestButton");
  connect(guest, &QPushButton::clicked, this, [this] {
    if (auto user = store_->findUser("guest")) login(*user);
  });
  right->addWidget(guest);
  auto* add_row = new QHBoxLayout;
  new_user_edit_ = new QLineEdit;
  new_user_edit_->setObjectName("newUserEdit");
  new_user_edit_->setPlaceholderText("new trainee's name (PIN from the field above)");
  auto* add = bigButton("Add trainee", "addUserButton");
  connect(add, &QPushButton::clicked, this, [this] {
    try {
      const records::User user = store_->addUser(new_user_edit_->text().trimmed().toStdString(),
                                                 records::Role::kTrainee, pin_edit_->text().toStdString());
      new_user_edit_->clear();
      refreshUsers();
      note("trainee " + q(user.name) + " added");
    } catch (const std::exception& error) {
      note(error.what());
    }
  });
  add_row->addWidget(new_user_edit_, 1);
  add_row->addWidget(add);
  right->addLayout(add_row);
  right->addStretch(1);
  layout->addLayout(right, 1);
  return page;
}

void MainWindow::refreshUsers() {
  user_list_->clear();
  for (const records::User& user : store_->users()) {
    auto* item = new QListWidgetItem(
        QString("%1   (%2%3)").arg(q(user.name), records::toString(user.role), user.has_pin ? "" : ", no PIN"));
    item->setData(Qt::UserRole, q(user.name));
    user_list_->addItem(item);
  }
}

void MainWindow::login(const records::User& user) {
  user_ = user;
  pin_edit_->clear();
  note("logged in as " + q(user.name));
  showScreen(kScenarios);
}

void MainWindow::logout() {
  if (station_.state == StationState::kRunning) stopSession();
  user_.reset();
  showScreen(kLogin);
}

// ---- scenarios ---------------------------------------------------------------------------------------------------

QWidget* MainWindow::buildScenarios() {
  auto* page = new QWidget;
  auto* layout = new QHBoxLayout(page);
  scenario_list_ = new QListWidget;
  scenario_list_->setObjectName("scenarioList");
  layout->addWidget(scenario_list_, 1);
  auto* right = new QVBoxLayout;
  scenario_details_ = new QLabel("asking the station for its scenarios ...");
  scenario_details_->setObjectName("scenarioDetails");
  scenario_details_->setWordWrap(true);
  scenario_details_->setAlignment(Qt::AlignTop | Qt::AlignLeft);
  right->addWidget(scenario_details_, 1);
  auto* row = new QHBoxLayout;
  row->addWidget(new QLabel("Difficulty"));
  difficulty_box_ = new QComboBox;
  difficulty_box_->setObjectName("difficultyBox");
  row->addWidget(difficulty_box_, 1);
  record_check_ = new QCheckBox("Record the session");
  record_check_->setObjectName("recordCheck");
  record_check_->setChecked(true);
  row->addWidget(record_check_);
  right->addLayout(row);
  load_button_ = bigButton("Load scenario", "loadButton");
  right->addWidget(load_button_);
  course_panel_ = new CoursePanel(store_);
  right->addWidget(course_panel_, 1);
  connect(course_panel_, &CoursePanel::startRequested, this, [this](const QString& scene, const QString& level) {
    if (!user_) return;
    SessionRequest request;
    request.user = q(user_->name);
    request.scene = scene;
    request.difficulty = level;
    request.record = record_check_->isChecked();
    loadSession(request);
  });
  layout->addLayout(right, 1);
  connect(scenario_list_, &QListWidget::currentRowChanged, this, [this] { showSceneDetails(); });
  connect(load_button_, &QPushButton::clicked, this, [this] { loadSelectedScene(record_check_->isChecked()); });
  return page;
}

void MainWindow::onScenes(const QVector<SceneInfo>& scenes, const QStringList& errors) {
  scenes_ = scenes;
  refreshScenarioList();
  refreshHistory();
  if (!errors.isEmpty()) note("the station could not load: " + errors.join("; "));
}

void MainWindow::refreshScenarioList() {
  const QString selected =
      scenario_list_->currentItem() ? scenario_list_->currentItem()->data(Qt::UserRole).toString() : QString();
  std::map<std::string, records::SceneSummary> summaries;
  if (user_)
    for (const auto& summary : store_->summaries(user_->name)) summaries[summary.scene] = summary;
  scenario_list_->blockSignals(true);
  scenario_list_->clear();
  for (const SceneInfo& scene : scenes_) {
    if (scene.scenario.isEmpty()) continue;  // a scene without a task has nothing to score
    QString text = scene.name;
    const auto summary = summaries.find(scene.name.toStdString());
    if (summary != summaries.end()) {
      text += QString("   best %1 · last %2").arg(summary->second.best, 0, 'f', 1).arg(summary->second.last, 0, 'f', 1);
    }
    auto* item = new QListWidgetItem(text);
    item->setData(Qt::UserRole, scene.name);
    scenario_list_->addItem(item);
    if (scene.name == selected) scenario_list_->setCurrentItem(item);
  }
  scenario_list_->blockSignals(false);
  if (!scenario_list_->currentItem() && scenario_list_->count() > 0) scenario_list_->setCurrentRow(0);
  showSceneDetails();
  course_panel_->refresh(user_, scenes_);
}

const SceneInfo* MainWindow::sceneNamed(const QString& name) const {
  for (const SceneInfo& scene : scenes_)
    if (scene.name == name) return &scene;
  return nullptr;
}

const SceneInfo* MainWindow::selectedScene() const {
  const auto* item = scenario_list_->currentItem();
  return item ? sceneNamed(item->data(Qt::UserRole).toString()) : nullptr;
}

void MainWindow::showSceneDetails() {
  const SceneInfo* scene = selectedScene();
  load_button_->setEnabled(scene != nullptr);
  if (!scene) return;
  QString text = QString("<h2>%1</h2><p>%2</p><p><b>Task:</b> %3</p>")
                     .arg(scene->name.toHtmlEscaped(), scene->description.toHtmlEscaped(),
                          scene->scenario_description.toHtmlEscaped());
  if (scene->time_limit > 0) text += QString("<p>Time limit: %1</p>").arg(clock(scene->time_limit));
  text += "<p><b>Scored:</b> ";
  for (int i = 0; i < scene->score_items.size(); ++i)
    text += QString("%1%2 (weight %3)").arg(i ? ", " : "", scene->score_items[i]).arg(scene->score_weights.value(i));
  text += "</p><p><b>Instruments:</b> ";
  for (const auto& slot : scene->instruments)
    text +=
        QString("%1: %2%3; ")
            .arg(slot.slot, slot.type, slot.alternatives.isEmpty() ? "" : " (or " + slot.alternatives.join(", ") + ")");
  if (user_) {
    for (const auto& summary : store_->summaries(user_->name)) {
      if (q(summary.scene) != scene->name) continue;
      text += QString("</p><p><b>Your sessions:</b> %1 · best %2 · last %3 (%4)")
                  .arg(summary.sessions)
                  .arg(summary.best, 0, 'f', 1)
                  .arg(summary.last, 0, 'f', 1)
                  .arg(q(summary.last_recorded_at));
    }
  }
  scenario_details_->setText(text + "</p>");
  difficulty_box_->clear();
  for (const QString& level : scene->difficulties) difficulty_box_->addItem(level);
  const QString wanted =
      pending_difficulty_override_.isEmpty() ? scene->default_difficulty : pending_difficulty_override_;
  difficulty_box_->setCurrentText(wanted);
  difficulty_box_->setEnabled(!scene->difficulties.isEmpty());
}

void MainWindow::loadSelectedScene(bool record) {
  const SceneInfo* scene = selectedScene();
  if (!scene || !user_) return;
  SessionRequest request;
  request.user = q(user_->name);
  request.scene = scene->name;
  request.difficulty = difficulty_box_->currentText();
  request.record = record;
  // A trainee's course locks its steps until the one before is passed, here as on the course panel.
  const QString locked = course_panel_->lockedReason(request.scene, request.difficulty);
  if (!locked.isEmpty()) return note(locked);
  loadSession(request);
}

void MainWindow::loadSession(const SessionRequest& request) {
  current_request_ = request;
  scenario_ = ScenarioState();
  replay_expected_hash_.clear();
  stereo_view_->clear(request.mode == "replay" ? "starting the replay ..." : "loading " + request.scene + " ...");
  rebuildInstrumentChoices(request.mode == "replay" ? nullptr : sceneNamed(request.scene));
  session_title_->setText(request.mode == "replay"
                              ? "Replay of " + QFileInfo(request.bag).fileName()
                              : request.scene + (request.difficulty.isEmpty() ? "" : " · " + request.difficulty));
  session_record_check_->blockSignals(true);
  session_record_check_->setChecked(request.record);
  session_record_check_->blockSignals(false);
  progress_bar_->setValue(0);
  progress_bar_->show();
  station_.state = StationState::kLoading;
  updateSessionControls();
  showScreen(kSession);
  link_->loadSession(request);
}

// ---- session -----------------------------------------------------------------------------------------------------

QWidget* MainWindow::buildSession() {
  auto* page = new QWidget;
  auto* layout = new QHBoxLayout(page);
  auto* left = new QVBoxLayout;
  auto* header = new QHBoxLayout;
  session_title_ = new QLabel;
  session_title_->setObjectName("title");
  header->addWidget(session_title_, 1);
  session_clock_ = new QLabel("0:00");
  session_clock_->setObjectName("sessionClock");
  session_clock_->setStyleSheet("font-size: 30px; font-weight: bold;");
  header->addWidget(session_clock_);
  left->addLayout(header);
  stereo_view_ = new StereoView;
  stereo_view_->setObjectName("stereoView");
  left->addWidget(stereo_view_, 1);
  progress_bar_ = new QProgressBar;
  progress_bar_->setObjectName("progressBar");
  progress_bar_->setRange(0, 100);
  left->addWidget(progress_bar_);
  auto* state_row = new QHBoxLayout;
  session_state_ = new QLabel("idle");
  session_state_->setObjectName("sessionState");
  session_state_->setStyleSheet("font-weight: bold;");
  state_row->addWidget(session_state_);
  session_message_ = new QLabel;
  session_message_->setObjectName("sessionMessage");
  session_message_->setWordWrap(true);
  state_row->addWidget(session_message_, 1);
  left->addLayout(state_row);
  auto* buttons = new QHBoxLayout;
  start_button_ = bigButton("Start  [Space]", "startButton");
  pause_button_ = bigButton("Pause", "pauseButton");
  stop_button_ = bigButton("Stop  [Esc]", "stopButton");
  reset_button_ = bigButton("Reset", "resetButton");
  for (QPushButton* button : {start_button_, pause_button_, stop_button_, reset_button_}) buttons->addWidget(button);
  left->addLayout(buttons);
  layout->addLayout(left, 3);

  auto* right = new QVBoxLayout;
  view_mode_box_ = new QComboBox;
  view_mode_box_->setObjectName("viewModeBox");
  view_mode_box_->addItems({"side by side", "anaglyph (red/cyan)"});
  view_mode_box_->setCurrentIndex(options_.view_mode == "anaglyph" ? 1 : 0);
  stereo_view_->setMode(options_.view_mode == "anaglyph" ? StereoView::Mode::kAnaglyph : StereoView::Mode::kSideBySide);
  connect(view_mode_box_, QOverload<int>::of(&QComboBox::currentIndexChanged), this, [this](int index) {
    stereo_view_->setMode(index == 1 ? StereoView::Mode::kAnaglyph : StereoView::Mode::kSideBySide);
  });
  right->addWidget(new QLabel("Stereo view"));
  right->addWidget(view_mode_box_);
  auto* instruments = new QGroupBox("Instruments");
  instrument_panel_ = instruments;
  instruments->setLayout(new QVBoxLayout);
  right->addWidget(instruments);
  auto* microscope = new QGroupBox("Microscope");
  auto* grid = new QGridLayout(microscope);
  auto slider = [&](const QString& label, const QString& name, int row, int minimum, int maximum, int value) {
    auto* s = new QSlider(Qt::Horizontal);
    s->setObjectName(name);
    s->setRange(minimum, maximum);
    s->setValue(value);
    s->setMinimumHeight(44);
    grid->addWidget(new QLabel(label), row, 0);
    grid->addWidget(s, row, 1);
    connect(s, &QSlider::sliderReleased, this, &MainWindow::sendMicroscope);
    connect(s, &QSlider::valueChanged, this, [this, s] {
      if (!s->isSliderDown()) sendMicroscope();
    });
    return s;
  };
  zoom_slider_ = slider("Zoom", "zoomSlider", 0, 10, 40, 10);        // x0.1: 1..4 (the knob twin's limits)
  focus_slider_ = slider("Focus", "focusSlider", 1, 150, 250, 200);  // mm: 150..250
  light_slider_ = slider("Light", "lightSlider", 2, 0, 100, 50);     // %
  right->addWidget(microscope);
  session_record_check_ = new QCheckBox("Record (reloads the scenario)");
  session_record_check_->setObjectName("sessionRecordCheck");
  connect(session_record_check_, &QCheckBox::toggled, this, [this](bool on) {
    SessionRequest request = current_request_;
    request.record = on;
    loadSession(request);
  });
  right->addWidget(session_record_check_);
  right->addStretch(1);
  layout->addLayout(right, 1);

  connect(start_button_, &QPushButton::clicked, this, [this] {
    const bool resume = scenario_.state == ScenarioState::kPaused;
    link_->sendCommand(resume ? SimulatorLink::kResume : SimulatorLink::kStart);
    if (!resume) {
      start_retries_ = 0;
      start_retry_timer_->start();
    }
  });
  // A command is one unlatched message: if the simulator's subscription was not connected yet it is lost, and the
  // scenario stays idle. START is sent again (a surplus START is refused by a running scenario, and recorded like
  // any command, so a replay still ends in the same state).
  start_retry_timer_ = new QTimer(this);
  start_retry_timer_->setInterval(3000);
  start_retry_timer_->setSingleShot(true);
  connect(start_retry_timer_, &QTimer::timeout, this, [this] {
    if (scenario_.state != ScenarioState::kIdle || station_.state != StationState::kReady || start_retries_ >= 3)
      return;
    ++start_retries_;
    note(QString("START not acknowledged by the simulator; sent again (%1)").arg(start_retries_));
    link_->sendCommand(SimulatorLink::kStart);
    start_retry_timer_->start();
  });
  connect(pause_button_, &QPushButton::clicked, this, [this] { link_->sendCommand(SimulatorLink::kPause); });
  connect(stop_button_, &QPushButton::clicked, this, &MainWindow::stopSession);
  connect(reset_button_, &QPushButton::clicked, this, [this] {
    // A fresh graph: the same scenario, newly loaded (and a new bag when recording).
    loadSession(current_request_);
  });
  updateSessionControls();
  return page;
}

void MainWindow::rebuildInstrumentChoices(const SceneInfo* scene) {
  QLayout* layout = instrument_panel_->layout();
  while (QLayoutItem* item = layout->takeAt(0)) {
    delete item->widget();
    delete item;
  }
  instrument_boxes_.clear();
  if (!scene) return;
  // Each type is shown by the label of its message constant (message_constants.h), sent by its scene name.
  const auto addType = [](QComboBox* box, const QString& type) {
    const char* label = instrumentTypeLabel(type.toStdString().c_str());
    box->addItem(label != nullptr ? QString(label) : type, type);
  };
  for (const InstrumentSlotInfo& slot : scene->instruments) {
    auto* box = new QComboBox;
    box->setObjectName("instrument_" + slot.slot);
    addType(box, slot.type);
    for (const QString& alternative : slot.alternatives) addType(box, alternative);
    box->setEnabled(!slot.alternatives.isEmpty());
    auto* row = new QWidget;
    auto* row_layout = new QHBoxLayout(row);
    row_layout->setContentsMargins(0, 0, 0, 0);
    row_layout->addWidget(new QLabel(slot.slot));
    row_layout->addWidget(box, 1);
    instrument_boxes_[slot.slot] = box;
    connect(box, QOverload<int>::of(&QComboBox::currentIndexChanged), this, [this, box, slot_name = slot.slot](int) {
      link_->sendCommand(SimulatorLink::kSelectInstrument, slot_name + ":" + box->currentData().toString());
    });
    // Issue 37: the laser console's power and exposure for a slot that can hold the laser probe; a change is a
    // SELECT_INSTRUMENT with the settings (recorded with the session like every command). Starts at the shipped
    // scenes' 200 mW / 100 ms.
    if (slot.type == "laser_probe" || slot.alternatives.contains("laser_probe")) {
      auto* power = new QSpinBox;
      power->setObjectName("laser_power_" + slot.slot);
      power->setRange(50, 1500);
      power->setSingleStep(10);
      power->setValue(200);
      power->setSuffix(" mW");
      power->setKeyboardTracking(false);
      auto* duration = new QSpinBox;
      duration->setObjectName("laser_duration_" + slot.slot);
      duration->setRange(20, 1000);
      duration->setSingleStep(10);
      duration->setValue(100);
      duration->setSuffix(" ms");
      duration->setKeyboardTracking(false);
      row_layout->addWidget(power);
      row_layout->addWidget(duration);
      const auto send = [this, power, duration, slot_name = slot.slot] {
        link_->sendCommand(SimulatorLink::kSelectInstrument, QString("%1:laser_probe:power_mw=%2,duration_ms=%3")
                                                                 .arg(slot_name)
                                                                 .arg(power->value())
                                                                 .arg(duration->value()));
      };
      connect(power, QOverload<int>::of(&QSpinBox::valueChanged), this, send);
      connect(duration, QOverload<int>::of(&QSpinBox::valueChanged), this, send);
    }
    layout->addWidget(row);
  }
}

void MainWindow::sendMicroscope() {
  MicroscopeSetting setting;
  setting.zoom = zoom_slider_->value() / 10.0;
  setting.focus_distance = focus_slider_->value() / 1000.0;
  setting.ambient_light = light_slider_->value() / 100.0;
  link_->setMicroscope(setting);
}

void MainWindow::startOrPause() {
  if (screen() != kSession) return;
  if (scenario_.state == ScenarioState::kRunning) {
    pause_button_->click();
  } else if (start_button_->isEnabled()) {
    start_button_->click();
  }
}

void MainWindow::stopSession() {
  if (scenario_.state == ScenarioState::kRunning || scenario_.state == ScenarioState::kPaused) {
    link_->sendCommand(SimulatorLink::kStop, "stopped at the console");
  } else if (station_.state == StationState::kLoading || station_.state == StationState::kReady ||
             station_.mode == "replay") {
    link_->endSession();
  }
}

void MainWindow::updateSessionControls() {
  const bool live = current_request_.mode != "replay";
  const bool ready = station_.state == StationState::kReady || station_.state == StationState::kRunning;
  const int state = scenario_.state;
  start_button_->setEnabled(live && ready && (state == ScenarioState::kIdle || state == ScenarioState::kPaused));
  start_button_->setText(state == ScenarioState::kPaused ? "Resume  [Space]" : "Start  [Space]");
  pause_button_->setEnabled(live && state == ScenarioState::kRunning);
  stop_button_->setEnabled(state == ScenarioState::kRunning || state == ScenarioState::kPaused ||
                           station_.state == StationState::kLoading || (!live && ready));
  reset_button_->setEnabled(live && station_.state != StationState::kLoading && !current_request_.scene.isEmpty());
  session_record_check_->setEnabled(live && state == ScenarioState::kIdle && station_.state != StationState::kLoading);
  instrument_panel_->setEnabled(live && ready);
}

void MainWindow::onStationStatus(const StationState& state) {
  station_ = state;
  if (state.state == StationState::kLoading) {
    progress_bar_->show();
    progress_bar_->setValue(static_cast<int>(100 * state.progress));
  } else {
    progress_bar_->hide();
  }
  session_state_->setText(state.mode == "replay" ? "replay " + stationStateName(state.state)
                                                 : stationStateName(state.state) + (state.recording ? "  ● REC" : ""));
  if (state.state == StationState::kFailed) session_message_->setText(state.message);
  if (state.state == StationState::kLoading || state.state == StationState::kReady)
    session_message_->setText(state.message);
  top_label_->setText(QString("EyeSi console — %1 — station %2: %3")
                          .arg(user_ ? q(user_->name) : "nobody", state.station, stationStateName(state.state)));
  updateSessionControls();
}

void MainWindow::onScenarioStatus(const ScenarioState& state) {
  if (!current_request_.scene.isEmpty() && current_request_.mode != "replay" &&
      state.scenario != current_request_.scene)
    return;  // the previous graph's latched status
  scenario_ = state;
  session_clock_->setText(clock(state.elapsed));
  session_state_->setText(stateName(state.state) + (station_.recording ? "  ● REC" : ""));
  session_message_->setText(state.message);
  updateSessionControls();
}

void MainWindow::onSessionResult(const QString& json) {
  if (result_jsons_seen_.contains(json)) return;  // latched: a reconnect delivers it again
  result_jsons_seen_ << json;
  // The simulator's one reader (vrm_sim/result/session_result.h), as the records store reads it.
  vrm_sim::result::SessionResult result;
  try {
    result = vrm_sim::result::resultFromJson(json.toStdString(), "session_result");
  } catch (const vrm_sim::result::ResultError& error) {
    note(QString("the session result could not be read: %1").arg(error.what()));
    return;
  }
  if (current_request_.mode == "replay") {
    const QString hash = QString::fromStdString(result.final_state_hash);
    const bool same = hash == replay_expected_hash_;
    session_message_->setText(QString("replay over: final state %1 %2 the recorded %3")
                                  .arg(hash, same ? "equals" : "DIFFERS FROM", replay_expected_hash_));
    note(session_message_->text());
    return;
  }
  if (!user_ || QString::fromStdString(result.scene) != current_request_.scene) return;
  try {
    // The station's graph outlives the session: the bag this session was recorded to is the station's to say.
    const std::string bag = station_.mode == "session" && station_.scene == current_request_.scene
                                ? station_.bag.toStdString()
                                : std::string();
    const records::ImportResult stored = store_->importResultJson(
        json.toStdString(), "live from station " + link_->stationName().toStdString(), user_->name, bag);
    last_stored_session_ = stored.session_id;
    showResult(stored.session_id);
  } catch (const std::exception& error) {
    note(QString("the result could not be stored: %1").arg(error.what()));
  }
}

void MainWindow::onLoadAnswered(bool accepted, const QString& message, quint32 seed) {
  if (!accepted) {
    station_.state = StationState::kFailed;
    session_message_->setText("the station refused: " + message);
    progress_bar_->hide();
    updateSessionControls();
  } else {
    note(QString("%1 (seed %2)").arg(message).arg(seed));
  }
}

void MainWindow::onLinkProblem(const QString& message) {
  note(message);
  if (station_.state == StationState::kLoading) {
    station_.state = StationState::kFailed;
    session_message_->setText(message);
    progress_bar_->hide();
    updateSessionControls();
  }
}

// ---- result ------------------------------------------------------------------------------------------------------

QWidget* MainWindow::buildResult() {
  auto* page = new QWidget;
  auto* layout = new QVBoxLayout(page);
  result_title_ = new QLabel;
  result_title_->setObjectName("title");
  layout->addWidget(result_title_);
  result_total_ = new QLabel;
  result_total_->setObjectName("resultTotal");
  result_total_->setStyleSheet("font-size: 34px; font-weight: bold;");
  layout->addWidget(result_total_);
  result_table_ = new QTableWidget(0, 5);
  result_table_->setObjectName("resultTable");
  result_table_->setHorizontalHeaderLabels({"item", "value", "unit", "weight", "points earned"});
  result_table_->horizontalHeader()->setSectionResizeMode(QHeaderView::Stretch);
  layout->addWidget(result_table_, 1);
  // Issue 35: the score by factor group, and every penalty with when, where and what it cost.
  result_groups_ = new QTableWidget(0, 3);
  result_groups_->setObjectName("resultGroups");
  result_groups_->setHorizontalHeaderLabels({"factor group", "points", "weight"});
  result_groups_->horizontalHeader()->setSectionResizeMode(QHeaderView::Stretch);
  layout->addWidget(result_groups_);
  result_events_note_ = new QLabel;
  result_events_note_->setObjectName("resultEventsNote");
  result_events_note_->setWordWrap(true);
  layout->addWidget(result_events_note_);
  result_events_ = new QTableWidget(0, 5);
  result_events_->setObjectName("resultEvents");
  result_events_->setHorizontalHeaderLabels({"time", "what happened", "instrument", "where (mm, eye)", "points lost"});
  result_events_->horizontalHeader()->setSectionResizeMode(QHeaderView::Stretch);
  layout->addWidget(result_events_, 1);
  result_comparison_ = new QLabel;
  result_comparison_->setObjectName("resultComparison");
  result_comparison_->setWordWrap(true);
  layout->addWidget(result_comparison_);
  auto* row = new QHBoxLayout;
  auto* again = bigButton("Again", "againButton");
  auto* other = bigButton("Other scenario", "otherButton");
  auto* history = bigButton("History", "resultHistoryButton");
  row->addWidget(again);
  row->addWidget(other);
  row->addWidget(history);
  layout->addLayout(row);
  connect(again, &QPushButton::clicked, this, [this] { loadSession(current_request_); });
  connect(other, &QPushButton::clicked, this, [this] { showScreen(kScenarios); });
  connect(history, &QPushButton::clicked, this, [this] { showScreen(kHistory); });
  return page;
}

void MainWindow::showResult(std::int64_t session_id) {
  const auto session = store_->session(session_id);
  if (!session) return;
  result_title_->setText(QString("%1 · %2 · %3").arg(q(session->scene), q(session->difficulty), q(session->user)));
  result_total_->setText(QString("%1 / 100   %2   (%3)")
                             .arg(session->total, 0, 'f', 1)
                             .arg(session->passed ? "PASSED" : "NOT PASSED", q(session->message)));
  result_total_->setStyleSheet(
      QString("font-size: 34px; font-weight: bold; color: %1;").arg(session->passed ? "#1b7f2a" : "#b3261e"));
  result_table_->setRowCount(static_cast<int>(session->items.size()));
  for (int row = 0; row < static_cast<int>(session->items.size()); ++row) {
    const records::ScoreItemRecord& item = session->items[row];
    result_table_->setItem(row, 0, cell(q(item.name)));
    result_table_->setItem(row, 1, cell(QString::number(item.value, 'g', 4)));
    result_table_->setItem(row, 2, cell(q(item.unit)));
    result_table_->setItem(row, 3, cell(QString::number(item.weight, 'g', 3)));
    result_table_->setItem(row, 4, cell(QString("%1 / 100").arg(item.points, 0, 'f', 0)));
  }
  const auto words = [](const std::string& name) { return q(name).replace('_', ' '); };
  result_groups_->setRowCount(static_cast<int>(session->groups.size()));
  for (int row = 0; row < static_cast<int>(session->groups.size()); ++row) {
    const records::GroupRecord& group = session->groups[row];
    result_groups_->setItem(row, 0, cell(words(group.name)));
    result_groups_->setItem(row, 1, cell(QString("%1 / 100").arg(group.points, 0, 'f', 0)));
    result_groups_->setItem(row, 2, cell(QString::number(group.weight, 'g', 3)));
  }
  result_events_->setRowCount(static_cast<int>(session->events.size()));
  double lost = 0.0;
  for (int row = 0; row < static_cast<int>(session->events.size()); ++row) {
    const records::PenaltyEventRecord& event = session->events[row];
    lost += event.points;
    const int seconds = static_cast<int>(event.time);
    result_events_->setItem(row, 0,
                            cell(QString("%1:%2.%3")
                                     .arg(seconds / 60)
                                     .arg(seconds % 60, 2, 10, QChar('0'))
                                     .arg(static_cast<int>((event.time - seconds) * 10.0))));
    result_events_->setItem(row, 1, cell(words(event.kind)));
    result_events_->setItem(
        row, 2, cell(event.slot.empty() ? QString("-") : QString("%1 (%2)").arg(q(event.instrument), q(event.slot))));
    const bool located =
        std::isfinite(event.position[0]) && std::isfinite(event.position[1]) && std::isfinite(event.position[2]);
    result_events_->setItem(row, 3,
                            cell(located ? QString("%1, %2, %3")
                                               .arg(1e3 * event.position[0], 0, 'f', 1)
                                               .arg(1e3 * event.position[1], 0, 'f', 1)
                                               .arg(1e3 * event.position[2], 0, 'f', 1)
                                         : QString("-")));
    result_events_->setItem(row, 4, cell(QString("%1").arg(-event.points, 0, 'f', 1)));
  }
  if (session->groups.empty() && session->events.empty()) {
    result_events_note_->setText("Recorded before factor groups and penalty events were kept.");
  } else if (session->events.empty()) {
    result_events_note_->setText("No penalties: no points were lost to mistakes.");
  } else {
    result_events_note_->setText(
        QString("%1 penalt%2 cost %3 points%4.")
            .arg(session->events.size() + session->events_dropped)
            .arg(session->events.size() + session->events_dropped == 1 ? "y" : "ies")
            .arg(lost, 0, 'f', 1)
            .arg(session->events_dropped > 0 ? QString(" (%1 not listed)").arg(session->events_dropped) : QString()));
  }
  // Against the trainee's earlier sessions of this scene.
  records::SessionFilter filter{session->user, session->scene};
  double best = -1.0, sum = 0.0;
  int earlier = 0;
  for (const auto& other : store_->sessions(filter)) {
    if (other.id == session->id) continue;
    best = std::max(best, other.total);
    sum += other.total;
    ++earlier;
  }
  result_comparison_->setText(earlier == 0
                                  ? "Your first session of this scenario."
                                  : QString("Your %1 earlier sessions: best %2, mean %3 — this one is %4 the mean%5.")
                                        .arg(earlier)
                                        .arg(best, 0, 'f', 1)
                                        .arg(sum / earlier, 0, 'f', 1)
                                        .arg(session->total >= sum / earlier ? "above" : "below")
                                        .arg(session->total > best ? " and your new best" : ""));
  showScreen(kResult);
}

// ---- history -----------------------------------------------------------------------------------------------------

QWidget* MainWindow::buildHistory() {
  auto* page = new QWidget;
  auto* layout = new QVBoxLayout(page);
  auto* row = new QHBoxLayout;
  row->addWidget(new QLabel("Scenario"));
  history_scene_box_ = new QComboBox;
  history_scene_box_->setObjectName("historySceneBox");
  row->addWidget(history_scene_box_, 1);
  auto* replay = bigButton("Replay", "replayButton");
  auto* export_button = bigButton("Export CSV", "exportButton");
  auto* import_button = bigButton("Import results", "importButton");
  row->addWidget(replay);
  row->addWidget(export_button);
  row->addWidget(import_button);
  layout->addLayout(row);
  history_chart_ = new QtCharts::QChartView;
  history_chart_->setObjectName("historyChart");
  history_chart_->setRenderHint(QPainter::Antialiasing);
  history_chart_->setMinimumHeight(260);
  layout->addWidget(history_chart_, 1);
  history_table_ = new QTableWidget(0, 8);
  history_table_->setObjectName("historyTable");
  history_table_->setHorizontalHeaderLabels(
      {"#", "recorded", "user", "scenario", "difficulty", "score", "result", "bag"});
  history_table_->horizontalHeader()->setSectionResizeMode(QHeaderView::ResizeToContents);
  history_table_->horizontalHeader()->setStretchLastSection(true);
  history_table_->setSelectionBehavior(QAbstractItemView::SelectRows);
  layout->addWidget(history_table_, 1);
  history_progress_ = new QProgressBar;
  history_progress_->setRange(0, 0);  // busy: import and export report when done
  history_progress_->hide();
  layout->addWidget(history_progress_);
  connect(history_scene_box_, &QComboBox::currentTextChanged, this, [this] { refreshHistory(); });
  connect(replay, &QPushButton::clicked, this, &MainWindow::replaySelected);
  connect(export_button, &QPushButton::clicked, this, &MainWindow::exportCsv);
  connect(import_button, &QPushButton::clicked, this, [this] {
    const QString folder = QFileDialog::getExistingDirectory(this, "Result files of another station");
    if (!folder.isEmpty()) importFolderInBackground(folder);
  });
  return page;
}

void MainWindow::refreshHistory() {
  if (!history_scene_box_) return;
  const QString scene_choice = history_scene_box_->currentText();
  history_scene_box_->blockSignals(true);
  history_scene_box_->clear();
  history_scene_box_->addItem("all scenarios");
  for (const SceneInfo& scene : scenes_)
    if (!scene.scenario.isEmpty()) history_scene_box_->addItem(scene.name);
  history_scene_box_->setCurrentText(scene_choice.isEmpty() ? "all scenarios" : scene_choice);
  history_scene_box_->blockSignals(false);
  if (!user_) return;
  const QString scene = history_scene_box_->currentIndex() <= 0 ? QString() : history_scene_box_->currentText();
  const auto sessions = store_->sessions({user_->name, scene.toStdString()});
  history_table_->setRowCount(static_cast<int>(sessions.size()));
  auto* chart = new QtCharts::QChart;
  chart->setTitle(
      QString("%1 — score per session (%2)").arg(q(user_->name), scene.isEmpty() ? "all scenarios" : scene));
  std::map<std::string, QtCharts::QLineSeries*> lines;
  for (int row = 0; row < static_cast<int>(sessions.size()); ++row) {
    const records::SessionRecord& session = sessions[row];
    history_table_->setItem(row, 0, cell(QString::number(session.id)));
    history_table_->item(row, 0)->setData(Qt::UserRole, QVariant::fromValue<qlonglong>(session.id));
    history_table_->setItem(row, 1, cell(q(session.recorded_at)));
    history_table_->setItem(row, 2, cell(q(session.user)));
    history_table_->setItem(row, 3, cell(q(session.scene)));
    history_table_->setItem(row, 4, cell(q(session.difficulty)));
    history_table_->setItem(row, 5, cell(QString::number(session.total, 'f', 1)));
    history_table_->setItem(row, 6, cell(session.passed ? "passed" : q(session.state)));
    history_table_->setItem(row, 7, cell(q(session.bag_path)));
    auto*& line = lines[session.scene];
    if (!line) {
      line = new QtCharts::QLineSeries;
      line->setName(q(session.scene));
      line->setPointsVisible(true);
    }
    line->append(row + 1, session.total);
  }
  for (auto& entry : lines) chart->addSeries(entry.second);
  chart->createDefaultAxes();
  for (QtCharts::QAbstractAxis* axis : chart->axes(Qt::Vertical)) axis->setRange(0, 100);
  for (QtCharts::QAbstractAxis* axis : chart->axes(Qt::Horizontal)) {
    axis->setRange(0.5, std::max<int>(2, sessions.size()) + 0.5);
    axis->setTitleText("session");
    if (auto* values = qobject_cast<QtCharts::QValueAxis*>(axis)) values->setLabelFormat("%d");
  }
  QtCharts::QChart* old = history_chart_->chart();
  history_chart_->setChart(chart);
  delete old;
}

void MainWindow::replaySelected() {
  const auto rows = history_table_->selectionModel()->selectedRows();
  if (rows.isEmpty()) return note("choose a session in the table");
  const auto session = store_->session(history_table_->item(rows.front().row(), 0)->data(Qt::UserRole).toLongLong());
  if (!session || session->bag_path.empty()) return note("that session was not recorded");
  SessionRequest request;
  request.mode = "replay";
  request.user = q(session->user);
  request.bag = q(session->bag_path);
  loadSession(request);
  replay_expected_hash_ = q(session->final_state_hash);
}

void MainWindow::exportCsv() {
  if (!user_) return;
  const QString scene = history_scene_box_->currentIndex() <= 0 ? QString() : history_scene_box_->currentText();
  const QString suggested = QString("eyesi_%1%2.csv").arg(q(user_->name), scene.isEmpty() ? "" : "_" + scene);
  const QString path = options_.export_dir.isEmpty()
                           ? QFileDialog::getSaveFileName(this, "Export CSV", QDir::home().filePath(suggested), "*.csv")
                           : QDir(options_.export_dir).filePath(suggested);
  if (path.isEmpty() || background_.isRunning()) return;
  history_progress_->show();
  const std::string database = store_->path(), user = user_->name, scene_name = scene.toStdString();
  // A connection of its own on a worker thread: a long history never freezes the UI.
  background_.setFuture(QtConcurrent::run([database, user, scene_name, path]() -> QString {
    try {
      records::Store store(database);
      std::ofstream out(path.toStdString());
      store.exportCsv(out, {user, scene_name});
      out.close();
      if (!out) return "could not write " + path;
      // The factor groups and penalty events beside it (issue 35): <name>_groups.csv, <name>_events.csv.
      const QString stem = path.endsWith(".csv", Qt::CaseInsensitive) ? path.left(path.size() - 4) : path;
      std::ofstream groups((stem + "_groups.csv").toStdString());
      store.exportGroupsCsv(groups, {user, scene_name});
      groups.close();
      std::ofstream events((stem + "_events.csv").toStdString());
      store.exportEventsCsv(events, {user, scene_name});
      events.close();
      if (!groups || !events) return "could not write " + stem + "_groups.csv / _events.csv";
      return "exported to " + path + " (with _groups.csv and _events.csv)";
    } catch (const std::exception& error) {
      return QString("export failed: %1").arg(error.what());
    }
  }));
}

void MainWindow::importFolderInBackground(const QString& folder) {
  if (background_.isRunning()) return;
  history_progress_->show();
  const std::string database = store_->path(), path = folder.toStdString();
  background_.setFuture(QtConcurrent::run([database, path, folder]() -> QString {
    try {
      records::Store store(database);
      std::vector<std::string> errors;
      const auto results = store.importFolder(path, &errors);
      int inserted = 0;
      for (const auto& result : results) inserted += result.inserted;
      QString text = QString("%1 result files in %2, %3 new").arg(results.size()).arg(folder).arg(inserted);
      if (!errors.empty()) text += QString("; %1 unreadable: %2").arg(errors.size()).arg(q(errors.front()));
      return text;
    } catch (const std::exception& error) {
      return QString("import failed: %1").arg(error.what());
    }
  }));
}

// ---- instructor --------------------------------------------------------------------------------------------------

QWidget* MainWindow::buildInstructor() {
  auto* page = new QWidget;
  auto* layout = new QVBoxLayout(page);
  layout->addWidget(
      new QLabel("Recorded sessions of every trainee: play one as ghost instruments over the running "
                 "session, annotate it, or set the difficulty of the next session."));
  instructor_table_ = new QTableWidget(0, 7);
  instructor_table_->setObjectName("instructorTable");
  instructor_table_->setHorizontalHeaderLabels({"#", "user", "scenario", "difficulty", "score", "bag", "annotation"});
  instructor_table_->horizontalHeader()->setSectionResizeMode(QHeaderView::ResizeToContents);
  instructor_table_->horizontalHeader()->setStretchLastSection(true);
  instructor_table_->setSelectionBehavior(QAbstractItemView::SelectRows);
  layout->addWidget(instructor_table_, 1);
  auto* row = new QHBoxLayout;
  auto* ghost = bigButton("Play as ghost", "ghostButton");
  auto* stop_ghost = bigButton("Stop ghost", "stopGhostButton");
  row->addWidget(ghost);
  row->addWidget(stop_ghost);
  row->addWidget(new QLabel("Difficulty of the next session"));
  override_box_ = new QComboBox;
  override_box_->setObjectName("overrideBox");
  override_box_->addItems({"(scenario default)", "easy", "medium", "hard"});
  row->addWidget(override_box_);
  layout->addLayout(row);
  annotation_edit_ = new QPlainTextEdit;
  annotation_edit_->setObjectName("annotationEdit");
  annotation_edit_->setPlaceholderText("note on the selected session");
  annotation_edit_->setMaximumHeight(110);
  layout->addWidget(annotation_edit_);
  auto* save = bigButton("Save note", "saveNoteButton");
  layout->addWidget(save);
  course_assigner_ = new CourseAssigner(store_, options_.course_dir);
  layout->addWidget(course_assigner_);
  connect(course_assigner_, &CourseAssigner::note, this, &MainWindow::note);
  auto selected = [this]() -> std::optional<records::SessionRecord> {
    const auto rows = instructor_table_->selectionModel()->selectedRows();
    if (rows.isEmpty()) return std::nullopt;
    return store_->session(instructor_table_->item(rows.front().row(), 0)->data(Qt::UserRole).toLongLong());
  };
  connect(ghost, &QPushButton::clicked, this, [this, selected] {
    const auto session = selected();
    if (!session || session->bag_path.empty()) return note("choose a recorded session");
    if (station_.state != StationState::kReady && station_.state != StationState::kRunning)
      return note("load a session first: the ghost plays over it");
    link_->playGhost(q(session->bag_path), 1.0);
    note("ghost: " + q(session->user) + "'s " + q(session->scene));
  });
  connect(stop_ghost, &QPushButton::clicked, this, [this] { link_->playGhost(QString(), 1.0); });
  connect(override_box_, &QComboBox::currentTextChanged, this, [this](const QString& level) {
    pending_difficulty_override_ = override_box_->currentIndex() == 0 ? QString() : level;
    showSceneDetails();
  });
  connect(save, &QPushButton::clicked, this, [this, selected] {
    const auto session = selected();
    if (!session) return note("choose a session");
    store_->annotate(session->id, annotation_edit_->toPlainText().toStdString());
    refreshInstructor();
  });
  connect(instructor_table_, &QTableWidget::itemSelectionChanged, this, [this, selected] {
    if (const auto session = selected()) annotation_edit_->setPlainText(q(session->annotation));
  });
  return page;
}

void MainWindow::refreshInstructor() {
  course_assigner_->refresh(user_, scenes_);
  const auto sessions = store_->sessions();
  instructor_table_->setRowCount(static_cast<int>(sessions.size()));
  for (int row = 0; row < static_cast<int>(sessions.size()); ++row) {
    const records::SessionRecord& session = sessions[row];
    instructor_table_->setItem(row, 0, cell(QString::number(session.id)));
    instructor_table_->item(row, 0)->setData(Qt::UserRole, QVariant::fromValue<qlonglong>(session.id));
    instructor_table_->setItem(row, 1, cell(q(session.user)));
    instructor_table_->setItem(row, 2, cell(q(session.scene)));
    instructor_table_->setItem(row, 3, cell(q(session.difficulty)));
    instructor_table_->setItem(row, 4, cell(QString::number(session.total, 'f', 1)));
    instructor_table_->setItem(row, 5, cell(q(session.bag_path)));
    instructor_table_->setItem(row, 6, cell(q(session.annotation)));
  }
}

// ---- navigation, notes, autopilot --------------------------------------------------------------------------------

void MainWindow::showScreen(Screen screen) {
  const bool logged_in = user_.has_value();
  if (!logged_in) screen = kLogin;
  if ((screen == kInstructor || screen == kCentre) && (!user_ || user_->role != records::Role::kInstructor)) {
    screen = kScenarios;
  }
  nav_scenarios_->setVisible(logged_in);
  nav_history_->setVisible(logged_in);
  nav_logout_->setVisible(logged_in);
  nav_instructor_->setVisible(logged_in && user_->role == records::Role::kInstructor);
  nav_centre_->setVisible(logged_in && user_->role == records::Role::kInstructor);
  if (screen == kScenarios) refreshScenarioList();
  if (screen == kHistory) refreshHistory();
  if (screen == kInstructor) refreshInstructor();
  if (screen == kLogin) refreshUsers();
  stack_->setCurrentIndex(screen);
  top_label_->setText(QString("EyeSi console — %1%2")
                          .arg(user_ ? q(user_->name) : "please log in",
                               station_.station.isEmpty() ? "" : " — station " + station_.station));
}

void MainWindow::note(const QString& message) {
  status_line_->setText(message);
  qInfo("console: %s", qPrintable(message));
}

bool MainWindow::saveScreenshot(const QString& path) {
  QPixmap picture;
  // Under a real display the X server's framebuffer (what a user sees), else the window's own rendering.
  if (QGuiApplication::platformName() == "xcb" && windowHandle() && windowHandle()->screen()) {
    picture = windowHandle()->screen()->grabWindow(0, geometry().x(), geometry().y(), width(), height());
  }
  if (picture.isNull()) picture = grab();
  const bool saved = picture.save(path, "PNG");
  note(saved ? "screenshot " + path : "could not save " + path);
  return saved;
}

void MainWindow::autopilotStep() {
  autopilot_elapsed_ += 0.25;
  auto shot = [this](const QString& name) {
    if (!options_.screenshot_dir.isEmpty()) saveScreenshot(QDir(options_.screenshot_dir).filePath(name + ".png"));
  };
  auto finish = [this](int code, const QString& why) {
    autopilot_timer_->stop();
    note("autopilot: " + why);
    emit autopilotFinished(code);
  };
  if (autopilot_elapsed_ > options_.autopilot_timeout && autopilot_stage_ < 7)
    return finish(1, QString("timed out in stage %1 (station: %2, scenario: %3)")
                         .arg(autopilot_stage_)
                         .arg(station_.message, scenario_.message));
  switch (autopilot_stage_) {
    case 0:  // the login screen, then log in by its own buttons
      if (user_list_->count() == 0 || autopilot_elapsed_ < 1.0) return;
      shot("login");
      for (int i = 0; i < user_list_->count(); ++i)
        if (user_list_->item(i)->data(Qt::UserRole).toString() == options_.autopilot_user) user_list_->setCurrentRow(i);
      if (options_.autopilot_user == "guest") {
        findChild<QPushButton*>("guestButton")->click();
      } else {
        pin_edit_->setText(options_.autopilot_pin);
        findChild<QPushButton*>("loginButton")->click();
      }
      if (!user_) return finish(1, "could not log in as " + options_.autopilot_user);
      autopilot_stage_ = 1;
      return;
    case 1:  // the scenario list from the station
      if (!sceneNamed(options_.autopilot_scene)) return;
      for (int i = 0; i < scenario_list_->count(); ++i)
        if (scenario_list_->item(i)->data(Qt::UserRole).toString() == options_.autopilot_scene)
          scenario_list_->setCurrentRow(i);
      shot("scenarios");
      load_button_->click();
      autopilot_stage_ = 2;
      return;
    case 2:  // loading with progress, then START by its button
      if (station_.state == StationState::kFailed) return finish(1, "the station failed: " + station_.message);
      if (!start_button_->isEnabled()) return;
      start_button_->click();
      autopilot_stage_ = 3;
      autopilot_elapsed_ = std::min(autopilot_elapsed_, options_.autopilot_timeout);
      return;
    case 3:  // the live session: a screenshot once the view shows frames
      if (scenario_.state == ScenarioState::kRunning && stereo_view_->hasFrame() && scenario_.elapsed > 2.0) {
        shot("session");
        autopilot_stage_ = 4;
      }
      [[fallthrough]];
    case 4:  // the result screen, once the session's result is stored
      if (screen() == kResult && last_stored_session_ > 0) {
        shot("result");
        showScreen(kHistory);
        autopilot_stage_ = 5;
      }
      return;
    case 5:
      shot("history");
      if (user_->role == records::Role::kInstructor) showScreen(kInstructor);
      autopilot_stage_ = 6;
      return;
    case 6:
      if (screen() == kInstructor) shot("instructor");
      autopilot_stage_ = 7;
      return;
    case 7:
      // Wait for the station to stop the graph (the bag is closed then).
      if (station_.state == StationState::kEnded || station_.state == StationState::kFailed ||
          autopilot_elapsed_ > options_.autopilot_timeout + 30)
        return finish(last_stored_session_ > 0 ? 0 : 1,
                      QString("session %1 stored; station %2").arg(last_stored_session_).arg(station_.message));
      return;
    default:
      return;
  }
}

}  // namespace eyesi_gui
