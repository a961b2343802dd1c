#pragma once
// Stereo microscope cameras (thesis §6): two parallel optical paths separated by the stereo baseline, with
// asymmetric (off-axis) frusta that share the field at the focal plane, so objects in focus have zero disparity.
// Reduced disparity (§6, against simulator sickness) scales the baseline. Zoom narrows the field.

#include <Eigen/Core>
#include <array>

#include "vrm_render/render_types.h"

namespace vrm_render {

struct CameraView {
  Eigen::Matrix4f view = Eigen::Matrix4f::Identity();
  Eigen::Matrix4f projection = Eigen::Matrix4f::Identity();
  Eigen::Vector3f position = Eigen::Vector3f::Zero();
  Eigen::Vector3f forward{0.0f, 0.0f, -1.0f};
  float near_plane = 0.1f;
  float far_plane = 0.3f;
  float focus_depth = 0.2f;  // along forward
  int width = 0;
  int height = 0;

  Eigen::Matrix4f viewProjection() const { return projection * view; }
};

// Throws RenderError for non-finite or non-positive knob values or sizes.
CameraView microscopeCamera(const MicroscopeRig& rig, const MicroscopeState& state, int width, int height, Eye eye,
                            bool stereo);

// Pixel coordinates (x right, y down, pixel centres at .5) of a world point; false when it is behind the camera.
bool projectToPixel(const CameraView& camera, const Eigen::Vector3f& world, Eigen::Vector2f* pixel);

// OpenGL-style perspective matrices, exposed for tests and the light pipe's shadow frustum.
Eigen::Matrix4f frustumMatrix(float left, float right, float bottom, float top, float near_plane, float far_plane);
Eigen::Matrix4f lookAtMatrix(const Eigen::Vector3f& eye, const Eigen::Vector3f& forward, const Eigen::Vector3f& up);

}  // namespace vrm_render
