#include "vrm_tracking/calibration.h"

#include <algorithm>
#include <cmath>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>
#include <random>

namespace vrm_tracking {

std::vector<cv::Point3f> ChessboardTarget::objectPoints() const {
  std::vector<cv::Point3f> points;
  for (int r = 0; r < rows; ++r) {
    for (int c = 0; c < cols; ++c) {
      points.emplace_back(static_cast<float>(c * square), static_cast<float>(r * square), 0.0f);
    }
  }
  return points;
}

void renderTarget(const CameraModel& camera, const Eigen::Isometry3d& target_to_world, const ChessboardTarget& target,
                  cv::Mat* bgr, int supersample) {
  bgr->create(camera.height, camera.width, CV_8UC3);
  const Eigen::Isometry3d camera_to_target = (camera.world_to_camera * target_to_world).inverse();
  const Eigen::Vector3d origin = camera_to_target.translation();
  const Eigen::Matrix3d rot = camera_to_target.linear();
  const double s = target.square;
  const int n = std::max(1, supersample);
  for (int y = 0; y < camera.height; ++y) {
    cv::Vec3b* row = bgr->ptr<cv::Vec3b>(y);
    for (int x = 0; x < camera.width; ++x) {
      double sum = 0.0;
      for (int sy = 0; sy < n; ++sy) {
        for (int sx = 0; sx < n; ++sx) {
          const Eigen::Vector2d px(x - 0.5 + (sx + 0.5) / n, y - 0.5 + (sy + 0.5) / n);
          const Eigen::Vector2d xy = camera.normalise(px);
          const Eigen::Vector3d dir = rot * Eigen::Vector3d(xy.x(), xy.y(), 1.0);
          double value = 110.0;  // background
          if (std::abs(dir.z()) > 1e-12) {
            const double t = -origin.z() / dir.z();
            if (t > 0.0) {
              const Eigen::Vector3d p = origin + t * dir;
              const bool on_board = p.x() >= -2.0 * s && p.x() <= (target.cols + 1) * s && p.y() >= -2.0 * s &&
                                    p.y() <= (target.rows + 1) * s;
              if (on_board) {
                const int a = static_cast<int>(std::floor(p.x() / s)) + 1,
                          b = static_cast<int>(std::floor(p.y() / s)) + 1;
                const bool squares = a >= 0 && a <= target.cols && b >= 0 && b <= target.rows;
                value = squares && (a + b) % 2 == 0 ? 20.0 : 235.0;
              }
            }
          }
          sum += value;
        }
      }
      const auto v = static_cast<std::uint8_t>(std::lround(sum / (n * n)));
      row[x] = cv::Vec3b(v, v, v);
    }
  }
}

bool detectTarget(const cv::Mat& bgr, const ChessboardTarget& target, std::vector<cv::Point2f>* corners) {
  if (bgr.empty()) return false;
  cv::Mat grey;
  if (bgr.channels() == 3) {
    cv::cvtColor(bgr, grey, cv::COLOR_BGR2GRAY);
  } else {
    grey = bgr;
  }
  const cv::Size pattern(target.cols, target.rows);
  std::vector<cv::Point2f> found;
  // OpenCV asserts on images it cannot search (fuzz_calibrator_images: a 14 x 224 view makes findChessboardCorners
  // pick an even adaptive-threshold block size, and adaptiveThreshold throws). Such an image holds no board for us.
  try {
    if (!cv::findChessboardCorners(grey, pattern, found, cv::CALIB_CB_ADAPTIVE_THRESH | cv::CALIB_CB_NORMALIZE_IMAGE)) {
      return false;
    }
    cv::cornerSubPix(grey, found, cv::Size(5, 5), cv::Size(-1, -1),
                     cv::TermCriteria(cv::TermCriteria::EPS + cv::TermCriteria::COUNT, 50, 1e-4));
  } catch (const cv::Exception&) {
    return false;
  }
  if (found.size() != static_cast<std::size_t>(target.cols * target.rows)) return false;
  // OpenCV may return the rows in either direction (a mirror of the target's order) and start at either end (a
  // 180° turn). Handedness first: the printed face (+z of the target) faces the camera, so the target's x and y
  // axes appear clockwise in the image (y down): cross(x, y) < 0.
  const cv::Point2f ex = found[1] - found[0], ey = found[target.cols] - found[0];
  if (ex.x * ey.y - ex.y * ey.x > 0.0f) {
    std::vector<cv::Point2f> flipped(found.size());
    for (int r = 0; r < target.rows; ++r) {
      for (int c = 0; c < target.cols; ++c)
        flipped[r * target.cols + c] = found[(target.rows - 1 - r) * target.cols + c];
    }
    found.swap(flipped);
  }
  // Then the end: the square between the first corners must be black (ChessboardTarget).
  auto darkFirstSquare = [&](const std::vector<cv::Point2f>& c) {
    const cv::Point2f centre = (c[0] + c[1] + c[target.cols] + c[target.cols + 1]) * 0.25f;
    const int x = std::clamp(static_cast<int>(std::lround(centre.x)), 0, grey.cols - 1);
    const int y = std::clamp(static_cast<int>(std::lround(centre.y)), 0, grey.rows - 1);
    return grey.at<std::uint8_t>(y, x) < 128;
  };
  if (!darkFirstSquare(found)) std::reverse(found.begin(), found.end());
  if (!darkFirstSquare(found)) return false;
  *corners = found;
  return true;
}

IntrinsicCalibration calibrateIntrinsics(const std::vector<cv::Mat>& views, const ChessboardTarget& target) {
  IntrinsicCalibration result;
  std::vector<std::vector<cv::Point3f>> object;
  std::vector<std::vector<cv::Point2f>> image;
  cv::Size size;
  for (const cv::Mat& view : views) {
    std::vector<cv::Point2f> corners;
    if (!detectTarget(view, target, &corners)) continue;
    object.push_back(target.objectPoints());
    image.push_back(corners);
    size = view.size();
  }
  result.views_used = static_cast<int>(image.size());
  if (image.size() < 3) return result;
  cv::Mat K, dist;
  std::vector<cv::Mat> rvecs, tvecs;
  // k3 fixed: a measurement lens with a narrow field does not constrain it, and freeing it trades focal accuracy.
  result.rms_px = cv::calibrateCamera(object, image, size, K, dist, rvecs, tvecs, cv::CALIB_FIX_K3);
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) result.K(r, c) = K.at<double>(r, c);
  }
  result.distortion.assign(5, 0.0);
  for (int i = 0; i < std::min(5, static_cast<int>(dist.total())); ++i) result.distortion[i] = dist.at<double>(i);
  result.ok = std::isfinite(result.rms_px);
  return result;
}

bool calibrateExtrinsics(const cv::Mat& reference, const ChessboardTarget& target,
                         const Eigen::Isometry3d& target_to_world, CameraModel* camera, double* rms_px) {
  std::vector<cv::Point2f> corners;
  if (!detectTarget(reference, target, &corners)) return false;
  cv::Mat K(3, 3, CV_64F), dist(1, 5, CV_64F, cv::Scalar(0));
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) K.at<double>(r, c) = camera->K(r, c);
  }
  for (std::size_t i = 0; i < camera->distortion.size() && i < 5; ++i)
    dist.at<double>(static_cast<int>(i)) = camera->distortion[i];
  const std::vector<cv::Point3f> object = target.objectPoints();
  cv::Mat rvec, tvec;
  if (!cv::solvePnP(object, corners, K, dist, rvec, tvec, false, cv::SOLVEPNP_ITERATIVE)) return false;
  cv::Mat R;
  cv::Rodrigues(rvec, R);
  Eigen::Isometry3d target_to_camera = Eigen::Isometry3d::Identity();
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) target_to_camera.linear()(r, c) = R.at<double>(r, c);
    target_to_camera.translation()(r) = tvec.at<double>(r);
  }
  camera->world_to_camera = target_to_camera * target_to_world.inverse();
  if (rms_px) {
    std::vector<cv::Point2f> projected;
    cv::projectPoints(object, rvec, tvec, K, dist, projected);
    double sum = 0.0;
    for (std::size_t i = 0; i < projected.size(); ++i) {
      const cv::Point2f d = projected[i] - corners[i];
      sum += d.dot(d);
    }
    *rms_px = std::sqrt(sum / projected.size());
  }
  return true;
}

Eigen::Isometry3d fixturePose(const ChessboardTarget& target, const Eigen::Vector3d& centre) {
  Eigen::Isometry3d fixture = Eigen::Isometry3d::Identity();
  fixture.linear() = Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitX()).toRotationMatrix();
  fixture.translation() = centre - fixture.linear() * target.centre();
  return fixture;
}

Eigen::Isometry3d facingPose(const CameraModel& camera, const ChessboardTarget& target, const Eigen::Vector3d& centre,
                             double tilt_x, double tilt_y, double spin) {
  const Eigen::Matrix3d camera_to_world = camera.world_to_camera.linear().transpose();
  // Target z along the camera's viewing direction (the printed face looks back at the camera), then the tilts and
  // an in-plane spin.
  const Eigen::Matrix3d facing = camera_to_world * Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitX()).toRotationMatrix();
  const Eigen::Matrix3d rot = facing * Eigen::AngleAxisd(tilt_x, Eigen::Vector3d::UnitX()) *
                              Eigen::AngleAxisd(tilt_y, Eigen::Vector3d::UnitY()) *
                              Eigen::AngleAxisd(spin, Eigen::Vector3d::UnitZ());
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.linear() = rot;
  pose.translation() = centre - rot * target.centre();
  return pose;
}

std::vector<Eigen::Isometry3d> calibrationPoses(const CameraModel& camera, const ChessboardTarget& target,
                                                const Eigen::Vector3d& centre, int count, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> pos(-0.004, 0.004), tilt(-0.7, 0.7), spin(-M_PI, M_PI);
  std::vector<Eigen::Isometry3d> poses;
  for (int i = 0; i < count; ++i) {
    const Eigen::Vector3d c = centre + Eigen::Vector3d(pos(rng), pos(rng), pos(rng));
    const double tx = tilt(rng), ty = tilt(rng), sp = spin(rng);
    poses.push_back(facingPose(camera, target, c, tx, ty, sp));
  }
  return poses;
}

CameraCalibrationResult calibrateCamera(const std::string& name, const std::vector<cv::Mat>& views,
                                        const cv::Mat& reference, const ChessboardTarget& target,
                                        const Eigen::Isometry3d& target_to_world) {
  CameraCalibrationResult result;
  const IntrinsicCalibration intr = calibrateIntrinsics(views, target);
  result.views_used = intr.views_used;
  result.intrinsic_rms_px = intr.rms_px;
  if (!intr.ok) {
    result.error = name + ": target found in " + std::to_string(intr.views_used) + " views (3 needed)";
    return result;
  }
  CameraModel& cam = result.camera;
  cam.name = name;
  cam.width = reference.cols;
  cam.height = reference.rows;
  cam.K = intr.K;
  cam.distortion = intr.distortion;
  if (!calibrateExtrinsics(reference, target, target_to_world, &cam, &result.extrinsic_rms_px)) {
    result.error = name + ": target not found in the reference (fixture) image";
    return result;
  }
  result.ok = true;
  return result;
}

CalibrationError compareCameras(const CameraModel& calibrated, const CameraModel& truth) {
  CalibrationError e;
  e.focal_percent = 100.0 * std::max(std::abs(calibrated.K(0, 0) / truth.K(0, 0) - 1.0),
                                     std::abs(calibrated.K(1, 1) / truth.K(1, 1) - 1.0));
  e.position_m = (calibrated.centreInWorld() - truth.centreInWorld()).norm();
  e.rotation_deg = Eigen::Quaterniond(calibrated.world_to_camera.linear())
                       .angularDistance(Eigen::Quaterniond(truth.world_to_camera.linear())) *
                   180.0 / M_PI;
  return e;
}

}  // namespace vrm_tracking
