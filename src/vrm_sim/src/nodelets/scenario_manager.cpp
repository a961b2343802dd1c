// The VR part's scenario manager (thesis §2.4): a thin adapter around the ROS-free simulation core — a
// vrm_sim::world::Session holding the World of the loaded scene (world/world.h — frame assembly by input stamps,
// collision, tissue, grasping, cutting, tearing, bleeding, and the scene's training scenario with its score). It
// converts the input messages (vrm_sim/conversions.h), hands them to the core and publishes what a frame produced.
// The offline tools (tissue_offline, scenario_offline, session replays) drive the very same core, so the same inputs
// give the same state and score here and there (test/graph/core_equivalence).
//
// Subscribes (~input = devices, the default): eye_state, instrument_state, pedals, scenario_command (LOAD with
// `scenario` = scene name or path and `argument` = difficulty switches the scene at run time; START, PAUSE, RESUME,
// STOP, RESET, SELECT_INSTRUMENT) — through the session's mediator (world/mediator.h), which closes input frames.
// With ~input = frames (replay.launch): recorded_input_frame (vrm_msgs/InputFrame, a session bag's input_frame),
// applied frame by frame as the live session applied them; a gap in their sequence is reported.
// Publishes (zero copy, stamps = the frame's input stamp):
//   input_frame         vrm_msgs/InputFrame for every frame, once its inputs are applied and before it steps (the
//                       applied eye and instrument states: what renderer, tf and markers draw; the session bag
//                       records it and a replay feeds it back)
//   scenario_status     vrm_msgs/ScenarioStatus, latched: on every state change, every 0.1 s of input time while
//                       running, and after every command (a refused one says why in `message`)
//   score               vrm_msgs/Score, latched: the final score when the scenario finishes or fails
//   tissue/<object>     vrm_msgs/TissueMesh of each deformable object, when it changed; of the retina (positions
//                       static, `injury` per vertex) when its bleeding changed
//   simulation_state    vrm_msgs/SimulationState after every frame (state hash, per-tissue grasp/strain/peel outcome,
//                       retina contacts)
//   tissue_timing       vrm_msgs/StageTiming (collision_<object>, tissue_<object>, bleeding_<object>; wall clock)
//   collision_report, collision_markers   only while subscribed (rigid objects without bleeding are only tested then)
// Parameters (private): scene (name or path), difficulty (level; "" = the scenario's default), collision_detector
// (override for every object), max_frame_time (s, default 0.05), collision_max_pixel_size (m), wall_clock_budget
// (default false: deterministic frames; true: each tissue stops at its scene time_budget_ms of wall time, as EyeSi
// did), auto_start (default true: the scenario starts with the first input; false: on START), result_file (the
// session's result JSON; "" = none; also published latched on session_result), user / station (the trainee and the
// simulator's host, written into the result; station defaults to the host name), bag (the session bag's path: the
// result also goes next to it as <bag without .bag>.result.json), seed, eye_frame / world_frame names. The result
// (final_state_hash, scene, seed, frames, score, ...; doc/session_result.md) is written when the session ends (scenario
// finished / failed / stopped, STOP of a scene without a scenario) and, if it never ended, when the nodelet shuts down.
// Crash safety (issue 14): while the scenario runs, the result files hold a provisional result ("in_progress":
// true, the score so far), rewritten every second of input time; every write goes to a temporary file that is then
// renamed, so a crash never leaves half a file. A scenario_manager that starts and finds a provisional result (its
// manager died mid-session) keeps it as <stem>.interrupted[-N].result.json with "state": "interrupted", so the
// interrupted session is in the records, not missing.
// Diagnostics (/diagnostics, 1 Hz wall clock): frames, inputs, rejected inputs (non-finite or implausible values,
// unknown slot or frame, stamps far ahead) and late inputs per second; WARN while inputs are being rejected.
#include <diagnostic_msgs/DiagnosticArray.h>
#include <nodelet/nodelet.h>
#include <ros/ros.h>
#include <unistd.h>
#include <visualization_msgs/MarkerArray.h>

#include <boost/make_shared.hpp>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <map>
#include <memory>
#include <mutex>
#include <pluginlib/class_list_macros.hpp>

#include "vrm_msgs/CollisionReport.h"
#include "vrm_msgs/RunningScene.h"
#include "vrm_msgs/ScenarioStatus.h"
#include "vrm_msgs/Score.h"
#include "vrm_msgs/SessionResult.h"
#include "vrm_msgs/SimulationState.h"
#include "vrm_msgs/StageTiming.h"
#include "vrm_msgs/TissueMesh.h"
#include "vrm_msgs/publish.h"
#include "vrm_sim/conversions.h"
#include "vrm_sim/graph_failure.h"
#include "vrm_sim/mge/membrane.h"
#include "vrm_sim/package_data.h"
#include "vrm_sim/scene/scene_loader.h"
#include "vrm_sim/tissue/tissue_simulator.h"
#include "vrm_sim/world/offline.h"
#include "vrm_sim/world/session.h"
#include "vrm_sim/world/session_result.h"

namespace vrm_sim {

class ScenarioManager : public nodelet::Nodelet {
 public:
  void onInit() override {
    ros::NodeHandle& nh = getNodeHandle();
    ros::NodeHandle& private_nh = getPrivateNodeHandle();
    usePackageData();  // shipped scenes by name (also for a LOAD): found through ROS_PACKAGE_PATH
    const std::string scene_parameter = private_nh.param<std::string>("scene", scene::kDefaultSceneName);
    const std::string difficulty = private_nh.param<std::string>("difficulty", "");
    world::WorldOptions options;
    options.detector_override = private_nh.param<std::string>("collision_detector", "");
    options.max_frame_time = private_nh.param("max_frame_time", 0.05);
    options.collision_max_pixel_size = private_nh.param("collision_max_pixel_size", 0.0);
    options.wall_clock_budget = private_nh.param("wall_clock_budget", false);
    options.auto_start = private_nh.param("auto_start", true);
    options.clock = [] { return ros::WallTime::now().toSec(); };
    options.log = [this](world::Severity severity, const std::string& message) {
      if (severity == world::Severity::kWarning) {
        NODELET_WARN("%s", message.c_str());
      } else {
        NODELET_INFO("%s", message.c_str());
      }
    };
    eye_frame_ = private_nh.param<std::string>("eye_frame", "eye");
    world_frame_ = private_nh.param<std::string>("world_frame", "world");
    input_mode_ = private_nh.param<std::string>("input", "devices");
    if (input_mode_ != "devices" && input_mode_ != "frames") {
      failGraph("scenario_manager: ~input must be 'devices' or 'frames', got '" + input_mode_ + "'");
      return;
    }
    result_file_ = private_nh.param<std::string>("result_file", "");
    bag_path_ = private_nh.param<std::string>("bag", "");
    if (!bag_path_.empty()) {
      const std::string stem = bag_path_.size() > 4 && bag_path_.compare(bag_path_.size() - 4, 4, ".bag") == 0
                                   ? bag_path_.substr(0, bag_path_.size() - 4)
                                   : bag_path_;
      result_files_.push_back(stem + ".result.json");
    }
    if (!result_file_.empty()) result_files_.push_back(result_file_);
    keepInterruptedResults();
    seed_ = static_cast<std::uint32_t>(private_nh.param("seed", 0));
    user_ = private_nh.param<std::string>("user", "");
    char host[256] = {0};
    station_ = private_nh.param<std::string>("station", gethostname(host, sizeof(host) - 1) == 0 ? host : "");
    try {
      session_ = std::make_unique<world::Session>(world::Session::loadByName(scene_parameter, difficulty), options);
    } catch (const std::exception& error) {
      NODELET_FATAL("scenario_manager: cannot set up scene '%s': %s", scene_parameter.c_str(), error.what());
      failGraph("scenario_manager: cannot set up scene '" + scene_parameter + "': " + error.what());
      return;
    }
    input_frame_publisher_ = nh.advertise<vrm_msgs::InputFrame>("input_frame", 100);
    state_publisher_ = nh.advertise<vrm_msgs::SimulationState>("simulation_state", 50);
    timing_publisher_ = nh.advertise<vrm_msgs::StageTiming>("tissue_timing", 5);
    report_publisher_ = nh.advertise<vrm_msgs::CollisionReport>("collision_report", 20);
    marker_publisher_ = nh.advertise<visualization_msgs::MarkerArray>("collision_markers", 2);
    status_publisher_ = nh.advertise<vrm_msgs::ScenarioStatus>("scenario_status", 5, true);
    score_publisher_ = nh.advertise<vrm_msgs::Score>("score", 2, true);
    result_publisher_ = nh.advertise<vrm_msgs::SessionResult>("session_result", 1, true);
    running_scene_publisher_ = nh.advertise<vrm_msgs::RunningScene>("running_scene", 1, /*latch=*/true);
    session_->setFrameObserver([this](const world::FrameResult& frame) { publish(frame); });
    session_->setInputObserver([this](const world::InputFrame& frame) { publishInputFrame(frame); });
    session_->setLoadObserver([this](world::World& world) { onLoaded(world); });
    onLoaded(session_->world());
    // Deep queues (pointers only, zero copy): on a loaded machine an input dropped here would be missing from the
    // live session but present in its bag, and the replay would differ. Two seconds of every input at 50 Hz.
    if (input_mode_ == "frames") {
      frame_subscriber_ = nh.subscribe("recorded_input_frame", 200, &ScenarioManager::onRecordedFrame, this);
    } else {
      eye_subscriber_ = nh.subscribe("eye_state", 100, &ScenarioManager::onEyeState, this);
      instrument_subscriber_ = nh.subscribe("instrument_state", 200, &ScenarioManager::onInstrumentState, this);
      pedal_subscriber_ = nh.subscribe("pedals", 100, &ScenarioManager::onPedals, this);
      command_subscriber_ = nh.subscribe("scenario_command", 50, &ScenarioManager::onScenarioCommand, this);
    }
    diagnostics_publisher_ = nh.advertise<diagnostic_msgs::DiagnosticArray>("/diagnostics", 5);
    diagnostics_timer_ = nh.createWallTimer(ros::WallDuration(1.0), &ScenarioManager::publishDiagnostics, this);
    NODELET_INFO("scenario_manager: deterministic frames: %s, scenario start: %s, input: %s",
                 options.wall_clock_budget ? "no (wall-clock budget)" : "yes",
                 options.auto_start ? "with the first input" : "on START",
                 input_mode_ == "frames" ? "recorded input frames" : "devices through the mediator");
  }

  // A session that never ended (Ctrl-C, a crash of another node) still leaves its result.
  ~ScenarioManager() override {
    std::lock_guard<std::mutex> lock(mutex_);
    if (session_) writeResult();
  }

 private:
  // The manager runs callbacks on several threads; the core is one state machine.
  void onEyeState(const vrm_msgs::EyeState::ConstPtr& eye) {
    std::lock_guard<std::mutex> lock(mutex_);
    session_->handle(toWorld(*eye));
  }
  void onInstrumentState(const vrm_msgs::InstrumentState::ConstPtr& instrument) {
    std::lock_guard<std::mutex> lock(mutex_);
    session_->handle(toWorld(*instrument));
  }
  void onPedals(const vrm_msgs::PedalState::ConstPtr& pedals) {
    std::lock_guard<std::mutex> lock(mutex_);
    session_->handle(toWorld(*pedals));
  }
  void onScenarioCommand(const vrm_msgs::ScenarioCommand::ConstPtr& command) {
    std::lock_guard<std::mutex> lock(mutex_);
    const auto converted = toWorld(*command);
    if (!converted) {
      NODELET_WARN("scenario_command with unknown command %u ignored", static_cast<unsigned>(command->command));
      session_->world().note("unknown command " + std::to_string(command->command) + " ignored");
      publishStatus(command->header.stamp, true);
      return;
    }
    session_->handle(*converted);
    // The command takes effect with the next frame (stamp order); a refusal or a LOAD shows at once.
    publishStatus(command->header.stamp, true);
  }

  // A recorded frame (replay): applied as it was live. Frames come in sequence; a gap is a lost frame, and the
  // replay then cannot be the session.
  void onRecordedFrame(const vrm_msgs::InputFrame::ConstPtr& message) {
    std::lock_guard<std::mutex> lock(mutex_);
    if (message->run != run_) {
      if (last_recorded_sequence_ != 0) {
        NODELET_WARN("scenario_manager: the recorded simulation node restarted here (a new run from sequence %lu)",
                     static_cast<unsigned long>(message->sequence));
      }
      last_recorded_sequence_ = 0;
    }
    if (last_recorded_sequence_ != 0 && message->sequence != last_recorded_sequence_ + 1) {
      ++sequence_gaps_;
      NODELET_ERROR(
          "scenario_manager: recorded input frames jump from sequence %lu to %lu: %s lost; this replay is "
          "not the recorded session",
          static_cast<unsigned long>(last_recorded_sequence_), static_cast<unsigned long>(message->sequence),
          message->sequence > last_recorded_sequence_ ? "frames" : "order");
    }
    last_recorded_sequence_ = message->sequence;
    run_ = message->run;  // republished under the recorded run, so the replay's frames are the recorded ones
    const world::InputFrame frame = toWorld(*message);
    session_->handle(frame);
    if (!frame.commands.empty()) publishStatus(message->header.stamp, true);
  }

  // Called once a frame's inputs are applied, before it steps: whether this frame reports rigid-object collisions
  // is decided here, once per frame (not per input message: a flood of them must not cost a subscriber count each).
  void publishInputFrame(const world::InputFrame& frame) {
    if (frame.kind == world::InputFrame::Kind::kFrame) prepareReports();
    if (frame.kind == world::InputFrame::Kind::kLoad) last_load_stamp_ = frame.stamp;  // announced by onLoaded
    auto message = boost::make_shared<vrm_msgs::InputFrame>();
    fillInputFrame(frame, world_frame_, eye_frame_, *message);
    message->run = run_;
    vrm_msgs::publishShared(input_frame_publisher_, message);
  }

  // A (new) scene: its tissue and retina topics, and its scenario's first status.
  void onLoaded(world::World& world) {
    ros::NodeHandle& nh = getNodeHandle();
    for (const std::string& name : world.tissueNames()) {
      if (mesh_publishers_.count(name) == 0)
        mesh_publishers_[name] = nh.advertise<vrm_msgs::TissueMesh>("tissue/" + name, 2);
    }
    for (const world::InjuryReport& injury : world.injuries()) {
      if (mesh_publishers_.count(injury.object) == 0) {
        mesh_publishers_[injury.object] = nh.advertise<vrm_msgs::TissueMesh>("tissue/" + injury.object, 2, true);
      }
    }
    last_state_.reset();
    result_written_ = false;
    last_provisional_ = ros::Time();
    const scenario::Status* status = world.scenarioStatus();
    NODELET_INFO(
        "scenario_manager: scene '%s'%s, %zu deformable objects, %zu bleeding surfaces%s", world.scene().name.c_str(),
        status ? (", scenario " + status->type + (status->difficulty.empty() ? "" : " (" + status->difficulty + ")"))
                     .c_str()
               : "",
        world.tissueNames().size(), world.injuries().size(), world.simulatesAnything() ? "" : "; nothing to simulate");
    publishStatus(ros::Time(0), true);
    announceScene(world);
  }

  // The one announcement of the running scene (latched): every node that depends on the scene follows it.
  void announceScene(const world::World& world) {
    auto message = boost::make_shared<vrm_msgs::RunningScene>();
    const bool startup = session_ == nullptr || session_->loads() == 0;
    message->header.stamp = startup ? ros::Time(0) : toRosTime(last_load_stamp_);
    message->load = startup ? 0 : static_cast<std::uint32_t>(session_->loads());
    message->name = world.scene().name;
    message->file = world.scene().source_file;
    message->difficulty = world.scene().scenario ? world.scene().scenario->difficulty : "";
    message->seed = startup ? seed_ : session_->seed();
    message->content_hash = scene::sceneContentHash(message->file, message->difficulty);
    vrm_msgs::publishShared(running_scene_publisher_, message);
  }

  void prepareReports() {
    reports_wanted_ = report_publisher_.getNumSubscribers() > 0;
    markers_wanted_ = marker_publisher_.getNumSubscribers() > 0;
    session_->world().setRigidReports(reports_wanted_ || markers_wanted_);
  }

  static ros::Time wallStamp(double seconds) { return ros::Time(std::max(seconds, 0.0)); }

  void publish(const world::FrameResult& frame) {
    const ros::Time stamp = toRosTime(frame.stamp);
    for (const world::TissueReport& tissue : frame.tissues) {
      if (!tissue.changed) continue;
      auto mesh = boost::make_shared<vrm_msgs::TissueMesh>();
      mge::Membrane& membrane = *session_->world().membrane(tissue.object);
      fillTissueMesh(membrane.positions(), membrane.nodeCount(), membrane.triangleNodeSlots(), membrane.triangleCount(),
                     *mesh);
      mesh->header.stamp = stamp;
      mesh->header.frame_id = frameName(tissue.frame_id);
      mesh->tissue_id = tissue.object;
      mesh->version = tissue.version;
      mesh->topology_version = tissue.topology_version;
      mesh->integrator = tissue.integrator;
      vrm_msgs::publishShared(mesh_publishers_[tissue.object], mesh);
      ++meshes_published_;
    }
    for (const world::InjuryReport& injury : frame.injuries) {
      if (!injury.changed) continue;
      auto mesh = boost::make_shared<vrm_msgs::TissueMesh>();
      fillTissueMesh(*injury.mesh, *mesh);
      mesh->injury = *injury.injury;
      mesh->header.stamp = stamp;
      mesh->header.frame_id = frameName(injury.frame_id);
      mesh->tissue_id = injury.object;
      mesh->version = injury.version;
      mesh->topology_version = 1;
      vrm_msgs::publishShared(mesh_publishers_[injury.object], mesh);
    }
    boost::shared_ptr<visualization_msgs::MarkerArray> markers;
    if (markers_wanted_) markers = boost::make_shared<visualization_msgs::MarkerArray>();
    for (const world::CollisionRecord& record : frame.collisions) {
      if (reports_wanted_) {
        auto report = boost::make_shared<vrm_msgs::CollisionReport>();
        report->header.stamp = stamp;
        report->header.frame_id = frameName(record.frame_id);
        report->detector = record.detector;
        report->object_a = "instrument_" + record.instrument;
        report->object_b = record.object;
        fillCollisionReport(record.result, *report);
        vrm_msgs::publishShared(report_publisher_, report);
      }
      if (markers) {
        visualization_msgs::Marker marker;
        marker.header.stamp = stamp;
        marker.header.frame_id = frameName(record.frame_id);
        marker.ns = record.object + "/" + record.instrument;
        if (record.result.triangles.empty()) {
          marker.action = visualization_msgs::Marker::DELETE;
        } else {
          fillTriangleListMarker(record.surface.positions, record.surface.triangles, record.result.triangles,
                                 {1.0f, 0.1f, 0.1f, 0.8f}, marker);
        }
        markers->markers.push_back(std::move(marker));
      }
    }
    if (markers) vrm_msgs::publishShared(marker_publisher_, markers);

    auto timing = boost::make_shared<vrm_msgs::StageTiming>();
    timing->header.stamp = stamp;
    timing->frame = frame.frame;
    for (const world::StageTime& stage : frame.stages) {
      vrm_msgs::StageStamp entry;
      entry.stage = stage.stage;
      entry.start = wallStamp(stage.start);
      entry.end = wallStamp(stage.end);
      timing->stages.push_back(entry);
    }
    vrm_msgs::publishShared(timing_publisher_, timing);

    auto state = boost::make_shared<vrm_msgs::SimulationState>();
    fillSimulationState(frame, session_->world().statistics(), *state);
    vrm_msgs::publishShared(state_publisher_, state);
    publishStatus(stamp, false);
    // A scene without a scenario ends with STOP (a scenario's end is handled with its status).
    if (!session_->world().scenarioStatus() && session_->world().sessionEnded()) writeResult();
    logProgress(frame);
  }

  // Latched status on a state change or a command, else every 0.1 s of input time while running (>= 5 Hz); the
  // final score and the result file once the scenario ends.
  void publishStatus(const ros::Time& stamp, bool force) {
    const scenario::Status* status = session_->world().scenarioStatus();
    if (status == nullptr) return;
    if (status->state == scenario::State::kRunning && !result_written_ &&
        (last_provisional_.isZero() || (stamp - last_provisional_).toSec() >= 1.0)) {
      last_provisional_ = stamp;
      writeResultFiles(sessionResult(/*in_progress=*/true));
    }
    const bool changed = !last_state_ || *last_state_ != status->state;
    const bool due = status->state == scenario::State::kRunning && (stamp - last_status_stamp_).toSec() >= 0.1;
    if (!force && !changed && !due && status->message == last_message_) return;
    last_state_ = status->state;
    last_message_ = status->message;
    last_status_stamp_ = stamp;
    auto message = boost::make_shared<vrm_msgs::ScenarioStatus>();
    message->header.stamp = stamp;
    fillScenarioStatus(*status, *message);
    vrm_msgs::publishShared(status_publisher_, message);
    if (changed && (status->state == scenario::State::kFinished || status->state == scenario::State::kFailed)) {
      auto score = boost::make_shared<vrm_msgs::Score>();
      fillScore(status->score, *score);
      vrm_msgs::publishShared(score_publisher_, score);
      NODELET_INFO("scenario '%s' %s: %s; score %.1f / 100", status->scenario.c_str(),
                   scenario::toString(status->state), status->message.c_str(), status->score.total);
      writeResult();
    }
  }

  // One JSON object per session, next to its bag and/or at result_file: what a training record needs (issue 13
  // stores it) and what a replay must reproduce (final_state_hash).
  void writeResult() {
    if (result_written_) return;
    result_written_ = true;
    NODELET_INFO("scenario_manager: session %s after %lu frames; final state %s",
                 session_->world().sessionEnded() ? "over" : "interrupted",
                 static_cast<unsigned long>(session_->world().statistics().frames),
                 world::hashString(session_->world().stateHash()).c_str());
    const result::SessionResult final_result = sessionResult(/*in_progress=*/false);
    const auto last_stamp = session_->world().lastFrameStamp();
    // The console imports this text (training records) whether or not a file is written, so a result reaches a
    // console on another host too.
    auto message = boost::make_shared<vrm_msgs::SessionResult>();
    message->header.stamp = last_stamp ? toRosTime(*last_stamp) : ros::Time(0);
    message->json = result::toJson(final_result);
    message->final_state_hash = final_result.final_state_hash;
    message->result_files = result_files_;
    if (ros::ok()) vrm_msgs::publishShared(result_publisher_, message);  // not from the destructor at shutdown
    writeResultFiles(final_result);
  }

  void writeResultFiles(const result::SessionResult& session_result) {
    for (const std::string& path : result_files_) {
      try {
        result::writeResultFile(path, session_result);
      } catch (const result::ResultError& error) {
        NODELET_ERROR("scenario_manager: %s", error.what());
        continue;
      }
      if (!session_result.in_progress) {
        NODELET_INFO("scenario_manager: result written to %s (final state %s)", path.c_str(),
                     session_result.final_state_hash.c_str());
      }
    }
  }

  // A provisional result left by a session whose process died: kept under its own name, marked interrupted (the
  // struct is read, changed and written again: result::interrupted).
  void keepInterruptedResults() {
    for (const std::string& path : result_files_) {
      if (!std::filesystem::exists(path)) continue;
      result::SessionResult provisional;
      try {
        provisional = result::readResultFile(path);
      } catch (const result::ResultError& error) {
        NODELET_WARN("scenario_manager: %s; it is overwritten by this session's result", error.what());
        continue;
      }
      if (!provisional.in_progress) continue;
      const std::string kept = result::interruptedPath(path);
      try {
        result::writeResultFile(kept, result::interrupted(provisional));
      } catch (const result::ResultError& error) {
        NODELET_ERROR("scenario_manager: cannot keep the interrupted session's result: %s", error.what());
        continue;
      }
      std::error_code error;
      std::filesystem::remove(path, error);
      NODELET_WARN(
          "scenario_manager: the previous session at %s was interrupted (its process died); its last "
          "provisional result is kept as %s",
          path.c_str(), kept.c_str());
    }
  }

  result::SessionResult sessionResult(bool in_progress) const {
    world::ResultContext context;
    context.seed = session_->loads() > 0 ? session_->seed() : seed_;
    if (!bag_path_.empty()) context.bag = bag_path_;
    if (!user_.empty()) context.user = user_;
    context.station = station_;
    context.in_progress = in_progress;
    return world::sessionResult(session_->world(), context);
  }

  // Rejected and late inputs per second: a flood of hostile or broken messages shows here, not only in the log.
  void publishDiagnostics(const ros::WallTimerEvent&) {
    namespace d = diagnostic_msgs;
    std::lock_guard<std::mutex> lock(mutex_);
    const world::WorldStatistics& statistics = session_->world().statistics();
    const ros::WallTime now = ros::WallTime::now();
    const double period = last_diagnostics_.isZero() ? 1.0 : std::max(1e-3, (now - last_diagnostics_).toSec());
    last_diagnostics_ = now;
    // A LOAD replaces the world and its statistics start at zero again.
    const auto since = [](std::uint64_t now_count, std::uint64_t before) {
      return now_count >= before ? now_count - before : now_count;
    };
    const std::uint64_t rejected = since(statistics.rejected_inputs, reported_.rejected_inputs);
    const std::uint64_t frames = since(statistics.frames, reported_.frames);
    const std::uint64_t inputs = since(statistics.inputs, reported_.inputs);
    reported_ = statistics;
    auto array = boost::make_shared<d::DiagnosticArray>();
    array->header.stamp = ros::Time::now();  // diagnostics describe the live graph, not one frame
    d::DiagnosticStatus status;
    status.name = "vrm_sim: " + getName();
    status.hardware_id = station_;
    status.level = rejected > 0 ? d::DiagnosticStatus::WARN : d::DiagnosticStatus::OK;
    status.message = rejected > 0 ? std::to_string(rejected) + " inputs rejected in the last " +
                                        std::to_string(static_cast<int>(period + 0.5)) + " s"
                                  : "inputs ok";
    const auto add = [&status](const std::string& key, const std::string& value) {
      d::KeyValue entry;
      entry.key = key;
      entry.value = value;
      status.values.push_back(entry);
    };
    char rate[32];
    std::snprintf(rate, sizeof(rate), "%.1f", frames / period);
    add("frames_per_s", rate);
    std::snprintf(rate, sizeof(rate), "%.1f", inputs / period);
    add("inputs_per_s", rate);
    std::snprintf(rate, sizeof(rate), "%.1f", rejected / period);
    add("rejected_per_s", rate);
    add("rejected_total", std::to_string(statistics.rejected_inputs));
    add("late_total", std::to_string(statistics.late_inputs));
    add("frames_without_source_total", std::to_string(statistics.frames_without_source));
    if (input_mode_ == "frames") add("recorded_frame_gaps", std::to_string(sequence_gaps_));
    add("frames_total", std::to_string(statistics.frames));
    // The integrator each membrane runs (with "auto", the one chosen for its stiffness, masses and dt).
    for (const std::string& name : session_->world().tissueNames()) {
      if (const auto* simulator = session_->world().tissueSimulator(name)) {
        add("integrator_" + name, simulator->integratorLabel());
      }
    }
    array->status.push_back(status);
    vrm_msgs::publishShared(diagnostics_publisher_, array);
  }

  // A status line every ~5 s of frames: what the simulation is doing, for the console and the launch log.
  void logProgress(const world::FrameResult& frame) {
    if (frame.frame % 250 != 0) return;
    const world::WorldStatistics& statistics = session_->world().statistics();
    std::string tissues;
    for (const world::TissueReport& tissue : frame.tissues) {
      char line[200];
      std::snprintf(line, sizeof(line), " %s: v%lu grasped %zu strain %.2f lift %.2f mm %s;", tissue.object.c_str(),
                    static_cast<unsigned long>(tissue.version), tissue.grasped_nodes, tissue.max_strain,
                    1e3 * tissue.max_lift, world::toString(tissue.outcome));
      tissues += line;
    }
    NODELET_INFO(
        "scenario_manager: frame %lu, %lu tissue meshes published,%s retina contacts %zu; frame %.2f ms mean, "
        "%.2f ms max",
        static_cast<unsigned long>(frame.frame), static_cast<unsigned long>(meshes_published_), tissues.c_str(),
        frame.injuries.empty() ? 0 : frame.injuries.front().contacts,
        1e3 * statistics.total_frame_wall_time / std::max<std::uint64_t>(statistics.frames, 1),
        1e3 * statistics.max_frame_wall_time);
  }

  const std::string& frameName(const std::string& core_frame) const {
    return core_frame == "world" ? world_frame_ : eye_frame_;
  }

  std::unique_ptr<world::Session> session_;
  std::mutex mutex_;
  std::string result_file_, bag_path_;
  std::vector<std::string> result_files_;
  std::uint32_t seed_ = 0;
  bool result_written_ = false;
  std::optional<scenario::State> last_state_;
  std::string last_message_;
  ros::Time last_status_stamp_;
  std::string eye_frame_, world_frame_;
  bool reports_wanted_ = false, markers_wanted_ = false;
  std::uint64_t meshes_published_ = 0;
  std::map<std::string, ros::Publisher> mesh_publishers_;
  ros::Publisher state_publisher_, timing_publisher_, report_publisher_, marker_publisher_, status_publisher_,
      score_publisher_, result_publisher_;
  std::string user_, station_;
  ros::Subscriber eye_subscriber_, instrument_subscriber_, pedal_subscriber_, command_subscriber_, frame_subscriber_;
  std::string input_mode_;
  std::uint64_t last_recorded_sequence_ = 0, sequence_gaps_ = 0;
  // This node's start (wall clock, ns): tells the frames of a restarted node from the crashed one's in a bag.
  std::uint64_t run_ = static_cast<std::uint64_t>(ros::WallTime::now().toNSec());
  ros::Publisher input_frame_publisher_;
  ros::Publisher running_scene_publisher_;
  world::Stamp last_load_stamp_ = 0;
  ros::Time last_provisional_;
  ros::Publisher diagnostics_publisher_;
  ros::WallTimer diagnostics_timer_;
  ros::WallTime last_diagnostics_;
  world::WorldStatistics reported_;
};

}  // namespace vrm_sim

PLUGINLIB_EXPORT_CLASS(vrm_sim::ScenarioManager, nodelet::Nodelet)
