// Tracker (issue 5, thesis §7.3.2): MarkerObservations of the rig's cameras → EyeState and InstrumentState, stamped
// with the cameras' exposure stamp. Input is the detector's output or pre-extracted centroids (the EyeSi FPGA
// path): `<camera>/<markers_topic>`. Frames are assembled by stamp; a frame is reconstructed as soon as every
// camera has reported, or with the cameras that did once a newer stamp is `sync_window` past it (a camera that
// stops costs one frame of latency, not the tracking). Roll, jaw and the other instrument inputs are not optical:
// they come from `instrument_sensors` (the instruments' own channels; in simulation the surgeon's ground truth).
// tf (publish_tf): world → eye (camera stamps), eye → trocar_* (static, from the layout or ~scene), trocar_* →
// instrument_* (camera stamps). In tracking mode this nodelet owns those transforms and vrm_sim's scene_manager must
// run with publish_pose_tf:=false (one publisher per transform); with publish_tf:=false scene_manager broadcasts them
// from the states published here. Optional pose filter (`filter`: none | one_euro | alpha_beta, pose_filter.h).
// Diagnostics (/diagnostics, wall-clock period): frames and cameras per frame, stale cameras, reprojection
// residuals, eye/instrument validity — OK / WARN / ERROR. Per frame, the wall time from reconstruction start to the
// poses published goes to tracking_timing (vrm_msgs/StageTiming, stage "reconstruction", header.stamp = the
// cameras' stamp; its end is "tracking done" for the latency monitor, issue 12).
// Camera dropout (issue 14, camera_watchdog.h): a camera silent for `dropout_timeout` (wall) is missing — WARN
// naming it, the others go on; with none delivering, a watchdog timer at `camera_rate` publishes the last valid
// poses marked invalid (quality 0) — ERROR — until frames return; the frames a returning camera needs until all
// cameras are used again are logged and reported.
// The scene (issue 32): the eye's rotation centre and the trocars come from the scene (the layout's markers stay), at
// start-up from ~scene (name or path; the default scene without one), then from running_scene (vrm_msgs/RunningScene,
// latched by scenario_manager, the one scene owner): an announcement whose (file, difficulty, content_hash) differs
// from the scene in use is loaded and applied at run time — the pose tracker starts afresh with the new geometry, the
// static trocar transforms are sent again. A scene that fails to load is an ERROR naming why, and the old one stays.
// The status on /diagnostics shows what is in use (sceneGeometryValues, tracker_diagnostics.h): "scene" (name),
// "scene_file", "scene_load" (the announcement's load count; "start-up": ~scene before any announcement),
// "eye_centre" (world, m, "x y z"), and per slot "trocar_SLOT" (eye frame, m, "x y z") and "trocar_SLOT_azimuth_deg".

#include <diagnostic_msgs/DiagnosticArray.h>
#include <nodelet/nodelet.h>
#include <ros/ros.h>
#include <tf2_ros/static_transform_broadcaster.h>
#include <tf2_ros/transform_broadcaster.h>
#include <vrm_msgs/EyeState.h>
#include <vrm_msgs/InstrumentState.h>
#include <vrm_msgs/MarkerObservations.h>
#include <vrm_msgs/RunningScene.h>
#include <vrm_msgs/StageTiming.h>
#include <vrm_msgs/publish.h>

#include <boost/make_shared.hpp>
#include <cmath>
#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <pluginlib/class_list_macros.hpp>
#include <set>
#include <string>
#include <vector>

#include "vrm_scene/package_data.h"
#include "vrm_scene/scene_loader.h"
#include "vrm_tracking/camera_watchdog.h"
#include "vrm_tracking/conversions.h"
#include "vrm_tracking/frame_sync.h"
#include "vrm_tracking/pose_tracker.h"
#include "vrm_tracking/scene_trocars.h"
#include "vrm_tracking/tracker_diagnostics.h"

namespace vrm_tracking {

class Tracker : public nodelet::Nodelet {
 private:
  // A set-up that throws after it opened handles (a camera name that is no ROS name makes a topic name throw) closes
  // them first: the manager frees this nodelet's callback queues before it destroys the nodelet (camera_rig_sim.cpp).
  void onInit() override {
    try {
      init();
    } catch (...) {
      closeRosHandles();
      throw;
    }
  }

  // Timers too: a node handle's shutdown() leaves them running, and a timer unregisters from its queue as it goes.
  void closeRosHandles() {
    watchdog_timer_.stop();
    diagnostic_timer_.stop();
    for (ros::Subscriber& sub : marker_subs_) sub.shutdown();
    marker_subs_.clear();
    sensor_sub_.shutdown();
    running_scene_sub_.shutdown();
    for (ros::Publisher* pub : {&eye_pub_, &instrument_pub_, &timing_pub_, &diagnostics_pub_}) pub->shutdown();
  }

  void init() {
    ros::NodeHandle& nh = getNodeHandle();
    ros::NodeHandle& pnh = getPrivateNodeHandle();
    std::string markers_topic;
    pnh.param<std::string>("markers_topic", markers_topic, "markers");
    TrackerConfig config;
    pnh.param("gate_px", config.gate_px, config.gate_px);
    pnh.param("max_radius", config.max_radius, config.max_radius);
    // Issue 43: which blobs make a marker (pose_tracker.h): the consistency thresholds (three cameras, pairs) and the
    // pair prediction gate.
    pnh.param("consistent_px", config.consistent_px, config.consistent_px);
    pnh.param("pair_consistent_px", config.pair_consistent_px, config.pair_consistent_px);
    pnh.param("max_marker_speed", config.max_marker_speed, config.max_marker_speed);
    pnh.param("occlusion_model", config.occlusion_model, config.occlusion_model);
    pnh.param("occlusion_margin_px", config.occlusion_margin_px, config.occlusion_margin_px);
    double sync_window = 0.03;
    pnh.param("sync_window", sync_window, sync_window);
    pnh.param("publish_tf", publish_tf_, false);
    pnh.param<std::string>("world_frame", world_frame_, "world");
    pnh.param<std::string>("eye_frame", eye_frame_, "eye");
    double stale_timeout = 1.0;
    pnh.param("stale_timeout", stale_timeout, stale_timeout);
    double camera_rate = 50.0;  // nominal: the rig's frame rate (the surgeon twin's tick in simulation)
    pnh.param("camera_rate", camera_rate, camera_rate);
    if (!(camera_rate > 0.0)) camera_rate = 50.0;
    CameraWatchdogConfig watchdog_config;
    watchdog_config.period_ns = static_cast<StampNs>(std::llround(1e9 / camera_rate));
    // 0.25 s, not the 3 periods a dedicated camera link would allow: the simulated rig and its detector share a
    // loaded machine and stall for 67-121 ms at times (measured at load 10 on 2 cores), and a hold is not free —
    // the VR part releases whatever the instruments grasp.
    watchdog_config.timeout = 0.25;
    pnh.param("dropout_timeout", watchdog_config.timeout, watchdog_config.timeout);
    double diagnostic_period = 1.0;
    pnh.param("diagnostic_period", diagnostic_period, diagnostic_period);
    std::string filter;
    pnh.param<std::string>("filter", filter, "none");
    pnh.param("filter_min_cutoff", config.filter.min_cutoff, config.filter.min_cutoff);
    pnh.param("filter_beta", config.filter.beta, config.filter.beta);
    pnh.param("filter_d_cutoff", config.filter.d_cutoff, config.filter.d_cutoff);
    pnh.param("filter_alpha", config.filter.alpha, config.filter.alpha);
    pnh.param("filter_beta_ab", config.filter.beta_ab, config.filter.beta_ab);
    // The filters' motion gate (pose_filter.h): the measured per-axis jitter at rest (m; 0: no gate), in σ, the hold.
    pnh.param("filter_noise_sigma", config.filter.noise_sigma, config.filter.noise_sigma);
    pnh.param("filter_gate_sigmas", config.filter.gate_sigmas, config.filter.gate_sigmas);
    pnh.param("filter_motion_hold", config.filter.motion_hold, config.filter.motion_hold);
    try {
      config.filter.type = filterTypeFromString(filter);
      config_ = config;
      tracker_ = std::make_unique<PoseTracker>(loadRig(pnh), loadLayout(pnh), config);
    } catch (const std::exception& e) {
      NODELET_FATAL("tracker: %s", e.what());
      throw;
    }
    const CameraRig& rig = tracker_->rig();
    watchdog_ = std::make_unique<CameraWatchdog>(rig.size(), watchdog_config);
    sync_ = std::make_unique<FrameSynchronizer>(rig.size(), ros::Duration(sync_window).toNSec());
    std::vector<std::string> names;
    for (const CameraModel& camera : rig.cameras) names.push_back(camera.name);
    diagnostics_ = std::make_unique<TrackerDiagnostics>(names, stale_timeout, ros::WallTime::now().toSec());

    eye_pub_ = nh.advertise<vrm_msgs::EyeState>("eye_state", 10);
    instrument_pub_ = nh.advertise<vrm_msgs::InstrumentState>("instrument_state", 20);
    sensor_sub_ = nh.subscribe("instrument_sensors", 20, &Tracker::onSensors, this);
    timing_pub_ = nh.advertise<vrm_msgs::StageTiming>("tracking_timing", 10);
    diagnostics_pub_ = nh.advertise<diagnostic_msgs::DiagnosticArray>("/diagnostics", 10);
    diagnostic_timer_ = nh.createWallTimer(ros::WallDuration(diagnostic_period), &Tracker::onDiagnosticTick, this);
    watchdog_timer_ = nh.createWallTimer(ros::WallDuration(1.0 / camera_rate), &Tracker::onWatchdogTick, this);
    for (std::size_t c = 0; c < rig.size(); ++c) {
      const std::string topic = rig.cameras[c].name + "/" + markers_topic;
      try {
        marker_subs_.push_back(nh.subscribe<vrm_msgs::MarkerObservations>(
            topic, 10, [this, c](const vrm_msgs::MarkerObservations::ConstPtr& msg) { onMarkers(c, msg); }));
      } catch (const ros::InvalidNameException& e) {
        NODELET_FATAL("tracker: camera %zu of the rig: %s", c, e.what());
        throw;
      }
    }
    if (publish_tf_) static_broadcaster_.sendTransform(trocarTransforms(tracker_->layout(), eye_frame_));
    NODELET_INFO("tracker: %zu cameras (%s), %zu instruments, tf %s, filter %s, dropout after %.0f ms", rig.size(),
                 markers_topic.c_str(), tracker_->layout().instruments.size(),
                 publish_tf_ ? "on" : "off (scene_manager broadcasts)", toString(config.filter.type).c_str(),
                 1e3 * watchdog_config.timeout);
    // Latched: the scene that runs now arrives however late this nodelet starts. Last: its callback replaces
    // tracker_, which the lines above read on this (the manager's loader) thread.
    running_scene_sub_ = nh.subscribe("running_scene", 1, &Tracker::onRunningScene, this);
  }

  CameraRig loadRig(const ros::NodeHandle& pnh) {
    std::string rig_file;
    pnh.param<std::string>("rig_file", rig_file, "");
    return rig_file.empty() ? makeDefaultRig() : loadRigYaml(rig_file);
  }

  // The layout's markers with the eye centre and trocars of ~scene (name or path), or of the default scene.
  MarkerLayout loadLayout(const ros::NodeHandle& pnh) {
    std::string layout_file, scene_param;
    pnh.param<std::string>("layout_file", layout_file, "");
    pnh.param<std::string>("scene", scene_param, "");
    layout_ = layout_file.empty() ? makeDefaultLayout() : loadLayoutYaml(layout_file);
    vrm_sim::usePackageData();  // a scene name means vrm_sim's shipped scene
    const vrm_sim::scene::SceneDescription scene = vrm_sim::scene::loadScene(sceneOrDefault(scene_param));
    MarkerLayout layout = layout_;
    const Eigen::Vector3d layout_centre = applyScene(scene, &layout);
    scene_ = sceneIdentity(scene);
    scene_load_ = "start-up";
    logSceneGeometry(scene, layout, layout_centre, scene_param.empty() ? ", the default: no ~scene given" : "");
    return layout;
  }

  void logSceneGeometry(const vrm_sim::scene::SceneDescription& scene, const MarkerLayout& layout,
                        const Eigen::Vector3d& layout_centre, const std::string& why) {
    NODELET_INFO("tracker: eye centre and trocars from scene '%s' (%s%s)", scene.name.c_str(),
                 scene.source_file.c_str(), why.c_str());
    const Eigen::Vector3d& c = layout.rotation_center;
    if ((c - layout_centre).norm() > 0.0) {
      NODELET_INFO(
          "tracker: eye rotation centre at [%.6f, %.6f, %.6f] m (world), the scene's, not the layout's "
          "[%.6f, %.6f, %.6f]",
          c.x(), c.y(), c.z(), layout_centre.x(), layout_centre.y(), layout_centre.z());
    } else {
      NODELET_INFO("tracker: eye rotation centre at [%.6f, %.6f, %.6f] m (world)", c.x(), c.y(), c.z());
    }
    for (const InstrumentMarker& m : layout.instruments) {
      NODELET_INFO("tracker: trocar %s at [%.6f, %.6f, %.6f] m (eye frame)", m.slot.c_str(), m.trocar.x(), m.trocar.y(),
                   m.trocar.z());
    }
  }

  // The scene owner announced the running scene: follow it unless it is the one in use. Loading (meshes included)
  // happens outside the lock, so frames keep being reconstructed meanwhile; the switch itself is one locked swap.
  void onRunningScene(const vrm_msgs::RunningScene::ConstPtr& msg) {
    SceneIdentity announced{msg->name, msg->file, msg->difficulty, msg->content_hash};
    {
      std::lock_guard<std::mutex> lock(mutex_);
      if (sameScene(announced, scene_)) {
        scene_load_ = std::to_string(msg->load);
        NODELET_INFO("tracker: running scene '%s' (load %u) is the one in use", msg->name.c_str(), msg->load);
        return;
      }
    }
    vrm_sim::scene::SceneDescription scene;
    MarkerLayout layout = layout_;  // the markers as configured; only the scene's geometry changes
    Eigen::Vector3d layout_centre;
    try {
      scene = vrm_sim::scene::loadScene(msg->file, msg->difficulty);
      layout_centre = applyScene(scene, &layout);
    } catch (const std::exception& e) {
      std::lock_guard<std::mutex> lock(mutex_);
      NODELET_ERROR("tracker: cannot follow running scene '%s' (load %u, %s): %s; keeping scene '%s'",
                    msg->name.c_str(), msg->load, msg->file.c_str(), e.what(), scene_.name.c_str());
      return;
    }
    std::lock_guard<std::mutex> lock(mutex_);
    // The held poses and filter states belong to the old geometry: the new tracker starts from the new scene's rest.
    tracker_ = std::make_unique<PoseTracker>(tracker_->rig(), layout, config_);
    scene_ = sceneIdentity(scene);
    scene_load_ = std::to_string(msg->load);
    if (publish_tf_) static_broadcaster_.sendTransform(trocarTransforms(tracker_->layout(), eye_frame_));
    logSceneGeometry(scene, layout, layout_centre, ", running_scene load " + std::to_string(msg->load));
    publishDiagnosticsLocked(ros::WallTime::now());  // the new geometry now, not at the next period
  }

  void onSensors(const vrm_msgs::InstrumentState::ConstPtr& msg) {
    std::lock_guard<std::mutex> lock(mutex_);
    sensors_[msg->instrument_id] = msg;
  }

  void onMarkers(std::size_t camera, const vrm_msgs::MarkerObservations::ConstPtr& msg) {
    std::lock_guard<std::mutex> lock(mutex_);
    const ros::WallTime now = ros::WallTime::now();
    const StampNs stamp = toStampNs(msg->header.stamp);
    watchdog_->onCameraFrame(camera, stamp, now.toSec());
    diagnostics_->onCameraMarkers(camera, now.toSec());
    std::vector<SyncedFrame> ready;
    switch (sync_->add(camera, stamp, msg->header.seq, fromMsg(*msg), &ready)) {
      case FrameSynchronizer::Verdict::kDuringHold:
        NODELET_INFO_THROTTLE(1.0,
                              "tracker: %s frame at %.3f exposed during the hold; dropped (outputs stay "
                              "monotonic)",
                              tracker_->rig().cameras[camera].name.c_str(), msg->header.stamp.toSec());
        return;
      case FrameSynchronizer::Verdict::kLate:
        NODELET_WARN_THROTTLE(2.0, "tracker: %s frame at %.3f arrived after its frame was reconstructed; dropped",
                              tracker_->rig().cameras[camera].name.c_str(), msg->header.stamp.toSec());
        return;
      case FrameSynchronizer::Verdict::kAccepted:
        break;
    }
    if (holding_) {
      holding_ = false;
      NODELET_WARN("tracker: camera frames again after %.2f s; %zu frames held", (now - hold_start_).toSec(),
                   hold_frames_);
    }
    for (const SyncedFrame& frame : ready) reconstruct(frame);
  }

  void reconstruct(const SyncedFrame& frame) {
    const ros::Time start = ros::Time::now();  // measurement only (tracking_timing)
    std_msgs::Header header;
    header.seq = frame.seq;
    header.stamp = toRosTime(frame.stamp);
    header.frame_id = world_frame_;
    const std::size_t n = tracker_->rig().size();
    if (frame.cameras.size() < n) {
      NODELET_WARN_THROTTLE(5.0, "tracker: frame %.3f with %zu of %zu cameras (%s)%s", header.stamp.toSec(),
                            frame.cameras.size(), n,
                            diagnostics_->whyMissing(frame, ros::WallTime::now().toSec(), *sync_).c_str(),
                            frame.cameras.size() < 2 ? "; no reconstruction possible" : "; continuing");
    }
    const TrackingResult result = tracker_->update(frame.observations(), header.stamp.toSec());
    diagnostics_->onFrame(frame, result);
    publishResult(header, result, true);
    watchdog_->onFrameReconstructed(frame.stamp, frame.cameras.size());
    reportRecoveries();
    auto timing = boost::make_shared<vrm_msgs::StageTiming>();
    timing->header.stamp = header.stamp;
    timing->frame = header.seq;
    vrm_msgs::StageStamp stage;
    stage.stage = "reconstruction";
    stage.start = start;
    stage.end = ros::Time::now();
    timing->stages.push_back(stage);
    vrm_msgs::publishShared(timing_pub_, timing);
  }

  // eye_state, one instrument_state per layout instrument, and (measured poses only) tf.
  void publishResult(const std_msgs::Header& header, const TrackingResult& result, bool measured) {
    auto eye = boost::make_shared<vrm_msgs::EyeState>();
    eye->header = header;
    toMsg(result.eye, eye.get());
    vrm_msgs::publishShared(eye_pub_, eye);
    if (!result.eye.valid && measured) {
      NODELET_WARN_THROTTLE(5.0, "tracker: eye markers not reconstructed; holding the rotation");
    }

    std::vector<geometry_msgs::TransformStamped> frames;
    if (publish_tf_ && result.eye.valid) {
      geometry_msgs::TransformStamped t;
      t.header = header;
      t.child_frame_id = eye_frame_;
      t.transform.translation = toVector3Msg(result.eye.rotation_center);
      t.transform.rotation = eye->rotation;
      frames.push_back(t);
    }
    for (const InstrumentEstimate& est : result.instruments) {
      auto msg = boost::make_shared<vrm_msgs::InstrumentState>();
      msg->header = header;
      msg->header.frame_id = eye_frame_;
      const auto sensor = sensors_.find(est.slot);
      toMsg(est, sensor == sensors_.end() ? nullptr : sensor->second.get(), msg.get());
      if (publish_tf_ && est.valid) {
        // Below its trocar: the trocar frame is the eye frame shifted to the insertion hole (no rotation).
        geometry_msgs::TransformStamped t;
        t.header = msg->header;
        t.header.frame_id = "trocar_" + est.slot;
        t.child_frame_id = "instrument_" + est.slot;
        t.transform.translation = toVector3Msg(est.tip - est.trocar);
        t.transform.rotation = msg->tip_pose.orientation;
        frames.push_back(t);
      }
      if (measured) reportLost(est, result);
      vrm_msgs::publishShared(instrument_pub_, msg);
    }
    if (!frames.empty()) broadcaster_.sendTransform(frames);
  }

  void reportLost(const InstrumentEstimate& est, const TrackingResult& result) {
    if (est.valid) {
      ever_seen_.insert(est.slot);
    } else if (!ever_seen_.count(est.slot)) {
      // Never seen since the start: not inserted (a session may use one instrument only) — no fault, said once.
      if (announced_unseen_.insert(est.slot).second) {
        NODELET_INFO("tracker: instrument '%s' not in view yet (not inserted, or outside the cameras' view)",
                     est.slot.c_str());
      }
    } else {
      // Lost after it was tracked. Why: its tip marker needs two cameras (thesis §7.3.2); say in how many it was.
      const InstrumentMarker* marker = tracker_->layout().findSlot(est.slot);
      int seen_by = 0;
      for (const MarkerEstimate& m : result.markers) {
        if (marker && m.class_id == marker->class_id) seen_by = m.cameras;
      }
      NODELET_WARN_THROTTLE(5.0,
                            "tracker: instrument '%s' lost (its tip marker in %d camera(s) of this frame, 2 "
                            "needed: occluded, withdrawn, or cameras missing from the frame); holding its last pose",
                            est.slot.c_str(), seen_by);
    }
  }

  // No camera frame for dropout_timeout (wall): publish the last valid poses, marked invalid with quality 0, once
  // per camera period. The VR part closes a frame per input stamp: without these it would stop stepping and the
  // view and tissue would freeze; with valid=false it keeps the instruments where they were and stops their
  // interaction (no grasp or cut with a stale pose). Stamps continue the cameras' (the last exposure stamp
  // advanced by the elapsed wall time, on the camera period grid) instead of the wall clock: the VR part's inputs
  // stay monotonic on one time base, and a replay of the recorded eye_state/instrument_state — held frames
  // included — steps the same frames and stays deterministic.
  void onWatchdogTick(const ros::WallTimerEvent&) {
    std::lock_guard<std::mutex> lock(mutex_);
    const ros::WallTime now = ros::WallTime::now();
    if (!watchdog_->holding(now.toSec())) return;
    if (!holding_) {
      // The frames still assembling can no longer complete: reconstruct them with what they have, first.
      for (const SyncedFrame& frame : sync_->flushAll()) reconstruct(frame);
      holding_ = true;
      hold_start_ = now;
      hold_frames_ = 0;
      NODELET_ERROR("tracker: no camera frame for %.0f ms: holding the last poses, marked invalid",
                    1e3 * watchdog_->silence(now.toSec()));
      publishDiagnosticsLocked(now);  // the ERROR now, not at the next period
    }
    const std::optional<StampNs> next = watchdog_->nextHoldStamp(now.toSec());
    if (!next) return;
    std_msgs::Header header;
    header.stamp = toRosTime(*next);
    header.frame_id = world_frame_;
    // No observations: the core returns the held eye rotation and instrument poses, all invalid, quality 0.
    const TrackingResult held = tracker_->update({}, header.stamp.toSec());
    publishResult(header, held, false);
    watchdog_->onHeldFrame(*next);
    sync_->onHeldFrame(*next);
    diagnostics_->onHeldFrame();
    ++hold_frames_;
  }

  void reportRecoveries() {
    const std::vector<CameraRecovery>& all = watchdog_->recoveries();
    for (; reported_recoveries_ < all.size(); ++reported_recoveries_) {
      const CameraRecovery& r = all[reported_recoveries_];
      diagnostics_->onRecovery(r);
      NODELET_INFO("tracker: %s back after %.2f s silent; all cameras used again after %d frame(s)",
                   tracker_->rig().cameras[r.camera].name.c_str(), r.silent_s, r.frames);
    }
  }

  // One status per period (and one when a hold starts); counters cover the period since the last one.
  void onDiagnosticTick(const ros::WallTimerEvent&) {
    std::lock_guard<std::mutex> lock(mutex_);
    publishDiagnosticsLocked(ros::WallTime::now());
  }

  void publishDiagnosticsLocked(const ros::WallTime& now) {
    diagnostic_msgs::DiagnosticStatus status;
    DiagnosticReport report = diagnostics_->report(now.toSec(), *watchdog_);
    for (auto& value : sceneGeometryValues(scene_.name, tracker_->layout())) report.values.push_back(std::move(value));
    report.values.emplace_back("scene_file", scene_.file);
    report.values.emplace_back("scene_load", scene_load_);
    toMsg(report, &status);
    status.name = getName() + ": pose reconstruction";
    status.hardware_id = "tracking_rig";
    auto array = boost::make_shared<diagnostic_msgs::DiagnosticArray>();
    array->header.stamp = ros::Time::now();  // diagnostics are about the wall-clock health, not a camera frame
    array->status.push_back(status);
    vrm_msgs::publishShared(diagnostics_pub_, array);
  }

  TrackerConfig config_;
  MarkerLayout layout_;  // as configured (layout_file), before any scene's geometry
  std::unique_ptr<PoseTracker> tracker_;
  std::unique_ptr<CameraWatchdog> watchdog_;
  std::unique_ptr<FrameSynchronizer> sync_;
  std::unique_ptr<TrackerDiagnostics> diagnostics_;
  std::mutex mutex_;        // guards tracker_ and everything below that the callbacks touch
  SceneIdentity scene_;     // the scene whose geometry tracker_ uses
  std::string scene_load_;  // the running_scene load it came with, for the status
  std::map<std::string, vrm_msgs::InstrumentState::ConstPtr> sensors_;
  std::set<std::string> ever_seen_, announced_unseen_;  // instrument slots tracked at least once / said "not yet"
  bool holding_ = false;
  ros::WallTime hold_start_;
  std::size_t hold_frames_ = 0;
  std::size_t reported_recoveries_ = 0;
  bool publish_tf_ = false;
  std::string world_frame_, eye_frame_;
  std::vector<ros::Subscriber> marker_subs_;
  ros::Subscriber sensor_sub_, running_scene_sub_;
  ros::Publisher eye_pub_, instrument_pub_, timing_pub_, diagnostics_pub_;
  ros::WallTimer watchdog_timer_, diagnostic_timer_;
  tf2_ros::TransformBroadcaster broadcaster_;
  tf2_ros::StaticTransformBroadcaster static_broadcaster_;
};

}  // namespace vrm_tracking

PLUGINLIB_EXPORT_CLASS(vrm_tracking::Tracker, nodelet::Nodelet)
