// What the console knows of the simulator, and the only way it talks to it: an abstract link whose ROS
// implementation (RosLink) uses the station's services and the graph's topics, so the console can run on another
// host than the simulator; the widget tests drive the console through a fake link without a ROS master.
#pragma once

#include <QImage>
#include <QObject>
#include <QString>
#include <QStringList>
#include <QVector>

namespace eyesi_gui {

struct InstrumentSlotInfo {
  QString slot;  // "left" / "right"
  QString type;
  QStringList alternatives;
};

struct SceneInfo {
  QString name, description, scenario, scenario_description, default_difficulty;
  QStringList difficulties;
  double time_limit = 0.0;
  QStringList score_items;
  QVector<double> score_weights;
  QVector<InstrumentSlotInfo> instruments;
};

// vrm_msgs/StationStatus
struct StationState {
  enum State { kIdle = 0, kLoading = 1, kReady = 2, kRunning = 3, kEnded = 4, kFailed = 5 };
  int state = kIdle;
  double progress = 0.0;
  QString message, mode, user, scene, difficulty, bag, result_file, station;
  quint32 seed = 0;
  bool recording = false;
};

struct ScoreItemInfo {
  QString name, unit;
  double value = 0.0, weight = 0.0;
};

// vrm_msgs/ScenarioStatus
struct ScenarioState {
  enum State { kIdle = 0, kRunning = 1, kPaused = 2, kFinished = 3, kFailed = 4 };
  QString scenario, difficulty, message;
  int state = kIdle;
  double elapsed = 0.0;
  double total = 0.0;
  QVector<ScoreItemInfo> items;
};

struct SessionRequest {
  QString mode = "session";  // or "replay"
  QString user, scene, difficulty, script, bag;
  quint32 seed = 0;  // 0: the station draws one
  bool record = true;
};

struct MicroscopeSetting {
  double zoom = 1.0, focus_distance = 0.2, ambient_light = 0.5, disparity_scale = 1.0;
};

class SimulatorLink : public QObject {
  Q_OBJECT

 public:
  enum Command { kLoad = 0, kStart = 1, kPause = 2, kResume = 3, kStop = 4, kReset = 5, kSelectInstrument = 6 };
  using QObject::QObject;
  ~SimulatorLink() override = default;

  virtual QString stationName() const = 0;
  // Asynchronous: the answers arrive as signals (a service call never blocks the UI thread).
  virtual void requestScenes() = 0;
  virtual void loadSession(const SessionRequest& request) = 0;
  virtual void endSession() = 0;
  virtual void playGhost(const QString& bag, double rate) = 0;
  virtual void sendCommand(Command command, const QString& argument = QString()) = 0;
  virtual void setMicroscope(const MicroscopeSetting& setting) = 0;

 signals:
  void scenesListed(const QVector<eyesi_gui::SceneInfo>& scenes, const QStringList& errors);
  void sessionLoadAnswered(bool accepted, const QString& message, quint32 seed);
  void stationStatus(const eyesi_gui::StationState& state);
  void scenarioStatus(const eyesi_gui::ScenarioState& state);
  void sessionResult(const QString& json);
  void stereoFrame(const QImage& left, const QImage& right);
  void linkProblem(const QString& message);  // a service that does not answer, a station that is gone
};

}  // namespace eyesi_gui

Q_DECLARE_METATYPE(eyesi_gui::SceneInfo)
Q_DECLARE_METATYPE(eyesi_gui::StationState)
Q_DECLARE_METATYPE(eyesi_gui::ScenarioState)
