// Microscope knob twin (thesis §7: focus, zoom, ambient light knobs): plays the script's microscope track, and the
// zoom/focus buttons of whatever publishes `pedals` (pedals_sim or a real pedal unit) move zoom and focus within
// their limits. A console (eyesi_gui) sets the knobs on `microscope_setpoint`: its values replace the scripted track
// from then on (the pedal buttons move on from there), the way a touchscreen sets the real microscope's motors, so the
// recorded input stays this node's `microscope`.
// With script:=scenario:NAME the track is derived from the scene's scripted session (device_script.h,
// scenario_devices.h: the working plane kept in focus at a fixed zoom) instead of the demo's sweeps (issue 33). With
// ~start_with_session (default true) a ScenarioCommand START restarts the track at the START's stamp, and the track is
// read on this twin's period grid from there, as pedals_sim does (issue 31): the same session gets the same knob
// values at the same stamps in every run, idle or loaded.

#include <nodelet/nodelet.h>
#include <ros/ros.h>
#include <vrm_msgs/MicroscopeSettings.h>
#include <vrm_msgs/PedalState.h>
#include <vrm_msgs/RunningScene.h>
#include <vrm_msgs/ScenarioCommand.h>
#include <vrm_msgs/publish.h>

#include <algorithm>
#include <boost/make_shared.hpp>
#include <cmath>
#include <memory>
#include <mutex>
#include <optional>
#include <pluginlib/class_list_macros.hpp>
#include <string>

#include "device_script.h"
#include "vrm_tracking/conversions.h"
#include "vrm_tracking/microscope_knobs.h"
#include "vrm_tracking/resume_gate.h"
#include "vrm_tracking/scene_trocars.h"
#include "vrm_tracking/surgeon_script.h"

namespace vrm_tracking {

class MicroscopeSim : public nodelet::Nodelet {
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

    MicroscopeLimits limits;
    pnh.param("zoom_min", limits.zoom_min, limits.zoom_min);
    pnh.param("zoom_max", limits.zoom_max, limits.zoom_max);
    pnh.param("zoom_rate", limits.zoom_rate, limits.zoom_rate);
    pnh.param("focus_min", limits.focus_min, limits.focus_min);
    pnh.param("focus_max", limits.focus_max, limits.focus_max);
    pnh.param("focus_rate", limits.focus_rate, limits.focus_rate);
    double rate = 20.0;
    pnh.param("rate", rate, rate);
    // Buttons count as released when pedal messages stop, so a dead pedal node cannot zoom forever.
    pnh.param("pedal_timeout", pedal_timeout_, 0.5);
    try {
      if (!(rate > 0.0)) throw std::invalid_argument("rate must be > 0");
      knobs_ = std::make_unique<MicroscopeKnobs>(limits);
    } catch (const std::exception& e) {
      NODELET_FATAL("bad parameters: %s", e.what());
      throw;
    }

    pub_ = nh.advertise<vrm_msgs::MicroscopeSettings>("microscope", 10);
    pedal_sub_ = nh.subscribe("pedals", 10, &MicroscopeSim::onPedals, this);
    setpoint_sub_ = nh.subscribe("microscope_setpoint", 5, &MicroscopeSim::onSetpoint, this);
    period_ = 1.0 / rate;
    if (pnh.param("start_with_session", true)) {
      session_sub_ = nh.subscribe("scenario_command", 10, &MicroscopeSim::onSessionCommand, this);
    }
    resume_gate_.init(nh, getMyArgv(), getName(), [this](const ros::Time& start, bool session_clock) {
      std::lock_guard<std::mutex> lock(mutex_);
      start_ = start;
      session_clock_ = session_clock;
    });
    timer_ = nh.createTimer(ros::Duration(period_), &MicroscopeSim::onTick, this);
    NODELET_INFO("microscope track of '%s' at %.1f Hz; zoom [%.2f, %.2f], focus [%.3f, %.3f] m",
                 script_->name().c_str(), rate, limits.zoom_min, limits.zoom_max, limits.focus_min, limits.focus_max);
    // Latched: the scene that runs now arrives however late this nodelet starts (subscribed last: the callback swaps
    // script_).
    if (follower_->active())
      running_scene_sub_ = nh.subscribe("running_scene", 1, &MicroscopeSim::onRunningScene, this);
  }

  void onPedals(const vrm_msgs::PedalState::ConstPtr& msg) {
    std::lock_guard<std::mutex> lock(mutex_);
    buttons_ = fromMsg(*msg);
    buttons_received_ = ros::Time::now();
  }

  void onSetpoint(const vrm_msgs::MicroscopeSettings::ConstPtr& msg) {
    if (!std::isfinite(msg->zoom) || !std::isfinite(msg->focus_distance) || !std::isfinite(msg->ambient_light) ||
        !std::isfinite(msg->disparity_scale)) {
      NODELET_WARN_THROTTLE(1.0, "microscope_setpoint with non-finite values ignored");
      return;
    }
    MicroscopeSample setpoint;
    setpoint.zoom = msg->zoom;
    setpoint.focus_distance = msg->focus_distance;
    setpoint.ambient_light = msg->ambient_light;
    setpoint.disparity_scale = msg->disparity_scale;
    std::lock_guard<std::mutex> lock(mutex_);
    setpoint_ = setpoint;
    knobs_->reset();  // the console set absolute values: earlier pedal offsets no longer apply
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
    const double dt = last_tick_.isZero() ? 0.0 : (stamp - last_tick_).toSec();
    last_tick_ = stamp;

    PedalSample buttons;
    MicroscopeSample baseline;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      if (!buttons_received_.isZero() && (ros::Time::now() - buttons_received_).toSec() <= pedal_timeout_) {
        buttons = buttons_;
      }
      if (start_.isZero()) start_ = stamp;
      double script_time = (stamp - start_).toSec();
      if (session_clock_) script_time = std::max(0.0, std::floor(script_time / period_) * period_);
      baseline = setpoint_ ? *setpoint_ : script_->sample(script_time).microscope;
    }
    const MicroscopeSample settings = knobs_->update(baseline, buttons, dt);

    auto msg = boost::make_shared<vrm_msgs::MicroscopeSettings>();
    msg->header.stamp = stamp;
    toMsg(settings, msg.get());
    vrm_msgs::publishShared(pub_, msg);
    NODELET_DEBUG_THROTTLE(5.0, "zoom %.2f focus %.4f m", settings.zoom, settings.focus_distance);
  }

  std::unique_ptr<SurgeonScript> script_;  // swapped under mutex_ when the running scene changes
  std::unique_ptr<ScenarioSceneFollower> follower_;
  ros::Subscriber running_scene_sub_;
  std::unique_ptr<MicroscopeKnobs> knobs_;
  double pedal_timeout_ = 0.5;
  ros::Publisher pub_;
  ros::Subscriber pedal_sub_, setpoint_sub_, session_sub_;
  ros::Timer timer_;
  ResumeGate resume_gate_;
  double period_ = 0.05;
  ros::Time start_;             // guarded by mutex_ (the START callback may run on another manager thread)
  bool session_clock_ = false;  // start_ is a START's stamp
  ros::Time last_tick_;

  std::mutex mutex_;
  PedalSample buttons_;
  ros::Time buttons_received_;
  std::optional<MicroscopeSample> setpoint_;
};

}  // namespace vrm_tracking

PLUGINLIB_EXPORT_CLASS(vrm_tracking::MicroscopeSim, nodelet::Nodelet)
