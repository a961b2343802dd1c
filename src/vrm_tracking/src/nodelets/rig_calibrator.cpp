// Rig calibrator (issue 5, thesis §7.3.2 — Zhang's method in place of Tsai's): collects chessboard views from each
// tracking camera (<camera>/image_raw, any ROS camera driver or camera_rig_sim in calibration mode) and one view of
// the target on the world fixture (<camera>/fixture/image_raw), then calibrates every camera (calibration.h) and
// writes standard camera calibration YAML per camera plus the rig file to `output_dir` — the files camera_rig_sim,
// the tracker and camera_info_manager load. Publishes the rig file's path, latched, on rig_calibration/rig_file.
// The offline equivalent is `rosrun vrm_tracking calibrate_rig`.

#include <cv_bridge/cv_bridge.h>
#include <image_transport/image_transport.h>
#include <nodelet/nodelet.h>
#include <ros/ros.h>
#include <sensor_msgs/image_encodings.h>
#include <std_msgs/String.h>
#include <vrm_msgs/publish.h>

#include <boost/make_shared.hpp>
#include <cmath>
#include <filesystem>
#include <memory>
#include <mutex>
#include <pluginlib/class_list_macros.hpp>
#include <string>
#include <vector>

#include "vrm_tracking/calibration.h"

namespace vrm_tracking {

class RigCalibrator : public nodelet::Nodelet {
 private:
  struct Camera {
    std::string name;
    std::vector<cv::Mat> views;
    std::vector<std::vector<cv::Point2f>> corners;  // of the stored views: a repeated pose adds nothing
    cv::Mat fixture;
    image_transport::Subscriber view_sub;
    ros::Subscriber fixture_sub;
  };

  void onInit() override {
    ros::NodeHandle& nh = getNodeHandle();
    ros::NodeHandle& pnh = getPrivateNodeHandle();
    std::vector<std::string> names = {"camera_0", "camera_1", "camera_2"};
    pnh.param("cameras", names, names);
    pnh.param("views", views_needed_, 12);
    pnh.param<std::string>("output_dir", output_dir_, "");
    pnh.param("target_cols", target_.cols, target_.cols);
    pnh.param("target_rows", target_.rows, target_.rows);
    pnh.param("target_square", target_.square, target_.square);
    std::vector<double> centre = {0.0, 0.0, 0.0};
    pnh.param("fixture_centre", centre, centre);
    if (output_dir_.empty() || centre.size() != 3 || views_needed_ < 3) {
      NODELET_FATAL("rig_calibrator: needs output_dir, views >= 3 and fixture_centre [x, y, z]");
      throw std::runtime_error("rig_calibrator: bad parameters");
    }
    fixture_ = fixturePose(target_, Eigen::Vector3d(centre[0], centre[1], centre[2]));
    result_pub_ = nh.advertise<std_msgs::String>("rig_calibration/rig_file", 1, /*latch=*/true);
    image_transport::ImageTransport it(nh);
    for (const std::string& name : names) {
      auto cam = std::make_unique<Camera>();
      cam->name = name;
      Camera* raw = cam.get();
      cam->view_sub = it.subscribe(name + "/image_raw", 2,
                                   [this, raw](const sensor_msgs::ImageConstPtr& msg) { onView(raw, msg); });
      cam->fixture_sub = nh.subscribe<sensor_msgs::Image>(
          name + "/fixture/image_raw", 1, [this, raw](const sensor_msgs::ImageConstPtr& msg) { onFixture(raw, msg); });
      cameras_.push_back(std::move(cam));
    }
    NODELET_INFO("rig_calibrator: %zu cameras, %d views each, %dx%d target of %.1f mm squares -> %s", cameras_.size(),
                 views_needed_, target_.cols, target_.rows, target_.square * 1e3, output_dir_.c_str());
  }

  static cv::Mat toBgr(const sensor_msgs::ImageConstPtr& msg) {
    try {
      return cv_bridge::toCvCopy(msg, sensor_msgs::image_encodings::BGR8)->image;
    } catch (const std::exception&) {
      return cv::Mat();
    }
  }

  void onFixture(Camera* cam, const sensor_msgs::ImageConstPtr& msg) {
    cv::Mat image = toBgr(msg);
    std::lock_guard<std::mutex> lock(mutex_);
    if (done_ || image.empty()) return;
    cam->fixture = image;
    maybeCalibrateLocked();
  }

  void onView(Camera* cam, const sensor_msgs::ImageConstPtr& msg) {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      if (done_ || static_cast<int>(cam->views.size()) >= views_needed_) return;
    }
    cv::Mat image = toBgr(msg);
    std::vector<cv::Point2f> corners;
    if (image.empty() || !detectTarget(image, target_, &corners)) {
      NODELET_WARN_THROTTLE(5.0, "rig_calibrator: %s: no target in view", cam->name.c_str());
      return;
    }
    std::lock_guard<std::mutex> lock(mutex_);
    for (const auto& seen : cam->corners) {
      double d = 0.0;
      for (std::size_t i = 0; i < corners.size(); ++i)
        d += std::hypot(corners[i].x - seen[i].x, corners[i].y - seen[i].y);
      if (d / corners.size() < 5.0) return;  // the same pose again
    }
    cam->views.push_back(image);
    cam->corners.push_back(corners);
    NODELET_INFO("rig_calibrator: %s view %zu/%d", cam->name.c_str(), cam->views.size(), views_needed_);
    maybeCalibrateLocked();
  }

  void maybeCalibrateLocked() {
    for (const auto& cam : cameras_) {
      if (cam->fixture.empty() || static_cast<int>(cam->views.size()) < views_needed_) return;
    }
    done_ = true;
    CameraRig rig;
    for (const auto& cam : cameras_) {
      const CameraCalibrationResult r = calibrateCamera(cam->name, cam->views, cam->fixture, target_, fixture_);
      if (!r.ok) {
        NODELET_ERROR("rig_calibrator: %s", r.error.c_str());
        return;
      }
      NODELET_INFO("rig_calibrator: %s fx %.2f fy %.2f cx %.2f cy %.2f, rms %.3f px (intrinsics) %.3f px (fixture)",
                   cam->name.c_str(), r.camera.K(0, 0), r.camera.K(1, 1), r.camera.K(0, 2), r.camera.K(1, 2),
                   r.intrinsic_rms_px, r.extrinsic_rms_px);
      rig.cameras.push_back(r.camera);
    }
    const std::filesystem::path dir(output_dir_);
    try {
      std::filesystem::create_directories(dir);
      for (const CameraModel& cam : rig.cameras) saveCameraYaml(cam, (dir / (cam.name + ".yaml")).string());
      saveRigYaml(rig, (dir / "rig.yaml").string());
    } catch (const std::exception& e) {
      NODELET_ERROR("rig_calibrator: %s", e.what());
      return;
    }
    auto msg = boost::make_shared<std_msgs::String>();
    msg->data = (dir / "rig.yaml").string();
    vrm_msgs::publishShared(result_pub_, msg);
    NODELET_INFO("rig_calibrator: wrote %s", msg->data.c_str());
  }

  std::vector<std::unique_ptr<Camera>> cameras_;
  ChessboardTarget target_;
  Eigen::Isometry3d fixture_ = Eigen::Isometry3d::Identity();
  int views_needed_ = 12;
  std::string output_dir_;
  ros::Publisher result_pub_;
  std::mutex mutex_;
  bool done_ = false;
};

}  // namespace vrm_tracking

PLUGINLIB_EXPORT_CLASS(vrm_tracking::RigCalibrator, nodelet::Nodelet)
