#include "vrm_tracking/calibration_collector.h"

#include <cmath>
#include <stdexcept>

namespace vrm_tracking {

CalibrationCollector::CalibrationCollector(std::vector<std::string> cameras, const ChessboardTarget& target,
                                           const Eigen::Isometry3d& target_to_world, int views_needed)
    : target_(target), target_to_world_(target_to_world), views_needed_(views_needed) {
  if (cameras.empty()) throw std::invalid_argument("calibration: no cameras");
  if (views_needed < 3) throw std::invalid_argument("calibration: views must be >= 3 (Zhang's method)");
  if (target.cols < 2 || target.rows < 2 || (target.cols + target.rows) % 2 == 0 || !(target.square > 0.0)) {
    throw std::invalid_argument("calibration: the target needs even x odd inner corners (>= 2 each) and a square > 0");
  }
  for (std::string& name : cameras) cameras_.push_back(Camera{std::move(name), {}, {}, {}});
}

// Why camera `cam` takes no view of this size now, if it does not (mutex_ held).
std::optional<CalibrationCollector::ViewOutcome> CalibrationCollector::refusal(const Camera& cam,
                                                                               const cv::Mat& bgr) const {
  if (done_ || static_cast<int>(cam.views.size()) >= views_needed_) return ViewOutcome::kEnough;
  if (!cam.views.empty() && bgr.size() != cam.views.front().size()) return ViewOutcome::kOtherSize;
  return std::nullopt;
}

CalibrationCollector::ViewOutcome CalibrationCollector::addView(std::size_t camera, const cv::Mat& bgr) {
  {
    // Before the detection (tens of ms): a camera that has its views costs nothing.
    std::lock_guard<std::mutex> lock(mutex_);
    if (const auto refused = refusal(cameras_.at(camera), bgr)) return *refused;
  }
  std::vector<cv::Point2f> corners;
  if (bgr.empty() || !detectTarget(bgr, target_, &corners)) return ViewOutcome::kNoTarget;
  std::lock_guard<std::mutex> lock(mutex_);
  Camera& cam = cameras_.at(camera);
  if (const auto refused = refusal(cam, bgr)) return *refused;  // again: another thread may have added meanwhile
  for (const auto& seen : cam.corners) {
    double distance = 0.0;
    for (std::size_t i = 0; i < corners.size(); ++i) {
      distance += std::hypot(corners[i].x - seen[i].x, corners[i].y - seen[i].y);
    }
    if (distance / static_cast<double>(corners.size()) < 5.0) return ViewOutcome::kSamePose;
  }
  cam.views.push_back(bgr);
  cam.corners.push_back(std::move(corners));
  return ViewOutcome::kAdded;
}

bool CalibrationCollector::setFixture(std::size_t camera, const cv::Mat& bgr) {
  std::lock_guard<std::mutex> lock(mutex_);
  Camera& cam = cameras_.at(camera);
  if (done_ || bgr.empty()) return false;
  cam.fixture = bgr;
  return true;
}

std::size_t CalibrationCollector::viewCount(std::size_t camera) const {
  std::lock_guard<std::mutex> lock(mutex_);
  return cameras_.at(camera).views.size();
}

bool CalibrationCollector::done() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return done_;
}

std::optional<CalibrationCollector::Calibration> CalibrationCollector::calibrateIfComplete() {
  std::vector<Camera> cameras;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (done_) return std::nullopt;
    for (const Camera& cam : cameras_) {
      if (cam.fixture.empty() || static_cast<int>(cam.views.size()) < views_needed_) return std::nullopt;
    }
    done_ = true;  // one attempt: the images are kept no longer than it takes
    cameras.swap(cameras_);
    for (const Camera& cam : cameras) cameras_.push_back(Camera{cam.name, {}, {}, {}});
  }
  Calibration calibration;
  for (const Camera& cam : cameras) {
    CameraCalibrationResult result;
    try {
      result = calibrateCamera(cam.name, cam.views, cam.fixture, target_, target_to_world_);
    } catch (const cv::Exception& error) {
      result.error = cam.name + ": OpenCV failed: " + error.what();
    }
    calibration.cameras.push_back(result);
    if (!result.ok) {
      calibration.error = result.error;
      return calibration;
    }
    calibration.rig.cameras.push_back(result.camera);
  }
  calibration.ok = true;
  return calibration;
}

}  // namespace vrm_tracking
