// Calibration fixture twin (issue 5; camera_rig_sim's former calibration mode): each camera of the rig sees a
// chessboard target from `views` seeded poses in turn on <camera>/image_raw (+ camera_info), at `rate` Hz (wall
// clock: a source, no ground truth drives the views), and the target on the world fixture, latched, on
// <camera>/fixture/image_raw — what rig_calibrator (and a person with a real target) uses. A camera with no
// subscriber to its images skips its views; the fixture image is published once.

#include <image_transport/image_transport.h>
#include <nodelet/nodelet.h>
#include <ros/ros.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/image_encodings.h>
#include <vrm_msgs/publish.h>

#include <boost/make_shared.hpp>
#include <cstdint>
#include <pluginlib/class_list_macros.hpp>
#include <string>
#include <vector>

#include "vrm_tracking/calibration.h"
#include "vrm_tracking/conversions.h"
#include "vrm_tracking/rig_renderer.h"

namespace vrm_tracking {

class CalibrationFixture : public nodelet::Nodelet {
 private:
  void onInit() override {
    ros::NodeHandle& nh = getNodeHandle();
    ros::NodeHandle& pnh = getPrivateNodeHandle();
    std::string rig_file, layout_file;
    pnh.param<std::string>("rig_file", rig_file, "");
    pnh.param<std::string>("layout_file", layout_file, "");  // its rotation centre is where the target poses aim
    Eigen::Vector3d rotation_center;
    try {
      rig_ = rig_file.empty() ? makeDefaultRig() : loadRigYaml(rig_file);
      rotation_center = (layout_file.empty() ? makeDefaultLayout() : loadLayoutYaml(layout_file)).rotation_center;
    } catch (const std::exception& e) {
      NODELET_FATAL("calibration_fixture: %s", e.what());
      throw;
    }
    int views = 12;
    pnh.param("views", views, views);
    if (views <= 0) {
      NODELET_FATAL("calibration_fixture: views must be > 0 (got %d)", views);
      throw std::invalid_argument("calibration_fixture: views must be > 0");
    }
    pnh.param("target_cols", target_.cols, target_.cols);
    pnh.param("target_rows", target_.rows, target_.rows);
    pnh.param("target_square", target_.square, target_.square);
    pnh.param<std::string>("optical_frame_suffix", frame_suffix_, "_optical");
    double rate = 5.0;
    pnh.param("rate", rate, rate);
    fixture_pose_ = fixturePose(target_, rotation_center);
    image_transport::ImageTransport it(nh);
    for (std::size_t c = 0; c < rig_.size(); ++c) {
      const CameraModel& cam = rig_.cameras[c];
      camera_pubs_.push_back(it.advertiseCamera(cam.name + "/image_raw", 2));
      fixture_pubs_.push_back(nh.advertise<sensor_msgs::Image>(cam.name + "/fixture/image_raw", 1, /*latch=*/true));
      poses_.push_back(calibrationPoses(cam, target_, rotation_center, views, 17 + 101 * (c + 1)));
    }
    timer_ = nh.createWallTimer(ros::WallDuration(1.0 / rate), &CalibrationFixture::onTick, this);
    NODELET_INFO("calibration_fixture: %zu cameras, %d target views each at %.1f Hz", rig_.size(), views, rate);
  }

  sensor_msgs::ImagePtr renderTargetImage(const CameraModel& cam, const Eigen::Isometry3d& pose,
                                          const std_msgs::Header& header) const {
    sensor_msgs::ImagePtr image = makeBgr8Image(header, cam.width, cam.height);
    cv::Mat view(cam.height, cam.width, CV_8UC3, image->data.data(), image->step);
    renderTarget(cam, pose, target_, &view);
    return image;
  }

  void onTick(const ros::WallTimerEvent&) {
    std_msgs::Header header;
    header.stamp = ros::Time::now();  // a source: no ground truth drives the calibration views
    header.seq = static_cast<std::uint32_t>(frame_);
    for (std::size_t c = 0; c < rig_.size(); ++c) {
      const CameraModel& cam = rig_.cameras[c];
      header.frame_id = cam.name + frame_suffix_;
      if (frame_ == 0) vrm_msgs::publishShared(fixture_pubs_[c], renderTargetImage(cam, fixture_pose_, header));
      if (camera_pubs_[c].getNumSubscribers() == 0) continue;
      auto image = renderTargetImage(cam, poses_[c][frame_ % poses_[c].size()], header);
      auto info = boost::make_shared<sensor_msgs::CameraInfo>();
      info->header = header;
      toMsg(cam, info.get());
      camera_pubs_[c].publish(image, info);
    }
    ++frame_;
  }

  CameraRig rig_;
  ChessboardTarget target_;
  Eigen::Isometry3d fixture_pose_ = Eigen::Isometry3d::Identity();
  std::string frame_suffix_;
  std::vector<std::vector<Eigen::Isometry3d>> poses_;  // per camera
  std::vector<image_transport::CameraPublisher> camera_pubs_;
  std::vector<ros::Publisher> fixture_pubs_;
  ros::WallTimer timer_;
  std::uint64_t frame_ = 0;
};

}  // namespace vrm_tracking

PLUGINLIB_EXPORT_CLASS(vrm_tracking::CalibrationFixture, nodelet::Nodelet)
