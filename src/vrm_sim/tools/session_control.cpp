// session_control: frames a recorded session so that its bag holds all of it (thesis §2.4.2). The recorder and the
// simulation start independently, so either may see inputs the other missed; the world therefore waits (auto_start
// off) and this node sends ScenarioCommand START once the recorder subscribes to every recorded topic, stamped a
// little after the newest simulated frame, and STOP once the session has run `duration` s of input time (unless its
// scenario ended before). Both commands are recorded inputs with stamps ahead of the frames they apply to, so the
// live session and every replay apply them to the same frames and end in the same state. After a short tail it
// exits, which ends the launch (required) and lets the recorder close the bag.
// Parameters (private): recorder (node name, default /session_recorder), topics (list the recorder must subscribe
// to), duration (s of input time; 0 = until Ctrl-C), start (default true; false: a console sends START),
// start_delay (s of input time between the newest frame and START, default 0.5), tail (s of input time recorded
// after STOP, default 1.0).
#include <ros/master.h>
#include <ros/ros.h>

#include <boost/make_shared.hpp>
#include <cstdio>
#include <string>
#include <vector>

#include "vrm_msgs/ScenarioCommand.h"
#include "vrm_msgs/ScenarioStatus.h"
#include "vrm_msgs/SimulationState.h"

namespace {

// Subscribers of each topic according to the master.
std::map<std::string, std::vector<std::string>> subscribersByTopic() {
  std::map<std::string, std::vector<std::string>> result;
  XmlRpc::XmlRpcValue request, response, payload;
  request[0] = ros::this_node::getName();
  if (!ros::master::execute("getSystemState", request, response, payload, false)) return result;
  const XmlRpc::XmlRpcValue& subscriptions = payload[1];
  for (int i = 0; i < subscriptions.size(); ++i) {
    std::vector<std::string>& nodes = result[static_cast<std::string>(subscriptions[i][0])];
    for (int j = 0; j < subscriptions[i][1].size(); ++j)
      nodes.push_back(static_cast<std::string>(subscriptions[i][1][j]));
  }
  return result;
}

class SessionControl {
 public:
  SessionControl() : private_nh_("~") {
    recorder_ = private_nh_.param<std::string>("recorder", "/session_recorder");
    private_nh_.getParam("topics", topics_);
    duration_ = private_nh_.param("duration", 0.0);
    send_start_ = private_nh_.param("start", true);
    start_delay_ = ros::Duration(private_nh_.param("start_delay", 0.5));
    tail_ = ros::Duration(private_nh_.param("tail", 1.0));
    command_publisher_ = nh_.advertise<vrm_msgs::ScenarioCommand>("scenario_command", 5);
    state_subscriber_ = nh_.subscribe("simulation_state", 50, &SessionControl::onFrame, this);
    status_subscriber_ = nh_.subscribe("scenario_status", 5, &SessionControl::onStatus, this);
    timer_ = nh_.createWallTimer(ros::WallDuration(0.1), &SessionControl::onTimer, this);
  }

 private:
  void onFrame(const vrm_msgs::SimulationState::ConstPtr& state) {
    newest_ = std::max(newest_, state->header.stamp);
    if (!started_ || duration_ <= 0.0) return;
    const ros::Time end = start_ + ros::Duration(duration_);
    // STOP goes out ahead of the frame it applies to (like START), so its arrival never races that frame.
    if (!stop_sent_ && newest_ + start_delay_ >= end) {
      stop_sent_ = true;
      if (scenario_ended_) {
        ROS_INFO("session_control: the scenario ended before the %.1f s of the session; no STOP", duration_);
      } else {
        char reason[64];
        std::snprintf(reason, sizeof(reason), "recording ended after %.1f s", duration_);
        send(vrm_msgs::ScenarioCommand::STOP, end, reason);
      }
    }
    if (newest_ >= end + tail_) {
      ROS_INFO("session_control: session over (%.1f s from START); ending the recording", duration_);
      ros::shutdown();
    }
  }

  void onStatus(const vrm_msgs::ScenarioStatus::ConstPtr& status) {
    scenario_ended_ =
        status->state == vrm_msgs::ScenarioStatus::FINISHED || status->state == vrm_msgs::ScenarioStatus::FAILED;
  }

  void onTimer(const ros::WallTimerEvent&) {
    if (started_) return;
    const auto subscribers = subscribersByTopic();
    std::string missing;
    for (const std::string& topic : topics_) {
      const auto nodes = subscribers.find(topic);
      if (nodes == subscribers.end() ||
          std::find(nodes->second.begin(), nodes->second.end(), recorder_) == nodes->second.end()) {
        missing += " " + topic;
      }
    }
    // Every subscriber the master knows of /scenario_command (recorder, simulation) must be connected to us.
    const auto command_subscribers = subscribers.find(command_publisher_.getTopic());
    const std::size_t expected = command_subscribers == subscribers.end() ? 0 : command_subscribers->second.size();
    const bool connected = expected >= 2 && command_publisher_.getNumSubscribers() >= expected;
    if (!missing.empty() || !connected || newest_.isZero()) {
      if ((ros::WallTime::now() - last_note_).toSec() > 5.0) {
        last_note_ = ros::WallTime::now();
        ROS_INFO("session_control: waiting for %s%s%s",
                 missing.empty() ? "" : (recorder_ + " to subscribe to" + missing + "; ").c_str(),
                 connected ? "" : "the scenario_command subscribers; ",
                 newest_.isZero() ? "the first simulated frame" : "");
      }
      return;
    }
    started_ = true;
    start_ = newest_ + start_delay_;
    if (send_start_) {
      send(vrm_msgs::ScenarioCommand::START, start_, "");
    } else {
      ROS_INFO("session_control: recording; the session starts with the console's START");
    }
  }

  void send(std::uint8_t command, const ros::Time& stamp, const std::string& argument) {
    auto message = boost::make_shared<vrm_msgs::ScenarioCommand>();
    message->header.stamp = stamp;
    message->command = command;
    message->argument = argument;
    command_publisher_.publish(message);
    ROS_INFO("session_control: %s at input time %.3f%s%s",
             command == vrm_msgs::ScenarioCommand::START ? "START" : "STOP", stamp.toSec(),
             argument.empty() ? "" : ": ", argument.c_str());
  }

  ros::NodeHandle nh_, private_nh_;
  std::string recorder_;
  std::vector<std::string> topics_;
  double duration_ = 0.0;
  bool send_start_ = true;
  ros::Duration start_delay_, tail_;
  ros::Publisher command_publisher_;
  ros::Subscriber state_subscriber_, status_subscriber_;
  ros::WallTimer timer_;
  ros::WallTime last_note_;
  ros::Time newest_, start_;
  bool started_ = false, stop_sent_ = false, scenario_ended_ = false;
};

}  // namespace

int main(int argc, char** argv) {
  ros::init(argc, argv, "session_control");
  SessionControl control;
  ros::spin();
  return 0;
}
