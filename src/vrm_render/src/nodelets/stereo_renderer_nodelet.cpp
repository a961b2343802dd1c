// Thin ROS wrapper of vrm_render::StereoRenderer (thesis §6, §7.4.2): collects the latest scene meshes, the input
// frames the simulation closed and microscope knobs, renders a stereo frame and publishes left/right rgb8 images
// with CameraInfo. Stamps are the input stamp the frame reflects; nothing reads a clock for them.
//
// What is drawn (issue 31): the eye and the instruments as the World applied them, from vrm_msgs/InputFrame on
// input_frame (scenario_manager publishes one per frame it closes, before it steps that frame): eye_pose, and per
// slot the applied type (the drawn mesh switches), jaw_angle (the forceps' jaws) and valid (an instrument that is not
// valid is hidden, as an untracked one always was). The raw inputs the frame also carries (instrument_inputs, ...)
// are never drawn: a type switch the World refused or an input it rejected shows as the World decided, so the drawn
// instrument is the colliding one. The renderer keeps no pose history of its own, only the last kHistory frames, so
// a frame can show the frame of its own stamp although newer ones arrived while the simulation computed it. Frames
// of kind STATE / LOAD (pedals and commands between simulation frames) carry nothing to draw. Scene objects the
// scenario moves (a carried box, a falling sphere; issue 36) are drawn where the simulation_state of the frame's stamp
// has them (objects[]: each replaces that object's scene pose); the others stay at their scene poses.
//
// When a frame starts (~trigger, the synchronisation patterns of thesis §2.5.2, Fig. 2.6; issue 12):
//   simulation (default; sequential, eq. 2.3) — when the simulation finished the frame of input stamp S
//     (simulation_state), drawn with input frame S (its applied poses) and the tissue of S. A simulation_state that
//     comes before its input frame (the renderer in another process: topics are not ordered among each other) waits
//     for that frame. Input frames come from the simulation node even while its scenario is paused or not started
//     (simulation_state flows then, too), so the fallback of the pose-driven renderer is only a fallback now: when no
//     simulation_state came for ~simulation_timeout s (a graph that plays input frames without a simulation, a
//     simulation step that stalls), input frames trigger as in `input`.
//   input (pipelined / interleaved, eq. 2.7) — as soon as input frame S arrives (the mediator closed it, so every
//     source has delivered or been declared silent), drawn with the newest tissue (the simulation of S runs
//     meanwhile, so the tissue is one frame older than the instruments).
//   timer (parallel asynchronous, eq. 2.4; the behaviour before issue 12) — on a ~rate Hz timer when an input
//     changed: the newest input frame with the newest tissue.
// Frames are rendered on the nodelet's own thread, always from the newest inputs: while a frame renders, newer
// triggers replace the pending one (no queue grows when rendering is slow); each replaced trigger counts as dropped.
// ~max_rate (event triggers, Hz, 0 = none) bounds the frame rate. ~max_input_age (event triggers, s, default 0.005):
// a trigger that waited longer than this for the previous frame is skipped when the next input is due within the
// tick, so frames start when their input arrives (latency before frame rate, eq. 2.5). The render thread and its
// llvmpipe threads run at ~render_nice (default 10): inputs, tracking and simulation go first.
//
// Lazy (image_pipeline's pattern): the renderer subscribes to its inputs only while somebody wants its output, and
// renders only then; a headless session keeps its cores for tracking and simulation. "Wants output" means: a
// subscriber on stereo/left or stereo/right (image_raw in any transport, or camera_info; in this process or another:
// a viewer, the console, a recorder, a graph test), or snapshots still due (~snapshot_dir with ~snapshot_count or
// ~snapshot_times). render_timing, /diagnostics and tf are by-products of frames, not reasons to render: a latency
// monitor alone does not make the renderer work, and ~save_snapshot returns the last frame rendered for a watcher.
// The publishers' connect / disconnect callbacks (and the last snapshot saved) switch the subscriptions.
//
// The scene (issue 32: one scene owner): the renderer starts on ~scene and follows scenario_manager's latched
// running_scene (vrm_msgs/RunningScene; subscribed whether watched or not). An announcement whose (file, difficulty,
// content_hash) differs from the scene shown is loaded and built (rest meshes by vrm_sim's scene::buildMesh, the
// one the scene manager and the World use, styles, fundus) on the thread that received it, then shown by the render
// thread between two frames: the previous scene's objects, instruments, ghosts and tissue subscriptions are removed,
// and input frames and tissue meshes stamped before the announcement are dropped (the previous World's); frames
// stamped after it wait until the scene is shown (an image shows the scene that ran at its stamp). They wait from
// the LOAD's input frame on (KIND_LOAD, ordered with the frames on input_frame; the announcement travels on another
// topic and may come after the first frames of the new scene), until its announcement comes, a simulation_state
// after it tells that the LOAD was refused (no announcement), or ~load_hold_limit s have passed. One INFO
// line per switch gives its time; a scene that cannot be loaded is an ERROR and the old scene stays. The static
// objects come from the scene itself, not from the scene manager's meshes/<object>: those carry the same meshes, and
// a latched copy of the previous scene's could arrive after the switch.
//
// Subscribes (node handle namespace): running_scene; tissue/<object> (vrm_msgs/TissueMesh) of the scene's deformable
//   objects, and of the retina of a scene that simulates bleeding, from the simulation; input_frame
//   (vrm_msgs/InputFrame), simulation_state (frame done), microscope (not part of a frame: the newest settings up to
//   the frame's stamp), and with ~ghost_instruments the instructor's recorded input frames replayed on ~ghost_topic
//   (default ghost/input_frame): their valid instruments[] drawn translucent, their stamps never stamp a frame. A bag
//   recorded before input frames has only instrument_state: the station plays it onto ~legacy_ghost_topic (default
//   ghost/instrument_state), drawn the same way (a warning says the bag is old).
// Publishes: stereo/left/image_raw + camera_info, stereo/right/image_raw + camera_info (image_transport; frame ids
//   <camera_frame>_left_optical / _right_optical); render_timing (vrm_msgs/StageTiming: render_<pass>, render,
//   image_published, and simulation_input = the input stamp of the simulation frame shown, as start = end);
//   /diagnostics (frames, dropped, fps; wall-clock period); and on tf with each frame's stamp: world ->
//   <camera_frame> (the objective; REP-103 body axes: x along the optical axis, z up) ->
//   <camera_frame>_{left,right}_optical (REP-103 optical: z forward, x right, y down). Default camera_frame:
//   microscope.
// Service: ~save_snapshot (std_srvs/Trigger): writes the last rendered frame (left, right) as PNGs into
//   ~snapshot_dir (/tmp when empty), with its render state (<prefix>.frame, vrm_render/render_state.h: frame_check
//   re-renders it), and returns the path prefix.

#include <cv_bridge/cv_bridge.h>
#include <diagnostic_msgs/DiagnosticArray.h>
#include <image_transport/image_transport.h>
#include <nodelet/nodelet.h>
#include <pthread.h>
#include <ros/ros.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>
#include <std_srvs/Trigger.h>
#include <sys/resource.h>
#include <sys/syscall.h>
#include <tf2_ros/transform_broadcaster.h>
#include <unistd.h>
#include <vrm_msgs/AppliedInstrument.h>
#include <vrm_msgs/InputFrame.h>
#include <vrm_msgs/InstrumentState.h>
#include <vrm_msgs/MicroscopeSettings.h>
#include <vrm_msgs/RunningScene.h>
#include <vrm_msgs/SimulationState.h>
#include <vrm_msgs/StageTiming.h>
#include <vrm_msgs/TissueMesh.h>
#include <vrm_msgs/publish.h>

#include <algorithm>
#include <atomic>
#include <boost/make_shared.hpp>
#include <chrono>
#include <condition_variable>
#include <cstdio>
#include <deque>
#include <filesystem>
#include <fstream>
#include <map>
#include <mutex>
#include <pluginlib/class_list_macros.hpp>
#include <set>
#include <sstream>
#include <stdexcept>
#include <string>
#include <thread>

#include "vrm_render/conversions.h"
#include "vrm_render/image_io.h"
#include "vrm_render/scene_setup.h"
#include "vrm_render/stereo_renderer.h"
#include "vrm_scene/instrument_model.h"
#include "vrm_scene/meshes/mesh_generators.h"
#include "vrm_scene/package_data.h"
#include "vrm_scene/scene_loader.h"
#include "vrm_sim/conversions.h"

namespace vrm_render {

namespace {

enum class Trigger { kSimulation, kInput, kTimer };

Trigger parseTrigger(const std::string& name) {
  if (name == "simulation") return Trigger::kSimulation;
  if (name == "input") return Trigger::kInput;
  if (name == "timer") return Trigger::kTimer;
  throw std::invalid_argument("trigger '" + name + "' (expected simulation, input or timer)");
}

// Input frames (and microscope settings) kept, so a frame can show the inputs of its own stamp although newer ones
// arrived while the simulation computed it (8 frames = 160 ms at 50 Hz).
constexpr std::size_t kHistory = 8;

template <class M>
void remember(std::deque<boost::shared_ptr<const M>>* history, const boost::shared_ptr<const M>& message) {
  if (!history->empty() && message->header.stamp < history->back()->header.stamp) return;  // late: never shown
  history->push_back(message);
  while (history->size() > kHistory) history->pop_front();
}

// The newest message stamped no later than `limit` (else the oldest kept).
template <class M>
boost::shared_ptr<const M> newestUpTo(const std::deque<boost::shared_ptr<const M>>& history, const ros::Time& limit) {
  for (auto it = history.rbegin(); it != history.rend(); ++it) {
    if ((*it)->header.stamp <= limit) return *it;
  }
  return history.empty() ? nullptr : history.front();
}

// The threads of this process (Linux: /proc/self/task).
std::set<pid_t> processThreads() {
  std::set<pid_t> threads;
  std::error_code error;
  for (const auto& entry : std::filesystem::directory_iterator("/proc/self/task", error)) {
    threads.insert(static_cast<pid_t>(std::stol(entry.path().filename().string())));
  }
  return threads;
}

std::string threadName(pid_t thread) {
  std::ifstream file("/proc/self/task/" + std::to_string(thread) + "/comm");
  std::string name;
  std::getline(file, name);
  return name;
}

}  // namespace

class StereoRendererNodelet : public nodelet::Nodelet {
 public:
  ~StereoRendererNodelet() override {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      stop_ = true;
    }
    wake_.notify_all();
    loader_wake_.notify_all();
    if (thread_.joinable()) thread_.join();
    if (loader_.joinable()) loader_.join();
  }

  void onInit() override {
    ros::NodeHandle& nh = getNodeHandle();
    ros::NodeHandle& pnh = getPrivateNodeHandle();
    const RenderOptions options = readParameters(pnh);
    const std::string scene_parameter = pnh.param<std::string>("scene", vrm_sim::scene::kDefaultSceneName);
    const std::string trigger_name = pnh.param<std::string>("trigger", "simulation");

    fundus_seed_ = pnh.param("fundus_seed", -1);
    std::unique_ptr<PreparedScene> startup;
    try {
      trigger_ = parseTrigger(trigger_name);
      vrm_sim::usePackageData();  // a scene name means vrm_sim's shipped scene (devel or install space)
      // The start-up scene, until scenario_manager announces the one it runs (usually this one: then nothing changes).
      startup = prepareScene(vrm_sim::scene::loadScene(scene_parameter));
      const std::set<pid_t> threads_before = processThreads();
      renderer_ = std::make_unique<StereoRenderer>(options);
      // The rasteriser threads llvmpipe started for this context run at the render thread's priority.
      for (pid_t thread : processThreads()) {
        if (threads_before.count(thread) == 0 && threadName(thread).rfind("llvmpipe", 0) == 0) {
          render_threads_.push_back(thread);
        }
      }
      // The same path as a switch at run time, so the start-up scene and a followed one are drawn alike.
      showPreparedScene(*startup);
      // This is the manager's loader thread, which goes on to load other nodelets: the render thread owns the context.
      StereoRenderer::releaseContext();
    } catch (const std::exception& error) {
      NODELET_FATAL("stereo_renderer cannot start: %s", error.what());
      throw;
    }
    shown_ = std::move(startup);
    // Read before the render thread starts: a scene announced meanwhile replaces shown_ there.
    const std::string startup_scene = shown_->scene.name;

    snapshots_pending_ = snapshot_count_ > 0 && !snapshot_dir_.empty();
    {
      // As image_proc does: a subscriber may connect while the publishers are being advertised; its callback waits
      // for this lock, so it sees both publishers assigned.
      std::lock_guard<std::mutex> lock(connect_mutex_);
      image_transport::ImageTransport it(nh);
      const auto image_cb = [this](const image_transport::SingleSubscriberPublisher&) { updateSubscriptions(); };
      const auto info_cb = [this](const ros::SingleSubscriberPublisher&) { updateSubscriptions(); };
      left_pub_ = it.advertiseCamera("stereo/left/image_raw", 1, image_cb, image_cb, info_cb, info_cb);
      if (options.stereo)
        right_pub_ = it.advertiseCamera("stereo/right/image_raw", 1, image_cb, image_cb, info_cb, info_cb);
    }
    updateSubscriptions();  // snapshots due: inputs from the start
    timing_pub_ = nh.advertise<vrm_msgs::StageTiming>("render_timing", 5);
    diagnostics_pub_ = nh.advertise<diagnostic_msgs::DiagnosticArray>("/diagnostics", 5);
    snapshot_srv_ = pnh.advertiseService("save_snapshot", &StereoRendererNodelet::onSaveSnapshot, this);
    if (trigger_ == Trigger::kTimer) {
      timer_ = nh.createTimer(ros::Duration(1.0 / std::max(1.0, rate_)), &StereoRendererNodelet::onTimer, this);
    }
    diagnostic_timer_ = nh.createWallTimer(ros::WallDuration(1.0), &StereoRendererNodelet::publishDiagnostics, this);
    last_diagnostics_ = ros::WallTime::now();
    thread_ = std::thread(&StereoRendererNodelet::renderLoop, this);
    loader_ = std::thread(&StereoRendererNodelet::loadLoop, this);
    // Not lazy: the scene must be current whenever somebody starts watching. Latched: the scene running now arrives.
    running_scene_subscriber_ = nh.subscribe("running_scene", 1, &StereoRendererNodelet::onRunningScene, this);
    // Rendering yields to the input side (tracking, simulation): a slower frame still shows the newest input, while
    // a delayed input delays every stage after it (thesis §2.5.3: never more busy threads than cores).
    for (pid_t thread : render_threads_) setpriority(PRIO_PROCESS, static_cast<id_t>(thread), render_nice_);
    NODELET_INFO(
        "stereo_renderer: scene '%s', %dx%d %s, passes shadow=%d dof=%d, frames %s; render thread and %zu "
        "llvmpipe threads at nice %d",
        startup_scene.c_str(), options.width, options.height, options.stereo ? "stereo" : "mono", options.shadow_pass,
        options.dof_pass, describeTrigger().c_str(), render_threads_.size(), render_nice_);
  }

 private:
  // What identifies the content of a scene (vrm_msgs/RunningScene): the file, its difficulty level and a hash of both.
  struct SceneKey {
    std::string file;
    std::string difficulty;
    std::uint64_t content_hash = 0;
    bool operator==(const SceneKey& other) const {
      return file == other.file && difficulty == other.difficulty && content_hash == other.content_hash;
    }
  };

  // A scene ready to be shown: loaded and its meshes and fundus built on the thread that received the announcement,
  // so the render thread only uploads (and keeps rendering the old scene meanwhile).
  struct PreparedScene {
    vrm_sim::scene::SceneDescription scene;
    SceneContent content;
    SceneKey key;
    std::uint32_t load = 0;  // of the announcement (0: the start-up scene)
    ros::Time since;         // the announcement's stamp: inputs stamped earlier were computed in the previous scene
    std::chrono::steady_clock::time_point announced;  // when the announcement arrived
    double prepare_ms = 0.0;                          // loading the file and building the content
  };

  struct Slot {
    vrm_sim::scene::InstrumentDescription description;  // as configured in the scene
    std::string object_id;
    bool ghost = false;
    // What the renderer shows (render thread): type and jaw step of the uploaded mesh.
    vrm_sim::scene::InstrumentType shown_type = vrm_sim::scene::InstrumentType::kLightPipe;
    int shown_jaw_deg = 0;
  };

  std::string describeTrigger() const {
    char text[160];
    switch (trigger_) {
      case Trigger::kSimulation:
        std::snprintf(text, sizeof(text), "when the simulation finished an input frame (sequential)%s",
                      max_rate_ > 0.0 ? ", rate-limited" : "");
        break;
      case Trigger::kInput:
        std::snprintf(text, sizeof(text), "when an input frame arrives (pipelined)%s",
                      max_rate_ > 0.0 ? ", rate-limited" : "");
        break;
      case Trigger::kTimer:
        std::snprintf(text, sizeof(text), "on a %.1f Hz timer when an input changed (parallel asynchronous)", rate_);
        break;
    }
    return text;
  }

  RenderOptions readParameters(ros::NodeHandle& pnh) {
    RenderOptions options;
    pnh.param("width", options.width, options.width);
    pnh.param("height", options.height, options.height);
    pnh.param("stereo", options.stereo, options.stereo);
    pnh.param("shadows", options.shadow_pass, options.shadow_pass);
    pnh.param("lighting", options.lighting, options.lighting);
    pnh.param("bump_mapping", options.bump_mapping, options.bump_mapping);
    pnh.param("depth_of_field", options.dof_pass, options.dof_pass);
    pnh.param("shadow_map_size", options.shadow_map_size, options.shadow_map_size);
    pnh.param("dof_downsample", options.dof_downsample, options.dof_downsample);
    pnh.param("ghost_instruments", ghost_instruments_, false);
    // glFinish between passes: exact per-pass StageTiming, at the cost of some llvmpipe overlap (bench_render).
    pnh.param("time_passes", options.time_passes, options.time_passes);
    pnh.param("rate", rate_, 30.0);
    pnh.param("max_rate", max_rate_, 0.0);
    pnh.param("max_input_age", max_input_age_, 0.005);
    pnh.param("render_nice", render_nice_, 10);
    pnh.param("simulation_timeout", simulation_timeout_, 0.5);
    pnh.param("load_hold_limit", load_hold_limit_, 2.0);
    pnh.param("snapshot_dir", snapshot_dir_, std::string());
    pnh.param("snapshot_count", snapshot_count_, 0);
    pnh.param("snapshot_every", snapshot_every_, 10);
    // "6 8 10": save at these seconds of input time after the first input instead of every snapshot_every-th frame
    // (so a bounded session's frames show its key moments, e.g. the grasp and the peel).
    std::istringstream times(pnh.param<std::string>("snapshot_times", ""));
    for (double t; times >> t;) snapshot_times_.push_back(t);
    std::sort(snapshot_times_.begin(), snapshot_times_.end());
    if (!snapshot_times_.empty()) snapshot_count_ = static_cast<int>(snapshot_times_.size());
    pnh.param("world_frame", world_frame_, std::string("world"));
    pnh.param("eye_frame", eye_frame_, std::string("eye"));
    pnh.param("camera_frame", camera_frame_, std::string("microscope"));
    pnh.param("ghost_topic", ghost_topic_, std::string("ghost/input_frame"));
    pnh.param("legacy_ghost_topic", legacy_ghost_topic_, std::string("ghost/instrument_state"));
    // llvmpipe's per-draw buffers would otherwise cost ~3,000 page faults per frame (see retainFreedHeapMemory).
    if (pnh.param("retain_heap_memory", true)) retainFreedHeapMemory();
    return options;
  }

  // --- lazy subscription (the rule: see the top of this file) ---

  // Publisher connect / disconnect callbacks (manager threads), onInit, and the render thread after the last
  // snapshot: subscribes to the inputs when output is wanted, drops them when not.
  void updateSubscriptions() {
    std::lock_guard<std::mutex> lock(connect_mutex_);
    const bool watched = left_pub_.getNumSubscribers() > 0 || right_pub_.getNumSubscribers() > 0;
    watched_ = watched;
    const bool wanted = watched || snapshots_pending_;
    if (wanted == subscribed_) return;
    if (wanted) {
      subscribeInputs();
    } else {
      for (ros::Subscriber& subscriber : input_subscribers_) subscriber.shutdown();
      input_subscribers_.clear();
      for (auto& entry : tissue_subscribers_) entry.second.shutdown();
      tissue_subscribers_.clear();
    }
    subscribed_ = wanted;
    NODELET_DEBUG("stereo_renderer: inputs %s", wanted ? "subscribed (output wanted)" : "dropped (nobody watches)");
  }

  void subscribeInputs() {
    ros::NodeHandle& nh = getNodeHandle();
    subscribeTissue();
    // Short queues: the newest input wins (a slow frame must not make them grow).
    input_subscribers_.push_back(nh.subscribe("input_frame", 5, &StereoRendererNodelet::onInputFrame, this));
    input_subscribers_.push_back(nh.subscribe("simulation_state", 5, &StereoRendererNodelet::onSimulationState, this));
    if (ghost_instruments_) {
      input_subscribers_.push_back(nh.subscribe(ghost_topic_, 5, &StereoRendererNodelet::onGhostFrame, this));
      input_subscribers_.push_back(
          nh.subscribe(legacy_ghost_topic_, 10, &StereoRendererNodelet::onLegacyGhostState, this));
    }
    input_subscribers_.push_back(nh.subscribe("microscope", 5, &StereoRendererNodelet::onMicroscope, this));
  }

  // (connect_mutex_) tissue/<object> of the shown scene's streamed objects (deformable ones: the simulation's deformed
  // versions; the retina of a bleeding scene: its injury field, the bleeding colour of thesis §6). A subscription the
  // new scene still needs is kept: subscribing again would deliver the old scene's latched copy once more.
  void subscribeTissue() {
    for (auto it = tissue_subscribers_.begin(); it != tissue_subscribers_.end();) {
      if (streamed_objects_.count(it->first) > 0) {
        ++it;
        continue;
      }
      it->second.shutdown();
      it = tissue_subscribers_.erase(it);
    }
    ros::NodeHandle& nh = getNodeHandle();
    for (const std::string& name : streamed_objects_) {
      if (tissue_subscribers_.count(name) > 0) continue;
      tissue_subscribers_[name] = nh.subscribe<vrm_msgs::TissueMesh>(
          "tissue/" + name, 2, boost::bind(&StereoRendererNodelet::onMesh, this, name, boost::placeholders::_1));
    }
  }

  // --- the running scene (issue 32: scenario_manager owns it, the renderer follows) ---

  // Loads nothing: builds what the renderer shows of an already loaded scene (CPU only).
  std::unique_ptr<PreparedScene> prepareScene(vrm_sim::scene::SceneDescription scene) const {
    auto prepared = std::make_unique<PreparedScene>();
    prepared->content = sceneContent(scene, fundus_seed_);
    // As scenario_manager derives what it announces, so the start-up scene and its announcement compare equal.
    prepared->key.file = scene.source_file;
    prepared->key.difficulty = scene.scenario ? scene.scenario->difficulty : "";
    prepared->key.content_hash = vrm_sim::scene::sceneContentHash(prepared->key.file, prepared->key.difficulty);
    prepared->scene = std::move(scene);
    return prepared;
  }

  // (manager thread) Loading a scene and baking its fundus take a good part of a second: the loader thread does it,
  // so the manager's threads keep serving the simulation meanwhile.
  void onRunningScene(const vrm_msgs::RunningScene::ConstPtr& message) {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      announced_ = message;  // a newer announcement replaces one not taken yet
      announced_at_ = std::chrono::steady_clock::now();
      // Inputs of another scene wait from here, not from when the loader thread (niced, on a busy machine maybe
      // hundreds of ms later) takes the announcement: a frame rendered in between would draw them in the old scene.
      SceneKey key;
      key.file = message->file;
      key.difficulty = message->difficulty;
      key.content_hash = message->content_hash;
      if (!(key == (next_scene_ ? next_scene_->key : shown_key_)) && !(key == shown_key_)) {
        scene_loading_ = true;
        loading_since_ = message->header.stamp;
      }
      if (message->header.stamp > newest_announcement_) newest_announcement_ = message->header.stamp;
      while (!pending_loads_.empty() && pending_loads_.front().first <= message->header.stamp) {
        pending_loads_.pop_front();  // announced (a later LOAD's announcement answers the earlier ones too)
      }
    }
    loader_wake_.notify_one();
  }

  void loadLoop() {
    pthread_setname_np(pthread_self(), "vrm_render_load");
    if (render_nice_ > 0) setpriority(PRIO_PROCESS, static_cast<id_t>(syscall(SYS_gettid)), render_nice_);
    std::unique_lock<std::mutex> lock(mutex_);
    while (true) {
      loader_wake_.wait(lock, [this] { return stop_ || announced_; });
      if (stop_) break;
      const vrm_msgs::RunningScene::ConstPtr message = std::move(announced_);
      announced_.reset();
      const auto announced = announced_at_;
      lock.unlock();
      prepareAnnounced(*message, announced);
      lock.lock();
    }
  }

  // (loader thread) An announcement of another scene than the one shown (or about to be shown) is loaded and built
  // here, then handed to the render thread. A scene that cannot be loaded changes nothing.
  void prepareAnnounced(const vrm_msgs::RunningScene& message, std::chrono::steady_clock::time_point announced) {
    SceneKey key;
    key.file = message.file;
    key.difficulty = message.difficulty;
    key.content_hash = message.content_hash;
    std::string shown_name;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      if (key == (next_scene_ ? next_scene_->key : shown_key_)) {
        scene_loading_ = next_scene_ != nullptr;  // onRunningScene may have marked a replaced announcement's load
        return;
      }
      if (key == shown_key_) {  // back to the shown scene before the switch to another one happened
        next_scene_.reset();
        scene_loading_ = false;
        return;
      }
      shown_name = shown_name_;
      scene_loading_ = true;
      loading_since_ = message.header.stamp;
    }
    std::unique_ptr<PreparedScene> prepared;
    try {
      prepared = prepareScene(vrm_sim::scene::loadScene(message.file, message.difficulty));
    } catch (const std::exception& error) {
      NODELET_ERROR(
          "stereo_renderer: cannot follow the running scene '%s' (load %u, file '%s', difficulty '%s'): %s; "
          "still rendering '%s'",
          message.name.c_str(), message.load, message.file.c_str(), message.difficulty.c_str(), error.what(),
          shown_name.c_str());
      std::lock_guard<std::mutex> lock(mutex_);
      scene_loading_ = next_scene_ != nullptr;  // an earlier announcement still to be shown
      return;
    }
    if (prepared->key.content_hash != message.content_hash) {
      NODELET_WARN("stereo_renderer: scene file '%s' changed since the simulation loaded it: rendering it as it is now",
                   message.file.c_str());
    }
    prepared->key = key;  // what was announced: the same announcement again changes nothing
    prepared->load = message.load;
    prepared->since = message.header.stamp;
    prepared->announced = announced;
    prepared->prepare_ms =
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - announced).count();
    {
      std::lock_guard<std::mutex> lock(mutex_);
      next_scene_ = std::move(prepared);
    }
    wake_.notify_all();
  }

  // (render thread) Shows the prepared scene; on failure goes back to the scene shown before.
  void switchScene(std::unique_ptr<PreparedScene> next) {
    std::lock_guard<std::mutex> render_lock(render_mutex_);
    const auto start = std::chrono::steady_clock::now();
    try {
      showPreparedScene(*next);
    } catch (const std::exception& error) {
      NODELET_ERROR("stereo_renderer: scene '%s' cannot be shown (%s); still rendering '%s'", next->scene.name.c_str(),
                    error.what(), shown_->scene.name.c_str());
      try {
        showPreparedScene(*shown_);
      } catch (const std::exception& again) {
        NODELET_ERROR("stereo_renderer: scene '%s' cannot be shown again either: %s", shown_->scene.name.c_str(),
                      again.what());
      }
      std::lock_guard<std::mutex> lock(mutex_);
      scene_loading_ = false;
      return;
    }
    const auto end = std::chrono::steady_clock::now();
    const double upload_ms = std::chrono::duration<double, std::milli>(end - start).count();
    const double total_ms = std::chrono::duration<double, std::milli>(end - next->announced).count();
    {
      std::lock_guard<std::mutex> lock(mutex_);
      ++scene_switches_;
      last_switch_ms_ = total_ms;
    }
    NODELET_INFO(
        "stereo_renderer: scene '%s' (load %u) replaces '%s', switched in %.1f ms after its announcement (loading "
        "and building %.1f ms, showing %.1f ms)",
        next->scene.name.c_str(), next->load, shown_->scene.name.c_str(), total_ms, next->prepare_ms, upload_ms);
    shown_ = std::move(next);
  }

  // Replaces everything drawn and every per-scene input by the scene's: objects and their frames, instruments and
  // ghosts, the tissue subscriptions; input frames and meshes stamped before the announcement are dropped (they
  // belong to the previous scene's World). The caller holds render_mutex_ (or the render thread does not run yet).
  void showPreparedScene(const PreparedScene& prepared) {
    showScene(renderer_.get(), prepared.content);
    std::map<std::string, Slot> slots, ghost_slots;
    for (const auto& instrument : prepared.scene.instruments) {
      const std::string slot_name = vrm_sim::scene::toString(instrument.slot);
      slots[slot_name] = makeSlot(instrument, instrumentObjectId(instrument), false);
      // The instructor's instrument in the same slot, replayed (e.g. from a recorded session), translucent.
      if (ghost_instruments_) ghost_slots[slot_name] = makeSlot(instrument, "ghost_" + slot_name, true);
    }
    mesh_frames_.clear();
    scene_poses_.clear();
    for (const vrm_sim::scene::ObjectDescription& object : prepared.scene.objects) {
      scene_poses_[object.name] = object.pose.toIsometry().cast<float>();
    }
    std::set<std::string> objects, streamed;
    for (const SceneContent::Object& object : prepared.content.objects) {
      mesh_frames_[object.drawn.id] = object.in_eye_frame ? eye_frame_ : world_frame_;
      objects.insert(object.drawn.id);
      if (object.streamed) streamed.insert(object.drawn.id);
    }
    frame_in_use_.reset();
    ghosts_in_use_.clear();
    {
      std::lock_guard<std::mutex> lock(mutex_);
      slots_.swap(slots);
      ghost_slots_.swap(ghost_slots);
      scene_objects_.swap(objects);
      pending_meshes_.clear();
      newest_mesh_version_.clear();
      scene_since_ = prepared.since;
      frames_.erase(std::remove_if(frames_.begin(), frames_.end(),
                                   [&](const vrm_msgs::InputFrame::ConstPtr& frame) {
                                     return frame->header.stamp < prepared.since;
                                   }),
                    frames_.end());
      states_.clear();
      state_in_use_.reset();
      ghost_applied_.clear();
      shown_key_ = prepared.key;
      shown_name_ = prepared.scene.name;
      shown_load_ = prepared.load;
      scene_loading_ = false;
      dirty_ = true;
    }
    std::lock_guard<std::mutex> lock(connect_mutex_);
    streamed_objects_.swap(streamed);
    if (subscribed_) subscribeTissue();
  }

  Slot makeSlot(const vrm_sim::scene::InstrumentDescription& instrument, const std::string& id, bool ghost) {
    Slot slot;
    slot.description = instrument;
    slot.object_id = id;
    slot.ghost = ghost;
    showInstrument(&slot, instrument.type, 0.0);
    renderer_->setVisible(id, false);  // until tracked
    return slot;
  }

  // Uploads the slot's mesh for `type` and `jaw_angle` when either changed what is drawn (instrument switching,
  // forceps jaws in whole degrees).
  void showInstrument(Slot* slot, vrm_sim::scene::InstrumentType type, double jaw_angle) {
    const int jaw = vrm_sim::scene::jawStepDeg(type, jaw_angle);
    if (renderer_->hasObject(slot->object_id) && type == slot->shown_type && jaw == slot->shown_jaw_deg) return;
    const vrm_sim::scene::InstrumentDescription shown = vrm_sim::scene::instrumentOfType(slot->description, type);
    const MeshData mesh = toMeshData(vrm_sim::scene::instrumentMesh(shown, jaw));
    renderer_->setStyle(slot->object_id, instrumentStyle(shown, slot->ghost));
    renderer_->updateMesh(slot->object_id, mesh.view(), ++instrument_mesh_version_);
    slot->shown_type = type;
    slot->shown_jaw_deg = jaw;
  }

  // --- inputs (manager threads; mutex_) ---

  void noteStamp(const ros::Time& stamp) {
    if (first_stamp_.isZero() && !stamp.isZero()) first_stamp_ = stamp;
    if (stamp > newest_stamp_) newest_stamp_ = stamp;
    dirty_ = true;
  }

  bool simulationRunning() const {
    return !simulation_wall_.isZero() && (ros::WallTime::now() - simulation_wall_).toSec() < simulation_timeout_;
  }

  // A frame could start for input stamp `stamp`. A frame offered earlier and not yet started is superseded: the
  // render thread always takes the newest, and the replaced one is counted as dropped (while somebody watches).
  void offer(const ros::Time& stamp) {
    if (stamp <= last_offered_) return;
    last_offered_ = stamp;
    ++offered_;
    if (!pending_stamp_.isZero() && watched_) ++dropped_;
    pending_stamp_ = stamp;
    const ros::WallTime now = ros::WallTime::now();
    const double interval = pending_wall_.isZero() ? 0.0 : (now - pending_wall_).toSec();
    if (interval > 0.0 && interval < 0.5)
      offer_interval_ = offer_interval_ > 0.0 ? 0.9 * offer_interval_ + 0.1 * interval : interval;
    pending_wall_ = now;
    if (trigger_ != Trigger::kTimer) wake_.notify_one();
  }

  void onMesh(const std::string& name, const vrm_msgs::TissueMesh::ConstPtr& mesh) {
    std::lock_guard<std::mutex> lock(mutex_);
    // Not the shown scene's: an object it does not have, or a copy the previous scene's World computed (a queued one
    // of a subscription just dropped, a late one).
    if (scene_objects_.count(name) == 0 || (!mesh->header.stamp.isZero() && mesh->header.stamp < scene_since_)) return;
    // A late latched rest shape must not replace a newer deformed version of the same object.
    auto newest = newest_mesh_version_.find(name);
    if (newest != newest_mesh_version_.end() && mesh->version < newest->second) return;
    newest_mesh_version_[name] = mesh->version;
    pending_meshes_[name] = mesh;
    noteStamp(mesh->header.stamp);
  }
  // A frame the simulation closed: kept for the frame of its stamp; with the trigger `input` (or no simulation_state
  // for a while) it starts a frame itself.
  void onInputFrame(const vrm_msgs::InputFrame::ConstPtr& frame) {
    std::lock_guard<std::mutex> lock(mutex_);
    const ros::Time& stamp = frame->header.stamp;
    if (stamp < scene_since_) return;  // the previous scene's World applied it: neither drawn nor a trigger
    if (stamp > newest_frame_stamp_) newest_frame_stamp_ = stamp;
    if (frame->kind == vrm_msgs::InputFrame::KIND_LOAD && stamp > newest_announcement_ &&
        (pending_loads_.empty() || stamp > pending_loads_.back().first)) {
      // Its announcement is still to come: later frames may belong to another scene.
      pending_loads_.emplace_back(stamp, ros::WallTime::now());
    }
    if (frame->kind == vrm_msgs::InputFrame::KIND_FRAME) {
      remember(&frames_, frame);
      noteStamp(stamp);
    }
    // The simulation_state that came first (or, had its frame been lost, the newest frame before it).
    if (!awaited_frame_.isZero() && stamp >= awaited_frame_) {
      offer(awaited_frame_);
      awaited_frame_ = ros::Time();
    }
    if (frame->kind == vrm_msgs::InputFrame::KIND_FRAME && (trigger_ == Trigger::kInput || !simulationRunning())) {
      offer(stamp);
    }
  }
  // The simulation finished the frame of this input stamp (its tissue meshes were published before, so they are
  // already here: one callback queue, in publishing order). Its input frame was published before, too; from another
  // process it may still be on its way, and then the frame starts when it arrives.
  void onSimulationState(const vrm_msgs::SimulationState::ConstPtr& state) {
    std::lock_guard<std::mutex> lock(mutex_);
    simulation_wall_ = ros::WallTime::now();
    const ros::Time& stamp = state->header.stamp;
    if (!simulation_stamps_.empty() && stamp <= simulation_stamps_.back()) return;
    simulation_stamps_.push_back(stamp);
    // The simulation announces a scene it loaded while it handles the LOAD, before it finishes any later frame (in
    // one manager: one callback queue, in publishing order); a later frame done without one means the LOAD was
    // refused and the scene stays.
    while (!pending_loads_.empty() && pending_loads_.front().first < stamp) pending_loads_.pop_front();
    if (stamp >= scene_since_) remember(&states_, state);  // where the scenario has moved objects in this frame
    while (simulation_stamps_.size() > kHistory) simulation_stamps_.pop_front();
    if (trigger_ == Trigger::kInput) return;
    if (stamp > newest_frame_stamp_) {
      awaited_frame_ = stamp;
      return;
    }
    offer(stamp);
  }
  // The instructor's recorded frames, replayed: their applied instruments are shown with the next frame, but their
  // (recorded) stamps do not stamp the frame.
  void onGhostFrame(const vrm_msgs::InputFrame::ConstPtr& frame) {
    if (frame->kind != vrm_msgs::InputFrame::KIND_FRAME) return;
    std::lock_guard<std::mutex> lock(mutex_);
    for (const vrm_msgs::AppliedInstrument& applied : frame->instruments) {
      if (ghost_slots_.count(applied.slot) > 0) ghost_applied_[applied.slot] = applied;
    }
    dirty_ = true;
  }
  // A bag recorded before input frames: its raw instrument states, drawn as if applied.
  void onLegacyGhostState(const vrm_msgs::InstrumentState::ConstPtr& state) {
    NODELET_WARN_ONCE(
        "stereo_renderer: ghost instruments from %s: the instructor's bag predates input frames, so they are drawn "
        "from its raw instrument states (types and validity as recorded, not as the simulation applied them)",
        legacy_ghost_topic_.c_str());
    std::lock_guard<std::mutex> lock(mutex_);
    if (ghost_slots_.count(state->instrument_id) == 0) return;
    ghost_applied_[state->instrument_id] = toAppliedInstrument(*state);
    dirty_ = true;
  }
  void onMicroscope(const vrm_msgs::MicroscopeSettings::ConstPtr& settings) {
    std::lock_guard<std::mutex> lock(mutex_);
    remember(&microscopes_, settings);
    noteStamp(settings->header.stamp);
  }

  void onTimer(const ros::TimerEvent&) {
    std::lock_guard<std::mutex> lock(mutex_);
    if (!dirty_) return;
    timer_due_ = true;
    wake_.notify_one();
  }

  bool onSaveSnapshot(std_srvs::Trigger::Request&, std_srvs::Trigger::Response& response) {
    std::lock_guard<std::mutex> lock(render_mutex_);
    if (last_frame_.images[0].data.empty()) {
      response.message = "no frame rendered yet";
      return true;
    }
    try {
      response.message = saveSnapshot(last_frame_, last_frame_stamp_);
      response.success = true;
    } catch (const std::exception& error) {
      response.message = error.what();
    }
    return true;
  }

  std::string saveSnapshot(const StereoFrame& frame, const ros::Time& stamp) {
    const std::string dir = snapshot_dir_.empty() ? std::string("/tmp") : snapshot_dir_;
    std::filesystem::create_directories(dir);  // throws (-> service message) when it cannot
    char name[64];
    std::snprintf(name, sizeof(name), "/render_%06llu_%u.%09u", static_cast<unsigned long long>(frame_count_),
                  stamp.sec, stamp.nsec);
    savePng(frame.images[0], dir + name + "_left.png");
    if (!frame.images[1].data.empty()) savePng(frame.images[1], dir + name + "_right.png");
    // Issue 33: what the frame was drawn from, so frame_check can re-render it with a pass switched off. The renderer
    // still holds the frame's state (render_mutex_ is held and inputs apply only before the next render).
    RenderState state;
    try {
      state = renderer_->captureState();  // binds the context to this service thread
    } catch (...) {
      StereoRenderer::releaseContext();
      throw;
    }
    StereoRenderer::releaseContext();
    writeRenderState(state, dir + name + ".frame");
    return dir + name;
  }

  // --- the render thread ---

  // Waits for a frame to start (a trigger, the timer, or — event triggers — inputs that changed without a trigger for
  // a while, e.g. only the microscope knobs), then renders it from the newest inputs.
  void renderLoop() {
    pthread_setname_np(pthread_self(), "vrm_render");
    if (render_nice_ > 0) setpriority(PRIO_PROCESS, static_cast<id_t>(syscall(SYS_gettid)), render_nice_);
    const auto idle_refresh = std::chrono::milliseconds(100);
    std::unique_lock<std::mutex> lock(mutex_);
    while (!stop_) {
      const bool triggered = wake_.wait_for(lock, idle_refresh, [this] {
        return stop_ || next_scene_ || (trigger_ == Trigger::kTimer ? timer_due_ : !pending_stamp_.isZero());
      });
      if (stop_) break;
      if (next_scene_) {  // before the frame: a frame after an announcement shows the announced scene
        std::unique_ptr<PreparedScene> next = std::move(next_scene_);
        lock.unlock();
        switchScene(std::move(next));
        lock.lock();
        continue;
      }
      if (!triggered && (trigger_ == Trigger::kTimer || !dirty_ || newest_stamp_ <= last_stamp_)) continue;
      if (triggered && max_rate_ > 0.0 && trigger_ != Trigger::kTimer && !last_frame_wall_.isZero()) {
        // Rate-limited: wait out the minimum frame interval, then take whatever trigger is newest by then.
        const ros::WallTime earliest = last_frame_wall_ + ros::WallDuration(1.0 / max_rate_);
        for (ros::WallTime now = ros::WallTime::now(); !stop_ && now < earliest; now = ros::WallTime::now()) {
          wake_.wait_for(lock, std::chrono::nanoseconds((earliest - now).toNSec()));
        }
        if (stop_) break;
      }
      if (triggered && trigger_ != Trigger::kTimer && max_input_age_ > 0.0 && watched_) {
        // Latency before throughput (thesis §2.5.2, eq. 2.5): a trigger that arrived while the previous frame was
        // rendering is already `age` old. If the next input is due within the tick, that one starts a frame on its
        // arrival instead (the stale trigger counts as dropped); if none comes, the stale one is shown.
        const double age = (ros::WallTime::now() - pending_wall_).toSec();
        if (age > max_input_age_ && offer_interval_ > 0.0 && age < offer_interval_) {
          const ros::Time stale = pending_stamp_;
          wake_.wait_for(lock, std::chrono::duration<double>(1.25 * offer_interval_ - age),
                         [&] { return stop_ || pending_stamp_ != stale; });
          if (stop_) break;
        }
      }
      // Event triggers show the inputs of the triggering stamp; the timer and idle refreshes the newest of all.
      const ros::Time limit = triggered && trigger_ != Trigger::kTimer ? pending_stamp_ : ros::TIME_MAX;
      pending_stamp_ = ros::Time();
      timer_due_ = false;
      lock.unlock();
      renderFrame(limit);
      lock.lock();
    }
  }

  // Collects the inputs up to `limit` (the frame's stamp; TIME_MAX = the newest stamp of any input); false when there
  // is nothing new to show.
  bool takeInputs(const ros::Time& limit, std::map<std::string, vrm_msgs::TissueMesh::ConstPtr>* meshes,
                  ros::Time* stamp, ros::Time* simulation_shown) {
    std::lock_guard<std::mutex> lock(mutex_);
    const bool newest = limit == ros::TIME_MAX;
    *stamp = newest ? newest_stamp_ : limit;
    if (*stamp <= last_stamp_ || (newest && !dirty_)) return false;
    // Inputs of an announced scene wait until it is shown: an image stamped after a LOAD shows the scene that ran then
    // (the old scene's objects with the new World's instruments would be neither).
    if (scene_loading_ && *stamp >= loading_since_) return false;
    if (!pending_loads_.empty() && *stamp >= pending_loads_.front().first) {
      if ((ros::WallTime::now() - pending_loads_.front().second).toSec() < load_hold_limit_) return false;
      NODELET_WARN_THROTTLE(10.0,
                            "stereo_renderer: no announcement and no simulation frame %.1f s after the LOAD at %.3f: "
                            "rendering on in scene '%s'",
                            load_hold_limit_, pending_loads_.front().first.toSec(), shown_name_.c_str());
      pending_loads_.pop_front();
    }
    last_stamp_ = *stamp;
    if (*stamp >= newest_stamp_) dirty_ = false;
    for (auto it = pending_meshes_.begin(); it != pending_meshes_.end();) {
      if (it->second->header.stamp > *stamp) {
        ++it;  // a newer simulation frame's mesh: for the next frame
        continue;
      }
      (*meshes)[it->first] = it->second;
      it = pending_meshes_.erase(it);
    }
    frame_in_use_ = newestUpTo(frames_, *stamp);
    microscope_in_use_ = newestUpTo(microscopes_, *stamp);
    const vrm_msgs::SimulationState::ConstPtr state = newestUpTo(states_, *stamp);
    if (state && state->header.stamp <= *stamp) state_in_use_ = state;
    ghosts_in_use_ = ghost_applied_;
    *simulation_shown = ros::Time();
    for (auto it = simulation_stamps_.rbegin(); it != simulation_stamps_.rend(); ++it) {
      if (*it <= *stamp) {
        *simulation_shown = *it;
        break;
      }
    }
    return true;
  }

  void renderFrame(const ros::Time& limit) {
    std::lock_guard<std::mutex> render_lock(render_mutex_);
    // Render only what somebody sees: with no image subscriber and no snapshot due, the frame is skipped (a headless
    // session keeps its cores for tracking and simulation). Inputs stay as the latest state.
    const bool snapshot_due = snapshotDue();
    if (!snapshot_due && !watched_) return;
    std::map<std::string, vrm_msgs::TissueMesh::ConstPtr> meshes;
    ros::Time stamp, simulation_shown;
    if (!takeInputs(limit, &meshes, &stamp, &simulation_shown)) return;
    last_frame_wall_ = ros::WallTime::now();
    const ros::Time start = ros::Time::now();  // measurement only (render_timing)
    applyInputs(meshes);
    try {
      renderer_->render(&last_frame_);
    } catch (const RenderError& error) {
      NODELET_ERROR_THROTTLE(1.0, "render failed: %s", error.what());
      return;
    }
    const ros::Time end = ros::Time::now();
    ++frame_count_;
    ++frames_since_diagnostics_;
    last_frame_stamp_ = stamp;
    publishFrames(stamp);
    publishEye(0, left_pub_, stamp);
    if (renderer_->options().stereo) publishEye(1, right_pub_, stamp);
    const ros::Time published = ros::Time::now();
    publishTiming(stamp, start, end, published, simulation_shown);
    saveSnapshotIfDue(snapshot_due, stamp);
  }

  // A snapshot is still to be saved and, with ~snapshot_times, its input time has come.
  bool snapshotDue() {
    bool snapshot_due = snapshot_count_ > 0 && !snapshot_dir_.empty() && snapshots_saved_ < snapshot_count_;
    if (snapshot_due && !snapshot_times_.empty()) {
      std::lock_guard<std::mutex> lock(mutex_);
      snapshot_due = !first_stamp_.isZero() && (newest_stamp_ - first_stamp_).toSec() >=
                                                   snapshot_times_[static_cast<std::size_t>(snapshots_saved_)];
    }
    return snapshot_due;
  }

  // The frame's inputs into the renderer: meshes, the eye and the poses, instrument types and jaws, the light pipe,
  // the microscope knobs.
  void applyInputs(const std::map<std::string, vrm_msgs::TissueMesh::ConstPtr>& meshes) {
    for (const auto& entry : meshes) {
      try {
        renderer_->updateMesh(entry.first, toMeshView(*entry.second), entry.second->version);
        mesh_frames_[entry.first] = entry.second->header.frame_id;
      } catch (const RenderError& error) {
        NODELET_ERROR_THROTTLE(1.0, "mesh '%s' rejected: %s", entry.first.c_str(), error.what());
      }
    }
    // The eye as the World applied it (it keeps the last valid rotation while the eye is not tracked).
    const Eigen::Isometry3f world_from_eye =
        frame_in_use_ ? toIsometry(frame_in_use_->eye_pose) : Eigen::Isometry3f::Identity();
    auto frameToWorld = [&](const std::string& frame) {
      return frame == world_frame_ ? Eigen::Isometry3f::Identity() : world_from_eye;
    };
    // Objects the scenario moves (a grasped box, a falling ring) are drawn where it has them: their meshes are built
    // at the scene pose, so they are displaced by (pose now) * (scene pose)^-1 in their frame.
    std::map<std::string, Eigen::Isometry3f> moved;
    if (state_in_use_) {
      for (const vrm_msgs::ObjectPose& object : state_in_use_->objects) {
        const auto scene_pose = scene_poses_.find(object.name);
        if (scene_pose == scene_poses_.end()) continue;
        const Eigen::Isometry3f pose = toIsometry(object.pose);
        if (!pose.matrix().allFinite()) continue;
        moved[object.name] = pose * scene_pose->second.inverse();
      }
    }
    // Each input on its own: a bad one (non-finite pose, unknown type) is skipped, the others still apply.
    for (const auto& entry : mesh_frames_) {
      try {
        const auto displacement = moved.find(entry.first);
        renderer_->setPose(entry.first, displacement == moved.end()
                                            ? frameToWorld(entry.second)
                                            : frameToWorld(entry.second) * displacement->second);
      } catch (const RenderError& error) {
        NODELET_WARN_THROTTLE(1.0, "mesh pose ignored: %s", error.what());
      }
    }
    // Issue 37: the laser burns so far, painted into the fundus (the renderer paints only new ones).
    renderer_->setFundusBurns(state_in_use_ ? toFundusBurns(*state_in_use_) : std::vector<FundusBurn>());
    LightPipe light;
    std::optional<LaserAimSpot> aim;  // in the world frame
    // The slot as applied: the World's type (a switch it refused keeps the old one), its jaw angle, and hidden
    // while it is not valid (untracked, rejected or silent: it does not interact either). nullptr: not in the frame.
    auto applyInstrument = [&](Slot& slot, const vrm_msgs::AppliedInstrument* applied) {
      const bool valid = applied && applied->valid;
      renderer_->setVisible(slot.object_id, valid);
      if (!valid) return;
      const std::optional<vrm_sim::scene::InstrumentType> type = vrm_sim::scene::instrumentTypeNamed(applied->type);
      if (!type) {
        NODELET_WARN_THROTTLE(1.0, "instrument '%s': unknown type '%s', keeping %s", applied->slot.c_str(),
                              applied->type.c_str(), vrm_sim::scene::toString(slot.shown_type));
      }
      try {
        showInstrument(&slot, type.value_or(slot.shown_type), applied->jaw_angle);
        const Eigen::Isometry3f pose =
            frameToWorld(applied->header.frame_id.empty() ? eye_frame_ : applied->header.frame_id) *
            toIsometry(applied->pose);
        renderer_->setPose(slot.object_id, pose);
        if (!slot.ghost && slot.shown_type == vrm_sim::scene::InstrumentType::kLightPipe)
          light = lightPipeAt(pose, endoilluminator());
        if (!slot.ghost && slot.shown_type == vrm_sim::scene::InstrumentType::kLaserProbe) {
          const vrm_sim::scene::InstrumentDescription probe =
              vrm_sim::scene::instrumentOfType(slot.description, slot.shown_type);
          aim = laserAimSpot(probe, world_from_eye.inverse() * pose, shown_->scene.eye.radius);
          if (aim) aim->eye_from_spot = world_from_eye * aim->eye_from_spot;
        }
      } catch (const std::exception& error) {
        renderer_->setVisible(slot.object_id, false);
        NODELET_WARN_THROTTLE(1.0, "instrument '%s' ignored: %s", applied->slot.c_str(), error.what());
      }
    };
    std::map<std::string, const vrm_msgs::AppliedInstrument*> applied;
    if (frame_in_use_) {
      for (const vrm_msgs::AppliedInstrument& instrument : frame_in_use_->instruments)
        applied[instrument.slot] = &instrument;
    }
    for (auto& entry : slots_) {
      const auto found = applied.find(entry.first);
      applyInstrument(entry.second, found == applied.end() ? nullptr : found->second);
    }
    for (auto& entry : ghost_slots_) {
      const auto found = ghosts_in_use_.find(entry.first);
      applyInstrument(entry.second, found == ghosts_in_use_.end() ? nullptr : &found->second);
    }
    renderer_->setLightPipe(light);
    showLaserAim(aim);
    if (microscope_in_use_) {
      try {
        renderer_->setMicroscope(toMicroscopeState(*microscope_in_use_));
      } catch (const RenderError& error) {
        NODELET_WARN_THROTTLE(1.0, "microscope settings ignored: %s", error.what());
      }
    }
  }

  // The aiming beam's spot (issue 37), a small disc re-uploaded only when its size changes by a 10 µm step.
  void showLaserAim(const std::optional<LaserAimSpot>& aim) {
    if (!aim) {
      if (renderer_->hasObject(kLaserAimId)) renderer_->setVisible(kLaserAimId, false);
      return;
    }
    try {
      const auto step = static_cast<std::uint64_t>(std::lround(aim->diameter / 1e-5f));
      if (!renderer_->hasObject(kLaserAimId)) renderer_->setStyle(kLaserAimId, laserAimStyle());
      if (renderer_->version(kLaserAimId) != step + 1) {
        renderer_->updateMesh(
            kLaserAimId, laserAimMesh(static_cast<float>(std::max<std::uint64_t>(step, 1)) * 1e-5f).view(), step + 1);
      }
      renderer_->setPose(kLaserAimId, aim->eye_from_spot);
      renderer_->setVisible(kLaserAimId, true);
    } catch (const RenderError& error) {
      NODELET_WARN_THROTTLE(1.0, "laser aim not drawn: %s", error.what());
    }
  }

  // Snapshots after the images: a PNG takes longer than the frame and must not delay what is watched.
  void saveSnapshotIfDue(bool snapshot_due, const ros::Time& stamp) {
    if (snapshot_due && !snapshot_times_.empty() && frame_in_use_ && snapshots_saved_ < snapshot_count_) {
      // Issue 33: the image shows the World's newest applied frame up to its stamp, which lags the inputs on a loaded
      // machine (a frame at 2.5 s of input time showed the instrument of ~1.5 s, still approaching). A snapshot at t
      // shows the applied state of t: it waits (the snapshot stays due, so the next input renders again) until the
      // applied frame reaches t, at most kSnapshotWaitSec of input time (the session may have ended before t).
      ros::Time first;
      {
        std::lock_guard<std::mutex> lock(mutex_);
        first = first_stamp_;
      }
      const double due = snapshot_times_[static_cast<std::size_t>(snapshots_saved_)];
      if ((frame_in_use_->header.stamp - first).toSec() < due && (stamp - first).toSec() < due + kSnapshotWaitSec) {
        return;
      }
    }
    const bool every_nth = snapshot_times_.empty() && frame_count_ % std::max(1, snapshot_every_) == 0;
    if (snapshot_count_ > 0 && !snapshot_dir_.empty() && snapshots_saved_ < snapshot_count_ &&
        (snapshot_due && !snapshot_times_.empty() ? true : every_nth)) {
      try {
        saveSnapshot(last_frame_, stamp);
        ++snapshots_saved_;
      } catch (const std::exception& error) {
        NODELET_WARN_THROTTLE(5.0, "snapshot failed: %s", error.what());
      }
      if (snapshots_saved_ >= snapshot_count_) {
        snapshots_pending_ = false;
        updateSubscriptions();  // the last one: the inputs stay only for watchers
      }
    }
  }

  std::string opticalFrame(int eye) const { return camera_frame_ + (eye == 0 ? "_left_optical" : "_right_optical"); }

  // world -> objective -> each eye's optical frame, with the frame's stamp (the eye positions follow focus, zoom
  // and the disparity setting).
  void publishFrames(const ros::Time& stamp) {
    std::vector<geometry_msgs::TransformStamped> frames;
    const Eigen::Isometry3f world_from_objective = worldFromObjective(renderer_->rig());
    geometry_msgs::TransformStamped frame;
    frame.header.stamp = stamp;
    frame.header.frame_id = world_frame_;
    frame.child_frame_id = camera_frame_;
    frame.transform = toTransformMsg(world_from_objective);
    frames.push_back(frame);
    for (int eye = 0; eye < (renderer_->options().stereo ? 2 : 1); ++eye) {
      const CameraView camera = renderer_->camera(eye == 0 ? Eye::kLeft : Eye::kRight);
      frame.header.frame_id = camera_frame_;
      frame.child_frame_id = opticalFrame(eye);
      frame.transform = toTransformMsg(world_from_objective.inverse() * worldFromOptical(camera));
      frames.push_back(frame);
    }
    broadcaster_.sendTransform(frames);
  }

  void publishEye(int eye, const image_transport::CameraPublisher& publisher, const ros::Time& stamp) {
    if (publisher.getNumSubscribers() == 0) return;
    const CameraView camera = renderer_->camera(eye == 0 ? Eye::kLeft : Eye::kRight);
    const RgbImage& rgb = last_frame_.images[eye];
    auto image = boost::make_shared<sensor_msgs::Image>();
    image->header.stamp = stamp;
    image->header.frame_id = opticalFrame(eye);
    image->width = rgb.width;
    image->height = rgb.height;
    image->encoding = "rgb8";
    image->step = rgb.width * 3;
    image->data = rgb.data;  // the snapshot service keeps last_frame_, so this is the one copy
    // Tx of the right eye: its offset from the left one (the stereo convention of sensor_msgs/CameraInfo).
    auto info = boost::make_shared<sensor_msgs::CameraInfo>(
        toCameraInfo(camera, renderer_->camera(Eye::kLeft), rgb.width, rgb.height));
    info->header = image->header;
    publisher.publish(image, info);
  }

  void publishTiming(const ros::Time& stamp, const ros::Time& start, const ros::Time& end, const ros::Time& published,
                     const ros::Time& simulation_shown) {
    auto timing = boost::make_shared<vrm_msgs::StageTiming>();
    timing->header.stamp = stamp;
    timing->frame = frame_count_;
    const PassTimings& t = last_frame_.timings;
    ros::Time cursor = start;
    for (const auto& stage :
         {std::make_pair("render_upload", t.ms_upload), std::make_pair("render_shadow", t.ms_shadow),
          std::make_pair("render_scene", t.ms_scene), std::make_pair("render_dof", t.ms_dof),
          std::make_pair("render_readback", t.ms_readback)}) {
      vrm_msgs::StageStamp s;
      s.stage = stage.first;
      s.start = cursor;
      cursor += ros::Duration(stage.second * 1e-3);
      s.end = cursor;
      timing->stages.push_back(s);
    }
    auto add = [&timing](const char* name, const ros::Time& from, const ros::Time& to) {
      vrm_msgs::StageStamp s;
      s.stage = name;
      s.start = from;
      s.end = to;
      timing->stages.push_back(s);
    };
    add("render", start, end);
    // A marker (no duration) for the frames that redrew the static layer (issue 30): its redraw rate in the graph.
    if (t.static_layers_drawn > 0) add("render_static_layer_redrawn", start, start);
    add("image_published", end, published);
    if (!simulation_shown.isZero()) add("simulation_input", simulation_shown, simulation_shown);
    vrm_msgs::publishShared(timing_pub_, timing);
  }

  // Frames, drops and rate of the last period (wall clock: the live health of the view).
  void publishDiagnostics(const ros::WallTimerEvent&) {
    namespace d = diagnostic_msgs;
    const ros::WallTime now = ros::WallTime::now();
    const double period = std::max(1e-3, (now - last_diagnostics_).toSec());
    last_diagnostics_ = now;
    std::uint64_t frames = 0, dropped = 0, offered = 0, dropped_total = 0, scene_switches = 0;
    std::string scene_name;
    std::uint32_t scene_load = 0;
    double last_switch_ms = 0.0;
    {
      std::lock_guard<std::mutex> lock(render_mutex_);
      frames = frames_since_diagnostics_;
      frames_since_diagnostics_ = 0;
    }
    {
      std::lock_guard<std::mutex> lock(mutex_);
      dropped = dropped_ - dropped_reported_;
      offered = offered_ - offered_reported_;
      dropped_reported_ = dropped_;
      offered_reported_ = offered_;
      dropped_total = dropped_;
      scene_name = shown_name_;
      scene_load = shown_load_;
      scene_switches = scene_switches_;
      last_switch_ms = last_switch_ms_;
    }
    d::DiagnosticStatus status;
    status.name = getName() + ": frames";
    status.hardware_id = "stereo_view";
    auto value = [&status](const std::string& key, const std::string& text) {
      d::KeyValue entry;
      entry.key = key;
      entry.value = text;
      status.values.push_back(entry);
    };
    char text[64];
    std::snprintf(text, sizeof(text), "%.3g", frames / period);
    value("fps", text);
    value("frames", std::to_string(frames));
    value("dropped", std::to_string(dropped));
    value("frames offered", std::to_string(offered));
    value("dropped total", std::to_string(dropped_total));
    value("trigger", describeTrigger());
    value("scene", scene_name);
    value("scene load", std::to_string(scene_load));
    value("scene switches", std::to_string(scene_switches));
    std::snprintf(text, sizeof(text), "%.1f", last_switch_ms);
    value("last scene switch ms", text);
    const bool watched = watched_;
    value("watched", watched ? "yes" : "no");
    status.level = d::DiagnosticStatus::OK;
    if (!watched) {
      status.message = "not watched: no frames (snapshots only)";
    } else if (frames == 0 && offered > 0) {
      status.level = d::DiagnosticStatus::WARN;
      status.message = "inputs arrive but no frame was rendered";
    } else {
      std::snprintf(text, sizeof(text), "%.1f fps, %llu dropped", frames / period,
                    static_cast<unsigned long long>(dropped));
      status.message = text;
    }
    auto array = boost::make_shared<d::DiagnosticArray>();
    array->header.stamp = ros::Time::now();
    array->status.push_back(status);
    vrm_msgs::publishShared(diagnostics_pub_, array);
  }

  std::unique_ptr<StereoRenderer> renderer_;
  long long fundus_seed_ = -1;  // ~fundus_seed (< 0: from the scene's name)
  bool ghost_instruments_ = false;
  Trigger trigger_ = Trigger::kSimulation;
  double rate_ = 30.0;
  double max_rate_ = 0.0;
  double max_input_age_ = 0.005;
  int render_nice_ = 10;               // nice value of the render thread and its llvmpipe threads
  std::vector<pid_t> render_threads_;  // llvmpipe's rasteriser threads of this renderer's context
  double simulation_timeout_ = 0.5;
  std::string snapshot_dir_;
  int snapshot_count_ = 0;
  int snapshot_every_ = 10;
  std::vector<double> snapshot_times_;  // s after first_stamp_
  static constexpr double kSnapshotWaitSec = 1.0;
  int snapshots_saved_ = 0;
  std::string world_frame_;
  std::string eye_frame_;
  std::string camera_frame_;
  std::string ghost_topic_;
  std::string legacy_ghost_topic_;
  std::uint64_t instrument_mesh_version_ = 0;

  std::mutex mutex_;  // inputs and triggers
  std::condition_variable wake_;
  bool stop_ = false;
  std::map<std::string, vrm_msgs::TissueMesh::ConstPtr> pending_meshes_;
  std::map<std::string, std::uint64_t> newest_mesh_version_;
  std::map<std::string, Slot> slots_;        // live instruments by slot ("left", "right")
  std::map<std::string, Slot> ghost_slots_;  // replayed ones (with ~ghost_instruments)
  std::set<std::string> scene_objects_;      // of the shown scene: meshes of other objects are dropped
  ros::Time scene_since_;  // the shown scene's announcement stamp: older inputs belong to the previous scene
  vrm_msgs::RunningScene::ConstPtr announced_;          // for the loader thread
  std::chrono::steady_clock::time_point announced_at_;  // when it arrived
  std::condition_variable loader_wake_;
  std::unique_ptr<PreparedScene> next_scene_;  // announced and built, for the render thread to show
  bool scene_loading_ = false;                 // another scene was announced and is not shown yet
  ros::Time loading_since_;                    // its announcement's stamp
  ros::Time newest_announcement_;              // stamp of the newest announcement received
  // LOAD frames whose announcement (or refusal) has not come yet: their stamps and when they came, oldest first.
  std::deque<std::pair<ros::Time, ros::WallTime>> pending_loads_;
  double load_hold_limit_ = 2.0;  // s that frames after such a LOAD wait at most
  SceneKey shown_key_;
  std::string shown_name_;
  std::uint32_t shown_load_ = 0;
  std::uint64_t scene_switches_ = 0;
  double last_switch_ms_ = 0.0;
  std::deque<vrm_msgs::InputFrame::ConstPtr> frames_;  // the newest simulation frames (kind FRAME)
  ros::Time newest_frame_stamp_;                       // of any input frame
  ros::Time awaited_frame_;  // a simulation frame done whose input frame has not arrived yet (zero: none)
  std::map<std::string, vrm_msgs::AppliedInstrument> ghost_applied_;  // newest replayed ones by slot
  std::deque<vrm_msgs::MicroscopeSettings::ConstPtr> microscopes_;
  std::deque<vrm_msgs::SimulationState::ConstPtr> states_;  // the newest simulation frames (object placements)
  std::deque<ros::Time> simulation_stamps_;                 // newest simulation frames
  ros::WallTime simulation_wall_;                           // when the newest simulation_state arrived
  ros::Time first_stamp_;
  ros::Time newest_stamp_;
  bool dirty_ = false;
  ros::Time last_offered_;
  ros::Time pending_stamp_;      // offered, not started yet (zero: none)
  ros::WallTime pending_wall_;   // when the newest trigger arrived
  double offer_interval_ = 0.0;  // s between triggers (running mean): the input tick
  bool timer_due_ = false;
  std::uint64_t offered_ = 0, dropped_ = 0, offered_reported_ = 0, dropped_reported_ = 0;
  std::atomic<bool> watched_{false};

  std::mutex render_mutex_;               // renderer and last frame (render thread, snapshot service)
  std::unique_ptr<PreparedScene> shown_;  // the scene drawn (kept to go back to when a switch fails)
  std::map<std::string, std::string> mesh_frames_;
  vrm_msgs::InputFrame::ConstPtr frame_in_use_;
  std::map<std::string, vrm_msgs::AppliedInstrument> ghosts_in_use_;
  vrm_msgs::MicroscopeSettings::ConstPtr microscope_in_use_;
  vrm_msgs::SimulationState::ConstPtr state_in_use_;
  std::map<std::string, Eigen::Isometry3f> scene_poses_;  // of the shown scene's objects, by name (render thread)
  StereoFrame last_frame_;
  ros::Time last_stamp_;        // of the newest frame taken (written with both mutexes held)
  ros::Time last_frame_stamp_;  // of last_frame_
  ros::WallTime last_frame_wall_;
  std::uint64_t frame_count_ = 0;
  std::uint64_t frames_since_diagnostics_ = 0;
  ros::WallTime last_diagnostics_;

  std::mutex connect_mutex_;                                   // the subscriptions below and the publishers' callbacks
  std::vector<ros::Subscriber> input_subscribers_;             // frames, simulation, microscope, ghosts
  std::map<std::string, ros::Subscriber> tissue_subscribers_;  // by object
  std::set<std::string> streamed_objects_;                     // of the shown scene: tissue/<object> wanted
  ros::Subscriber running_scene_subscriber_;
  bool subscribed_ = false;
  std::atomic<bool> snapshots_pending_{false};
  tf2_ros::TransformBroadcaster broadcaster_;
  image_transport::CameraPublisher left_pub_, right_pub_;
  ros::Publisher timing_pub_, diagnostics_pub_;
  ros::ServiceServer snapshot_srv_;
  ros::Timer timer_;
  ros::WallTimer diagnostic_timer_;
  std::thread thread_;
  std::thread loader_;  // loads and builds announced scenes
};

}  // namespace vrm_render

PLUGINLIB_EXPORT_CLASS(vrm_render::StereoRendererNodelet, nodelet::Nodelet)
