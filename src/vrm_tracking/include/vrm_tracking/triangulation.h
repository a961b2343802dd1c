#pragma once
// 3D reconstruction of a marker from its centroids in several calibrated cameras (thesis §7.3.2: one solution per
// camera pair, the third camera adds accuracy and covers occlusion). The linear DLT (Hartley & Zisserman §12.2,
// on normalised coordinates, so it is well conditioned) starts a Gauss-Newton refinement of the pixel reprojection
// error: the maximum-likelihood point for isotropic Gaussian centroid noise, which is what the benchmark's ideal
// floor assumes.

#include <Eigen/Core>
#include <cstddef>
#include <limits>
#include <vector>

#include "vrm_tracking/camera_rig.h"

namespace vrm_tracking {

struct PixelObservation {
  std::size_t camera = 0;
  Eigen::Vector2d pixel = Eigen::Vector2d::Zero();
};

struct Triangulation {
  bool valid = false;
  Eigen::Vector3d point = Eigen::Vector3d::Constant(std::numeric_limits<double>::quiet_NaN());
  double rms_px = std::numeric_limits<double>::infinity();  // reprojection residual over the cameras used
  double max_px = std::numeric_limits<double>::infinity();
  std::vector<std::size_t> cameras;
};

// Linear solution only. Invalid for < 2 observations, unknown cameras, non-finite pixels, or a point behind a camera.
Triangulation triangulateDlt(const CameraRig& rig, const std::vector<PixelObservation>& observations);
// DLT + Gauss-Newton on the pixel residuals (stops when the step is below 1e-10 m).
Triangulation triangulate(const CameraRig& rig, const std::vector<PixelObservation>& observations,
                          int max_iterations = 10);
// One refined solution for every pair of observations (diagnostics; the EyeSi-style per-pair reconstruction).
std::vector<Triangulation> triangulatePairs(const CameraRig& rig, const std::vector<PixelObservation>& observations);
// RMS and max pixel residual of a point; infinity if it does not project into some camera.
double reprojectionRms(const CameraRig& rig, const std::vector<PixelObservation>& observations,
                       const Eigen::Vector3d& point, double* max_px = nullptr);

}  // namespace vrm_tracking
