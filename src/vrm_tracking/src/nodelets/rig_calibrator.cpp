// Rig calibrator (issue 5, thesis §7.3.2 — Zhang's method in place of Tsai's): collects chessboard views from each
// tracking camera (<camera>/image_raw, any ROS camera driver or camera_rig_sim in calibration mode) and one view of
// the target on the world fixture (<camera>/fixture/image_raw), then calibrates every camera (calibration.h) and
// writes standard camera calibration YAML per camera plus the rig file to `output_dir` — the files camera_rig_sim,
// the tracker and camera_info_manager load. Publishes the rig file's path, latched, on rig_calibration/rig_file.
// The offline equivalent is `rosrun vrm_tracking calibrate_rig`.

#include <image_transport/image_transport.h>
#include <nodelet/nodelet.h>
#include <ros/ros.h>
#include <std_msgs/String.h>
#include <vrm_msgs/publish.h>

#include <boost/make_shared.hpp>
#include <cmath>
#include <filesystem>
#include <memory>
#include <optional>
#include <pluginlib/class_list_macros.hpp>
#include <string>
#include <vector>

#include "vrm_tracking/calibration.h"
#include "vrm_tracking/calibration_collector.h"
#include "vrm_tracking/conversions.h"

namespace vrm_tracking {

// The images in, the files and the rig file's path out; what is done with the images is CalibrationCollector's.
class RigCalibrator : public nodelet::Nodelet {
 private:
  void onInit() override {
    ros::NodeHandle& nh = getNodeHandle();
    ros::NodeHandle& pnh = getPrivateNodeHandle();
    std::vector<std::string> names = {"camera_0", "camera_1", "camera_2"};
    pnh.param("cameras", names, names);
    int views_needed = 12;
    pnh.param("views", views_needed, views_needed);
    pnh.param<std::string>("output_dir", output_dir_, "");
    ChessboardTarget target;
    pnh.param("target_cols", target.cols, target.cols);
    pnh.param("target_rows", target.rows, target.rows);
    pnh.param("target_square", target.square, target.square);
    std::vector<double> centre = {0.0, 0.0, 0.0};
    pnh.param("fixture_centre", centre, centre);
    if (output_dir_.empty() || centre.size() != 3) {
      NODELET_FATAL("rig_calibrator: needs output_dir and fixture_centre [x, y, z]");
      throw std::runtime_error("rig_calibrator: bad parameters");
    }
    try {
      collector_ = std::make_unique<CalibrationCollector>(
          names, target, fixturePose(target, Eigen::Vector3d(centre[0], centre[1], centre[2])), views_needed);
    } catch (const std::invalid_argument& error) {
      NODELET_FATAL("rig_calibrator: %s", error.what());
      throw std::runtime_error(std::string("rig_calibrator: bad parameters: ") + error.what());
    }
    result_pub_ = nh.advertise<std_msgs::String>("rig_calibration/rig_file", 1, /*latch=*/true);
    image_transport::ImageTransport it(nh);
    for (std::size_t camera = 0; camera < names.size(); ++camera) {
      view_subs_.push_back(
          it.subscribe(names[camera] + "/image_raw", 2,
                       [this, camera](const sensor_msgs::ImageConstPtr& msg) { onView(camera, *msg); }));
      fixture_subs_.push_back(nh.subscribe<sensor_msgs::Image>(
          names[camera] + "/fixture/image_raw", 1,
          [this, camera](const sensor_msgs::ImageConstPtr& msg) { onFixture(camera, *msg); }));
    }
    NODELET_INFO("rig_calibrator: %zu cameras, %d views each, %dx%d target of %.1f mm squares -> %s", names.size(),
                 views_needed, target.cols, target.rows, target.square * 1e3, output_dir_.c_str());
  }

  void onFixture(std::size_t camera, const sensor_msgs::Image& msg) {
    if (collector_->setFixture(camera, toBgrImage(msg))) finishIfComplete();
  }

  void onView(std::size_t camera, const sensor_msgs::Image& msg) {
    const std::string& name = collector_->cameraName(camera);
    switch (collector_->addView(camera, toBgrImage(msg))) {
      case CalibrationCollector::ViewOutcome::kAdded:
        NODELET_INFO("rig_calibrator: %s view %zu/%d", name.c_str(), collector_->viewCount(camera),
                     collector_->viewsNeeded());
        finishIfComplete();
        break;
      case CalibrationCollector::ViewOutcome::kNoTarget:
        NODELET_WARN_THROTTLE(5.0, "rig_calibrator: %s: no target in view", name.c_str());
        break;
      case CalibrationCollector::ViewOutcome::kOtherSize:
        NODELET_WARN_THROTTLE(5.0, "rig_calibrator: %s: a view of another image size than the first (ignored)",
                              name.c_str());
        break;
      case CalibrationCollector::ViewOutcome::kSamePose:
      case CalibrationCollector::ViewOutcome::kEnough:
        break;
    }
  }

  void finishIfComplete() {
    const std::optional<CalibrationCollector::Calibration> calibration = collector_->calibrateIfComplete();
    if (!calibration) return;
    for (const CameraCalibrationResult& r : calibration->cameras) {
      if (!r.ok) continue;
      NODELET_INFO("rig_calibrator: %s fx %.2f fy %.2f cx %.2f cy %.2f, rms %.3f px (intrinsics) %.3f px (fixture)",
                   r.camera.name.c_str(), r.camera.K(0, 0), r.camera.K(1, 1), r.camera.K(0, 2), r.camera.K(1, 2),
                   r.intrinsic_rms_px, r.extrinsic_rms_px);
    }
    if (!calibration->ok) {
      NODELET_ERROR("rig_calibrator: %s", calibration->error.c_str());
      return;
    }
    const std::filesystem::path dir(output_dir_);
    try {
      std::filesystem::create_directories(dir);
      for (const CameraModel& cam : calibration->rig.cameras)
        saveCameraYaml(cam, (dir / (cam.name + ".yaml")).string());
      saveRigYaml(calibration->rig, (dir / "rig.yaml").string());
    } catch (const std::exception& e) {
      NODELET_ERROR("rig_calibrator: %s", e.what());
      return;
    }
    auto msg = boost::make_shared<std_msgs::String>();
    msg->data = (dir / "rig.yaml").string();
    vrm_msgs::publishShared(result_pub_, msg);
    NODELET_INFO("rig_calibrator: wrote %s", msg->data.c_str());
  }

  std::unique_ptr<CalibrationCollector> collector_;
  std::vector<image_transport::Subscriber> view_subs_;
  std::vector<ros::Subscriber> fixture_subs_;
  std::string output_dir_;
  ros::Publisher result_pub_;
};

}  // namespace vrm_tracking

PLUGINLIB_EXPORT_CLASS(vrm_tracking::RigCalibrator, nodelet::Nodelet)
