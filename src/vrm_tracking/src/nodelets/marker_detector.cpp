// Marker detector (issue 5, thesis §7.3.2): colour images of the tracking cameras → MarkerObservations, the same
// message the EyeSi FPGA sends, so the tracker cannot tell a real camera + this nodelet from pre-extracted
// centroids. Works on any ROS camera driver's sensor_msgs/Image (bgr8/rgb8/bgra8/rgba8); other encodings, empty
// or truncated images are reported (throttled) and skipped — the other cameras carry on. Diagnostics per camera on
// /diagnostics (wall-clock period `diagnostic_period`): ERROR when a camera never delivered or stopped (no image
// for `stale_timeout` s) or every frame of the period was rejected; WARN for rejected frames (bad encoding, empty,
// truncated) or a missing CameraInfo; values: rate, rejections and why, colour classes found per frame.
// Per image, the wall time of its detection goes to tracking_timing (vrm_msgs/StageTiming, stage
// "detection_<camera>", header.stamp = the exposure stamp; issue 12).
// Lazy (image_proc's pattern): a camera's images and CameraInfo are subscribed only while someone subscribes to its
// <camera>/markers. Only the markers count: tracking_timing and /diagnostics describe the work, they do not ask for
// it, so a latency monitor or a diagnostics aggregator alone never keeps the cameras rendering and this detecting.
// An idle camera is reported OK ("idle") on /diagnostics, not as a stopped camera.

#include "vrm_tracking/marker_detector.h"

#include <cv_bridge/cv_bridge.h>
#include <diagnostic_msgs/DiagnosticArray.h>
#include <image_transport/image_transport.h>
#include <nodelet/nodelet.h>
#include <ros/ros.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/image_encodings.h>
#include <vrm_msgs/MarkerObservations.h>
#include <vrm_msgs/StageTiming.h>
#include <vrm_msgs/publish.h>

#include <algorithm>
#include <boost/make_shared.hpp>
#include <cstdio>
#include <memory>
#include <mutex>
#include <pluginlib/class_list_macros.hpp>
#include <string>
#include <vector>

#include "vrm_tracking/conversions.h"

namespace vrm_tracking {

class MarkerDetectorNodelet : public nodelet::Nodelet {
 private:
  struct Camera {
    std::string name;
    std::unique_ptr<RoiTracker> roi;
    image_transport::Subscriber image_sub;  // both empty while nobody subscribes to markers_pub
    ros::Subscriber info_sub;
    ros::Publisher markers_pub;
    ros::WallTime idle_since;     // zero while subscribed
    ros::WallTime watched_since;  // when its images were last subscribed
    std::mutex mutex;
    int images_without_info = 0;
    bool have_info = false;
    // Diagnostics of the current period (guarded by mutex).
    int images = 0, rejected = 0, found_classes = 0;
    std::vector<std::string> reject_reasons;  // distinct, at most a few
    ros::WallTime last_image;
  };

  void reject(Camera* cam, const std::string& reason) {
    std::lock_guard<std::mutex> lock(cam->mutex);
    ++cam->rejected;
    if (cam->reject_reasons.size() < 5 &&
        std::find(cam->reject_reasons.begin(), cam->reject_reasons.end(), reason) == cam->reject_reasons.end()) {
      cam->reject_reasons.push_back(reason);
    }
    cam->last_image = ros::WallTime::now();
  }

  // A set-up that throws after it opened handles (a camera name that is no ROS name) closes them first: the manager
  // frees this nodelet's callback queues before it destroys the nodelet (camera_rig_sim.cpp).
  void onInit() override {
    try {
      init();
    } catch (...) {
      diagnostic_timer_.stop();
      {
        std::lock_guard<std::mutex> lock(connect_mutex_);
        cameras_.clear();  // their publishers and the subscriptions connectCb opened
      }
      timing_pub_.shutdown();
      diagnostics_pub_.shutdown();
      throw;
    }
  }

  void init() {
    ros::NodeHandle& nh = getNodeHandle();
    ros::NodeHandle& pnh = getPrivateNodeHandle();
    std::string layout_file;
    pnh.param<std::string>("layout_file", layout_file, "");
    try {
      const MarkerLayout layout = layout_file.empty() ? makeDefaultLayout() : loadLayoutYaml(layout_file);
      detector_ = std::make_unique<MarkerDetector>(layout.classes);
    } catch (const std::exception& e) {
      NODELET_FATAL("marker_detector: %s", e.what());
      throw;
    }
    RoiTrackerConfig roi;
    pnh.param("roi_half", roi.roi_half, roi.roi_half);
    pnh.param("lost_search_interval", roi.lost_search_interval, roi.lost_search_interval);
    pnh.param("max_candidates", roi.max_candidates, roi.max_candidates);
    pnh.param("use_roi", roi.use_roi, roi.use_roi);
    std::vector<std::string> names = {"camera_0", "camera_1", "camera_2"};
    pnh.param("cameras", names, names);
    pnh.param("stale_timeout", stale_timeout_, 1.0);
    double diagnostic_period = 1.0;
    pnh.param("diagnostic_period", diagnostic_period, diagnostic_period);

    it_ = std::make_unique<image_transport::ImageTransport>(nh);
    {
      // Held while advertising, so connectCb cannot run before every camera exists.
      std::lock_guard<std::mutex> lock(connect_mutex_);
      const ros::SubscriberStatusCallback connect_cb = [this](const ros::SingleSubscriberPublisher&) { connectCb(); };
      for (const std::string& name : names) {
        auto cam = std::make_unique<Camera>();
        cam->name = name;
        cam->roi = std::make_unique<RoiTracker>(detector_.get(), roi);
        cam->idle_since = ros::WallTime::now();
        try {
          cam->markers_pub = nh.advertise<vrm_msgs::MarkerObservations>(name + "/markers", 5, connect_cb, connect_cb);
        } catch (const ros::InvalidNameException& e) {
          NODELET_FATAL("marker_detector: camera '%s': %s", name.c_str(), e.what());
          throw;
        }
        cameras_.push_back(std::move(cam));
      }
    }
    timing_pub_ = nh.advertise<vrm_msgs::StageTiming>("tracking_timing", 10);
    last_diag_wall_ = ros::WallTime::now();
    diagnostics_pub_ = nh.advertise<diagnostic_msgs::DiagnosticArray>("/diagnostics", 10);
    diagnostic_timer_ =
        nh.createWallTimer(ros::WallDuration(diagnostic_period), &MarkerDetectorNodelet::publishDiagnostics, this);
    NODELET_INFO("marker_detector: %zu cameras, %zu colour classes, ROI %s", cameras_.size(),
                 detector_->classes().size(), roi.use_roi ? "on" : "off");
  }

  // Subscribes a camera's inputs when its markers gain a first subscriber, drops them when they lose the last.
  void connectCb() {
    std::lock_guard<std::mutex> lock(connect_mutex_);
    ros::NodeHandle& nh = getNodeHandle();
    for (const auto& cam : cameras_) {
      Camera* raw = cam.get();
      if (cam->markers_pub.getNumSubscribers() == 0) {
        if (!cam->image_sub) continue;
        cam->image_sub.shutdown();
        cam->info_sub.shutdown();
        std::lock_guard<std::mutex> cam_lock(cam->mutex);
        cam->idle_since = ros::WallTime::now();
        NODELET_DEBUG("%s: nobody subscribes to its markers; images unsubscribed", cam->name.c_str());
      } else if (!cam->image_sub) {
        {
          std::lock_guard<std::mutex> cam_lock(cam->mutex);
          cam->idle_since = ros::WallTime();
          cam->watched_since = ros::WallTime::now();  // the stale timeout counts from the subscription
          cam->last_image = ros::WallTime();
          cam->have_info = false;
          cam->images_without_info = 0;
        }
        // One image deep: the newest exposure wins when detection falls behind (no queue grows).
        cam->image_sub = it_->subscribe(cam->name + "/image_raw", 1,
                                        [this, raw](const sensor_msgs::ImageConstPtr& msg) { onImage(raw, msg); });
        cam->info_sub = nh.subscribe<sensor_msgs::CameraInfo>(cam->name + "/camera_info", 2,
                                                              [raw](const sensor_msgs::CameraInfoConstPtr&) {
                                                                std::lock_guard<std::mutex> lock(raw->mutex);
                                                                raw->have_info = true;
                                                              });
      }
    }
  }

  void onImage(Camera* cam, const sensor_msgs::ImageConstPtr& msg) {
    namespace enc = sensor_msgs::image_encodings;
    if (msg->width == 0 || msg->height == 0 || msg->data.empty()) {
      NODELET_WARN_THROTTLE(2.0, "%s: empty image skipped", cam->name.c_str());
      reject(cam, "empty image");
      return;
    }
    if (msg->encoding != enc::BGR8 && msg->encoding != enc::RGB8 && msg->encoding != enc::BGRA8 &&
        msg->encoding != enc::RGBA8) {
      NODELET_WARN_THROTTLE(2.0,
                            "%s: encoding '%s' is not a colour image (bgr8/rgb8/bgra8/rgba8 expected); "
                            "colour markers cannot be classified, frame skipped",
                            cam->name.c_str(), msg->encoding.c_str());
      reject(cam, "encoding '" + msg->encoding + "' is not a colour image");
      return;
    }
    if (static_cast<std::size_t>(msg->step) * msg->height > msg->data.size() ||
        msg->step < msg->width * enc::numChannels(msg->encoding)) {
      NODELET_WARN_THROTTLE(2.0, "%s: truncated image (step %u, %zu bytes) skipped", cam->name.c_str(), msg->step,
                            msg->data.size());
      reject(cam, "truncated image");
      return;
    }
    bool have_info;
    {
      std::lock_guard<std::mutex> lock(cam->mutex);
      have_info = cam->have_info;
    }
    if (!have_info && ++cam->images_without_info == 50) {
      NODELET_WARN(
          "%s: no CameraInfo on %s/camera_info after 50 images: detection continues, but the tracker "
          "relies on its rig calibration file for this camera",
          cam->name.c_str(), cam->name.c_str());
    }
    cv_bridge::CvImageConstPtr image;
    try {
      // bgr8 shares the message buffer (zero copy); the other colour encodings are converted.
      image = cv_bridge::toCvShare(msg, enc::BGR8);
    } catch (const std::exception& e) {
      NODELET_WARN_THROTTLE(2.0, "%s: cannot read image: %s", cam->name.c_str(), e.what());
      reject(cam, std::string("cannot read image: ") + e.what());
      return;
    }
    const ros::Time start = ros::Time::now();  // measurement only (tracking_timing)
    auto out = boost::make_shared<vrm_msgs::MarkerObservations>();
    out->header = msg->header;  // the exposure stamp travels on unchanged
    out->camera_name = cam->name;
    out->image_width = msg->width;
    out->image_height = msg->height;
    {
      std::lock_guard<std::mutex> lock(cam->mutex);
      DetectionStats stats;
      toMsg(cam->roi->process(image->image, &stats), out.get());
      ++cam->images;
      cam->found_classes += stats.found_classes;
      cam->last_image = ros::WallTime::now();
    }
    vrm_msgs::publishShared(cam->markers_pub, out);
    auto timing = boost::make_shared<vrm_msgs::StageTiming>();
    timing->header.stamp = msg->header.stamp;
    timing->frame = msg->header.seq;
    vrm_msgs::StageStamp stage;
    stage.stage = "detection_" + cam->name;
    stage.start = start;
    stage.end = ros::Time::now();
    timing->stages.push_back(stage);
    vrm_msgs::publishShared(timing_pub_, timing);
  }

  // One status per camera; counters cover the period since the last report.
  void publishDiagnostics(const ros::WallTimerEvent&) {
    namespace d = diagnostic_msgs;
    const ros::WallTime now = ros::WallTime::now();
    const double period = std::max(1e-3, (now - last_diag_wall_).toSec());
    last_diag_wall_ = now;
    auto array = boost::make_shared<d::DiagnosticArray>();
    array->header.stamp = ros::Time::now();  // wall-clock health, not a camera frame
    for (const auto& cam : cameras_) {
      std::lock_guard<std::mutex> lock(cam->mutex);
      d::DiagnosticStatus status;
      status.name = getName() + ": " + cam->name;
      status.hardware_id = cam->name;
      auto kv = [&status](const std::string& key, const std::string& value) {
        d::KeyValue k;
        k.key = key;
        k.value = value;
        status.values.push_back(k);
      };
      char buf[64];
      std::vector<std::string> problems;
      int level = d::DiagnosticStatus::OK;
      auto raise = [&level, &problems](int l, const std::string& what) {
        level = std::max(level, l);
        problems.push_back(what);
      };
      const bool idle = !cam->idle_since.isZero();
      const double age =
          cam->last_image.isZero() ? (now - cam->watched_since).toSec() : (now - cam->last_image).toSec();
      if (idle) {
        // Nobody wants its markers: not subscribed to its images, so silence is expected.
      } else if (age > stale_timeout_) {
        std::snprintf(buf, sizeof(buf), "%.1f", age);
        raise(d::DiagnosticStatus::ERROR, cam->last_image.isZero()
                                              ? std::string("no image received")
                                              : std::string("camera stopped: no image for ") + buf + " s");
      }
      std::string reasons;
      for (const std::string& r : cam->reject_reasons) reasons += (reasons.empty() ? "" : ", ") + r;
      if (cam->rejected > 0) {
        raise(cam->images == 0 ? d::DiagnosticStatus::ERROR : d::DiagnosticStatus::WARN,
              std::to_string(cam->rejected) + " frame(s) rejected (" + reasons + ")");
      }
      if (!cam->have_info && !idle) raise(d::DiagnosticStatus::WARN, "no CameraInfo on " + cam->name + "/camera_info");
      std::snprintf(buf, sizeof(buf), "%.3g", cam->images / period);
      kv("rate hz", buf);
      kv("frames", std::to_string(cam->images));
      kv("rejected", std::to_string(cam->rejected));
      kv("rejection reasons", reasons);
      kv("camera_info", cam->have_info ? "yes" : "no");
      std::snprintf(buf, sizeof(buf), "%.3g",
                    cam->images ? static_cast<double>(cam->found_classes) / cam->images : 0.0);
      kv("colour classes found per frame", buf);
      status.level = static_cast<std::uint8_t>(level);
      if (idle) {
        status.message = "idle: nobody subscribes to " + cam->name + "/markers";
      } else if (problems.empty()) {
        status.message = "detecting";
      } else {
        for (std::size_t i = 0; i < problems.size(); ++i) status.message += (i ? "; " : "") + problems[i];
      }
      array->status.push_back(status);
      cam->images = cam->rejected = cam->found_classes = 0;
      cam->reject_reasons.clear();
    }
    vrm_msgs::publishShared(diagnostics_pub_, array);
  }

  std::unique_ptr<MarkerDetector> detector_;
  std::unique_ptr<image_transport::ImageTransport> it_;
  std::mutex connect_mutex_;  // subscribe / unsubscribe (connectCb)
  ros::Publisher timing_pub_;
  ros::Publisher diagnostics_pub_;
  ros::WallTimer diagnostic_timer_;
  ros::WallTime last_diag_wall_;
  double stale_timeout_ = 1.0;
  std::vector<std::unique_ptr<Camera>> cameras_;
};

}  // namespace vrm_tracking

PLUGINLIB_EXPORT_CLASS(vrm_tracking::MarkerDetectorNodelet, nodelet::Nodelet)
