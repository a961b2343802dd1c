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
// Observations of unequal reliability (issue 43 §2: a marker partly hidden by a shaft or another marker). The
// visible part of a disc cut by a straight edge is symmetric about the normal of the edge through the disc's centre,
// so its centroid moves along that normal only: a cut centroid is exact along the edge and biased across it.
// information[i] (2×2, symmetric positive semi-definite, px⁻²) weighs observation i's pixel residual rᵢ (an
// ordinary centroid of noise σ: identity / σ²); prior (optional): a point and its isotropic standard deviation (m),
// e.g. the marker's prediction, for the direction two rays alone cannot fix when one of them is cut along it.
// Gauss-Newton on Σ rᵢᵀ Wᵢ rᵢ + |x − prior|² / σ², started from the DLT. rms_px / max_px measure each residual in
// its observation's reliable directions (rᵢᵀ Ŵᵢ rᵢ with Ŵᵢ = Wᵢ / its largest eigenvalue), so a bias in a direction
// known to be biased does not make the solution look inconsistent. Invalid as triangulate(), or for a non-finite or
// missing weight.
struct PointPrior {
  Eigen::Vector3d point = Eigen::Vector3d::Zero();
  double sigma = 0.0;  // m; <= 0 or non-finite: no prior
};
Triangulation triangulateWeighted(const CameraRig& rig, const std::vector<PixelObservation>& observations,
                                  const std::vector<Eigen::Matrix2d>& information, const PointPrior* prior = nullptr,
                                  int max_iterations = 10);
// One refined solution for every pair of observations (diagnostics; the EyeSi-style per-pair reconstruction).
std::vector<Triangulation> triangulatePairs(const CameraRig& rig, const std::vector<PixelObservation>& observations);
// RMS and max pixel residual of a point; infinity if it does not project into some camera.
double reprojectionRms(const CameraRig& rig, const std::vector<PixelObservation>& observations,
                       const Eigen::Vector3d& point, double* max_px = nullptr);

}  // namespace vrm_tracking
