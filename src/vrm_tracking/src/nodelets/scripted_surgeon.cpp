// Scripted surgeon: the mediator twin of the tracked eye and instruments (thesis §2.4.1). It plays a SurgeonScript
// and publishes what the optical tracking would report, at the tracking rate, as ground truth. Parameters (private):
// script (loadSession: empty = the shipped demo, a shipped script's name, a file, or scenario:NAME), scene, loop (set:
// overrides the script's playback), tremor_um (set: every instrument's tremor amplitude instead of the script's,
// whose frequency stays), eye_frame, world_frame, rate (Hz, default 50: instruments, and the eye unless
// eye_rate differs), eye_rate (Hz, default rate: the eye state on ticks of its own, stamped with them — devices at
// different rates, as the mediator must handle, issue 31), start_with_session (default true: a ScenarioCommand START
// on scenario_command restarts the script at the START's stamp, as a trainee begins when the session does; until
// then, or without a START, the script runs from the first tick). With the session's clock the same script gives
// the same inputs relative to the session's start in every run, idle or loaded (session_control stamps START on the
// tick grid), so the session ends in the same state (issue 31).
// The scene (issue 32: trocars, keyframes written `on` scene objects, and the script itself for `scenario:NAME`): at
// start-up ~scene (the default scene without one), then whatever running_scene (vrm_msgs/RunningScene, latched by
// scenario_manager, the one scene owner) announces: a scene whose (file, difficulty, content_hash) differs from the
// one in use is loaded and the script rebuilt for it at run time — a file script gets the new scene's trocars and
// surfaces, `scenario:NAME` becomes the new scene's script of that name. The new script plays on the same clock (a
// LOAD's session starts with its START, which restarts it). A scene that fails to load, or for which the script
// cannot be built, is an ERROR naming why, and the old script plays on.

#include <nodelet/nodelet.h>
#include <ros/ros.h>
#include <vrm_msgs/EyeState.h>
#include <vrm_msgs/InstrumentState.h>
#include <vrm_msgs/RunningScene.h>
#include <vrm_msgs/ScenarioCommand.h>
#include <vrm_msgs/publish.h>

#include <boost/make_shared.hpp>
#include <memory>
#include <mutex>
#include <pluginlib/class_list_macros.hpp>
#include <string>
#include <vector>

#include "vrm_scene/package_data.h"
#include "vrm_scene/scene_loader.h"
#include "vrm_tracking/conversions.h"
#include "vrm_tracking/resume_gate.h"
#include "vrm_tracking/scene_trocars.h"
#include "vrm_tracking/surgeon_script.h"

namespace vrm_tracking {

class ScriptedSurgeon : public nodelet::Nodelet {
 private:
  void onInit() override {
    ros::NodeHandle& nh = getNodeHandle();
    ros::NodeHandle& pnh = getPrivateNodeHandle();

    // The scene whose trocars the instruments pivot at and whose objects the waypoints written `on` an object are
    // placed on; without ~scene the default scene.
    std::string scene_param;
    pnh.param<std::string>("scene", scene_param, "");
    vrm_sim::usePackageData();  // a scene name means vrm_sim's shipped scene
    pnh.param<std::string>("script", script_spec_, "");
    has_tremor_override_ = pnh.getParam("tremor_um", tremor_um_);
    if (has_tremor_override_ && !(tremor_um_ >= 0.0 && tremor_um_ <= 1000.0)) {
      NODELET_FATAL("tremor_um must be in [0, 1000] um (got %g)", tremor_um_);
      throw std::invalid_argument("scripted_surgeon: tremor_um must be in [0, 1000]");
    }
    try {
      if (isScenarioSpec(script_spec_) && scene_param.empty()) {
        throw std::invalid_argument("script '" + script_spec_ + "' needs the ~scene parameter");
      }
      const vrm_sim::scene::SceneDescription scene = vrm_sim::scene::loadScene(sceneOrDefault(scene_param));
      // A file (or the demo) is read once and applied to every scene the owner announces; a scene's session is
      // looked up in each scene.
      if (!isScenarioSpec(script_spec_)) written_ = loadSession(script_spec_, scene);
      script_ = scriptFor(scene, scene_param.empty() ? ", the default: no ~scene given" : "");
      scene_ = sceneIdentity(scene);
    } catch (const std::exception& e) {
      NODELET_FATAL("cannot load surgeon script or scene: %s", e.what());
      throw;
    }

    pnh.param<std::string>("eye_frame", eye_frame_, "eye");
    pnh.param<std::string>("world_frame", world_frame_, "world");
    double rate = 50.0;  // §7: EyeSi tracking runs at <= 50 Hz
    pnh.param("rate", rate, rate);
    if (!(rate > 0.0)) {
      NODELET_FATAL("rate must be > 0 (got %g)", rate);
      throw std::invalid_argument("scripted_surgeon: rate must be > 0");
    }
    double eye_rate = rate;
    pnh.param("eye_rate", eye_rate, eye_rate);
    if (!(eye_rate > 0.0)) {
      NODELET_FATAL("eye_rate must be > 0 (got %g)", eye_rate);
      throw std::invalid_argument("scripted_surgeon: eye_rate must be > 0");
    }
    separate_eye_ = eye_rate != rate;

    eye_pub_ = nh.advertise<vrm_msgs::EyeState>("eye_state", 10);
    // One message per instrument per tick; room for a few ticks of every slot.
    instrument_pub_ = nh.advertise<vrm_msgs::InstrumentState>(
        "instrument_state",
        static_cast<uint32_t>(10 * std::max<std::size_t>(1, script_->session().instruments.size())));
    if (pnh.param("start_with_session", true)) {
      command_sub_ = nh.subscribe("scenario_command", 10, &ScriptedSurgeon::onCommand, this);
    }
    resume_gate_.init(nh, getMyArgv(), getName(), [this](const ros::Time& start, bool session_clock) {
      std::lock_guard<std::mutex> lock(mutex_);
      start_ = start;
      session_clock_ = session_clock;
    });
    timer_ = nh.createTimer(ros::Duration(1.0 / rate), &ScriptedSurgeon::onTick, this);
    if (separate_eye_) eye_timer_ = nh.createTimer(ros::Duration(1.0 / eye_rate), &ScriptedSurgeon::onEyeTick, this);

    NODELET_INFO("playing script '%s' (%s, %zu instruments, %.1f s, %s) at %.1f Hz (eye %.1f Hz)",
                 script_->name().c_str(), script_->source().c_str(), script_->session().instruments.size(),
                 script_->duration(), script_->playback() == Playback::kLoop ? "loop" : "once", rate, eye_rate);
    // Latched: the scene that runs now arrives however late this nodelet starts. Last: its callback replaces script_,
    // which the lines above read on this (the manager's loader) thread.
    running_scene_sub_ = nh.subscribe("running_scene", 1, &ScriptedSurgeon::onRunningScene, this);
  }

  // The script to play in `scene`: the scene's session of that name (scenario:NAME, what scenario_offline plays), or
  // the file's with the scene's trocars and its waypoints placed on the scene's objects (always from the script as
  // written, never from an earlier scene's result). Throws ScriptError, SceneError, std::invalid_argument; logs only
  // once it has the script.
  std::unique_ptr<SurgeonScript> scriptFor(const vrm_sim::scene::SceneDescription& scene, const std::string& why) {
    const vrm_sim::scene::ScriptedSession session =
        isScenarioSpec(script_spec_) ? vrm_sim::scene::findScript(scene, script_spec_.substr(9)) : written_;
    vrm_sim::scene::SurfaceTargetReport targets;
    auto script = std::make_unique<SurgeonScript>(playInScene(scene, session, &targets));
    applyLoopParam(getPrivateNodeHandle(), script.get());
    if (has_tremor_override_) script->setTremorAmplitude(tremor_um_ * 1e-6);
    if (!targets.missing_objects.empty()) {
      NODELET_WARN("scene '%s' has no object %s: %zu waypoints of script '%s' keep their written tips",
                   scene.name.c_str(), joinNames(targets.missing_objects).c_str(), targets.kept_waypoints,
                   script->name().c_str());
    }
    NODELET_INFO("script '%s' in scene '%s' (%s%s): %zu waypoints placed on its objects", script->name().c_str(),
                 scene.name.c_str(), scene.source_file.c_str(), why.c_str(), targets.resolved_waypoints);
    for (std::size_t i = 0; i < script->tracks().size(); ++i) {
      const vrm_sim::scene::ScriptedInstrument& instrument = script->session().instruments[i];
      const Eigen::Vector3d& trocar = script->tracks()[i].trocar;
      NODELET_INFO("trocar %s at [%.6f, %.6f, %.6f] m (eye frame), tremor %.1f um at %.1f Hz",
                   vrm_sim::scene::toString(instrument.slot), trocar.x(), trocar.y(), trocar.z(),
                   instrument.tremor.amplitude * 1e6, instrument.tremor.frequency_hz);
    }
    return script;
  }

  // The scene owner announced the running scene: follow it unless it is the one in use. The scene is loaded and the
  // script built outside the lock (the ticks go on meanwhile); the switch is one locked swap.
  void onRunningScene(const vrm_msgs::RunningScene::ConstPtr& msg) {
    const SceneIdentity announced{msg->name, msg->file, msg->difficulty, msg->content_hash};
    std::string current;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      if (sameScene(announced, scene_)) {
        NODELET_INFO("running scene '%s' (load %u) is the one in use", msg->name.c_str(), msg->load);
        return;
      }
      current = scene_.name;
    }
    std::unique_ptr<SurgeonScript> script;
    SceneIdentity identity;
    try {
      const vrm_sim::scene::SceneDescription scene = vrm_sim::scene::loadScene(msg->file, msg->difficulty);
      script = scriptFor(scene, ", running_scene load " + std::to_string(msg->load));
      identity = sceneIdentity(scene);
    } catch (const std::exception& e) {
      NODELET_ERROR("cannot follow running scene '%s' (load %u, %s): %s; script '%s' of scene '%s' plays on",
                    msg->name.c_str(), msg->load, msg->file.c_str(), e.what(), script_spec_.c_str(), current.c_str());
      return;
    }
    std::lock_guard<std::mutex> lock(mutex_);
    script_ = std::move(script);
    scene_ = std::move(identity);
    announced_end_ = false;
    NODELET_INFO("playing script '%s' (%.1f s, %s) for scene '%s' from now on", script_->name().c_str(),
                 script_->duration(), script_->playback() == Playback::kLoop ? "loop" : "once", scene_.name.c_str());
  }

  static std::string joinNames(const std::vector<std::string>& names) {
    std::string joined;
    for (const std::string& name : names) joined += (joined.empty() ? "'" : ", '") + name + "'";
    return joined;
  }

  // A device is where stamps originate: the tick's scheduled time, like a camera's exposure clock. Zero: simulated
  // time is not running yet. The script's clock starts at the first tick of either timer.
  ros::Time tickStamp(const ros::TimerEvent& event) {
    ros::Time stamp = event.current_expected;
    if (stamp.isZero()) stamp = ros::Time::now();
    if (!stamp.isZero() && !session_clock_ && (start_.isZero() || stamp < start_)) start_ = stamp;
    return stamp;
  }

  // The session starts (START, also after a RESET): the script starts over at the command's stamp. Ticks before it
  // hold the script's first pose.
  void onCommand(const vrm_msgs::ScenarioCommand::ConstPtr& command) {
    if (command->command != vrm_msgs::ScenarioCommand::START || command->header.stamp.isZero()) return;
    std::lock_guard<std::mutex> lock(mutex_);
    start_ = command->header.stamp;
    session_clock_ = true;
    announced_end_ = false;
    NODELET_INFO("script '%s' starts with the session at %.3f s", script_->name().c_str(), start_.toSec());
  }

  void publishEye(const SurgeonSnapshot& snap, const ros::Time& stamp) {
    auto eye = boost::make_shared<vrm_msgs::EyeState>();
    eye->header.stamp = stamp;
    eye->header.frame_id = world_frame_;
    toMsg(snap, eye.get());
    vrm_msgs::publishShared(eye_pub_, eye);
  }

  // The manager's worker threads may run both timers at once: one at a time through the script.
  void onEyeTick(const ros::TimerEvent& event) {
    std::lock_guard<std::mutex> lock(mutex_);
    const ros::Time stamp = tickStamp(event);
    if (stamp.isZero() || resume_gate_.withholds(stamp)) return;
    publishEye(script_->sample((stamp - start_).toSec()), stamp);
  }

  void onTick(const ros::TimerEvent& event) {
    std::lock_guard<std::mutex> lock(mutex_);
    const ros::Time stamp = tickStamp(event);
    if (stamp.isZero() || resume_gate_.withholds(stamp)) return;

    const SurgeonSnapshot snap = script_->sample((stamp - start_).toSec());
    if (snap.finished && !announced_end_) {
      announced_end_ = true;
      NODELET_INFO("script '%s' finished after %.1f s; holding the final pose", script_->name().c_str(),
                   script_->duration());
    }

    if (!separate_eye_) publishEye(snap, stamp);

    for (const InstrumentSample& sample : snap.instruments) {
      auto msg = boost::make_shared<vrm_msgs::InstrumentState>();
      msg->header.stamp = stamp;
      msg->header.frame_id = eye_frame_;
      toMsg(sample, msg.get());
      vrm_msgs::publishShared(instrument_pub_, msg);
    }
    NODELET_DEBUG_THROTTLE(5.0, "script time %.2f s", snap.script_time);
  }

  std::string script_spec_;
  vrm_sim::scene::ScriptedSession written_;  // a file's (not scenario:NAME): every scene is applied to this
  bool has_tremor_override_ = false;
  double tremor_um_ = 0.0;
  std::unique_ptr<SurgeonScript> script_;  // guarded by mutex_ once the timers run
  SceneIdentity scene_;                    // guarded by mutex_
  std::string eye_frame_;
  std::string world_frame_;
  ros::Publisher eye_pub_;
  ros::Publisher instrument_pub_;
  ros::Timer timer_, eye_timer_;
  bool separate_eye_ = false;
  std::mutex mutex_;
  ros::Time start_;
  bool session_clock_ = false;  // start_ is a START's stamp
  ros::Subscriber command_sub_, running_scene_sub_;
  ResumeGate resume_gate_;
  bool announced_end_ = false;
};

}  // namespace vrm_tracking

PLUGINLIB_EXPORT_CLASS(vrm_tracking::ScriptedSurgeon, nodelet::Nodelet)
