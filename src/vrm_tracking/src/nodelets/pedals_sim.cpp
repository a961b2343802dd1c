// Foot pedal twin (thesis §7): plays the script's pedal track; a PedalState on pedals_sim/command (keyboard teleop,
// GUI) takes over, the way the mediator swaps a real device for another input (§2.4.1). With script:=scenario:NAME the
// track is derived from the scene's scripted session (device_script.h, scenario_devices.h; issue 33): the travel
// follows the working instrument's suction and no zoom/focus button is pressed, so the knob twin keeps its focus.
// With ~start_with_session (default true) a ScenarioCommand START restarts the track at the START's stamp, like the
// scripted surgeon, and the track is read on its own period's grid from there (the last whole period before the
// tick): the pedal timer's phase against the surgeon's ticks differs from run to run, and the frame the mediator
// closes at a surgeon tick takes the newest pedal state before it — so every run, idle or loaded, applies the same
// pedal values in the same frames (issue 31).

#include <nodelet/nodelet.h>
#include <ros/ros.h>
#include <vrm_msgs/PedalState.h>
#include <vrm_msgs/RunningScene.h>
#include <vrm_msgs/ScenarioCommand.h>
#include <vrm_msgs/publish.h>

#include <boost/make_shared.hpp>
#include <cmath>
#include <memory>
#include <mutex>
#include <pluginlib/class_list_macros.hpp>
#include <string>

#include "device_script.h"
#include "vrm_tracking/conversions.h"
#include "vrm_tracking/resume_gate.h"
#include "vrm_tracking/scene_trocars.h"
#include "vrm_tracking/surgeon_script.h"

namespace vrm_tracking {

class PedalsSim : public nodelet::Nodelet {
 private:
  void onInit() override {
    ros::NodeHandle& nh = getNodeHandle();
    ros::NodeHandle& pnh = getPrivateNodeHandle();

    try {
      script_ = std::make_unique<SurgeonScript>(loadDeviceScript(pnh));
      follower_ = std::make_unique<ScenarioSceneFollower>(pnh.param<std::string>("script", ""),
                                                          pnh.param<std::string>("scene", ""));
    } catch (const std::exception& e) {
      NODELET_FATAL("cannot load surgeon script: %s", e.what());
      throw;
    }

    double rate = 100.0;
    pnh.param("rate", rate, rate);
    // 0: a command holds until the next one (a foot stays where it was put); > 0: the script resumes after this
    // many seconds without a command, for teleops that repeat while a key is held.
    pnh.param("override_timeout", override_timeout_, 0.0);
    if (!(rate > 0.0) || !(override_timeout_ >= 0.0)) {
      NODELET_FATAL("need rate > 0 and override_timeout >= 0 (got %g, %g)", rate, override_timeout_);
      throw std::invalid_argument("pedals_sim: bad parameters");
    }

    pub_ = nh.advertise<vrm_msgs::PedalState>("pedals", 10);
    command_sub_ = nh.subscribe("pedals_sim/command", 10, &PedalsSim::onCommand, this);
    period_ = 1.0 / rate;
    if (pnh.param("start_with_session", true)) {
      session_sub_ = nh.subscribe("scenario_command", 10, &PedalsSim::onSessionCommand, this);
    }
    resume_gate_.init(nh, getMyArgv(), getName(), [this](const ros::Time& start, bool session_clock) {
      std::lock_guard<std::mutex> lock(mutex_);
      start_ = start;
      session_clock_ = session_clock;
    });
    timer_ = nh.createTimer(ros::Duration(period_), &PedalsSim::onTick, this);
    NODELET_INFO("pedal track of '%s' at %.1f Hz; overrides on %s", script_->name().c_str(), rate,
                 command_sub_.getTopic().c_str());
    // Latched: the scene that runs now arrives however late this nodelet starts (subscribed last: the callback swaps
    // script_).
    if (follower_->active()) running_scene_sub_ = nh.subscribe("running_scene", 1, &PedalsSim::onRunningScene, this);
  }

  void onCommand(const vrm_msgs::PedalState::ConstPtr& msg) {
    std::lock_guard<std::mutex> lock(mutex_);
    override_ = fromMsg(*msg);
    // Received time, not msg->header.stamp: a GUI may leave the stamp empty and the timeout is about liveness.
    override_received_ = ros::Time::now();
    if (!overriding_) NODELET_INFO("pedal command received; script pedal track overridden");
    overriding_ = true;
  }

  void onSessionCommand(const vrm_msgs::ScenarioCommand::ConstPtr& command) {
    if (command->command != vrm_msgs::ScenarioCommand::START || command->header.stamp.isZero()) return;
    std::lock_guard<std::mutex> lock(mutex_);
    start_ = command->header.stamp;
    session_clock_ = true;
  }

  // scenario:NAME follows the running scene (a LOAD in a station's one graph): the new scene's session, same clock.
  void onRunningScene(const vrm_msgs::RunningScene::ConstPtr& msg) {
    std::unique_ptr<SurgeonScript> script;
    try {
      script = follower_->follow(msg->name, msg->file, msg->difficulty, msg->content_hash);
    } catch (const std::exception& e) {
      NODELET_ERROR("cannot follow running scene '%s' (%s): %s; the old track plays on", msg->name.c_str(),
                    msg->file.c_str(), e.what());
      return;
    }
    if (!script) return;
    NODELET_INFO("track of '%s' for scene '%s' from now on", script->name().c_str(), follower_->sceneName().c_str());
    std::lock_guard<std::mutex> lock(mutex_);
    script_ = std::move(script);
  }

  void onTick(const ros::TimerEvent& event) {
    ros::Time stamp = event.current_expected;
    if (stamp.isZero()) stamp = ros::Time::now();
    if (stamp.isZero() || resume_gate_.withholds(stamp)) return;
    PedalSample pedals;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      if (start_.isZero()) start_ = stamp;
      double script_time = (stamp - start_).toSec();
      if (session_clock_) script_time = std::max(0.0, std::floor(script_time / period_) * period_);
      if (overriding_ && override_timeout_ > 0.0 &&
          (ros::Time::now() - override_received_).toSec() > override_timeout_) {
        overriding_ = false;
        NODELET_INFO("no pedal command for %.2f s; back to the script", override_timeout_);
      }
      pedals = overriding_ ? override_ : script_->sample(script_time).pedals;
    }

    auto msg = boost::make_shared<vrm_msgs::PedalState>();
    msg->header.stamp = stamp;
    toMsg(pedals, msg.get());
    vrm_msgs::publishShared(pub_, msg);
  }

  std::unique_ptr<SurgeonScript> script_;  // swapped under mutex_ when the running scene changes
  std::unique_ptr<ScenarioSceneFollower> follower_;
  ros::Subscriber running_scene_sub_;
  double override_timeout_ = 0.0;
  ros::Publisher pub_;
  ros::Subscriber command_sub_;
  ros::Timer timer_;
  ResumeGate resume_gate_;
  ros::Time start_;
  double period_ = 0.01;
  bool session_clock_ = false;  // start_ is a START's stamp
  ros::Subscriber session_sub_;

  std::mutex mutex_;  // the command callback may run on another manager thread than the timer
  bool overriding_ = false;
  PedalSample override_;
  ros::Time override_received_;
};

}  // namespace vrm_tracking

PLUGINLIB_EXPORT_CLASS(vrm_tracking::PedalsSim, nodelet::Nodelet)
