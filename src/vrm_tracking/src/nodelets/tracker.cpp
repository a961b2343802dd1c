// Tracker (issue 5, thesis §7.3.2): MarkerObservations of the rig's cameras → EyeState and InstrumentState, stamped
// with the cameras' exposure stamp. Input is the detector's output or pre-extracted centroids (the EyeSi FPGA
// path): `<camera>/<markers_topic>`. Frames are assembled by stamp; a frame is reconstructed as soon as every
// camera has reported, or with the cameras that did once a newer stamp is `sync_window` past it (a camera that
// stops costs one frame of latency, not the tracking). Roll, jaw and the other instrument inputs are not optical:
// they come from `instrument_sensors` (the instruments' own channels; in simulation the surgeon's ground truth).
// tf: off by default — vrm_sim's scene_manager broadcasts world → eye → trocar_* / instrument_* from the states
// this nodelet publishes; publish_tf:=true broadcasts them here instead (then do not run both).

#include <geometry_msgs/TransformStamped.h>
#include <nodelet/nodelet.h>
#include <ros/ros.h>
#include <tf2_ros/static_transform_broadcaster.h>
#include <tf2_ros/transform_broadcaster.h>
#include <vrm_msgs/EyeState.h>
#include <vrm_msgs/InstrumentState.h>
#include <vrm_msgs/MarkerObservations.h>
#include <vrm_msgs/publish.h>

#include <boost/make_shared.hpp>
#include <map>
#include <memory>
#include <mutex>
#include <pluginlib/class_list_macros.hpp>
#include <string>
#include <vector>

#include "vrm_tracking/conversions.h"
#include "vrm_tracking/pose_tracker.h"

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
    pnh.param<std::string>("markers_topic", markers_topic, "markers");
    TrackerConfig config;
    pnh.param("gate_px", config.gate_px, config.gate_px);
    pnh.param("max_radius", config.max_radius, config.max_radius);
    pnh.param("sync_window", sync_window_, 0.03);
    pnh.param("publish_tf", publish_tf_, false);
    pnh.param<std::string>("world_frame", world_frame_, "world");
    pnh.param<std::string>("eye_frame", eye_frame_, "eye");
    try {
      CameraRig rig = rig_file.empty() ? makeDefaultRig() : loadRigYaml(rig_file);
      MarkerLayout layout = layout_file.empty() ? makeDefaultLayout() : loadLayoutYaml(layout_file);
      tracker_ = std::make_unique<PoseTracker>(rig, layout, config);
    } catch (const std::exception& e) {
      NODELET_FATAL("tracker: %s", e.what());
      throw;
    }
    eye_pub_ = nh.advertise<vrm_msgs::EyeState>("eye_state", 10);
    instrument_pub_ = nh.advertise<vrm_msgs::InstrumentState>("instrument_state", 20);
    sensor_sub_ = nh.subscribe("instrument_sensors", 20, &Tracker::onSensors, this);
    const CameraRig& rig = tracker_->rig();
    last_seen_.assign(rig.size(), ros::Time());
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
    NODELET_INFO("tracker: %zu cameras (%s), %zu instruments, tf %s", rig.size(), markers_topic.c_str(),
                 tracker_->layout().instruments.size(), publish_tf_ ? "on" : "off (scene_manager broadcasts)");
  }

  void onSensors(const vrm_msgs::InstrumentState::ConstPtr& msg) {
    std::lock_guard<std::mutex> lock(mutex_);
    sensors_[msg->instrument_id] = msg;
  }

  void onMarkers(std::size_t camera, const vrm_msgs::MarkerObservations::ConstPtr& msg) {
    std::lock_guard<std::mutex> lock(mutex_);
    const ros::Time stamp = msg->header.stamp;
    if (!last_processed_.isZero() && stamp <= last_processed_) {
      NODELET_WARN_THROTTLE(2.0, "tracker: %s frame at %.3f arrived after its frame was reconstructed; dropped",
                            tracker_->rig().cameras[camera].name.c_str(), stamp.toSec());
      return;
    }
    last_seen_[camera] = stamp;
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
    Pending frame = std::move(it->second);
    pending_.erase(it);
    last_processed_ = frame.header.stamp;
    const std::size_t n = tracker_->rig().size();
    if (frame.cameras.size() < n) {
      std::string missing;
      for (std::size_t c = 0; c < n; ++c) {
        if (!frame.cameras.count(c)) missing += " " + tracker_->rig().cameras[c].name;
      }
      NODELET_WARN_THROTTLE(5.0, "tracker: frame %.3f with %zu of %zu cameras (missing:%s)%s",
                            frame.header.stamp.toSec(), frame.cameras.size(), n, missing.c_str(),
                            frame.cameras.size() < 2 ? "; no reconstruction possible" : "; continuing");
    }
    std::vector<CameraObservations> observations;
    for (auto& entry : frame.cameras) observations.push_back(std::move(entry.second));
    const TrackingResult result = tracker_->update(observations);

    auto eye = boost::make_shared<vrm_msgs::EyeState>();
    eye->header = frame.header;
    toMsg(result.eye, eye.get());
    vrm_msgs::publishShared(eye_pub_, eye);
    if (!result.eye.valid) NODELET_WARN_THROTTLE(5.0, "tracker: eye markers not reconstructed; holding the rotation");

    std::vector<geometry_msgs::TransformStamped> frames;
    if (publish_tf_ && result.eye.valid) {
      geometry_msgs::TransformStamped t;
      t.header = frame.header;
      t.child_frame_id = eye_frame_;
      t.transform.translation = toVector3Msg(result.eye.rotation_center);
      t.transform.rotation = eye->rotation;
      frames.push_back(t);
    }
    for (const InstrumentEstimate& est : result.instruments) {
      auto msg = boost::make_shared<vrm_msgs::InstrumentState>();
      msg->header = frame.header;
      msg->header.frame_id = eye_frame_;
      const auto sensor = sensors_.find(est.slot);
      toMsg(est, sensor == sensors_.end() ? nullptr : sensor->second.get(), msg.get());
      if (publish_tf_ && est.valid) {
        geometry_msgs::TransformStamped t;
        t.header = msg->header;
        t.child_frame_id = "instrument_" + est.slot;
        t.transform.translation = toVector3Msg(est.tip);
        t.transform.rotation = msg->tip_pose.orientation;
        frames.push_back(t);
      }
      if (!est.valid) NODELET_WARN_THROTTLE(5.0, "tracker: instrument '%s' not seen", est.slot.c_str());
      vrm_msgs::publishShared(instrument_pub_, msg);
    }
    if (!frames.empty()) broadcaster_.sendTransform(frames);
  }

  std::unique_ptr<PoseTracker> tracker_;
  std::vector<ros::Subscriber> marker_subs_;
  ros::Subscriber sensor_sub_;
  ros::Publisher eye_pub_, instrument_pub_;
  tf2_ros::TransformBroadcaster broadcaster_;
  tf2_ros::StaticTransformBroadcaster static_broadcaster_;
  std::mutex mutex_;
  std::map<ros::Time, Pending> pending_;
  std::map<std::string, vrm_msgs::InstrumentState::ConstPtr> sensors_;
  std::vector<ros::Time> last_seen_;
  ros::Time last_processed_;
  double sync_window_ = 0.03;
  bool publish_tf_ = false;
  std::string world_frame_, eye_frame_;
};

}  // namespace vrm_tracking

PLUGINLIB_EXPORT_CLASS(vrm_tracking::Tracker, nodelet::Nodelet)
