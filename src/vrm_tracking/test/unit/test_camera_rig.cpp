// Camera model, default rig geometry and the calibration YAML round trip.

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <string>

#include "vrm_scene/yaml/yaml_error.h"
#include "vrm_tracking/camera_rig.h"

namespace vrm_tracking {
namespace {

TEST(CameraRig, DefaultRigSeesTheWholeWorkingVolumeInEveryCamera) {
  const CameraRig rig = makeDefaultRig();
  ASSERT_EQ(rig.size(), 3u);
  // The thesis' working volume: a 30 mm cube around the eye centre (corners and a grid inside).
  for (const CameraModel& cam : rig.cameras) {
    EXPECT_EQ(cam.width, 640);
    EXPECT_EQ(cam.height, 480);
    for (int i = 0; i <= 6; ++i) {
      for (int j = 0; j <= 6; ++j) {
        for (int k = 0; k <= 6; ++k) {
          const Eigen::Vector3d p(-0.015 + 0.005 * i, -0.015 + 0.005 * j, -0.015 + 0.005 * k);
          Eigen::Vector2d px;
          ASSERT_TRUE(cam.project(p, &px));
          EXPECT_TRUE(cam.inImage(px, 10.0)) << cam.name << " misses " << p.transpose() << " at " << px.transpose();
        }
      }
    }
    // Below the eye, looking up at its centre.
    EXPECT_LT(cam.centreInWorld().z(), -0.05);
    Eigen::Vector2d centre;
    ASSERT_TRUE(cam.project(Eigen::Vector3d::Zero(), &centre));
    EXPECT_NEAR(centre.x(), 319.5, 1e-9);
    EXPECT_NEAR(centre.y(), 239.5, 1e-9);
    EXPECT_NEAR(cam.metresPerPixel(0.1) * 1e6, 105.3, 0.1);
  }
}

TEST(CameraRig, ProjectRejectsPointsBehindAndNaN) {
  const CameraModel cam = makeDefaultRig().cameras[0];
  Eigen::Vector2d px;
  EXPECT_FALSE(cam.project(cam.centreInWorld() - 0.01 * cam.opticalAxisInWorld(), &px));
  EXPECT_FALSE(cam.project(Eigen::Vector3d(NAN, 0, 0), &px));
}

TEST(CameraRig, NormaliseInvertsDistortion) {
  CameraModel cam = makeDefaultRig().cameras[1];
  cam.distortion = {-0.12, 0.05, 0.001, -0.0005, 0.0};
  for (const Eigen::Vector3d p : {Eigen::Vector3d(0.01, -0.012, 0.005), Eigen::Vector3d(-0.014, 0.01, -0.013)}) {
    Eigen::Vector2d px;
    ASSERT_TRUE(cam.project(p, &px));
    const Eigen::Vector3d pc = cam.world_to_camera * p;
    EXPECT_LT((cam.normalise(px) - pc.head<2>() / pc.z()).norm(), 1e-10);
  }
}

TEST(CameraRig, YamlRoundTripIsExact) {
  CameraRig rig = makeDefaultRig();
  rig.cameras[2].distortion = {0.01, -0.02, 0.0, 0.0, 0.003};
  const std::string path = testing::TempDir() + "/rig_roundtrip.yaml";
  saveRigYaml(rig, path);
  const CameraRig back = loadRigYaml(path);
  ASSERT_EQ(back.size(), rig.size());
  for (std::size_t i = 0; i < rig.size(); ++i) {
    EXPECT_EQ(back.cameras[i].name, rig.cameras[i].name);
    EXPECT_EQ(back.cameras[i].width, 640);
    EXPECT_LT((back.cameras[i].K - rig.cameras[i].K).norm(), 1e-12);
    EXPECT_LT((back.cameras[i].world_to_camera.matrix() - rig.cameras[i].world_to_camera.matrix()).norm(), 1e-12);
  }
  EXPECT_DOUBLE_EQ(back.cameras[2].distortion[4], 0.003);
  std::remove(path.c_str());
}

TEST(CameraRig, ReadsAStandardCalibrationFileWithoutExtrinsics) {
  // As written by camera_calibration / camera_info_manager.
  const std::string text = R"(cameras:
  - image_width: 640
    image_height: 480
    camera_name: cam
    camera_matrix: {rows: 3, cols: 3, data: [800, 0, 320, 0, 810, 240, 0, 0, 1]}
    distortion_model: plumb_bob
    distortion_coefficients: {rows: 1, cols: 5, data: [0.1, 0, 0, 0, 0]}
    rectification_matrix: {rows: 3, cols: 3, data: [1, 0, 0, 0, 1, 0, 0, 0, 1]}
    projection_matrix: {rows: 3, cols: 4, data: [800, 0, 320, 0, 0, 810, 240, 0, 0, 0, 1, 0]}
)";
  const CameraRig rig = rigFromYamlString(text);
  ASSERT_EQ(rig.size(), 1u);
  EXPECT_DOUBLE_EQ(rig.cameras[0].K(1, 1), 810.0);
  EXPECT_TRUE(rig.cameras[0].world_to_camera.matrix().isIdentity());
}

TEST(CameraRig, MalformedFilesNameTheField) {
  EXPECT_THROW(rigFromYamlString("cameras: []"), std::runtime_error);
  try {
    rigFromYamlString(
        "cameras:\n  - {image_width: 640, image_height: 480, camera_matrix: {rows: 3, cols: 3, data: [1, 2]}}");
    FAIL();
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("camera_matrix"), std::string::npos) << e.what();
  }
  try {
    rigFromYamlString(
        "cameras:\n  - {image_width: 640, image_height: 480, camera_matrix: {data: [1, 0, 0, 0, 1, 0, 0, 0, 1]},\n"
        "     world_to_camera: {rotation: {data: [2, 0, 0, 0, 1, 0, 0, 0, 1]}, translation: [0, 0, 0]}}");
    FAIL();
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("world_to_camera.rotation"), std::string::npos) << e.what();
  }
  EXPECT_THROW(loadRigYaml("/nonexistent/rig.yaml"), std::runtime_error);
}

// The strict reader's contract (as for scenes and marker layouts): file:line:col, the field path, typo hints.
TEST(CameraRig, StrictReaderNamesFileLineColumnAndTypos) {
  auto error = [](const std::string& text) -> std::string {
    try {
      rigFromYamlString(text, "rig.yaml");
    } catch (const vrm_sim::YamlError& e) {
      return e.what();
    }
    return "no error";
  };
  const std::string camera =
      "  - image_width: 640\n    image_height: 480\n    camera_matrix: [800, 0, 320, 0, 800, 240, 0, 0, 1]\n";
  EXPECT_EQ(error("cameras:\n" + camera), "no error");
  EXPECT_EQ(error("cameras:\n" + camera + "    camera_nmae: cam0\n"),
            "rig.yaml:5:5: cameras[0].camera_nmae: unknown key (did you mean 'camera_name'?); allowed keys: "
            "image_width, image_height, camera_name, camera_matrix, distortion_model, distortion_coefficients, "
            "rectification_matrix, projection_matrix, world_to_camera");
  EXPECT_EQ(error("cameras:\n" + camera + "    distortion_model: equidistant\n"),
            "rig.yaml:5:23: cameras[0].distortion_model: expected one of plumb_bob, rational_polynomial, got "
            "'equidistant'");
  EXPECT_EQ(error("cameras:\n" + camera + "    world_to_camera: {rotation: [1, 0, 0, 0, 1, 0, 0, 0, 1]}\n"),
            "rig.yaml:5:22: cameras[0].world_to_camera: missing required key 'translation'");
  EXPECT_EQ(error("camera:\n" + camera), "rig.yaml:1:1: missing required key 'cameras'");
  EXPECT_EQ(error("cameras:\n  - image_width: 0\n"),
            "rig.yaml:2:18: cameras[0].image_width: expected an integer in [1, 100000], got '0'");
}

TEST(CameraRig, ShippedConfigIsTheDefaultRig) {
  const CameraRig file = loadRigYaml(std::string(VRM_TRACKING_SOURCE_DIR) + "/config/rig_default.yaml");
  const CameraRig rig = makeDefaultRig();
  ASSERT_EQ(file.size(), rig.size());
  for (std::size_t i = 0; i < rig.size(); ++i) {
    EXPECT_LT((file.cameras[i].K - rig.cameras[i].K).norm(), 1e-9);
    EXPECT_LT((file.cameras[i].world_to_camera.matrix() - rig.cameras[i].world_to_camera.matrix()).norm(), 1e-12);
  }
}

}  // namespace
}  // namespace vrm_tracking
