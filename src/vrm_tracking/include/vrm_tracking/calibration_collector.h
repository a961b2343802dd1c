#pragma once
// What the rig_calibrator nodelet does with the images it receives (issue 5; ROS-free since issue 39, so the fuzz
// target calibrator_images runs exactly this): per camera, chessboard views until `views_needed` distinct poses, and
// one fixture view; once every camera has both, each camera is calibrated (calibration.h calibrateCamera) and the
// rig is complete. Thread-safe: the detection runs outside the lock (it is the slow part, one camera's callback
// must not stall the others).

#include <Eigen/Geometry>
#include <mutex>
#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <vector>

#include "vrm_tracking/calibration.h"
#include "vrm_tracking/camera_rig.h"

namespace vrm_tracking {

class CalibrationCollector {
 public:
  // Throws std::invalid_argument for no cameras, views_needed < 3 or a target that is not even x odd.
  CalibrationCollector(std::vector<std::string> cameras, const ChessboardTarget& target,
                       const Eigen::Isometry3d& target_to_world, int views_needed);

  enum class ViewOutcome {
    kAdded,      // a new pose
    kNoTarget,   // an empty image or no chessboard in it
    kSamePose,   // within 5 px (mean corner distance) of a view already kept
    kOtherSize,  // not the size of the camera's first view (Zhang's method needs one image size)
    kEnough,     // the camera has its views, or the rig is calibrated
  };
  ViewOutcome addView(std::size_t camera, const cv::Mat& bgr);
  // The fixture view replaces the previous one (the latest wins); false for an empty image or once calibrated.
  bool setFixture(std::size_t camera, const cv::Mat& bgr);

  struct Calibration {
    bool ok = false;
    CameraRig rig;                                 // when ok
    std::vector<CameraCalibrationResult> cameras;  // one per camera calibrated so far (the failing one last)
    std::string error;                             // why not ok
  };
  // Calibrates once every camera has its views and fixture (then never again, whatever the outcome); nullopt while
  // images are missing. Failures inside OpenCV are an error, not an exception.
  std::optional<Calibration> calibrateIfComplete();

  std::size_t cameraCount() const { return cameras_.size(); }
  const std::string& cameraName(std::size_t camera) const { return cameras_.at(camera).name; }
  std::size_t viewCount(std::size_t camera) const;
  int viewsNeeded() const { return views_needed_; }
  bool done() const;

 private:
  struct Camera {
    std::string name;
    std::vector<cv::Mat> views;
    std::vector<std::vector<cv::Point2f>> corners;  // of the kept views
    cv::Mat fixture;
  };
  std::optional<ViewOutcome> refusal(const Camera& cam, const cv::Mat& bgr) const;

  mutable std::mutex mutex_;
  std::vector<Camera> cameras_;
  ChessboardTarget target_;
  Eigen::Isometry3d target_to_world_;
  int views_needed_;
  bool done_ = false;
};

}  // namespace vrm_tracking
