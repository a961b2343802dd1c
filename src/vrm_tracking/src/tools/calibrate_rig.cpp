// calibrate_rig (issue 5): calibrates the tracking rig from images of a chessboard target (Zhang's method,
// calibration.h) and writes standard camera calibration YAML per camera (camera_calibration_parsers /
// camera_info_manager layout + world_to_camera extrinsics) and a rig file that camera_rig_sim and the tracker load.
//
//   calibrate_rig --synthetic [--rig TRUE_RIG.yaml] [--views N] [--seed N] [--save-images DIR] --out DIR
//       renders the target through the (true) rig from N poses per camera plus the fixture view, calibrates, and
//       prints the recovered rig's errors against the truth as JSON (focal %, centre mm, rotation deg).
//   calibrate_rig --images DIR --out DIR
//       real images: DIR/<camera>/*.png views of the target in any pose, DIR/<camera>/reference.png the target on
//       the world fixture (centred on the eye's rotation centre, face down; calibration.h fixturePose()).
//   Target options: --cols 9 --rows 6 --square 0.0025 (m), --centre X Y Z (world, m; default 0 0 0).
// Output: DIR/<camera>.yaml per camera, DIR/rig.yaml. Exit 0 ok, 1 calibration failed, 2 usage.

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <opencv2/imgcodecs.hpp>
#include <string>
#include <vector>

#include "vrm_tracking/calibration.h"
#include "vrm_tracking/camera_rig.h"

using namespace vrm_tracking;
namespace fs = std::filesystem;

namespace {

int usage() {
  std::fprintf(stderr,
               "usage: calibrate_rig (--synthetic [--rig FILE] [--views N] [--seed N] [--save-images DIR] | "
               "--images DIR) --out DIR [--cols N --rows N --square M] [--centre X Y Z]\n");
  return 2;
}

}  // namespace

int main(int argc, char** argv) {
  bool synthetic = false;
  std::string rig_file, images_dir, out_dir, save_dir;
  int views = 15;
  unsigned seed = 17;
  ChessboardTarget target;
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto next = [&]() -> const char* { return i + 1 < argc ? argv[++i] : nullptr; };
    const char* v = nullptr;
    if (a == "--synthetic") {
      synthetic = true;
    } else if (a == "--rig" && (v = next())) {
      rig_file = v;
    } else if (a == "--images" && (v = next())) {
      images_dir = v;
    } else if (a == "--out" && (v = next())) {
      out_dir = v;
    } else if (a == "--save-images" && (v = next())) {
      save_dir = v;
    } else if (a == "--views" && (v = next())) {
      views = std::atoi(v);
    } else if (a == "--seed" && (v = next())) {
      seed = static_cast<unsigned>(std::atoi(v));
    } else if (a == "--cols" && (v = next())) {
      target.cols = std::atoi(v);
    } else if (a == "--rows" && (v = next())) {
      target.rows = std::atoi(v);
    } else if (a == "--square" && (v = next())) {
      target.square = std::atof(v);
    } else if (a == "--centre" && i + 3 < argc) {
      centre = Eigen::Vector3d(std::atof(argv[i + 1]), std::atof(argv[i + 2]), std::atof(argv[i + 3]));
      i += 3;
    } else {
      return usage();
    }
  }
  if (out_dir.empty() || synthetic == !images_dir.empty() || views < 3 || target.square <= 0.0) return usage();
  const Eigen::Isometry3d fixture = fixturePose(target, centre);

  std::vector<std::string> names;
  std::vector<std::vector<cv::Mat>> all_views;
  std::vector<cv::Mat> references;
  CameraRig truth;
  try {
    if (synthetic) {
      truth = rig_file.empty() ? makeDefaultRig() : loadRigYaml(rig_file);
      for (std::size_t c = 0; c < truth.size(); ++c) {
        const CameraModel& cam = truth.cameras[c];
        names.push_back(cam.name);
        std::vector<cv::Mat> imgs;
        for (const Eigen::Isometry3d& pose : calibrationPoses(cam, target, centre, views, seed + 101 * c)) {
          cv::Mat image;
          renderTarget(cam, pose, target, &image, 3);
          imgs.push_back(image);
        }
        cv::Mat reference;
        renderTarget(cam, fixture, target, &reference, 4);
        if (!save_dir.empty()) {
          fs::create_directories(fs::path(save_dir) / cam.name);
          for (std::size_t i = 0; i < imgs.size(); ++i) {
            char file[32];
            std::snprintf(file, sizeof(file), "view_%03zu.png", i);
            cv::imwrite((fs::path(save_dir) / cam.name / file).string(), imgs[i]);
          }
          cv::imwrite((fs::path(save_dir) / cam.name / "reference.png").string(), reference);
        }
        all_views.push_back(std::move(imgs));
        references.push_back(reference);
      }
    } else {
      std::vector<fs::path> dirs;
      for (const auto& entry : fs::directory_iterator(images_dir)) {
        if (entry.is_directory()) dirs.push_back(entry.path());
      }
      std::sort(dirs.begin(), dirs.end());
      for (const fs::path& dir : dirs) {
        std::vector<fs::path> files;
        for (const auto& entry : fs::directory_iterator(dir)) {
          if (entry.path().extension() == ".png" && entry.path().filename() != "reference.png") {
            files.push_back(entry.path());
          }
        }
        std::sort(files.begin(), files.end());
        std::vector<cv::Mat> imgs;
        for (const fs::path& f : files) imgs.push_back(cv::imread(f.string(), cv::IMREAD_COLOR));
        const cv::Mat reference = cv::imread((dir / "reference.png").string(), cv::IMREAD_COLOR);
        if (reference.empty()) {
          std::fprintf(stderr, "calibrate_rig: %s: missing reference.png (the target on the world fixture)\n",
                       dir.c_str());
          return 1;
        }
        names.push_back(dir.filename().string());
        all_views.push_back(std::move(imgs));
        references.push_back(reference);
      }
      if (names.empty()) {
        std::fprintf(stderr, "calibrate_rig: %s: no camera folders\n", images_dir.c_str());
        return 1;
      }
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "calibrate_rig: %s\n", e.what());
    return 1;
  }

  CameraRig calibrated;
  std::string json = "{\"cameras\": [";
  bool ok = true;
  for (std::size_t c = 0; c < names.size(); ++c) {
    const CameraCalibrationResult r = calibrateCamera(names[c], all_views[c], references[c], target, fixture);
    if (!r.ok) {
      std::fprintf(stderr, "calibrate_rig: %s\n", r.error.c_str());
      ok = false;
      continue;
    }
    calibrated.cameras.push_back(r.camera);
    char buf[512];
    std::snprintf(buf, sizeof(buf),
                  "%s{\"name\": \"%s\", \"views_used\": %d, \"intrinsic_rms_px\": %.4f, \"extrinsic_rms_px\": %.4f, "
                  "\"fx\": %.3f, \"fy\": %.3f, \"cx\": %.3f, \"cy\": %.3f",
                  c ? ", " : "", names[c].c_str(), r.views_used, r.intrinsic_rms_px, r.extrinsic_rms_px,
                  r.camera.K(0, 0), r.camera.K(1, 1), r.camera.K(0, 2), r.camera.K(1, 2));
    json += buf;
    if (synthetic) {
      const CalibrationError e = compareCameras(r.camera, truth.cameras[c]);
      std::snprintf(buf, sizeof(buf),
                    ", \"focal_err_percent\": %.4f, \"position_err_mm\": %.4f, \"rotation_err_deg\": %.4f",
                    e.focal_percent, e.position_m * 1e3, e.rotation_deg);
      json += buf;
    }
    json += "}";
  }
  json += "]}";
  if (!ok) return 1;
  try {
    fs::create_directories(out_dir);
    for (const CameraModel& cam : calibrated.cameras)
      saveCameraYaml(cam, (fs::path(out_dir) / (cam.name + ".yaml")).string());
    saveRigYaml(calibrated, (fs::path(out_dir) / "rig.yaml").string());
  } catch (const std::exception& e) {
    std::fprintf(stderr, "calibrate_rig: %s\n", e.what());
    return 1;
  }
  std::printf("%s\n", json.c_str());
  return 0;
}
