// Camera rig files (vrm_tracking camera_rig.h, `cameras:` list): a rig the parser accepts is used as the tracker and
// the rig renderer use it (project, normalise, serialise back).
#include <stdexcept>

#include "fuzz_target.h"
#include "vrm_tracking/camera_rig.h"

namespace {
void exerciseCamera(const vrm_tracking::CameraModel& camera) {
  Eigen::Vector2d pixel;
  for (const Eigen::Vector3d& p : {Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(0.01, -0.01, 0.005)}) {
    if (camera.project(p, &pixel)) {
      camera.inImage(pixel, 2.0);
      camera.normalise(pixel);
    }
  }
  camera.normalise(Eigen::Vector2d(camera.width / 2.0, camera.height / 2.0));
  camera.centreInWorld();
  camera.opticalAxisInWorld();
}
}  // namespace

VRM_FUZZ_TARGET(rig_yaml) {
  using namespace vrm_tracking;
  const std::string text(reinterpret_cast<const char*>(data), size);
  CameraRig rig;
  try {
    rig = rigFromYamlString(text, "fuzzed_rig.yaml");
  } catch (const std::runtime_error&) {
    return 0;
  }
  for (const CameraModel& camera : rig.cameras) exerciseCamera(camera);
  // What the rig calibrator writes must read back.
  const std::string written = rigToYamlString(rig);
  rigFromYamlString(written, "written_rig.yaml");
  return 0;
}
