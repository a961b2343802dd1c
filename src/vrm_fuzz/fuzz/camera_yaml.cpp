// Camera calibration files (vrm_tracking camera_rig.h: the camera_calibration_parsers YAML + world_to_camera, what
// the rig calibrator writes and the tracker reads), and a CameraInfo built from it handed back to
// updateIntrinsics() as the detector/tracker would receive it from a driver.
#include <yaml-cpp/yaml.h>

#include <stdexcept>

#include "fuzz_target.h"
#include "vrm_tracking/camera_rig.h"
#include "vrm_tracking/conversions.h"

VRM_FUZZ_TARGET(camera_yaml) {
  using namespace vrm_tracking;
  const std::string text(reinterpret_cast<const char*>(data), size);
  CameraModel camera;
  try {
    camera = cameraFromYaml(YAML::Load(text), "fuzzed_camera.yaml");
  } catch (const std::exception&) {  // YAML::Exception and std::runtime_error: both are the loader's rejections
    return 0;
  }
  Eigen::Vector2d pixel;
  if (camera.project(Eigen::Vector3d(0.001, 0.002, 0.0), &pixel)) camera.normalise(pixel);
  camera.distortNormalised(Eigen::Vector2d(0.1, -0.2));
  YAML::Emitter out;
  cameraToYaml(camera, &out);
  cameraFromYaml(YAML::Load(out.c_str()), "written_camera.yaml");

  sensor_msgs::CameraInfo info;
  toMsg(camera, &info);
  CameraModel updated;
  try {
    updateIntrinsics(info, &updated);
  } catch (const std::invalid_argument&) {
  }
  return 0;
}
