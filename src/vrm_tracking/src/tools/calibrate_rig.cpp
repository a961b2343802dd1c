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
#include <filesystem>
#include <opencv2/imgcodecs.hpp>
#include <string>
#include <vector>

#include "vrm_scene/cli/cli.h"
#include "vrm_tracking/calibration.h"
#include "vrm_tracking/camera_rig.h"

using namespace vrm_tracking;
namespace fs = std::filesystem;

int main(int argc, char** argv) {
  namespace po = vrm_sim::cli::po;
  bool synthetic = false;
  std::string rig_file, images_dir, out_dir, save_dir;
  int views = 15;
  std::uint32_t seed = 17;
  ChessboardTarget target;
  std::vector<double> centre_xyz{0.0, 0.0, 0.0};
  vrm_sim::cli::CommandLine cli(
      "calibrate_rig",
      "(--synthetic [--rig FILE] [--views N] [--seed N] [--save-images DIR] | --images DIR) --out DIR "
      "[--cols N --rows N --square M] [--centre X Y Z]",
      "Calibrates the tracking rig from chessboard images; writes DIR/<camera>.yaml per camera and DIR/rig.yaml.",
      "Exit status: 0 ok, 1 calibration failed, 2 usage.");
  cli.add()("synthetic", po::bool_switch(&synthetic), "render the target through the (true) rig and calibrate")(
      "rig", po::value(&rig_file)->value_name("FILE"), "the true rig of --synthetic (default: the built-in rig)")(
      "views", vrm_sim::cli::integer(&views)->value_name("N"), "poses per camera of --synthetic (default 15, >= 3)")(
      "seed", vrm_sim::cli::uint32(&seed)->value_name("N"), "pose seed of --synthetic (default 17)")(
      "save-images", po::value(&save_dir)->value_name("DIR"), "write the rendered views of --synthetic")(
      "images", po::value(&images_dir)->value_name("DIR"),
      "real images: DIR/<camera>/*.png views, DIR/<camera>/reference.png the target on the world fixture")(
      "out", po::value(&out_dir)->required()->value_name("DIR"), "where the calibration files go")(
      "cols", vrm_sim::cli::integer(&target.cols)->value_name("N"), "inner corners per row (default 9)")(
      "rows", vrm_sim::cli::integer(&target.rows)->value_name("N"), "inner corners per column (default 6)")(
      "square", vrm_sim::cli::real(&target.square)->value_name("M"), "square size (m, default 0.0025)")(
      "centre", vrm_sim::cli::reals(&centre_xyz, 3)->value_name("X Y Z"),
      "the fixture's centre in the world (m, default 0 0 0)");
  if (const auto status = cli.parse(argc, argv)) return *status;
  if (synthetic == !images_dir.empty()) return cli.fail("give either --synthetic or --images DIR");
  if (views < 3) return cli.fail("--views expects at least 3");
  if (!(target.square > 0.0)) return cli.fail("--square expects a positive number");
  const Eigen::Vector3d centre(centre_xyz[0], centre_xyz[1], centre_xyz[2]);
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
          renderTarget(cam, pose, target, &image);
          imgs.push_back(image);
        }
        cv::Mat reference;
        renderTarget(cam, fixture, target, &reference);
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
