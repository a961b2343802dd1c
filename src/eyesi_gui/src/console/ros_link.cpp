#include "ros_link.h"

#include <std_srvs/Trigger.h>

#include <QtConcurrent/QtConcurrent>
#include <boost/make_shared.hpp>

#include "eyesi_gui/console/message_constants.h"
#include "vrm_msgs/InstrumentTypes.h"
#include "vrm_msgs/ListScenes.h"
#include "vrm_msgs/LoadSession.h"
#include "vrm_msgs/MicroscopeSettings.h"
#include "vrm_msgs/PlayGhost.h"
#include "vrm_msgs/ScenarioCommand.h"
#include "vrm_msgs/ScenarioStatus.h"
#include "vrm_msgs/StationStatus.h"

namespace eyesi_gui {
namespace {

// The console's mirror of the message constants (message_constants.h) against the generated headers: a renumbered
// constant stops the build here; test_message_constants catches one added or removed in a .msg file.
constexpr bool sameConstant(const MessageConstant& constant, int value) { return constant.value == value; }
static_assert(sameConstant(kScenarioCommandConstants[0], vrm_msgs::ScenarioCommand::LOAD));
static_assert(sameConstant(kScenarioCommandConstants[1], vrm_msgs::ScenarioCommand::START));
static_assert(sameConstant(kScenarioCommandConstants[2], vrm_msgs::ScenarioCommand::PAUSE));
static_assert(sameConstant(kScenarioCommandConstants[3], vrm_msgs::ScenarioCommand::RESUME));
static_assert(sameConstant(kScenarioCommandConstants[4], vrm_msgs::ScenarioCommand::STOP));
static_assert(sameConstant(kScenarioCommandConstants[5], vrm_msgs::ScenarioCommand::RESET));
static_assert(sameConstant(kScenarioCommandConstants[6], vrm_msgs::ScenarioCommand::SELECT_INSTRUMENT));
static_assert(sameConstant(kStationStatusConstants[0], vrm_msgs::StationStatus::IDLE));
static_assert(sameConstant(kStationStatusConstants[1], vrm_msgs::StationStatus::LOADING));
static_assert(sameConstant(kStationStatusConstants[2], vrm_msgs::StationStatus::READY));
static_assert(sameConstant(kStationStatusConstants[3], vrm_msgs::StationStatus::RUNNING));
static_assert(sameConstant(kStationStatusConstants[4], vrm_msgs::StationStatus::ENDED));
static_assert(sameConstant(kStationStatusConstants[5], vrm_msgs::StationStatus::FAILED));
static_assert(sameConstant(kScenarioStatusConstants[0], vrm_msgs::ScenarioStatus::IDLE));
static_assert(sameConstant(kScenarioStatusConstants[1], vrm_msgs::ScenarioStatus::RUNNING));
static_assert(sameConstant(kScenarioStatusConstants[2], vrm_msgs::ScenarioStatus::PAUSED));
static_assert(sameConstant(kScenarioStatusConstants[3], vrm_msgs::ScenarioStatus::FINISHED));
static_assert(sameConstant(kScenarioStatusConstants[4], vrm_msgs::ScenarioStatus::FAILED));
static_assert(sameConstant(kInstrumentTypeConstants[0], vrm_msgs::InstrumentTypes::LIGHT_PIPE));
static_assert(sameConstant(kInstrumentTypeConstants[1], vrm_msgs::InstrumentTypes::FORCEPS));
static_assert(sameConstant(kInstrumentTypeConstants[2], vrm_msgs::InstrumentTypes::VITRECTOR));
static_assert(sameConstant(kInstrumentTypeConstants[3], vrm_msgs::InstrumentTypes::NEEDLE));
static_assert(sameConstant(kInstrumentTypeConstants[4], vrm_msgs::InstrumentTypes::HOOK));
static_assert(sameConstant(kInstrumentTypeConstants[5], vrm_msgs::InstrumentTypes::LASER_PROBE));

QString q(const std::string& text) { return QString::fromStdString(text); }

QImage toImage(const sensor_msgs::Image& image) {
  const bool rgb = image.encoding == "rgb8", bgr = image.encoding == "bgr8", mono = image.encoding == "mono8";
  if (!(rgb || bgr || mono) || image.width == 0 || image.height == 0 ||
      image.data.size() < static_cast<std::size_t>(image.step) * image.height)
    return QImage();
  const QImage view(image.data.data(), static_cast<int>(image.width), static_cast<int>(image.height),
                    static_cast<int>(image.step), mono ? QImage::Format_Grayscale8 : QImage::Format_RGB888);
  return bgr ? view.rgbSwapped() : view.copy();  // both copy: the message may go away after the callback
}

}  // namespace

RosLink::RosLink(ros::NodeHandle nh, const std::string& station, QObject* parent)
    : SimulatorLink(parent), nh_(nh), station_(station) {
  station_subscriber_ = nh_.subscribe(station_ + "/station_status", 5, &RosLink::onStationStatus, this);
  status_subscriber_ = nh_.subscribe("scenario_status", 10, &RosLink::onScenarioStatus, this);
  result_subscriber_ = nh_.subscribe("session_result", 2, &RosLink::onSessionResult, this);
  state_subscriber_ = nh_.subscribe("simulation_state", 1, &RosLink::onSimulationState, this);
  left_subscriber_ = nh_.subscribe<sensor_msgs::Image>(
      "stereo/left/image_raw", 1, [this](const sensor_msgs::Image::ConstPtr& image) { onImage(0, image); });
  right_subscriber_ = nh_.subscribe<sensor_msgs::Image>(
      "stereo/right/image_raw", 1, [this](const sensor_msgs::Image::ConstPtr& image) { onImage(1, image); });
  command_publisher_ = nh_.advertise<vrm_msgs::ScenarioCommand>("scenario_command", 10);
  microscope_publisher_ = nh_.advertise<vrm_msgs::MicroscopeSettings>("microscope_setpoint", 2);
}

RosLink::~RosLink() { calls_.waitForFinished(); }

QString RosLink::stationName() const { return q(station_); }

template <typename Service>
bool RosLink::call(const std::string& name, Service& service) {
  const std::string full = station_ + "/" + name;
  if (!ros::service::waitForService(full, ros::Duration(3.0))) {
    emit linkProblem(QString("the station does not answer (%1): is the simulator running?").arg(q(full)));
    return false;
  }
  if (!ros::service::call(full, service)) {
    emit linkProblem(QString("the call of %1 failed").arg(q(full)));
    return false;
  }
  return true;
}

void RosLink::requestScenes() {
  calls_.addFuture(QtConcurrent::run([this] {
    vrm_msgs::ListScenes service;
    if (!call("list_scenes", service)) return;
    QVector<SceneInfo> scenes;
    for (const auto& entry : service.response.scenes) {
      SceneInfo scene;
      scene.name = q(entry.name);
      scene.description = q(entry.description);
      scene.scenario = q(entry.scenario);
      scene.scenario_description = q(entry.scenario_description);
      scene.default_difficulty = q(entry.default_difficulty);
      for (const auto& level : entry.difficulties) scene.difficulties << q(level);
      scene.time_limit = entry.time_limit;
      for (const auto& item : entry.score_items) scene.score_items << q(item);
      for (double weight : entry.score_weights) scene.score_weights << weight;
      for (const auto& slot : entry.instruments) {
        InstrumentSlotInfo info{q(slot.slot), q(slot.type), {}};
        for (const auto& alternative : slot.alternatives) info.alternatives << q(alternative);
        scene.instruments << info;
      }
      scenes << scene;
    }
    QStringList errors;
    for (const auto& error : service.response.errors) errors << q(error);
    emit scenesListed(scenes, errors);
  }));
}

void RosLink::loadSession(const SessionRequest& request) {
  calls_.addFuture(QtConcurrent::run([this, request] {
    vrm_msgs::LoadSession service;
    service.request.mode = request.mode.toStdString();
    service.request.user = request.user.toStdString();
    service.request.scene = request.scene.toStdString();
    service.request.difficulty = request.difficulty.toStdString();
    service.request.seed = request.seed;
    service.request.record = request.record;
    service.request.script = request.script.toStdString();
    service.request.bag = request.bag.toStdString();
    {
      std::lock_guard<std::mutex> lock(mutex_);
      newest_input_ = ros::Time();  // a new session: its commands are stamped from its scene's frames
    }
    if (!call("load_session", service)) {
      emit sessionLoadAnswered(false, "the station did not answer", 0);
      return;
    }
    emit sessionLoadAnswered(service.response.accepted, q(service.response.message), service.response.seed);
  }));
}

void RosLink::endSession() {
  calls_.addFuture(QtConcurrent::run([this] {
    std_srvs::Trigger service;
    call("end_session", service);
  }));
}

void RosLink::playGhost(const QString& bag, double rate) {
  calls_.addFuture(QtConcurrent::run([this, bag, rate] {
    vrm_msgs::PlayGhost service;
    service.request.bag = bag.toStdString();
    service.request.rate = rate;
    if (call("play_ghost", service) && !service.response.accepted) emit linkProblem(q(service.response.message));
  }));
}

void RosLink::sendCommand(Command command, const QString& argument) {
  auto message = boost::make_shared<vrm_msgs::ScenarioCommand>();
  {
    std::lock_guard<std::mutex> lock(mutex_);
    // Stamped ahead of the newest simulated frame (like session_control), so the command applies to the same frame
    // live and in every replay of the recorded session.
    const ros::Time base = newest_input_.isZero() ? ros::Time::now() : newest_input_;
    message->header.stamp = base + ros::Duration(command == kStart ? 0.5 : 0.2);
  }
  message->command = static_cast<std::uint8_t>(command);
  message->argument = argument.toStdString();
  command_publisher_.publish(message);
}

void RosLink::setMicroscope(const MicroscopeSetting& setting) {
  auto message = boost::make_shared<vrm_msgs::MicroscopeSettings>();
  message->header.stamp = ros::Time::now();  // a setpoint of the console, not a session input (the knob twin is)
  message->zoom = setting.zoom;
  message->focus_distance = setting.focus_distance;
  message->ambient_light = setting.ambient_light;
  message->disparity_scale = setting.disparity_scale;
  microscope_publisher_.publish(message);
}

void RosLink::onStationStatus(const vrm_msgs::StationStatus::ConstPtr& status) {
  StationState state;
  state.state = status->state;
  state.progress = status->progress;
  state.message = q(status->message);
  state.mode = q(status->mode);
  state.user = q(status->user);
  state.scene = q(status->scene);
  state.difficulty = q(status->difficulty);
  state.bag = q(status->bag);
  state.result_file = q(status->result_file);
  state.station = q(status->station);
  state.seed = status->seed;
  state.recording = status->recording;
  emit stationStatus(state);
}

void RosLink::onScenarioStatus(const vrm_msgs::ScenarioStatus::ConstPtr& status) {
  ScenarioState state;
  state.scenario = q(status->scenario);
  state.difficulty = q(status->difficulty);
  state.message = q(status->message);
  state.state = status->state;
  state.elapsed = status->elapsed;
  state.total = status->score.total;
  for (const auto& item : status->score.items)
    state.items << ScoreItemInfo{q(item.name), q(item.unit), item.value, item.weight};
  emit scenarioStatus(state);
}

void RosLink::onSessionResult(const vrm_msgs::SessionResult::ConstPtr& result) { emit sessionResult(q(result->json)); }

void RosLink::onSimulationState(const vrm_msgs::SimulationState::ConstPtr& state) {
  std::lock_guard<std::mutex> lock(mutex_);
  newest_input_ = std::max(newest_input_, state->header.stamp);
}

void RosLink::onImage(int eye, const sensor_msgs::Image::ConstPtr& image) {
  QImage converted = toImage(*image);
  if (converted.isNull()) return;
  QImage left, right;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    latest_[eye] = converted;
    latest_stamp_[eye] = image->header.stamp;
    // A stereo pair is complete when both eyes carry the same stamp (the renderer publishes them together).
    if (latest_stamp_[0] != latest_stamp_[1]) return;
    left = latest_[0];
    right = latest_[1];
  }
  emit stereoFrame(left, right);
}

}  // namespace eyesi_gui
