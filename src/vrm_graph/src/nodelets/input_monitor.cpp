// Input monitor (issue 20): tells the user what the simulator is waiting for. The VR part steps only on input stamps,
// so a graph started without devices (sim:=false, nothing connected) would otherwise wait silently. Per expected
// input it reports "no publisher", "silent" (no message for silence_timeout s) or "slow" (below min_rate_fraction of
// the expected rate) as a throttled console warning and as a /diagnostics status (thin wrapper around
// world::InputMonitor; wall clock, since device liveness is a wall-clock matter and nothing here feeds the
// simulation).
//
// Subscribes: each ~inputs[i].topic with its message type (in the same manager: no copy, no serialisation). The
//   messages wait in the monitor's own callback queue and are counted every ~drain_period s (wall), not one by one:
//   a worker thread woken per message would cost the view two context switches for each input of a 1.5 kHz flood,
//   and liveness needs no finer arrival time than silence_timeout and rate_window resolve.
// Publishes: /diagnostics (diagnostic_msgs/DiagnosticArray), one status "input_monitor: <topic>" per input every
//   ~period s (wall; the first 1 s after start).
// Parameters (private): inputs (list of {topic, type, rate, hint}; config/input_monitor.yaml), period (1.0),
//   silence_timeout (1.0), rate_window (2.0), min_rate_fraction (0.5), startup_grace (2.0), warn_period (10.0: the
//   console repeats a warning at most this often), drain_period (0.1), queue_size (200 per input: the most one
//   drain period holds; more is dropped and still reads as a high rate).
#include "vrm_sim/world/input_monitor.h"

#include <diagnostic_msgs/DiagnosticArray.h>
#include <nodelet/nodelet.h>
#include <ros/callback_queue.h>
#include <ros/ros.h>
#include <xmlrpcpp/XmlRpcException.h>

#include <boost/make_shared.hpp>
#include <mutex>
#include <optional>
#include <pluginlib/class_list_macros.hpp>
#include <string>
#include <vector>

#include "vrm_msgs/EyeState.h"
#include "vrm_msgs/InstrumentState.h"
#include "vrm_msgs/MicroscopeSettings.h"
#include "vrm_msgs/PedalState.h"
#include "vrm_msgs/ScenarioCommand.h"
#include "vrm_msgs/publish.h"

namespace vrm_graph {

// The monitor's ROS-free core and its unit test stay in vrm_sim (world/input_monitor.h, library vrm_monitoring).
namespace world = vrm_sim::world;

class InputMonitorNodelet : public nodelet::Nodelet {
 public:
  void onInit() override {
    ros::NodeHandle& nh = getNodeHandle();
    ros::NodeHandle& pnh = getPrivateNodeHandle();
    std::vector<world::ExpectedInput> inputs;
    std::vector<std::string> types;
    XmlRpc::XmlRpcValue list;
    if (pnh.getParam("inputs", list)) {
      try {
        for (int i = 0; i < list.size(); ++i) {
          XmlRpc::XmlRpcValue& entry = list[i];
          world::ExpectedInput input;
          input.topic = static_cast<std::string>(entry["topic"]);
          input.expected_rate_hz = entry.hasMember("rate") ? toDouble(entry["rate"]) : 0.0;
          if (entry.hasMember("hint")) input.hint = static_cast<std::string>(entry["hint"]);
          types.push_back(static_cast<std::string>(entry["type"]));
          inputs.push_back(input);
        }
      } catch (const XmlRpc::XmlRpcException& error) {
        NODELET_ERROR("input_monitor: ~inputs must be a list of {topic, type, rate, hint}: %s",
                      error.getMessage().c_str());
        return;
      }
    } else {
      NODELET_WARN("input_monitor: no ~inputs parameter (config/input_monitor.yaml); nothing to monitor");
      return;
    }
    world::InputMonitorOptions options;
    pnh.param("silence_timeout", options.silence_timeout_s, options.silence_timeout_s);
    pnh.param("rate_window", options.rate_window_s, options.rate_window_s);
    pnh.param("min_rate_fraction", options.min_rate_fraction, options.min_rate_fraction);
    pnh.param("startup_grace", options.startup_grace_s, options.startup_grace_s);
    pnh.param("warn_period", warn_period_, warn_period_);
    const double period = pnh.param("period", 1.0);
    const double drain_period = pnh.param("drain_period", 0.1);
    queue_size_ = pnh.param("queue_size", queue_size_);
    if (!(drain_period > 0.0 && drain_period <= options.silence_timeout_s) || queue_size_ < 1) {
      NODELET_ERROR("input_monitor: ~drain_period must be in (0, silence_timeout] and ~queue_size >= 1");
      return;
    }
    try {
      monitor_.emplace(inputs, options, ros::WallTime::now().toSec());
    } catch (const std::invalid_argument& error) {
      NODELET_ERROR("input_monitor: %s", error.what());
      return;
    }
    for (std::size_t i = 0; i < inputs.size(); ++i) {
      const std::string& type = types[i];
      const std::string& topic = inputs[i].topic;
      if (type == "vrm_msgs/EyeState") {
        subscribers_.push_back(subscribe<vrm_msgs::EyeState>(nh, topic, i));
      } else if (type == "vrm_msgs/InstrumentState") {
        subscribers_.push_back(subscribe<vrm_msgs::InstrumentState>(nh, topic, i));
      } else if (type == "vrm_msgs/PedalState") {
        subscribers_.push_back(subscribe<vrm_msgs::PedalState>(nh, topic, i));
      } else if (type == "vrm_msgs/MicroscopeSettings") {
        subscribers_.push_back(subscribe<vrm_msgs::MicroscopeSettings>(nh, topic, i));
      } else if (type == "vrm_msgs/ScenarioCommand") {
        subscribers_.push_back(subscribe<vrm_msgs::ScenarioCommand>(nh, topic, i));
      } else {
        NODELET_ERROR(
            "input_monitor: %s: unsupported type '%s' (EyeState, InstrumentState, PedalState, "
            "MicroscopeSettings, ScenarioCommand)",
            topic.c_str(), type.c_str());
        subscribers_.emplace_back();
      }
    }
    last_warned_.assign(inputs.size(), -1e9);
    last_health_.assign(inputs.size(), world::InputHealth::kStarting);
    diagnostics_publisher_ = nh.advertise<diagnostic_msgs::DiagnosticArray>("/diagnostics", 10);
    // The first report after 1 s: a user who started the graph without devices is told within seconds.
    first_timer_ = nh.createWallTimer(ros::WallDuration(1.0), &InputMonitorNodelet::onTick, this, /*oneshot=*/true);
    timer_ = nh.createWallTimer(ros::WallDuration(period), &InputMonitorNodelet::onTick, this);
    drain_timer_ = nh.createWallTimer(ros::WallDuration(drain_period), [this](const ros::WallTimerEvent&) { drain(); });
    NODELET_INFO("input_monitor: watching %zu inputs", inputs.size());
  }

 private:
  static double toDouble(XmlRpc::XmlRpcValue& value) {
    if (value.getType() == XmlRpc::XmlRpcValue::TypeInt) return static_cast<int>(value);
    return static_cast<double>(value);
  }

  template <typename Message>
  ros::Subscriber subscribe(ros::NodeHandle& nh, const std::string& topic, std::size_t index) {
    ros::SubscribeOptions options;
    options.template init<Message>(topic, static_cast<std::uint32_t>(queue_size_),
                                   [this, index](const typename Message::ConstPtr&) {
                                     monitor_->onMessage(index, drained_at_);  // under mutex_, from drain()
                                   });
    options.callback_queue = &arrivals_;
    return nh.subscribe(options);
  }

  // Counts what arrived since the last drain, as arrived now.
  void drain() {
    std::lock_guard<std::mutex> lock(mutex_);
    drained_at_ = ros::WallTime::now().toSec();
    arrivals_.callAvailable();
  }

  void onTick(const ros::WallTimerEvent&) {
    drain();
    std::lock_guard<std::mutex> lock(mutex_);
    const double now = ros::WallTime::now().toSec();
    std::vector<int> publishers;
    for (const ros::Subscriber& subscriber : subscribers_) {
      publishers.push_back(subscriber ? static_cast<int>(subscriber.getNumPublishers()) : 0);
    }
    const std::vector<world::InputReport> reports = monitor_->evaluate(now, publishers);
    auto array = boost::make_shared<diagnostic_msgs::DiagnosticArray>();
    array->header.stamp = ros::Time::now();  // diagnostics only, never an input of the pipeline
    for (std::size_t i = 0; i < reports.size(); ++i) {
      const world::InputReport& report = reports[i];
      diagnostic_msgs::DiagnosticStatus status;
      status.name = "input_monitor: " + report.topic;
      status.hardware_id = report.topic;
      status.message = report.message;
      const bool problem = report.health == world::InputHealth::kNoPublisher ||
                           report.health == world::InputHealth::kSilent || report.health == world::InputHealth::kSlow;
      status.level = problem ? diagnostic_msgs::DiagnosticStatus::WARN : diagnostic_msgs::DiagnosticStatus::OK;
      status.values.resize(4);
      status.values[0].key = "health";
      status.values[0].value = world::toString(report.health);
      status.values[1].key = "publishers";
      status.values[1].value = std::to_string(report.publishers);
      status.values[2].key = "rate_hz";
      status.values[2].value = std::to_string(report.rate_hz);
      status.values[3].key = "received";
      status.values[3].value = std::to_string(report.received);
      array->status.push_back(status);

      // The console: a warning when an input turns bad (and every warn_period while it stays bad), one line when
      // it recovers.
      if (problem && (report.health != last_health_[i] || now - last_warned_[i] >= warn_period_)) {
        NODELET_WARN("%s", report.message.c_str());
        last_warned_[i] = now;
      } else if (!problem && report.health == world::InputHealth::kOk && last_health_[i] != world::InputHealth::kOk &&
                 last_health_[i] != world::InputHealth::kStarting) {
        NODELET_INFO("%s (recovered)", report.message.c_str());
      }
      last_health_[i] = report.health;
    }
    vrm_msgs::publishShared(diagnostics_publisher_, array);
  }

  std::mutex mutex_;
  ros::CallbackQueue arrivals_;  // filled by roscpp's receiving threads, emptied by drain()
  double drained_at_ = 0.0;
  int queue_size_ = 200;
  std::optional<world::InputMonitor> monitor_;
  std::vector<ros::Subscriber> subscribers_;
  std::vector<double> last_warned_;
  std::vector<world::InputHealth> last_health_;
  double warn_period_ = 10.0;
  ros::Publisher diagnostics_publisher_;
  ros::WallTimer first_timer_, timer_, drain_timer_;
};

}  // namespace vrm_graph

PLUGINLIB_EXPORT_CLASS(vrm_graph::InputMonitorNodelet, nodelet::Nodelet)
