// eyesi_gui: the trainee and instructor console as a ROS node (rosrun eyesi_gui eyesi_gui, or
// roslaunch launch/simulator.launch headless:=false). Private parameters: station (the station node, default
// /station), database (default ~/.ros/eyesi/records.sqlite), import_dir (result files to import at start),
// export_dir, view (side_by_side | anaglyph), course_dir (the courses an instructor assigns; default: the package's
// config/courses). Options (for demos and tests) override them; see --help.
#include <ros/package.h>
#include <ros/ros.h>

#include <QApplication>
#include <QCommandLineParser>
#include <QDir>
#include <QMessageBox>
#include <QTimer>
#include <cstdio>

#include "eyesi_gui/console/main_window.h"
#include "eyesi_gui/records/server.h"
#include "ros_link.h"

namespace {

QString expandHome(QString path) {
  if (path.startsWith("~/")) path = QDir::home().filePath(path.mid(2));
  return path;
}

}  // namespace

int main(int argc, char** argv) {
  ros::init(argc, argv, "console", ros::init_options::NoSigintHandler);
  QApplication app(argc, argv);
  QApplication::setApplicationName("eyesi_gui");
  qRegisterMetaType<eyesi_gui::SceneInfo>();
  qRegisterMetaType<QVector<eyesi_gui::SceneInfo>>();
  qRegisterMetaType<eyesi_gui::StationState>();
  qRegisterMetaType<eyesi_gui::ScenarioState>();

  ros::NodeHandle nh, private_nh("~");
  eyesi_gui::ConsoleOptions options;
  options.database =
      expandHome(QString::fromStdString(private_nh.param<std::string>("database", "~/.ros/eyesi/records.sqlite")));
  options.import_dir = expandHome(QString::fromStdString(private_nh.param<std::string>("import_dir", "")));
  options.export_dir = expandHome(QString::fromStdString(private_nh.param<std::string>("export_dir", "")));
  options.view_mode = QString::fromStdString(private_nh.param<std::string>("view", "side_by_side"));
  // Found at run time (a devel space's source package, an install space's share/eyesi_gui), never compiled in.
  const std::string package = ros::package::getPath("eyesi_gui");
  options.course_dir = expandHome(QString::fromStdString(
      private_nh.param<std::string>("course_dir", package.empty() ? "" : package + "/config/courses")));
  const std::string station = private_nh.param<std::string>("station", "/station");
  // The centre's records server (issue 41), libpq key=value without user and password, e.g. "host=records.centre
  // dbname=records sslmode=verify-full sslrootcert=/etc/eyesi/centre-ca.crt"; "" = a station on its own.
  const std::string centre_server = private_nh.param<std::string>("centre_server", "");
  // This station's login on that server (station_<name>): where people sign in for the centre.
  const std::string centre_station = private_nh.param<std::string>("centre_station", "");

  QCommandLineParser parser;
  parser.setApplicationDescription("EyeSi trainee and instructor console");
  parser.addHelpOption();
  parser.addOptions({
      {"database", "training records (SQLite)", "path"},
      {"autopilot", "log in, load SCENE, press START, wait for the result, visit every screen, quit", "scene"},
      {"user", "autopilot: log in as this user (default guest)", "name"},
      {"pin", "autopilot: the user's PIN", "pin"},
      {"screenshots", "autopilot: save a PNG of every screen into this folder", "dir"},
      {"timeout", "autopilot: give up after this many seconds (exit 1)", "seconds"},
      {"fullscreen", "full screen (the simulator's touch panel)"},
  });
  parser.process(app);
  if (parser.isSet("database")) options.database = parser.value("database");
  options.autopilot_scene = parser.value("autopilot");
  if (parser.isSet("user")) options.autopilot_user = parser.value("user");
  options.autopilot_pin = parser.value("pin");
  options.screenshot_dir = parser.value("screenshots");
  if (parser.isSet("timeout")) options.autopilot_timeout = parser.value("timeout").toDouble();
  if (!options.screenshot_dir.isEmpty()) QDir().mkpath(options.screenshot_dir);

  std::unique_ptr<eyesi_gui::records::Store> store;
  try {
    store = std::make_unique<eyesi_gui::records::Store>(options.database.toStdString());
  } catch (const eyesi_gui::records::StoreError& error) {
    // A damaged store is never modified: say what is wrong and stop, so the records can be rescued.
    const QString text =
        QString("%1\n\nintegrity check:\n%2").arg(error.what(), QString::fromStdString(error.integrityReport()));
    std::fprintf(stderr, "eyesi_gui: %s\n", qPrintable(text));
    if (options.autopilot_scene.isEmpty()) QMessageBox::critical(nullptr, "Training records damaged", text);
    return 1;
  }

  ros::AsyncSpinner spinner(2);
  spinner.start();
  eyesi_gui::RosLink link(nh, station);
  eyesi_gui::MainWindow window(&link, store.get(), options);
  if (!centre_server.empty() && !centre_station.empty()) {
    window.setCentreSignIn([centre_server, centre_station](const QString& user, const QString& password) {
      eyesi_gui::records::signInOnServer(centre_server +
                                             " user=" + eyesi_gui::records::connectionValue(user.toStdString()) +
                                             " password=" + eyesi_gui::records::connectionValue(password.toStdString()),
                                         centre_station);
    });
  }
  if (!centre_server.empty()) {
    // As the instructor themselves, with the password typed on the centre screen (never stored).
    window.setCentreSource(
        [centre_server](const QString& user, const QString& password, const eyesi_gui::records::CentreFilter& filter) {
          return eyesi_gui::records::fetchCentre(
              centre_server + " user=" + eyesi_gui::records::connectionValue(user.toStdString()) +
                  " password=" + eyesi_gui::records::connectionValue(password.toStdString()),
              filter);
        });
  }
  if (parser.isSet("fullscreen")) {
    window.showFullScreen();
  } else {
    window.resize(1280, 800);
    window.show();
  }
  QObject::connect(&window, &eyesi_gui::MainWindow::autopilotFinished, &app, [&app](int code) { app.exit(code); });
  // The ROS graph going down (roslaunch's SIGINT, rosnode kill) closes the window.
  QTimer ros_watch;
  QObject::connect(&ros_watch, &QTimer::timeout, &app, [&app] {
    if (!ros::ok()) app.exit(0);
  });
  ros_watch.start(200);
  const int code = app.exec();
  spinner.stop();
  ros::shutdown();
  return code;
}
