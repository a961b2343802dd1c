// Marker detector (issue 5, thesis §7.3.2): colour images of the tracking cameras → MarkerObservations, the same
// message the EyeSi FPGA sends, so the tracker cannot tell a real camera + this nodelet from pre-extracted
// centroids. Works on any ROS camera driver's sensor_msgs/Image (bgr8/rgb8/bgra8/rgba8); other encodings, empty
// or truncated images are reported (throttled) and skipped — the other cameras carry on.

#include "vrm_tracking/marker_detector.h"

#include <cv_bridge/cv_bridge.h>
#include <image_transport/image_transport.h>
#include <nodelet/nodelet.h>
#include <ros/ros.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/image_encodings.h>
#include <vrm_msgs/MarkerObservations.h>
#include <vrm_msgs/publish.h>

#include <boost/make_shared.hpp>
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
    image_transport::Subscriber image_sub;
    ros::Subscriber info_sub;
    ros::Publisher markers_pub;
    std::mutex mutex;
    int images_without_info = 0;
    bool have_info = false;
  };

  void onInit() override {
    ros::NodeHandle& nh = getNodeHandle();
    ros::NodeHandle& pnh = getPrivateNodeHandle();
    std::string layout_file;
    pnh.param<std::string>("layout_file", layout_file, "");
    try {
      layout_ = layout_file.empty() ? makeDefaultLayout() : loadLayoutYaml(layout_file);
    } catch (const std::exception& e) {
      NODELET_FATAL("marker_detector: %s", e.what());
      throw;
    }
    detector_ = std::make_unique<MarkerDetector>(layout_.classes);
    RoiTrackerConfig roi;
    pnh.param("roi_half", roi.roi_half, roi.roi_half);
    pnh.param("lost_search_interval", roi.lost_search_interval, roi.lost_search_interval);
    pnh.param("max_candidates", roi.max_candidates, roi.max_candidates);
    pnh.param("use_roi", roi.use_roi, roi.use_roi);
    std::vector<std::string> names = {"camera_0", "camera_1", "camera_2"};
    pnh.param("cameras", names, names);

    image_transport::ImageTransport it(nh);
    for (const std::string& name : names) {
      auto cam = std::make_unique<Camera>();
      cam->name = name;
      cam->roi = std::make_unique<RoiTracker>(detector_.get(), roi);
      cam->markers_pub = nh.advertise<vrm_msgs::MarkerObservations>(name + "/markers", 5);
      Camera* raw = cam.get();
      cam->image_sub = it.subscribe(name + "/image_raw", 2,
                                    [this, raw](const sensor_msgs::ImageConstPtr& msg) { onImage(raw, msg); });
      cam->info_sub = nh.subscribe<sensor_msgs::CameraInfo>(
          name + "/camera_info", 2, [raw](const sensor_msgs::CameraInfoConstPtr&) { raw->have_info = true; });
      cameras_.push_back(std::move(cam));
    }
    NODELET_INFO("marker_detector: %zu cameras, %zu colour classes, ROI %s", cameras_.size(), layout_.classes.size(),
                 roi.use_roi ? "on" : "off");
  }

  void onImage(Camera* cam, const sensor_msgs::ImageConstPtr& msg) {
    namespace enc = sensor_msgs::image_encodings;
    if (msg->width == 0 || msg->height == 0 || msg->data.empty()) {
      NODELET_WARN_THROTTLE(2.0, "%s: empty image skipped", cam->name.c_str());
      return;
    }
    if (msg->encoding != enc::BGR8 && msg->encoding != enc::RGB8 && msg->encoding != enc::BGRA8 &&
        msg->encoding != enc::RGBA8) {
      NODELET_WARN_THROTTLE(2.0,
                            "%s: encoding '%s' is not a colour image (bgr8/rgb8/bgra8/rgba8 expected); "
                            "colour markers cannot be classified, frame skipped",
                            cam->name.c_str(), msg->encoding.c_str());
      return;
    }
    if (static_cast<std::size_t>(msg->step) * msg->height > msg->data.size() ||
        msg->step < msg->width * enc::numChannels(msg->encoding)) {
      NODELET_WARN_THROTTLE(2.0, "%s: truncated image (step %u, %zu bytes) skipped", cam->name.c_str(), msg->step,
                            msg->data.size());
      return;
    }
    if (!cam->have_info && ++cam->images_without_info == 50) {
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
      return;
    }
    auto out = boost::make_shared<vrm_msgs::MarkerObservations>();
    out->header = msg->header;  // the exposure stamp travels on unchanged
    out->camera_name = cam->name;
    out->image_width = msg->width;
    out->image_height = msg->height;
    {
      std::lock_guard<std::mutex> lock(cam->mutex);
      toMsg(cam->roi->process(image->image), out.get());
    }
    vrm_msgs::publishShared(cam->markers_pub, out);
  }

  MarkerLayout layout_;
  std::unique_ptr<MarkerDetector> detector_;
  std::vector<std::unique_ptr<Camera>> cameras_;
};

}  // namespace vrm_tracking

PLUGINLIB_EXPORT_CLASS(vrm_tracking::MarkerDetectorNodelet, nodelet::Nodelet)
