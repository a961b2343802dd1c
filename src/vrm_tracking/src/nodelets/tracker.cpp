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

#include <diagnostic_msgs/DiagnosticArray.h>
#include <geometry_msgs/TransformStamped.h>
#include <nodelet/nodelet.h>
#include <ros/ros.h>
#include <tf2_ros/static_transform_broadcaster.h>
#include <tf2_ros/transform_broadcaster.h>
#include <vrm_msgs/EyeState.h>
#include <vrm_msgs/InstrumentState.h>
#include <vrm_msgs/MarkerObservations.h>
#include <vrm_msgs/StageTiming.h>
#include <vrm_msgs/publish.h>

#include <algorithm>
#include <boost/make_shared.hpp>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <pluginlib/class_list_macros.hpp>
#include <set>
#include <string>
#include <vector>

#include "vrm_sim/package_data.h"
#include "vrm_tracking/camera_watchdog.h"
#include "vrm_tracking/conversions.h"
#include "vrm_tracking/pose_tracker.h"
#include "vrm_tracking/scene_trocars.h"

namespace vrm_tracking {

class Tracker : public nodelet::Nodelet {
 private:
  struct Pending {
    std_msgs::Header header;
    std::map<std::size_t, CameraObservations> cameras;
  };

  void onInit() override {
    ros::NodeHandle& nh = getNodeHandle();
    ros::NodeHandle& pnh = getPrivateNodeHandle();
    std::string rig_file, layout_file, markers_topic;
    pnh.param<std::string>("rig_file", rig_file, "");
    pnh.param<std::string>("layout_file", layout_file, "");
    std::string scene_spec;  // optional: the scene whose trocars override the layout's (name or path)
    pnh.param<std::string>("scene", scene_spec, "");
    vrm_sim::usePackageData();  // a scene name means vrm_sim's shipped scene
    pnh.param<std::string>("markers_topic", markers_topic, "markers");
    TrackerConfig config;
    pnh.param("gate_px", config.gate_px, config.gate_px);
    pnh.param("max_radius", config.max_radius, config.max_radius);
    pnh.param("sync_window", sync_window_, 0.03);
    pnh.param("publish_tf", publish_tf_, false);
    pnh.param<std::string>("world_frame", world_frame_, "world");
    pnh.param<std::string>("eye_frame", eye_frame_, "eye");
    pnh.param("stale_timeout", stale_timeout_, 1.0);
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
    try {
      config.filter.type = filterTypeFromString(filter);
      CameraRig rig = rig_file.empty() ? makeDefaultRig() : loadRigYaml(rig_file);
      MarkerLayout layout = layout_file.empty() ? makeDefaultLayout() : loadLayoutYaml(layout_file);
      if (!scene_spec.empty()) {
        const vrm_sim::scene::SceneDescription scene = loadSceneSpec(scene_spec);
        applySceneTrocars(scene, &layout);
        NODELET_INFO("tracker: trocars from scene '%s' (%s), overriding the layout's", scene.name.c_str(),
                     scene.source_file.c_str());
      } else {
        NODELET_INFO("tracker: trocars from the marker layout (no ~scene given)");
      }
      for (const InstrumentMarker& m : layout.instruments) {
        NODELET_INFO("tracker: trocar %s at [%.6f, %.6f, %.6f] m (eye frame)", m.slot.c_str(), m.trocar.x(),
                     m.trocar.y(), m.trocar.z());
      }
      tracker_ = std::make_unique<PoseTracker>(rig, layout, config);
      watchdog_ = std::make_unique<CameraWatchdog>(rig.size(), watchdog_config);
    } catch (const std::exception& e) {
      NODELET_FATAL("tracker: %s", e.what());
      throw;
    }
    eye_pub_ = nh.advertise<vrm_msgs::EyeState>("eye_state", 10);
    instrument_pub_ = nh.advertise<vrm_msgs::InstrumentState>("instrument_state", 20);
    sensor_sub_ = nh.subscribe("instrument_sensors", 20, &Tracker::onSensors, this);
    timing_pub_ = nh.advertise<vrm_msgs::StageTiming>("tracking_timing", 10);
    const CameraRig& rig = tracker_->rig();
    last_seen_.assign(rig.size(), ros::Time());
    last_wall_.assign(rig.size(), ros::WallTime());
    diag_missing_.assign(rig.size(), 0);
    late_frames_.assign(rig.size(), 0);
    diagnostics_pub_ = nh.advertise<diagnostic_msgs::DiagnosticArray>("/diagnostics", 10);
    diagnostic_timer_ = nh.createWallTimer(ros::WallDuration(diagnostic_period), &Tracker::publishDiagnostics, this);
    start_wall_ = last_diag_wall_ = ros::WallTime::now();
    watchdog_timer_ = nh.createWallTimer(ros::WallDuration(1.0 / camera_rate), &Tracker::onWatchdogTick, this);
    for (std::size_t c = 0; c < rig.size(); ++c) {
      const std::string topic = rig.cameras[c].name + "/" + markers_topic;
      marker_subs_.push_back(nh.subscribe<vrm_msgs::MarkerObservations>(
          topic, 10, [this, c](const vrm_msgs::MarkerObservations::ConstPtr& msg) { onMarkers(c, msg); }));
    }
    if (publish_tf_) {
      std::vector<geometry_msgs::TransformStamped> trocars;
      for (const InstrumentMarker& m : tracker_->layout().instruments) {
        geometry_msgs::TransformStamped t;
        t.header.frame_id = eye_frame_;
        t.child_frame_id = "trocar_" + m.slot;
        t.transform.translation = toVector3Msg(m.trocar);
        t.transform.rotation.w = 1.0;
        trocars.push_back(t);
      }
      static_broadcaster_.sendTransform(trocars);
    }
    NODELET_INFO("tracker: %zu cameras (%s), %zu instruments, tf %s, filter %s, dropout after %.0f ms", rig.size(),
                 markers_topic.c_str(), tracker_->layout().instruments.size(),
                 publish_tf_ ? "on" : "off (scene_manager broadcasts)", toString(config.filter.type).c_str(),
                 1e3 * watchdog_config.timeout);
  }

  void onSensors(const vrm_msgs::InstrumentState::ConstPtr& msg) {
    std::lock_guard<std::mutex> lock(mutex_);
    sensors_[msg->instrument_id] = msg;
  }

  void onMarkers(std::size_t camera, const vrm_msgs::MarkerObservations::ConstPtr& msg) {
    std::lock_guard<std::mutex> lock(mutex_);
    const ros::Time stamp = msg->header.stamp;
    const ros::WallTime now = ros::WallTime::now();
    watchdog_->onCameraFrame(camera, static_cast<StampNs>(stamp.toNSec()), now.toSec());
    last_seen_[camera] = stamp;
    last_wall_[camera] = now;
    if (!last_held_.isZero() && stamp <= last_held_) {
      NODELET_INFO_THROTTLE(1.0, "tracker: %s frame at %.3f exposed during the hold; dropped (outputs stay monotonic)",
                            tracker_->rig().cameras[camera].name.c_str(), stamp.toSec());
      return;
    }
    if (!last_processed_.isZero() && stamp <= last_processed_) {
      ++late_frames_[camera];
      NODELET_WARN_THROTTLE(2.0, "tracker: %s frame at %.3f arrived after its frame was reconstructed; dropped",
                            tracker_->rig().cameras[camera].name.c_str(), stamp.toSec());
      return;
    }
    if (holding_) endHold(now);
    Pending& frame = pending_[stamp];
    frame.header = msg->header;
    frame.header.frame_id = world_frame_;
    frame.cameras[camera] = CameraObservations{camera, fromMsg(*msg)};

    // Older frames that can no longer complete: reconstruct them with the cameras they have, in stamp order.
    const ros::Duration window(sync_window_);
    while (!pending_.empty() && pending_.begin()->first + window < stamp) flush(pending_.begin());
    const auto it = pending_.find(stamp);
    if (it != pending_.end() && it->second.cameras.size() == tracker_->rig().size()) {
      while (pending_.begin() != it) flush(pending_.begin());
      flush(it);
    }
  }

  void flush(std::map<ros::Time, Pending>::iterator it) {
    const ros::Time start = ros::Time::now();  // measurement only (tracking_timing)
    Pending frame = std::move(it->second);
    pending_.erase(it);
    last_processed_ = frame.header.stamp;
    const std::size_t n = tracker_->rig().size();
    if (frame.cameras.size() < n) {
      NODELET_WARN_THROTTLE(5.0, "tracker: frame %.3f with %zu of %zu cameras (%s)%s", frame.header.stamp.toSec(),
                            frame.cameras.size(), n, whyMissing(frame).c_str(),
                            frame.cameras.size() < 2 ? "; no reconstruction possible" : "; continuing");
    }
    std::vector<CameraObservations> observations;
    for (auto& entry : frame.cameras) observations.push_back(std::move(entry.second));
    const TrackingResult result = tracker_->update(observations, frame.header.stamp.toSec());
    accumulateDiagnostics(frame, result);
    publishResult(frame.header, result, true);
    watchdog_->onFrameReconstructed(static_cast<StampNs>(frame.header.stamp.toNSec()), frame.cameras.size());
    reportRecoveries();
    const ros::Time end = ros::Time::now();
    auto timing = boost::make_shared<vrm_msgs::StageTiming>();
    timing->header.stamp = frame.header.stamp;
    timing->frame = frame.header.seq;
    vrm_msgs::StageStamp stage;
    stage.stage = "reconstruction";
    stage.start = start;
    stage.end = end;
    timing->stages.push_back(stage);
    vrm_msgs::publishShared(timing_pub_, timing);
  }

  // Why a camera is missing from a frame, so the warning tells a fault from load (issue 20): a camera whose frames have
  // come after their frame was already reconstructed is late — its detection runs behind the cameras, as on a
  // saturated CPU (the rig twin renders three cameras and the detector analyses them on the manager's worker
  // threads); one silent for longer than a few frames dropped out; otherwise its frame missed the sync window.
  std::string whyMissing(const Pending& frame) const {
    std::string why;
    const ros::WallTime now = ros::WallTime::now();
    for (std::size_t c = 0; c < tracker_->rig().size(); ++c) {
      if (frame.cameras.count(c)) continue;
      const std::string& name = tracker_->rig().cameras[c].name;
      char reason[200];
      const double silent = last_wall_[c].isZero() ? -1.0 : (now - last_wall_[c]).toSec();
      if (last_wall_[c].isZero()) {
        std::snprintf(reason, sizeof reason, "%s: no frame yet", name.c_str());
      } else if (silent > 0.2) {
        std::snprintf(reason, sizeof reason, "%s: silent for %.1f s, the camera dropped out", name.c_str(), silent);
      } else if (late_frames_[c] > 0) {
        std::snprintf(reason, sizeof reason,
                      "%s: late, %zu of its frames came after the %.0f ms sync window so far: its detection runs "
                      "behind, e.g. on a saturated CPU",
                      name.c_str(), late_frames_[c], 1e3 * sync_window_);
      } else {
        std::snprintf(reason, sizeof reason, "%s: no frame within the %.0f ms sync window", name.c_str(),
                      1e3 * sync_window_);
      }
      why += (why.empty() ? "" : "; ") + std::string(reason);
    }
    return why;
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
      if (est.valid) ever_seen_.insert(est.slot);
      if (!est.valid && measured && !ever_seen_.count(est.slot)) {
        // Never seen since the start: not inserted (a session may use one instrument only) — no fault, said once.
        if (announced_unseen_.insert(est.slot).second) {
          NODELET_INFO("tracker: instrument '%s' not in view yet (not inserted, or outside the cameras' view)",
                       est.slot.c_str());
        }
      } else if (!est.valid && measured) {
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
      vrm_msgs::publishShared(instrument_pub_, msg);
    }
    if (!frames.empty()) broadcaster_.sendTransform(frames);
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
      while (!pending_.empty()) flush(pending_.begin());
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
    header.stamp.fromNSec(static_cast<std::uint64_t>(*next));
    header.frame_id = world_frame_;
    // No observations: the core returns the held eye rotation and instrument poses, all invalid, quality 0.
    const TrackingResult held = tracker_->update({}, header.stamp.toSec());
    publishResult(header, held, false);
    watchdog_->onHeldFrame(*next);
    last_held_ = header.stamp;
    ++hold_frames_;
    ++diag_held_;
  }

  void endHold(const ros::WallTime& now) {
    holding_ = false;
    NODELET_WARN("tracker: camera frames again after %.2f s; %zu frames held", (now - hold_start_).toSec(),
                 hold_frames_);
  }

  void reportRecoveries() {
    const std::vector<CameraRecovery>& all = watchdog_->recoveries();
    for (; reported_recoveries_ < all.size(); ++reported_recoveries_) {
      const CameraRecovery& r = all[reported_recoveries_];
      const std::string& name = tracker_->rig().cameras[r.camera].name;
      char text[128];
      std::snprintf(text, sizeof(text), "%d frame(s) after %.2f s silent (back at %.3f)", r.frames, r.silent_s,
                    1e-9 * static_cast<double>(r.returned));
      last_recovery_[r.camera] = text;
      NODELET_INFO("tracker: %s back after %.2f s silent; all cameras used again after %d frame(s)", name.c_str(),
                   r.silent_s, r.frames);
    }
  }

  void accumulateDiagnostics(const Pending& frame, const TrackingResult& result) {
    ++diag_frames_;
    const std::size_t n = tracker_->rig().size();
    if (frame.cameras.size() < 2) {
      ++diag_no_reconstruction_;
    } else if (frame.cameras.size() < n) {
      ++diag_partial_;
    }
    for (std::size_t c = 0; c < n; ++c) diag_missing_[c] += frame.cameras.count(c) ? 0 : 1;
    for (const MarkerEstimate& m : result.markers) {
      if (!m.valid) continue;
      ++diag_markers_;
      diag_cameras_used_ += m.cameras;
      diag_residual_sum_ += m.rms_px;
      diag_residual_max_ = std::max(diag_residual_max_, m.rms_px);
    }
    diag_eye_valid_ += result.eye.valid;
    for (const InstrumentEstimate& est : result.instruments) {
      ++diag_instruments_;
      diag_instruments_valid_ += est.valid;
    }
  }

  // One status per period (and one when a hold starts); counters cover the period since the last one.
  void publishDiagnostics(const ros::WallTimerEvent&) {
    std::lock_guard<std::mutex> lock(mutex_);
    publishDiagnosticsLocked(ros::WallTime::now());
  }

  void publishDiagnosticsLocked(const ros::WallTime& now) {
    diagnostic_msgs::DiagnosticStatus status;
    status.name = getName() + ": pose reconstruction";
    status.hardware_id = "tracking_rig";
    auto kv = [&status](const std::string& key, const std::string& value) {
      diagnostic_msgs::KeyValue k;
      k.key = key;
      k.value = value;
      status.values.push_back(k);
    };
    auto fmt = [](double v) {
      char buf[32];
      std::snprintf(buf, sizeof(buf), "%.3g", v);
      return std::string(buf);
    };
    std::vector<std::string> problems;
    int level = diagnostic_msgs::DiagnosticStatus::OK;
    auto raise = [&level, &problems](int l, const std::string& what) {
      level = std::max(level, l);
      problems.push_back(what);
    };
    const double period = std::max(1e-3, (now - last_diag_wall_).toSec());
    const bool started =
        std::any_of(last_wall_.begin(), last_wall_.end(), [](const ros::WallTime& t) { return !t.isZero(); });
    const std::size_t n = tracker_->rig().size();
    int cameras_live = 0;
    const bool holding = watchdog_->holding(now.toSec());
    for (std::size_t c = 0; c < n; ++c) {
      const std::string& name = tracker_->rig().cameras[c].name;
      const double age = last_wall_[c].isZero() ? (now - start_wall_).toSec() : (now - last_wall_[c]).toSec();
      kv(name + " last markers age s", last_wall_[c].isZero() ? "never" : fmt(age));
      kv(name + " frames missing", std::to_string(diag_missing_[c]));
      if (last_recovery_.count(c)) kv(name + " last recovery", last_recovery_.at(c));
      if (last_wall_[c].isZero()) {
        // Start-up: cameras connect one by one; a camera that never delivered is reported after stale_timeout.
        if (started && age > stale_timeout_)
          raise(diagnostic_msgs::DiagnosticStatus::WARN, name + " never delivered markers");
      } else if (age > watchdog_->config().timeout) {
        if (!holding) {
          raise(diagnostic_msgs::DiagnosticStatus::WARN,
                name + " missing for " + fmt(age) + " s (tracking with the others)");
        }
      } else {
        ++cameras_live;
      }
    }
    if (holding) {
      raise(diagnostic_msgs::DiagnosticStatus::ERROR, "no camera frame for " + fmt(watchdog_->silence(now.toSec())) +
                                                          " s: holding the last poses, marked invalid");
    } else if (!started) {
      const double waited = (now - start_wall_).toSec();
      raise(
          waited > stale_timeout_ ? diagnostic_msgs::DiagnosticStatus::ERROR : diagnostic_msgs::DiagnosticStatus::WARN,
          "no marker frames yet");
    } else if (cameras_live < 2) {
      raise(diagnostic_msgs::DiagnosticStatus::ERROR,
            std::to_string(cameras_live) + " camera(s) live: no reconstruction possible");
    }
    if (diag_held_ > 0 && !holding) {
      raise(diagnostic_msgs::DiagnosticStatus::WARN,
            std::to_string(diag_held_) + " frames held (no camera), now tracking again");
    }
    if (diag_frames_ > 0) {
      if (diag_no_reconstruction_ > 0) {
        // A few under load are frames whose other cameras arrived late; most of them means no tracking.
        raise(2 * diag_no_reconstruction_ > diag_frames_ ? diagnostic_msgs::DiagnosticStatus::ERROR
                                                         : diagnostic_msgs::DiagnosticStatus::WARN,
              std::to_string(diag_no_reconstruction_) + " of " + std::to_string(diag_frames_) +
                  " frames with fewer than 2 cameras (late or missing)");
      }
      if (diag_partial_ > 0) {
        std::string which;
        for (std::size_t c = 0; c < n; ++c) {
          if (diag_missing_[c] > 0) which += (which.empty() ? " (" : ", ") + tracker_->rig().cameras[c].name;
        }
        raise(diagnostic_msgs::DiagnosticStatus::WARN,
              std::to_string(diag_partial_) + " of " + std::to_string(diag_frames_) + " frames with a camera missing" +
                  (which.empty() ? "" : which + ")") + ", continuing with the others");
      }
      if (diag_eye_valid_ < 0.9 * diag_frames_) {
        raise(diagnostic_msgs::DiagnosticStatus::WARN, "eye markers reconstructed in " +
                                                           std::to_string(diag_eye_valid_) + " of " +
                                                           std::to_string(diag_frames_) + " frames");
      }
    }
    kv("frames", std::to_string(diag_frames_));
    kv("held frames", std::to_string(diag_held_));
    kv("rate hz", fmt(diag_frames_ / period));
    kv("cameras live", std::to_string(cameras_live) + " of " + std::to_string(n));
    kv("cameras used per marker (mean)",
       diag_markers_ ? fmt(static_cast<double>(diag_cameras_used_) / diag_markers_) : "-");
    kv("reprojection rms px (mean)", diag_markers_ ? fmt(diag_residual_sum_ / diag_markers_) : "-");
    kv("reprojection rms px (max)", diag_markers_ ? fmt(diag_residual_max_) : "-");
    kv("eye valid", std::to_string(diag_eye_valid_) + " of " + std::to_string(diag_frames_));
    kv("instruments valid", std::to_string(diag_instruments_valid_) + " of " + std::to_string(diag_instruments_));
    status.level = static_cast<std::uint8_t>(level);
    if (problems.empty()) {
      status.message = "tracking with " + std::to_string(cameras_live) + " cameras";
    } else {
      for (std::size_t i = 0; i < problems.size(); ++i) status.message += (i ? "; " : "") + problems[i];
    }
    auto array = boost::make_shared<diagnostic_msgs::DiagnosticArray>();
    array->header.stamp = ros::Time::now();  // diagnostics are about the wall-clock health, not a camera frame
    array->status.push_back(status);
    vrm_msgs::publishShared(diagnostics_pub_, array);
    last_diag_wall_ = now;
    diag_frames_ = diag_no_reconstruction_ = diag_partial_ = diag_markers_ = diag_cameras_used_ = 0;
    diag_eye_valid_ = diag_instruments_ = diag_instruments_valid_ = diag_held_ = 0;
    diag_residual_sum_ = diag_residual_max_ = 0.0;
    std::fill(diag_missing_.begin(), diag_missing_.end(), 0);
  }

  std::unique_ptr<PoseTracker> tracker_;
  std::unique_ptr<CameraWatchdog> watchdog_;
  ros::WallTimer watchdog_timer_;
  bool holding_ = false;
  ros::WallTime hold_start_;
  std::size_t hold_frames_ = 0;
  ros::Time last_held_;  // stamp of the newest held frame
  std::size_t reported_recoveries_ = 0;
  std::map<std::size_t, std::string> last_recovery_;  // per camera, for diagnostics
  std::vector<ros::Subscriber> marker_subs_;
  ros::Subscriber sensor_sub_;
  ros::Publisher eye_pub_, instrument_pub_, timing_pub_;
  tf2_ros::TransformBroadcaster broadcaster_;
  tf2_ros::StaticTransformBroadcaster static_broadcaster_;
  std::mutex mutex_;
  std::map<ros::Time, Pending> pending_;
  std::map<std::string, vrm_msgs::InstrumentState::ConstPtr> sensors_;
  std::vector<ros::Time> last_seen_;
  std::vector<std::size_t> late_frames_;
  std::set<std::string> ever_seen_,
      announced_unseen_;  // instrument slots tracked at least once / said "not yet"  // per camera: frames that came
                          // after their frame was reconstructed
  ros::Time last_processed_;
  // Diagnostics (wall clock: they report the live health of the inputs).
  ros::Publisher diagnostics_pub_;
  ros::WallTimer diagnostic_timer_;
  ros::WallTime start_wall_, last_diag_wall_;
  std::vector<ros::WallTime> last_wall_;
  std::vector<int> diag_missing_;
  int diag_frames_ = 0, diag_no_reconstruction_ = 0, diag_partial_ = 0, diag_markers_ = 0, diag_cameras_used_ = 0;
  int diag_eye_valid_ = 0, diag_instruments_ = 0, diag_instruments_valid_ = 0, diag_held_ = 0;
  double diag_residual_sum_ = 0.0, diag_residual_max_ = 0.0;
  double stale_timeout_ = 1.0;
  double sync_window_ = 0.03;
  bool publish_tf_ = false;
  std::string world_frame_, eye_frame_;
};

}  // namespace vrm_tracking

PLUGINLIB_EXPORT_CLASS(vrm_tracking::Tracker, nodelet::Nodelet)
