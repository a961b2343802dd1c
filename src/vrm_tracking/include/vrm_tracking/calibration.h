#pragma once
// Rig calibration from images of a chessboard target (issue 5; the thesis calibrates EyeSi's cameras with Tsai's
// method, §7.3.2 — here Zhang's method as implemented by OpenCV's calibrateCamera). Intrinsics per camera from
// several views; the extrinsics (world -> camera) from one view of the target at a known world pose (a fixture in
// place of the mechanical eye defines the world frame). Includes a renderer of exact synthetic target images so the
// whole procedure is testable against a known rig.

#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "vrm_tracking/camera_rig.h"

namespace vrm_tracking {

// A chessboard of cols × rows inner corners; corner (c, r) sits at (c·square, r·square, 0) in the target frame.
// The square touching corners (0,0), (1,0), (0,1), (1,1) is black. cols × rows must be even × odd (or odd × even)
// so that a 180° turn swaps the square colours, which makes the detected corner order unambiguous.
struct ChessboardTarget {
  int cols = 9;
  int rows = 6;
  double square = 0.0025;  // m
  std::vector<cv::Point3f> objectPoints() const;
  Eigen::Vector3d centre() const { return Eigen::Vector3d((cols - 1) * square / 2.0, (rows - 1) * square / 2.0, 0.0); }
};

// Rays per pixel side of the synthetic sensor: a pixel integrates the light over its area, and 8 x 8 samples come
// within 0.004 px of 16 x 16 in the detected corners' RMS error (default rig, fixture and three views; 3 x 3 left
// 0.027 px more on camera_0, and made the estimated rig's tip error 15.4 um where 8 x 8 gives 4.1 on the worst random
// fast trajectory of bench_tracking).
constexpr int kSensorSupersample = 8;

// Renders the target (with a one-square white border on a grey background) as seen by `camera`, anti-aliased by
// supersample² rays per pixel; pixels whose ray misses the board's front side see the background.
void renderTarget(const CameraModel& camera, const Eigen::Isometry3d& target_to_world, const ChessboardTarget& target,
                  cv::Mat* bgr, int supersample = kSensorSupersample);

// Corners in the target's order (objectPoints()), refined to sub-pixel; false if the board is not found.
bool detectTarget(const cv::Mat& bgr, const ChessboardTarget& target, std::vector<cv::Point2f>* corners);

struct IntrinsicCalibration {
  bool ok = false;
  Eigen::Matrix3d K = Eigen::Matrix3d::Identity();
  std::vector<double> distortion;  // k1 k2 p1 p2 k3
  double rms_px = 0.0;             // reprojection RMS over all views
  int views_used = 0;
};

// Zhang's method over the views in which the target is found (needs >= 3).
IntrinsicCalibration calibrateIntrinsics(const std::vector<cv::Mat>& views, const ChessboardTarget& target);

// world -> camera from one image of the target at the known pose target_to_world (intrinsics from `camera`).
// false if the target is not found.
bool calibrateExtrinsics(const cv::Mat& reference, const ChessboardTarget& target,
                         const Eigen::Isometry3d& target_to_world, CameraModel* camera, double* rms_px = nullptr);

// --- Whole-rig procedure (the calibrate_rig tool and its tests) ---

// The world fixture: the target centred on `centre` (the eye's rotation centre), printed face down towards the
// cameras below. Its pose defines the world frame of the extrinsics.
Eigen::Isometry3d fixturePose(const ChessboardTarget& target, const Eigen::Vector3d& centre);

// A target pose facing `camera`, its centre at `centre` (world), tilted about its x and y axes and spun in-plane.
Eigen::Isometry3d facingPose(const CameraModel& camera, const ChessboardTarget& target, const Eigen::Vector3d& centre,
                             double tilt_x, double tilt_y, double spin);

// `count` seeded calibration poses for one camera: centres within ±4 mm of `centre`, tilts within ±0.7 rad.
std::vector<Eigen::Isometry3d> calibrationPoses(const CameraModel& camera, const ChessboardTarget& target,
                                                const Eigen::Vector3d& centre, int count, unsigned seed);

struct CameraCalibrationResult {
  bool ok = false;
  CameraModel camera;  // calibrated intrinsics + extrinsics (name and size from the images)
  double intrinsic_rms_px = 0.0;
  double extrinsic_rms_px = 0.0;
  int views_used = 0;
  std::string error;  // why not ok
};

// Intrinsics (Zhang) from `views`, extrinsics from `reference` (the target at `target_to_world`).
CameraCalibrationResult calibrateCamera(const std::string& name, const std::vector<cv::Mat>& views,
                                        const cv::Mat& reference, const ChessboardTarget& target,
                                        const Eigen::Isometry3d& target_to_world);

// Errors of a calibrated camera against the true one: focal length (%, worst of fx/fy), centre (m), rotation (deg).
struct CalibrationError {
  double focal_percent = 0.0;
  double position_m = 0.0;
  double rotation_deg = 0.0;
};
CalibrationError compareCameras(const CameraModel& calibrated, const CameraModel& truth);

}  // namespace vrm_tracking
