#pragma once
// Pinhole cameras and the three-camera tracking rig of EyeSi (thesis §7.3.2: three CMOS colour cameras, 640×480,
// below the eye, calibrated). ROS-free; the YAML layout is the standard camera calibration file of
// camera_calibration_parsers / camera_info_manager, plus a `world_to_camera` extrinsics block that those readers
// ignore, so each camera entry can be handed to a stock ROS camera driver unchanged.
//
// Conventions: the camera frame is the OpenCV optical frame (x right, y down, z forward); pixel centres are at
// integer coordinates (the MarkerObservation convention); distortion is plumb_bob (k1 k2 p1 p2 k3) or none.

#include <Eigen/Geometry>
#include <string>
#include <vector>

namespace YAML {
class Node;
class Emitter;
}  // namespace YAML

namespace vrm_tracking {

struct CameraModel {
  std::string name = "camera";
  int width = 640;
  int height = 480;
  Eigen::Matrix3d K = Eigen::Matrix3d::Identity();
  std::vector<double> distortion;  // plumb_bob k1 k2 p1 p2 k3; empty or all zero = no distortion
  Eigen::Isometry3d world_to_camera = Eigen::Isometry3d::Identity();  // p_camera = world_to_camera * p_world

  // Pixel of a world point; false when it lies behind the camera (z <= 1 mm) or is not finite. Points outside the
  // image still project (the caller decides about visibility: see inImage()).
  bool project(const Eigen::Vector3d& p_world, Eigen::Vector2d* pixel) const;
  bool inImage(const Eigen::Vector2d& pixel, double margin = 0.0) const;
  // Normalised image coordinates (z = 1) of a distorted pixel (iterative inverse of plumb_bob).
  Eigen::Vector2d normalise(const Eigen::Vector2d& pixel) const;
  Eigen::Vector2d distortNormalised(const Eigen::Vector2d& xy) const;
  bool hasDistortion() const;
  Eigen::Vector3d centreInWorld() const { return world_to_camera.inverse().translation(); }
  Eigen::Vector3d opticalAxisInWorld() const { return world_to_camera.linear().transpose().col(2); }
  // Size of one pixel on a fronto-parallel plane at this depth (m/px), from fx.
  double metresPerPixel(double depth) const { return depth / K(0, 0); }
};

struct CameraRig {
  std::vector<CameraModel> cameras;
  std::size_t size() const { return cameras.size(); }
};

// A camera at `position` looking at `target`; the image x axis is as close as possible to `image_x_hint`.
CameraModel lookAtCamera(const std::string& name, int width, int height, double focal_px,
                         const Eigen::Vector3d& position, const Eigen::Vector3d& target,
                         const Eigen::Vector3d& image_x_hint);

// The default rig (see config/rig_default.yaml, README): three 640×480 cameras 100 mm from the eye centre, below
// the eye, 40° off the downward vertical, 120° apart in azimuth (90°, 210°, 330°), portrait-rolled (image x in the
// camera's vertical plane, the long image side along the longer silhouette of the tilted working volume),
// f = 950 px. The 30×30×30 mm working volume around the eye centre projects into every image with >= 10 px
// margin; at the eye centre a pixel covers 105 µm.
struct DefaultRigGeometry {
  double distance = 0.100;     // m, camera centre to eye centre
  double tilt_deg = 40.0;      // optical axis from the downward vertical (-z)
  double azimuth0_deg = 90.0;  // azimuth of camera 0; the others follow at +120°
  double focal_px = 950.0;
  int width = 640;
  int height = 480;
  bool portrait = true;
};
CameraRig makeDefaultRig(const DefaultRigGeometry& geometry = DefaultRigGeometry());

// Standard camera calibration YAML (image_width, image_height, camera_name, camera_matrix, distortion_model,
// distortion_coefficients, rectification_matrix, projection_matrix) + world_to_camera {rotation (3×3 row major),
// translation [m]}. Missing world_to_camera = identity. Read by the strict reader (vrm_scene/yaml/strict_reader.h):
// unknown keys and bad values throw vrm_sim::YamlError (a std::runtime_error) "<file>:<line>:<column>: <field>: ...".
CameraModel cameraFromYaml(const YAML::Node& node, const std::string& source);
void cameraToYaml(const CameraModel& camera, YAML::Emitter* out);
CameraModel loadCameraYaml(const std::string& path);
void saveCameraYaml(const CameraModel& camera, const std::string& path);
// Rig file: `cameras:` a list of camera entries as above.
CameraRig loadRigYaml(const std::string& path);
CameraRig rigFromYamlString(const std::string& text, const std::string& source = "<string>");
void saveRigYaml(const CameraRig& rig, const std::string& path);
std::string rigToYamlString(const CameraRig& rig);

}  // namespace vrm_tracking
