#include "vrm_render/microscope_camera.h"

#include <cmath>
#include <string>

namespace vrm_render {

Eigen::Matrix4f frustumMatrix(float left, float right, float bottom, float top, float near_plane, float far_plane) {
  Eigen::Matrix4f m = Eigen::Matrix4f::Zero();
  m(0, 0) = 2.0f * near_plane / (right - left);
  m(0, 2) = (right + left) / (right - left);
  m(1, 1) = 2.0f * near_plane / (top - bottom);
  m(1, 2) = (top + bottom) / (top - bottom);
  m(2, 2) = -(far_plane + near_plane) / (far_plane - near_plane);
  m(2, 3) = -2.0f * far_plane * near_plane / (far_plane - near_plane);
  m(3, 2) = -1.0f;
  return m;
}

Eigen::Matrix4f lookAtMatrix(const Eigen::Vector3f& eye, const Eigen::Vector3f& forward, const Eigen::Vector3f& up) {
  const Eigen::Vector3f f = forward.normalized();
  Eigen::Vector3f s = f.cross(up);
  if (s.norm() < 1e-6f) s = f.cross(std::abs(f.x()) < 0.9f ? Eigen::Vector3f::UnitX() : Eigen::Vector3f::UnitY());
  s.normalize();
  const Eigen::Vector3f u = s.cross(f);
  Eigen::Matrix4f m = Eigen::Matrix4f::Identity();
  m.block<1, 3>(0, 0) = s.transpose();
  m.block<1, 3>(1, 0) = u.transpose();
  m.block<1, 3>(2, 0) = -f.transpose();
  m(0, 3) = -s.dot(eye);
  m(1, 3) = -u.dot(eye);
  m(2, 3) = f.dot(eye);
  return m;
}

CameraView microscopeCamera(const MicroscopeRig& rig, const MicroscopeState& state, int width, int height, Eye eye,
                            bool stereo) {
  if (!std::isfinite(state.focus_distance) || !std::isfinite(state.zoom) || !std::isfinite(state.disparity_scale) ||
      state.focus_distance <= 0.0 || state.zoom <= 0.0) {
    throw RenderError("microscope: focus_distance and zoom must be finite and positive (got focus " +
                      std::to_string(state.focus_distance) + ", zoom " + std::to_string(state.zoom) + ")");
  }
  if (width <= 0 || height <= 0) throw RenderError("microscope: image size must be positive");
  CameraView camera;
  camera.width = width;
  camera.height = height;
  camera.forward = rig.view_direction.normalized();
  Eigen::Vector3f right = camera.forward.cross(rig.up).normalized();
  const float focus = static_cast<float>(state.focus_distance);
  const float disparity = static_cast<float>(std::clamp(state.disparity_scale, 0.0, 1.0));
  const float offset =
      stereo ? (eye == Eye::kLeft ? -0.5f : 0.5f) * rig.stereo_baseline * disparity : 0.0f;  // along `right`
  camera.position = rig.objective + right * offset;
  camera.near_plane = rig.near_plane;
  camera.far_plane = std::max(rig.far_plane, focus * 1.5f);
  camera.focus_depth = focus;
  // The window at the focal plane is the same for both eyes: shift each frustum by the eye's offset.
  const float half_w = 0.5f * rig.field_width / static_cast<float>(state.zoom);
  const float half_h = half_w * static_cast<float>(height) / static_cast<float>(width);
  const float scale = camera.near_plane / focus;
  camera.projection = frustumMatrix((-half_w - offset) * scale, (half_w - offset) * scale, -half_h * scale,
                                    half_h * scale, camera.near_plane, camera.far_plane);
  camera.view = lookAtMatrix(camera.position, camera.forward, rig.up);
  return camera;
}

bool projectToPixel(const CameraView& camera, const Eigen::Vector3f& world, Eigen::Vector2f* pixel) {
  const Eigen::Vector4f clip = camera.viewProjection() * world.homogeneous();
  if (clip.w() <= 0.0f) return false;
  const float x_ndc = clip.x() / clip.w();
  const float y_ndc = clip.y() / clip.w();
  (*pixel)(0) = (x_ndc * 0.5f + 0.5f) * camera.width;
  (*pixel)(1) = (1.0f - (y_ndc * 0.5f + 0.5f)) * camera.height;
  return true;
}

}  // namespace vrm_render
