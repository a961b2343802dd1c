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
// Crash = pause (issue 39). A recorded session (~bag set, ~journal true) appends every input frame it applies to
// <bag without .bag>.journal before publishing it (bag/session_journal.h). A scenario_manager that starts and finds
// the journal of an unfinished session (no final result; the same scene, difficulty and seed) restores the session
// from it instead of starting a new one: the frames go to the Session as in a replay, so the World, the scenario,
// the bleeding and every random draw are where the crashed process left them, the grasps included. Once the
// recorder listens again it picks a resume stamp R (now + ~resume_margin, default 0.3 s), records PAUSE at the last
// restored frame and RESUME at R (the session clock stands still in between), resends the journal's last
// ~resend_frames frames (default 150) as one latched vrm_msgs/InputFrames on input_frame_resent (frames the dead
// process had queued for the recorder; a replay skips those it has), and announces vrm_msgs/SessionResume on
// simulation_resume (latched). Inputs stamped before R are not applied; the device twins loaded again into the
// restarted manager play on from their script time at R. The session keeps its one result. A node loaded again
// (nodelet_keeper --reloaded) with nothing to resume announces resumed = false, and a new session starts.
// Diagnostics (/diagnostics, 1 Hz wall clock): frames, inputs, rejected inputs (non-finite or implausible values,
// unknown slot or frame, stamps far ahead) and late inputs per second; WARN while inputs are being rejected. Per
// membrane: its integrator and tissue_stable_<name> (finite and bounded, issue 40).
#include <diagnostic_msgs/DiagnosticArray.h>
#include <nodelet/nodelet.h>
#include <ros/callback_queue.h>
#include <ros/master.h>
#include <ros/ros.h>
#include <unistd.h>
#include <visualization_msgs/MarkerArray.h>

#include <algorithm>
#include <atomic>
#include <boost/make_shared.hpp>
#include <cmath>
#include <condition_variable>
#include <cstdio>
#include <deque>
#include <filesystem>
#include <map>
#include <memory>
#include <mutex>
#include <pluginlib/class_list_macros.hpp>
#include <thread>

#include "vrm_msgs/CollisionReport.h"
#include "vrm_msgs/InputFrames.h"
#include "vrm_msgs/RunningScene.h"
#include "vrm_msgs/ScenarioStatus.h"
#include "vrm_msgs/Score.h"
#include "vrm_msgs/SessionResult.h"
#include "vrm_msgs/SessionResume.h"
#include "vrm_msgs/SimulationState.h"
#include "vrm_msgs/StageTiming.h"
#include "vrm_msgs/TissueMesh.h"
#include "vrm_msgs/publish.h"
#include "vrm_scene/package_data.h"
#include "vrm_scene/scene_loader.h"
#include "vrm_sim/bag/session_journal.h"
#include "vrm_sim/conversions.h"
#include "vrm_sim/graph_failure.h"
#include "vrm_sim/mge/membrane.h"
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
    seed_ = static_cast<std::uint32_t>(private_nh.param("seed", 0));
    const std::vector<std::string>& argv = getMyArgv();
    reloaded_ = std::find(argv.begin(), argv.end(), "--reloaded") != argv.end();
    journal_enabled_ = private_nh.param("journal", true) && !bag_path_.empty() && input_mode_ == "devices";
    resume_margin_ = std::max(0.0, private_nh.param("resume_margin", 0.3));
    resend_frames_ = static_cast<std::size_t>(std::max(0, private_nh.param("resend_frames", 150)));
    journal_header_ = bag::JournalHeader{scene_parameter, difficulty, seed_, run_};
    checkpoint_interval_ = std::max(0.0, private_nh.param("checkpoint_interval", 10.0));
    std::optional<bag::JournalContents> journal = resumableJournal(journal_header_);
    if (!journal) keepInterruptedResults();
    user_ = private_nh.param<std::string>("user", "");
    char host[256] = {0};
    station_ = private_nh.param<std::string>("station", gethostname(host, sizeof(host) - 1) == 0 ? host : "");
    world_options_ = options;
    try {
      start_scene_ = world::Session::loadByName(scene_parameter, difficulty);
      session_ = std::make_unique<world::Session>(*start_scene_, options);
    } catch (const std::exception& error) {
      NODELET_FATAL("scenario_manager: cannot set up scene '%s': %s", scene_parameter.c_str(), error.what());
      failGraph("scenario_manager: cannot set up scene '" + scene_parameter + "': " + error.what());
      return;
    }
    ring_frames_ = static_cast<std::size_t>(std::max(0, private_nh.param("ring_frames", 500)));
    input_frame_publisher_ = nh.advertise<vrm_msgs::InputFrame>(
        "input_frame", 100, [this](const ros::SingleSubscriberPublisher& peer) { onFrameSubscriber(peer, true); },
        [this](const ros::SingleSubscriberPublisher& peer) { onFrameSubscriber(peer, false); });
    state_publisher_ = nh.advertise<vrm_msgs::SimulationState>("simulation_state", 50);
    timing_publisher_ = nh.advertise<vrm_msgs::StageTiming>("tissue_timing", 5);
    report_publisher_ = nh.advertise<vrm_msgs::CollisionReport>("collision_report", 20);
    marker_publisher_ = nh.advertise<visualization_msgs::MarkerArray>("collision_markers", 2);
    status_publisher_ = nh.advertise<vrm_msgs::ScenarioStatus>("scenario_status", 5, true);
    score_publisher_ = nh.advertise<vrm_msgs::Score>("score", 2, true);
    result_publisher_ = nh.advertise<vrm_msgs::SessionResult>("session_result", 1, true);
    running_scene_publisher_ = nh.advertise<vrm_msgs::RunningScene>("running_scene", 1, /*latch=*/true);
    attachSession();
    resume_publisher_ = nh.advertise<vrm_msgs::SessionResume>("simulation_resume", 1, /*latch=*/true);
    resent_publisher_ = nh.advertise<vrm_msgs::InputFrames>("input_frame_resent", 1, /*latch=*/true);
    if (journal) {
      restore(std::move(*journal));
    } else {
      if (journal_enabled_) startJournal(journal_header_);
      if (reloaded_) announceFreshStart();
    }
    if (journal_enabled_ && checkpoint_interval_ > 0.0) {
      // One checkpoint now, not written: it finds out whether this scene can be checkpointed at all and touches the
      // memory the periodic ones reuse (the first touch of a fresh page costs several µs in a VM: 4 ms for the
      // first checkpoint of the default scene, 0.1 ms for the next).
      try {
        session_->checkpoint(spare_checkpoint_);
      } catch (const StateError& error) {
        checkpoints_refused_ = true;
        NODELET_WARN("scenario_manager: no checkpoints in this session (%s); a restore replays the whole journal",
                     error.what());
      }
      checkpoint_writer_ = std::thread(&ScenarioManager::writeCheckpoints, this);
    }
    // Deep queues (pointers only, zero copy): on a loaded machine an input dropped here would be missing from the
    // live session but present in its bag, and the replay would differ. Two seconds of every input at 50 Hz.
    // A replay's frames come from rosbag play, which cannot wait for a simulation slower than the recording (a slow
    // or sanitizer-built machine, or rate > 1): every frame it sends is kept, up to 20 minutes of them at 50 Hz (a
    // lost one ends the replay's equality, see onRecordedFrame).
    if (input_mode_ == "frames") {
      frame_subscriber_ = nh.subscribe("recorded_input_frame", 60000, &ScenarioManager::onRecordedFrame, this);
    } else {
      eye_subscriber_ = nh.subscribe("eye_state", 100, &ScenarioManager::onEyeState, this);
      instrument_subscriber_ = nh.subscribe("instrument_state", 200, &ScenarioManager::onInstrumentState, this);
      pedal_subscriber_ = nh.subscribe("pedals", 100, &ScenarioManager::onPedals, this);
      // Commands take a queue and thread of their own, so they never wait behind the device inputs. Those share
      // the single-threaded queue, one callback per queued message, up to the deep queues above: a command queued
      // behind them on a simulation slower than its inputs waited for all of them, ~400 callbacks, each a frame
      // (12 s under ASan, while the inputs' own lag stayed at 2 s: full device queues drop their oldest). The
      // mediator orders a command by its stamp, not by its arrival, so only its delay changes.
      // Not the nodelet's multi-threaded queue: nodelet 1.10 frees both of a nodelet's queues at unload, and when a
      // frame is still running on a worker then, this nodelet is destroyed on that worker afterwards, and a
      // subscriber on the other queue unsubscribes from freed memory (ASan: SEGV in Subscription::removeCallback
      // under ~ScenarioManager at a graph's shutdown). This queue lives as long as the nodelet.
      ros::NodeHandle command_nh(nh);
      command_nh.setCallbackQueue(&command_queue_);
      command_subscriber_ = command_nh.subscribe("scenario_command", 50, &ScenarioManager::onScenarioCommand, this);
      command_spinner_ = std::make_unique<ros::AsyncSpinner>(1, &command_queue_);
      command_spinner_->start();
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
    // The command thread first (it takes mutex_), then its subscription, while its queue still exists.
    if (command_spinner_) command_spinner_->stop();
    command_subscriber_.shutdown();
    stopCheckpointWriter();
    std::lock_guard<std::mutex> lock(mutex_);
    if (session_) writeResult();
  }

  // ---- crash = pause (issue 39) ----
 private:
  // The journal of this session's crashed process, if there is one to resume; otherwise why not (logged) and nullopt.
  std::optional<bag::JournalContents> resumableJournal(const bag::JournalHeader& expected) {
    if (!journal_enabled_) return std::nullopt;
    const std::string path = bag::journalPath(bag_path_);
    if (!std::filesystem::exists(path)) return std::nullopt;
    const auto not_resumed = [&](const std::string& why) -> std::optional<bag::JournalContents> {
      resume_reason_ = why;
      NODELET_WARN("scenario_manager: the journal %s is not resumed: %s; a new session starts", path.c_str(),
                   why.c_str());
      return std::nullopt;
    };
    for (const std::string& result_path : result_files_) {
      try {
        if (std::filesystem::exists(result_path) && !result::readResultFile(result_path).in_progress) {
          return not_resumed("the session it records has ended (" + result_path + " is final)");
        }
      } catch (const result::ResultError&) {
        // An unreadable result is no final result.
      }
    }
    bag::JournalContents journal;
    try {
      journal = bag::readJournal(path);
    } catch (const bag::JournalError& error) {
      const std::string kept = path + ".unreadable";
      std::error_code ignored;
      std::filesystem::rename(path, kept, ignored);
      NODELET_ERROR("scenario_manager: %s (kept as %s)", error.what(), kept.c_str());
      return not_resumed(error.what());
    }
    if (journal.header.scene != expected.scene || journal.header.difficulty != expected.difficulty ||
        journal.header.seed != expected.seed) {
      return not_resumed("it records scene '" + journal.header.scene + "' (difficulty '" + journal.header.difficulty +
                         "', seed " + std::to_string(journal.header.seed) + "), this node runs '" + expected.scene +
                         "' ('" + expected.difficulty + "', " + std::to_string(expected.seed) + ")");
    }
    if (journal.frames.empty()) return not_resumed("it holds no frame");
    return journal;
  }

  void startJournal(const bag::JournalHeader& header) {
    try {
      journal_.create(bag::journalPath(bag_path_), header);
    } catch (const bag::JournalError& error) {
      NODELET_ERROR("scenario_manager: %s; this session cannot resume after a crash", error.what());
    }
  }

  // The crashed process's session: its last checkpoint (issue 39 §1), if one fits the journal, and the journal's
  // frames after it — else every frame of the journal — applied as a replay applies them; nothing is published
  // meanwhile.
  void restore(bag::JournalContents journal) {
    const ros::WallTime wall_start = ros::WallTime::now();
    restoring_ = true;
    // The frames' run, continued: the resumed session's frames form one sequence with the crashed process's.
    run_ = journal.frames.back()->run;
    journal_header_.run = run_;
    const std::uint64_t from_checkpoint = restoreCheckpoint(journal);
    for (const vrm_msgs::InputFrame::Ptr& message : journal.frames) {
      for (const vrm_msgs::ScenarioCommand& command : message->commands) {
        if (command.command == vrm_msgs::ScenarioCommand::START) session_start_ = command.header.stamp;
        if (command.command == vrm_msgs::ScenarioCommand::LOAD) session_start_ = ros::Time();
      }
      paused_at_ = std::max(paused_at_, message->header.stamp);
      if (message->sequence > from_checkpoint) session_->handle(toWorld(*message));
    }
    restoring_ = false;
    restored_sequence_ = journal.frames.back()->sequence;
    session_->continueSequence(restored_sequence_ + 1);
    frames_restored_ = static_cast<std::uint32_t>(journal.frames.size());
    restore_seconds_ = (ros::WallTime::now() - wall_start).toSec();
    const std::size_t tail = std::min(resend_frames_, journal.frames.size());
    resend_.assign(journal.frames.end() - static_cast<std::ptrdiff_t>(tail), journal.frames.end());
    try {
      journal_.reopen(bag::journalPath(bag_path_), journal.valid_bytes);
    } catch (const bag::JournalError& error) {
      NODELET_ERROR("scenario_manager: %s; this session cannot resume after another crash", error.what());
    }
    // Until the resume stamp is chosen every device input is held off (stamps before it are never applied).
    resume_stamp_ = ros::TIME_MAX;
    const std::string source =
        checkpoint_restored_ > 0
            ? "its checkpoint at frame " + std::to_string(checkpoint_restored_) + " and the journal's frames after it"
            : std::string("its journal");
    NODELET_WARN(
        "scenario_manager: resumed the session of %s from %s: %u frames (to sequence %lu, input time "
        "%.3f s) restored in %.2f s%s; state %s",
        bag_path_.c_str(), source.c_str(), frames_restored_, static_cast<unsigned long>(restored_sequence_),
        paused_at_.toSec(), restore_seconds_,
        journal.torn_bytes
            ? (", a torn last record of " + std::to_string(journal.torn_bytes) + " bytes dropped").c_str()
            : "",
        world::hashString(session_->world().stateHash()).c_str());
    resume_timer_ = getNodeHandle().createWallTimer(ros::WallDuration(0.05), &ScenarioManager::finishResume, this);
  }

  // The session's frames, inputs and scene switches reach this node's publishers.
  void attachSession() {
    session_->setFrameObserver([this](const world::FrameResult& frame) { publish(frame); });
    session_->setInputObserver([this](const world::InputFrame& frame) { publishInputFrame(frame); });
    session_->setLoadObserver([this](world::World& world) { onLoaded(world); });
    onLoaded(session_->world());
  }

  // The last checkpoint, restored into session_ if it belongs to this journal: the sequence of the last frame it
  // includes, or 0 (then session_ is as built and the whole journal is replayed). A checkpoint that does not fit —
  // another session's, a frame the journal does not hold, bytes this build cannot read — is logged and not used.
  std::uint64_t restoreCheckpoint(const bag::JournalContents& journal) {
    const std::string path = bag::checkpointPath(bag_path_);
    if (!std::filesystem::exists(path)) return 0;
    std::string why;
    try {
      const bag::Checkpoint checkpoint = bag::readCheckpoint(path);
      const bool ours = checkpoint.header.scene == journal.header.scene &&
                        checkpoint.header.difficulty == journal.header.difficulty &&
                        checkpoint.header.seed == journal.header.seed && checkpoint.header.run == journal.header.run;
      const bool in_journal = std::any_of(journal.frames.begin(), journal.frames.end(), [&](const auto& frame) {
        return frame->sequence == checkpoint.sequence && toStamp(frame->header.stamp) == checkpoint.stamp;
      });
      if (!ours) {
        why = "it belongs to another session";
      } else if (!in_journal) {
        why = "the journal does not hold its frame " + std::to_string(checkpoint.sequence);
      } else {
        // A LOAD among the frames the checkpoint replaces is announced with its own stamp, as a replay of it would.
        for (const vrm_msgs::InputFrame::Ptr& frame : journal.frames) {
          if (frame->sequence > checkpoint.sequence) break;
          for (const vrm_msgs::ScenarioCommand& command : frame->commands) {
            if (command.command == vrm_msgs::ScenarioCommand::LOAD) last_load_stamp_ = toStamp(frame->header.stamp);
          }
        }
        session_->restoreCheckpoint(checkpoint.state);
        if (session_->world().stateHash() != checkpoint.state_hash) {
          throw StateError("the restored state hash " + world::hashString(session_->world().stateHash()) +
                           " is not the checkpoint's " + world::hashString(checkpoint.state_hash));
        }
        checkpoint_restored_ = checkpoint.sequence;
        return checkpoint.sequence;
      }
    } catch (const std::exception& error) {  // JournalError, StateError, SceneError
      why = error.what();
      // A half-restored session is discarded: the journal alone restores it.
      session_ = std::make_unique<world::Session>(*start_scene_, world_options_);
      attachSession();
    }
    NODELET_WARN("scenario_manager: the checkpoint %s is not used (%s); the whole journal is replayed", path.c_str(),
                 why.c_str());
    return 0;
  }

  // Checkpoints (issue 39 §1): every checkpoint_interval of input time, after a frame closed, the session's state is
  // copied on the frame thread (Session::checkpoint) and written beside the journal by a thread of its own, so a
  // restore replays only the frames since. A state that cannot be checkpointed (a scene with local refinement or the
  // chainmail model) is said once; its session restores from the whole journal.
  void maybeCheckpoint(world::Stamp stamp) {
    if (!(checkpoint_interval_ > 0.0) || checkpoints_refused_ || !journal_.isOpen() || restoring_) return;
    if (last_checkpoint_stamp_ && world::toSeconds(stamp - *last_checkpoint_stamp_) < checkpoint_interval_) return;
    last_checkpoint_stamp_ = stamp;
    bag::Checkpoint checkpoint;
    {
      std::lock_guard<std::mutex> lock(checkpoint_mutex_);
      checkpoint.state = std::move(spare_checkpoint_);  // the last one's memory, handed back by the writer
    }
    const ros::WallTime start = ros::WallTime::now();
    try {
      session_->checkpoint(checkpoint.state);
    } catch (const StateError& error) {
      checkpoints_refused_ = true;
      NODELET_WARN("scenario_manager: no checkpoints in this session (%s); a restore replays the whole journal",
                   error.what());
      return;
    }
    checkpoint_ms_ = (ros::WallTime::now() - start).toSec() * 1e3;
    checkpoint.header = journal_header_;
    checkpoint.sequence = session_->nextSequence() - 1;
    checkpoint.stamp = stamp;
    checkpoint.state_hash = session_->world().stateHash();
    {
      std::lock_guard<std::mutex> lock(checkpoint_mutex_);
      pending_checkpoint_ = std::move(checkpoint);  // a slow disk keeps only the newest
    }
    checkpoint_ready_.notify_all();
  }

  void writeCheckpoints() {
    std::unique_lock<std::mutex> lock(checkpoint_mutex_);
    while (true) {
      checkpoint_ready_.wait(lock, [this] { return pending_checkpoint_ || stop_checkpoints_; });
      if (!pending_checkpoint_) return;
      bag::Checkpoint checkpoint = std::move(*pending_checkpoint_);
      pending_checkpoint_.reset();
      checkpoint_writing_ = true;
      lock.unlock();
      try {
        bag::writeCheckpoint(bag::checkpointPath(bag_path_), checkpoint);
        ++checkpoints_written_;
      } catch (const bag::JournalError& error) {
        NODELET_WARN_THROTTLE(30.0, "scenario_manager: %s; a restore falls back to an older checkpoint or the journal",
                              error.what());
      }
      lock.lock();
      spare_checkpoint_ = std::move(checkpoint.state);
      checkpoint_writing_ = false;
      checkpoint_ready_.notify_all();
    }
  }

  void stopCheckpointWriter() {
    {
      std::lock_guard<std::mutex> lock(checkpoint_mutex_);
      stop_checkpoints_ = true;
    }
    checkpoint_ready_.notify_all();
    if (checkpoint_writer_.joinable()) checkpoint_writer_.join();
  }

  // Whether every subscriber the master knows of `publisher`'s topic is connected to it (the recorder, a process of
  // its own, connects to this new process a moment after it advertises).
  static bool allSubscribersConnected(const ros::Publisher& publisher) {
    XmlRpc::XmlRpcValue request, response, payload;
    request[0] = ros::this_node::getName();
    if (!ros::master::execute("getSystemState", request, response, payload, false)) return false;
    const XmlRpc::XmlRpcValue& subscriptions = payload[1];
    for (int i = 0; i < subscriptions.size(); ++i) {
      if (static_cast<std::string>(subscriptions[i][0]) != publisher.getTopic()) continue;
      return publisher.getNumSubscribers() >= static_cast<std::uint32_t>(subscriptions[i][1].size());
    }
    return true;
  }

  // Once the recorder listens (or after 10 s): PAUSE at the last restored frame, RESUME at the resume stamp, the
  // journal's tail resent, the resume announced.
  void finishResume(const ros::WallTimerEvent&) {
    std::lock_guard<std::mutex> lock(mutex_);
    if (resume_wait_start_.isZero()) resume_wait_start_ = ros::WallTime::now();
    const double waited = (ros::WallTime::now() - resume_wait_start_).toSec();
    const bool connected =
        allSubscribersConnected(input_frame_publisher_) && allSubscribersConnected(resent_publisher_);
    if (!connected && waited < 10.0) return;
    if (!connected) NODELET_ERROR("scenario_manager: the recorder did not connect within 10 s; resuming all the same");
    resume_timer_.stop();
    // A live decision (when the session goes on), recorded as the PAUSE / RESUME commands below: a replay reads them.
    const ros::Time resume_at = std::max(ros::Time::now(), paused_at_) + ros::Duration(resume_margin_);
    const bool clock_running = session_->world().simulating();
    std::vector<vrm_msgs::InputFrame::Ptr> own;
    if (clock_running) {
      own.push_back(applyOwnCommand(world::ScenarioCommand::Type::kPause, paused_at_));
      own.push_back(applyOwnCommand(world::ScenarioCommand::Type::kResume, resume_at));
    }
    resume_stamp_ = resume_at;
    auto resent = boost::make_shared<vrm_msgs::InputFrames>();
    resent->header.stamp = resume_at;
    for (const auto& frame : resend_) resent->frames.push_back(*frame);
    for (const auto& frame : own) resent->frames.push_back(*frame);
    resend_.clear();
    vrm_msgs::publishShared(resent_publisher_, resent);
    resent_latched_ = true;
    auto message = boost::make_shared<vrm_msgs::SessionResume>();
    message->header.stamp = resume_at;
    message->resumed = true;
    message->run = run_;
    message->sequence = restored_sequence_;
    message->paused_at = paused_at_;
    message->session_start = session_start_;
    message->frames_restored = frames_restored_;
    message->restore_seconds = restore_seconds_;
    vrm_msgs::publishShared(resume_publisher_, message);
    publishAllTissues(paused_at_);
    publishStatus(resume_at, true);
    NODELET_WARN(
        "scenario_manager: the session goes on at input time %.3f s (paused at %.3f s, script time %.3f s%s); "
        "%zu frames resent for the recorder",
        resume_at.toSec(), paused_at_.toSec(), session_start_.isZero() ? 0.0 : (paused_at_ - session_start_).toSec(),
        clock_running ? ", PAUSE and RESUME recorded" : ", its clock was not running", resent->frames.size());
  }

  // A command of this node's own (the resume's PAUSE and RESUME) as a frame of its own, applied, journaled and
  // published like every frame.
  vrm_msgs::InputFrame::Ptr applyOwnCommand(world::ScenarioCommand::Type type, const ros::Time& stamp) {
    world::InputFrame frame;
    frame.kind = world::InputFrame::Kind::kState;
    frame.stamp = toStamp(stamp);
    frame.sequence = session_->nextSequence();
    session_->continueSequence(frame.sequence + 1);
    frame.commands.push_back(world::ScenarioCommand{frame.stamp, type, "", "", 0});
    last_own_frame_.reset();
    session_->handle(frame);
    return last_own_frame_;
  }

  void announceFreshStart() {
    auto message = boost::make_shared<vrm_msgs::SessionResume>();
    message->header.stamp = ros::Time::now();
    message->resumed = false;
    message->run = run_;
    message->reason = resume_reason_.empty() ? "no journal of an unfinished session" : resume_reason_;
    vrm_msgs::publishShared(resume_publisher_, message);
    NODELET_WARN("scenario_manager: loaded again after a crash of its manager; nothing to resume (%s)",
                 message->reason.c_str());
  }

  void removeJournal() {
    if (!journal_.isOpen()) return;
    const std::string path = journal_.path();
    journal_.close();
    std::error_code ignored;
    std::filesystem::remove(path, ignored);
    // With the journal goes its checkpoint: one not written yet is dropped, one being written is waited for (else it
    // would land after the removal and could be taken for a later session's).
    {
      std::unique_lock<std::mutex> lock(checkpoint_mutex_);
      pending_checkpoint_.reset();
      checkpoint_ready_.wait(lock, [this] { return !checkpoint_writing_; });
    }
    std::filesystem::remove(bag::checkpointPath(bag_path_), ignored);
    last_checkpoint_stamp_.reset();
  }

 private:
  // A resumed session applies no device input stamped before its resume stamp (the twins of the restarted manager
  // start their scripts over until they hear where the session was).
  bool beforeResume(const ros::Time& stamp) {
    if (stamp >= resume_stamp_) return false;
    ++inputs_before_resume_;
    return true;
  }
  // The manager runs callbacks on several threads; the core is one state machine.
  void onEyeState(const vrm_msgs::EyeState::ConstPtr& eye) {
    std::lock_guard<std::mutex> lock(mutex_);
    applyWaitingCommands();
    if (beforeResume(eye->header.stamp)) return;
    session_->handle(toWorld(*eye));
  }
  void onInstrumentState(const vrm_msgs::InstrumentState::ConstPtr& instrument) {
    std::lock_guard<std::mutex> lock(mutex_);
    applyWaitingCommands();
    if (beforeResume(instrument->header.stamp)) return;
    session_->handle(toWorld(*instrument));
  }
  void onPedals(const vrm_msgs::PedalState::ConstPtr& pedals) {
    std::lock_guard<std::mutex> lock(mutex_);
    applyWaitingCommands();
    if (beforeResume(pedals->header.stamp)) return;
    session_->handle(toWorld(*pedals));
  }
  // A command goes through an inbox that the input callbacks empty first. Taking mutex_ alone is not enough: the
  // input thread releases and retakes it between queued inputs faster than a waiting thread wakes (std::mutex is not
  // fair), so a STOP behind a burst of 85 queued inputs was applied after all of them, in 3 of 5 runs of
  // test_scenario's ACommandTakesEffectAtItsStamp... (2026-12-03). Whichever thread gets mutex_ first applies it.
  void onScenarioCommand(const vrm_msgs::ScenarioCommand::ConstPtr& command) {
    {
      std::lock_guard<std::mutex> lock(command_inbox_mutex_);
      command_inbox_.push_back(command);
    }
    command_waiting_.store(true, std::memory_order_release);
    std::lock_guard<std::mutex> lock(mutex_);
    applyWaitingCommands();
  }
  // With mutex_ held. Commands keep their arrival order: each call takes the whole inbox.
  void applyWaitingCommands() {
    if (!command_waiting_.exchange(false, std::memory_order_acq_rel)) return;
    std::vector<vrm_msgs::ScenarioCommand::ConstPtr> commands;
    {
      std::lock_guard<std::mutex> lock(command_inbox_mutex_);
      commands.swap(command_inbox_);
    }
    for (const auto& command : commands) applyCommand(command);
  }
  void applyCommand(const vrm_msgs::ScenarioCommand::ConstPtr& command) {
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
    if (frame.kind == world::InputFrame::Kind::kLoad) last_load_stamp_ = frame.stamp;  // announced by onLoaded
    if (restoring_) return;
    if (frame.kind == world::InputFrame::Kind::kLoad && resent_latched_) {
      // The latched resend belongs to the session before this LOAD. A recorder that subscribes from now on — the
      // next session's, started by the station under the same name — would record it as its own first frames, and
      // a gap between them and the frames it records live makes its bag unreplayable. An empty one replaces it.
      auto cleared = boost::make_shared<vrm_msgs::InputFrames>();
      cleared->header.stamp = toRosTime(frame.stamp);
      vrm_msgs::publishShared(resent_publisher_, cleared);
      resent_latched_ = false;
    }
    if (frame.kind == world::InputFrame::Kind::kFrame) prepareReports();
    auto message = boost::make_shared<vrm_msgs::InputFrame>();
    fillInputFrame(frame, world_frame_, eye_frame_, *message);
    message->run = run_;
    // A LOAD after a finished session (its journal removed with its final result) starts the next session's journal:
    // a restore replays the LOAD first, so the header's scene (this node's parameters) still describes it.
    if (!journal_.isOpen() && journal_enabled_ && frame.kind == world::InputFrame::Kind::kLoad) {
      startJournal(journal_header_);
    }
    // Journaled before it is published: every frame the recorder may hold is one a restart restores.
    if (journal_.isOpen()) {
      try {
        journal_.append(*message);
      } catch (const bag::JournalError& error) {
        NODELET_ERROR("scenario_manager: %s; this session cannot resume after a crash from here on", error.what());
        journal_.close();
      }
    }
    if (frame.kind == world::InputFrame::Kind::kState && !frame.commands.empty()) last_own_frame_ = message;
    if (ring_frames_ > 0) {
      ring_.push_back(message);  // read-only from here on, like every subscriber's copy
      if (ring_.size() > ring_frames_) ring_.pop_front();
    }
    vrm_msgs::publishShared(input_frame_publisher_, message);
  }

  // No gap in the record (issue 39): a subscriber of input_frame that left (a recorder that died) and comes back under
  // its name (the respawned recorder) gets the frames published since it left, and the last ~100 before (those the
  // dead process may not have written), from the ring of the last ~ring_frames frames, as one latched InputFrames on
  // input_frame_resent, which the recorder also records. A replay merges the parts and skips the frames it has.
  void onFrameSubscriber(const ros::SingleSubscriberPublisher& peer, bool connected) {
    std::lock_guard<std::mutex> lock(mutex_);
    const std::string name = peer.getSubscriberName();
    const std::uint64_t newest = ring_.empty() ? 0 : ring_.back()->sequence;
    if (!connected) {
      departed_[name] = newest;
      return;
    }
    const auto departed = departed_.find(name);
    if (departed == departed_.end()) return;
    const std::uint64_t left_at = departed->second;
    departed_.erase(departed);
    constexpr std::uint64_t kBeforeLeaving = 100;
    const std::uint64_t from = left_at > kBeforeLeaving ? left_at - kBeforeLeaving : 0;
    auto resent = boost::make_shared<vrm_msgs::InputFrames>();
    for (const vrm_msgs::InputFrame::ConstPtr& frame : ring_) {
      if (frame->sequence > from) resent->frames.push_back(*frame);
    }
    if (resent->frames.empty()) return;
    resent->header.stamp = resent->frames.back().header.stamp;
    const std::uint64_t oldest = resent->frames.front().sequence;
    if (oldest > left_at + 1) {
      NODELET_ERROR(
          "scenario_manager: %s is back after %lu frames; the ring holds the last %zu, so frames %lu to %lu are not "
          "in the record",
          name.c_str(), static_cast<unsigned long>(newest - left_at), ring_.size(),
          static_cast<unsigned long>(left_at + 1), static_cast<unsigned long>(oldest - 1));
    }
    NODELET_WARN("scenario_manager: %s is back; %zu frames resent (sequence %lu to %lu; it left after %lu)",
                 name.c_str(), resent->frames.size(), static_cast<unsigned long>(oldest),
                 static_cast<unsigned long>(resent->frames.back().sequence), static_cast<unsigned long>(left_at));
    vrm_msgs::publishShared(resent_publisher_, resent);
    resent_latched_ = true;
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

  void publishTissue(const world::TissueReport& tissue, const ros::Time& stamp) {
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

  void publishInjury(const world::InjuryReport& injury, const ros::Time& stamp) {
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

  // Every tissue and bleeding surface as it is now (after a restore, whose frames published nothing).
  void publishAllTissues(const ros::Time& stamp) {
    world::World& world = session_->world();
    for (const std::string& name : world.tissueNames()) publishTissue(world.tissueReport(name), stamp);
    for (const world::InjuryReport& injury : world.injuries()) {
      if (injury.mesh && injury.injury) publishInjury(injury, stamp);
    }
  }

  void publish(const world::FrameResult& frame) {
    if (restoring_) return;
    const ros::Time stamp = toRosTime(frame.stamp);
    for (const world::TissueReport& tissue : frame.tissues) {
      if (tissue.changed) publishTissue(tissue, stamp);
    }
    for (const world::InjuryReport& injury : frame.injuries) {
      if (injury.changed) publishInjury(injury, stamp);
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
    maybeCheckpoint(frame.stamp);  // after the frame's messages: its cost does not delay them
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
    removeJournal();  // a final result is never resumed
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
    if (frames_restored_ > 0) {
      add("frames_restored", std::to_string(frames_restored_));
      add("inputs_before_resume_total", std::to_string(inputs_before_resume_));
    }
    // The integrator each membrane runs (with "auto", the one chosen for its stiffness, masses and dt).
    for (const std::string& name : session_->world().tissueNames()) {
      if (const auto* simulator = session_->world().tissueSimulator(name)) {
        add("integrator_" + name, simulator->integratorLabel());
        // Stable = finite and bounded (issue 40): no step the watchdog could not recover, no spring left stretched
        // beyond the strain bound at a frame's end.
        add("tissue_stable_" + name, simulator->stable() ? "true" : "false");
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
  std::mutex command_inbox_mutex_;  // only around command_inbox_, never while waiting for mutex_
  std::vector<vrm_msgs::ScenarioCommand::ConstPtr> command_inbox_;
  std::atomic<bool> command_waiting_{false};  // saves the input callbacks a lock when the inbox is empty
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
  ros::CallbackQueue command_queue_;  // before the subscribers: destroyed after them
  ros::Subscriber eye_subscriber_, instrument_subscriber_, pedal_subscriber_, command_subscriber_, frame_subscriber_;
  std::unique_ptr<ros::AsyncSpinner> command_spinner_;
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
  // Crash = pause (issue 39).
  bool reloaded_ = false, journal_enabled_ = false, restoring_ = false;
  double resume_margin_ = 0.3;
  std::size_t resend_frames_ = 150;
  bag::JournalWriter journal_;
  // Checkpoints (issue 39 §1).
  std::optional<scene::SceneDescription> start_scene_;  // the session's scene as built (a failed restore rebuilds it)
  world::WorldOptions world_options_;
  double checkpoint_interval_ = 10.0;  // s of input time; 0: none
  std::optional<world::Stamp> last_checkpoint_stamp_;
  bool checkpoints_refused_ = false;
  double checkpoint_ms_ = 0.0;             // the last checkpoint's copy on the frame thread
  std::uint64_t checkpoint_restored_ = 0;  // the frame the restore's checkpoint ended at (0: the whole journal)
  std::mutex checkpoint_mutex_;
  std::condition_variable checkpoint_ready_;
  std::optional<bag::Checkpoint> pending_checkpoint_;
  std::string spare_checkpoint_;  // memory of the last checkpoint, for the next
  bool checkpoint_writing_ = false, stop_checkpoints_ = false;
  std::atomic<std::uint64_t> checkpoints_written_{0};
  std::thread checkpoint_writer_;      // last member: joined (stopCheckpointWriter) before the others go
  bag::JournalHeader journal_header_;  // this node's scene, difficulty, seed and run
  std::string resume_reason_;
  ros::Time resume_stamp_;  // device inputs stamped before it are not applied
  ros::Time paused_at_, session_start_;
  std::uint64_t restored_sequence_ = 0, inputs_before_resume_ = 0;
  std::uint32_t frames_restored_ = 0;
  double restore_seconds_ = 0.0;
  std::vector<vrm_msgs::InputFrame::Ptr> resend_;
  vrm_msgs::InputFrame::Ptr last_own_frame_;
  ros::WallTimer resume_timer_;
  ros::WallTime resume_wait_start_;
  ros::Publisher resume_publisher_, resent_publisher_;
  bool resent_latched_ = false;  // input_frame_resent holds frames (the latest resend), not an empty message
  std::size_t ring_frames_ = 500;
  std::deque<vrm_msgs::InputFrame::ConstPtr> ring_;  // the last published frames
  std::map<std::string, std::uint64_t> departed_;    // subscribers that left: the newest frame when they did
};

}  // namespace vrm_sim

PLUGINLIB_EXPORT_CLASS(vrm_sim::ScenarioManager, nodelet::Nodelet)
