// input_relay: a test relay between the devices and the simulation node (issue 31). It forwards eye_state,
// instrument_state, pedals and scenario_command to <prefix><topic> (default perturbed/...), which the scenario_manager
// subscribes instead when simulator.launch runs it with input_relay:=true; the recorder keeps recording the devices'
// own topics. Perturbations, each chosen by parameter, make the simulation node see its inputs in another order than
// the recorder, in every run and not only when the machine happens to be loaded:
//   ~delay_source, ~delay_ticks (3)   each message of that source is held until delay_ticks later messages of the
//                                     same source arrived (the last delay_ticks messages are never forwarded)
//   ~silence_source, ~silence_start (s of input time), ~silence_seconds (1.0), ~silence_clock
//                                     that source's messages stamped within the window are dropped; the window
//                                     starts silence_start s after the first input's stamp (silence_clock
//                                     first_input, the default) or after the first START command's (start: inside
//                                     the scenario whatever the graph's start-up took)
// A source is "eye", "instrument:<slot>" (e.g. instrument:right), "pedals" or "command"; "" = none. Input time is the
// messages' header stamps, so the perturbation is the same whatever the load.
//   <node pkg="vrm_graph" type="input_relay" name="input_relay"><param name="delay_source" value="eye"/></node>
#include <ros/ros.h>
#include <vrm_msgs/EyeState.h>
#include <vrm_msgs/InstrumentState.h>
#include <vrm_msgs/PedalState.h>
#include <vrm_msgs/ScenarioCommand.h>

#include <algorithm>
#include <cstdint>
#include <deque>
#include <functional>
#include <optional>
#include <stdexcept>
#include <string>

#include "vrm_scene/cli/cli.h"

namespace {

class InputRelay {
 public:
  InputRelay(const ros::NodeHandle& nh, const ros::NodeHandle& pnh) : nh_(nh) {
    const std::string prefix = pnh.param<std::string>("prefix", "perturbed/");
    delay_source_ = pnh.param<std::string>("delay_source", "");
    delay_ticks_ = std::max(0, pnh.param("delay_ticks", 3));
    silence_source_ = pnh.param<std::string>("silence_source", "");
    silence_start_ = pnh.param("silence_start", 5.0);
    silence_seconds_ = pnh.param("silence_seconds", 1.0);
    const std::string clock = pnh.param<std::string>("silence_clock", "first_input");
    if (clock != "first_input" && clock != "start") {
      throw std::invalid_argument("input_relay: ~silence_clock must be first_input or start, got '" + clock + "'");
    }
    silence_from_start_ = clock == "start";

    // Forwarded over TCP without Nagle's delay: the relay must not add its own reordering.
    eye_pub_ = nh_.advertise<vrm_msgs::EyeState>(prefix + "eye_state", 100);
    instrument_pub_ = nh_.advertise<vrm_msgs::InstrumentState>(prefix + "instrument_state", 200);
    pedal_pub_ = nh_.advertise<vrm_msgs::PedalState>(prefix + "pedals", 100);
    command_pub_ = nh_.advertise<vrm_msgs::ScenarioCommand>(prefix + "scenario_command", 50, /*latch=*/false);
    // Inputs are taken only once the simulation node listens to every forwarded topic, so nothing it should see
    // (session_control's START above all) is forwarded into a connection that is not up yet.
    wait_timer_ = nh_.createWallTimer(ros::WallDuration(0.02), [this](const ros::WallTimerEvent&) {
      if (!eye_sub_ && eye_pub_.getNumSubscribers() > 0 && instrument_pub_.getNumSubscribers() > 0 &&
          pedal_pub_.getNumSubscribers() > 0 && command_pub_.getNumSubscribers() > 0) {
        subscribe();
        wait_timer_.stop();
      }
    });
    ROS_INFO(
        "input_relay: -> %s*; delay: %s by %d messages; silence: %s for %.2f s from %.2f s of input time after "
        "the %s",
        prefix.c_str(), delay_source_.empty() ? "none" : delay_source_.c_str(), delay_ticks_,
        silence_source_.empty() ? "none" : silence_source_.c_str(), silence_seconds_, silence_start_,
        silence_from_start_ ? "first START" : "first input");
  }

  ~InputRelay() {
    ROS_INFO("input_relay: %lu messages forwarded, %lu dropped (silence), %lu held at the end (delay)",
             static_cast<unsigned long>(forwarded_), static_cast<unsigned long>(dropped_),
             static_cast<unsigned long>(held_.size()));
  }

 private:
  void subscribe() {
    // Over TCP without Nagle's delay: the relay must not add reordering of its own.
    const ros::TransportHints hints = ros::TransportHints().tcpNoDelay();
    eye_sub_ = nh_.subscribe<vrm_msgs::EyeState>(
        "eye_state", 100,
        [this](const vrm_msgs::EyeState::ConstPtr& msg) {
          relay("eye", msg->header.stamp, [this, msg] { eye_pub_.publish(msg); });
        },
        ros::VoidConstPtr(), hints);
    instrument_sub_ = nh_.subscribe<vrm_msgs::InstrumentState>(
        "instrument_state", 200,
        [this](const vrm_msgs::InstrumentState::ConstPtr& msg) {
          relay("instrument:" + msg->instrument_id, msg->header.stamp, [this, msg] { instrument_pub_.publish(msg); });
        },
        ros::VoidConstPtr(), hints);
    pedal_sub_ = nh_.subscribe<vrm_msgs::PedalState>(
        "pedals", 100,
        [this](const vrm_msgs::PedalState::ConstPtr& msg) {
          relay("pedals", msg->header.stamp, [this, msg] { pedal_pub_.publish(msg); });
        },
        ros::VoidConstPtr(), hints);
    command_sub_ = nh_.subscribe<vrm_msgs::ScenarioCommand>(
        "scenario_command", 50,
        [this](const vrm_msgs::ScenarioCommand::ConstPtr& msg) {
          if (msg->command == vrm_msgs::ScenarioCommand::START && !start_stamp_) start_stamp_ = msg->header.stamp;
          relay("command", msg->header.stamp, [this, msg] { command_pub_.publish(msg); });
        },
        ros::VoidConstPtr(), hints);
    ROS_INFO("input_relay: the simulation node listens; relaying");
  }

  void relay(const std::string& source, const ros::Time& stamp, std::function<void()> publish) {
    if (!stamp.isZero() && (!first_stamp_ || stamp < *first_stamp_)) first_stamp_ = stamp;
    const std::optional<ros::Time>& origin = silence_from_start_ ? start_stamp_ : first_stamp_;
    if (source == silence_source_ && origin && !stamp.isZero()) {
      const double t = (stamp - *origin).toSec();
      if (t >= silence_start_ && t < silence_start_ + silence_seconds_) {
        if (dropped_++ == 0) ROS_INFO("input_relay: %s silent from %.3f s of input time", source.c_str(), t);
        return;
      }
    }
    if (source == delay_source_ && delay_ticks_ > 0) {
      held_.push_back(std::move(publish));
      if (static_cast<int>(held_.size()) <= delay_ticks_) return;
      publish = std::move(held_.front());
      held_.pop_front();
    }
    publish();
    ++forwarded_;
  }

  ros::NodeHandle nh_;
  std::string delay_source_, silence_source_;
  int delay_ticks_ = 3;
  double silence_start_ = 5.0, silence_seconds_ = 1.0;
  bool silence_from_start_ = false;
  std::optional<ros::Time> first_stamp_, start_stamp_;
  std::deque<std::function<void()>> held_;
  std::uint64_t forwarded_ = 0, dropped_ = 0;
  ros::Publisher eye_pub_, instrument_pub_, pedal_pub_, command_pub_;
  ros::Subscriber eye_sub_, instrument_sub_, pedal_sub_, command_sub_;
  ros::WallTimer wait_timer_;
};

}  // namespace

int main(int argc, char** argv) {
  ros::init(argc, argv, "input_relay");  // takes the remappings (name:=value) out of argv
  vrm_sim::cli::CommandLine cli(
      "input_relay", "[NAME:=VALUE ...]",
      "A test relay between the devices and the simulation node that delays or silences one input source.",
      "Private parameters: ~delay_source, ~delay_ticks (3), ~silence_source, ~silence_start (s), ~silence_seconds "
      "(1.0),\n~silence_clock (first_input | start). A source: eye, instrument:<slot>, pedals, command; \"\" = none.");
  if (const auto status = cli.parse(argc, argv)) return *status;
  ros::NodeHandle nh, pnh("~");
  InputRelay relay(nh, pnh);
  ros::spin();
  return 0;
}
