// Benchmark `tracking` (issue 5): accuracy and speed of the optical tracking pipeline on the default rig.
//   (1) centroid_noise: exact projected centroids + Gaussian noise (0, 0.1, 0.3, 1 px), 3 cameras and 2 cameras,
//       against the ideal floor of the same rig (Monte Carlo optimal least-squares triangulation) and the CRLB;
//   (2) rendered: synthetic images (noise, blur, exposure, marker size, speed up to 50 mm/s, one camera occluded,
//       distractors) through detection + reconstruction;
//   (3) rendered, fast (issue 15): the eye turning at >= 0.8 rad/s (±12°), both tips sweeping at 50 mm/s near the
//       posterior pole, all at once, with three cameras and with each camera occluded in turn under the same motion.
// Usage: bench_tracking [--quick] [--out FILE]   (writes JSON; prints a table)

#include <time.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <functional>
#include <sstream>
#include <string>
#include <vector>

#include "vrm_tracking/evaluation.h"
#include "vrm_tracking/pose_filter.h"

using namespace vrm_tracking;

namespace {

// CPU time of this thread: "ms per frame triple on one core" regardless of what else the shared machine runs
// (wall time on a loaded 2-core box measures the neighbours).
double now() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return ts.tv_sec + 1e-9 * ts.tv_nsec;
}

struct Row {
  std::string source, label;
  double noise_px = 0.0;
  int width = 640, height = 480, occluded_cams = 0;
  double speed_mm_s = 0.0;
  EvalResult r;
  bool has_floor = false;
  double floor_um = 0.0, crlb_um = 0.0;
  RenderConfig render;
  double tip_marker_mm = 0.4;
  bool roi = true;
  PoseFilterConfig filter;  // kNone for the accuracy rows
  double filter_lag_ms = 0.0;
  std::string motion = "circling";  // circlingSurgeon, or "fast_posterior" (fastPosteriorSurgeon)
  int occluded_camera = -1;
  double eye_speed_min = 0.0, eye_speed_max = 0.0;  // rad/s over the sampled frames
  double ratio_to_three_cameras = 0.0;              // occluded fast rows: tip RMS / the three-camera row's
  double camera_skew_ms = 0.0;                      // camera_1 exposes this late (sensitivity rows)
};

std::string num(double v) {
  char buf[64];
  std::snprintf(buf, sizeof(buf), "%.6g", v);
  return buf;
}

std::string toJson(const Row& row) {
  std::ostringstream o;
  o << "{\"suite\": \"tracking\", \"source\": \"" << row.source << "\", \"label\": \"" << row.label << "\""
    << ", \"noise_px\": " << num(row.noise_px) << ", \"width\": " << row.width << ", \"height\": " << row.height
    << ", \"occluded_cams\": " << row.occluded_cams << ", \"speed_mm_s\": " << num(row.speed_mm_s)
    << ", \"tip_rms_um\": " << num(row.r.tip_rms_um) << ", \"tip_max_um\": " << num(row.r.tip_max_um)
    << ", \"floor_um\": " << (row.has_floor ? num(row.floor_um) : "null")
    << ", \"crlb_um\": " << (row.has_floor ? num(row.crlb_um) : "null")
    << ", \"ratio_to_floor\": " << (row.has_floor && row.floor_um > 0 ? num(row.r.tip_rms_um / row.floor_um) : "null")
    << ", \"tip_eye_rms_um\": " << num(row.r.tip_eye_rms_um) << ", \"eye_err_deg\": " << num(row.r.eye_err_deg)
    << ", \"eye_err_max_deg\": " << num(row.r.eye_err_max_deg) << ", \"detect_rate\": " << num(row.r.detect_rate)
    << ", \"track_rate\": " << num(row.r.track_rate) << ", \"ms_detect\": " << num(row.r.ms_detect)
    << ", \"ms_reconstruct\": " << num(row.r.ms_reconstruct) << ", \"full_frame_rate\": " << num(row.r.full_frame_rate)
    << ", \"frames\": " << row.r.frames << ", \"filter\": \"" << toString(row.filter.type) << "\""
    << ", \"filter_lag_ms\": " << num(row.filter_lag_ms);
  if (row.source == "rendered") {
    o << ", \"read_noise_dn\": " << num(row.render.read_noise) << ", \"blur_px\": " << num(row.render.blur_px)
      << ", \"exposure\": " << num(row.render.exposure) << ", \"distractors\": " << row.render.distractors
      << ", \"tip_marker_radius_mm\": " << num(row.tip_marker_mm) << ", \"roi\": " << (row.roi ? "true" : "false")
      << ", \"ms_render\": " << num(row.r.ms_render) << ", \"motion\": \"" << row.motion << "\""
      << ", \"occluded_camera\": " << row.occluded_camera;
    if (row.motion != "circling") {
      o << ", \"eye_speed_min_rad_s\": " << num(row.eye_speed_min)
        << ", \"eye_speed_max_rad_s\": " << num(row.eye_speed_max)
        << ", \"tip_eye_max_um\": " << num(row.r.tip_eye_max_um) << ", \"ratio_to_three_cameras\": "
        << (row.ratio_to_three_cameras > 0 ? num(row.ratio_to_three_cameras) : "null")
        << ", \"camera_skew_ms\": " << num(row.camera_skew_ms);
    }
  }
  o << "}";
  return o.str();
}

}  // namespace

int main(int argc, char** argv) {
  bool quick = false;
  std::string only;  // run only the rows whose label contains this (development; the suite runs everything)
  std::string out = "bench/results/tracking.json";
  std::string command = "bench_tracking";
  for (int i = 1; i < argc; ++i) {
    command += std::string(" ") + argv[i];
    if (!std::strcmp(argv[i], "--quick")) {
      quick = true;
    } else if (!std::strcmp(argv[i], "--out") && i + 1 < argc) {
      out = argv[++i];
      command += std::string(" ") + argv[i];
    } else if (!std::strcmp(argv[i], "--only") && i + 1 < argc) {
      only = argv[++i];
      command += std::string(" ") + argv[i];
    } else {
      std::fprintf(stderr, "usage: bench_tracking [--quick] [--out FILE] [--only LABEL_SUBSTRING]\n");
      return 2;
    }
  }
  const CameraRig rig = makeDefaultRig();
  const MarkerLayout layout = makeDefaultLayout();
  const int frames_noise = quick ? 60 : 2000;
  const int frames_rendered = quick ? 5 : 300;
  const int frames_fast = quick ? 25 : 500;  // 10 s: 6.5 eye cycles, 50 sweep legs
  const int floor_trials = quick ? 20 : 200;
  std::vector<Row> rows;

  auto wanted = [&only](const std::string& label) { return only.empty() || label.find(only) != std::string::npos; };
  // (1) Centroid noise: the FPGA path. Tips move at 10 mm/s (positions only; no images).
  if (wanted("cameras")) {
    const auto truth = circlingSurgeon(layout, 0.010);
    std::vector<double> times;
    std::vector<Eigen::Vector3d> tip_points;
    for (int f = 0; f < frames_noise; ++f) {
      times.push_back(f / 50.0);
      const SurgeonSnapshot s = truth(times.back());
      for (const InstrumentSample& inst : s.instruments) {
        tip_points.push_back(s.rotation_center + s.eye_rotation * inst.tip);
      }
    }
    std::vector<Eigen::Vector3d> floor_points;
    for (std::size_t i = 0; i < tip_points.size(); i += quick ? 10 : 20) floor_points.push_back(tip_points[i]);
    for (int occluded : {0, 1}) {
      for (double noise : {0.0, 0.1, 0.3, 1.0}) {
        Row row;
        row.source = "centroid_noise";
        row.label = occluded ? "2 cameras (camera_2 occluded)" : "3 cameras";
        row.noise_px = noise;
        row.occluded_cams = occluded;
        row.speed_mm_s = 10.0;
        EvalOptions opt;
        opt.noise_px = noise;
        opt.occluded_camera = occluded ? 2 : -1;
        opt.seed = 11;
        opt.clock = now;
        row.r = evaluate(rig, layout, truth, times, opt);
        row.has_floor = true;
        const std::vector<std::size_t> cams =
            occluded ? std::vector<std::size_t>{0, 1} : std::vector<std::size_t>{0, 1, 2};
        row.floor_um = noise > 0 ? idealFloorUm(rig, floor_points, noise, cams, floor_trials, 99, &row.crlb_um) : 0.0;
        rows.push_back(row);
      }
    }
  }

  // (1b) Filters (pose_filter.h) on the centroid path: noise reduction at rest (the truth frozen at t = 0) and the
  // cost of their lag at 10 mm/s, 0.3 px noise, three cameras. filter_lag_ms: steady-state lag on a 10 mm/s ramp.
  std::vector<PoseFilterConfig> filters(3);
  filters[1].type = FilterType::kOneEuro;
  filters[2].type = FilterType::kAlphaBeta;
  {
    const auto moving = circlingSurgeon(layout, 0.010);
    const std::function<SurgeonSnapshot(double)> resting = [moving](double) { return moving(0.0); };
    std::vector<double> times;
    for (int f = 0; f < frames_noise; ++f) times.push_back(f / 50.0);
    for (const PoseFilterConfig& filter : filters) {
      for (bool still : {true, false}) {
        Row row;
        row.source = "centroid_noise";
        row.label = std::string(still ? "at rest" : "10 mm/s") + ", filter " + toString(filter.type);
        if (!wanted(row.label)) continue;
        row.noise_px = 0.3;
        row.speed_mm_s = still ? 0.0 : 10.0;
        row.filter = filter;
        row.filter_lag_ms = filter.type == FilterType::kNone ? 0.0 : 1e3 * measureRampLag(filter, 0.010, 50.0);
        EvalOptions opt;
        opt.noise_px = 0.3;
        opt.seed = 13;
        opt.clock = now;
        opt.tracker.filter = filter;
        row.r = evaluate(rig, layout, still ? resting : moving, times, opt);
        rows.push_back(row);
      }
    }
  }

  // (2) Rendered images: detection + reconstruction end to end.
  struct Case {
    std::string label;
    double speed_mm_s;
    int occluded;
    RenderConfig render;
    double tip_marker_mm;
    bool roi;
    double scale;  // resolution scale (focal length scales with it)
    PoseFilterConfig filter = PoseFilterConfig();
    double clean_quality_ratio = TrackerConfig().clean_quality_ratio;
  };
  std::vector<Case> cases;
  RenderConfig base;
  cases.push_back({"baseline static", 0.0, 0, base, 0.4, true, 1.0});
  cases.push_back({"10 mm/s", 10.0, 0, base, 0.4, true, 1.0});
  cases.push_back({"50 mm/s", 50.0, 0, base, 0.4, true, 1.0});
  {
    RenderConfig c = base;
    c.read_noise = 6.0;
    c.shot_gain = 0.2;
    cases.push_back({"high sensor noise", 10.0, 0, c, 0.4, true, 1.0});
  }
  {
    RenderConfig c = base;
    c.blur_px = 1.5;
    cases.push_back({"defocus blur 1.5 px", 10.0, 0, c, 0.4, true, 1.0});
  }
  {
    RenderConfig c = base;
    c.exposure = 0.5;
    cases.push_back({"under-exposed 0.5", 10.0, 0, c, 0.4, true, 1.0});
  }
  {
    RenderConfig c = base;
    c.exposure = 1.4;
    cases.push_back({"over-exposed 1.4 (saturated)", 10.0, 0, c, 0.4, true, 1.0});
  }
  cases.push_back({"small tip markers 0.25 mm", 10.0, 0, base, 0.25, true, 1.0});
  cases.push_back({"large tip markers 0.6 mm", 10.0, 0, base, 0.6, true, 1.0});
  cases.push_back({"one camera occluded", 10.0, 1, base, 0.4, true, 1.0});
  {
    RenderConfig c = base;
    c.distractors = 12;
    cases.push_back({"12 distractor blobs", 10.0, 0, c, 0.4, true, 1.0});
    Case untiered{"12 distractor blobs, no quality tiering", 10.0, 0, c, 0.4, true, 1.0};
    untiered.clean_quality_ratio = 0.0;
    cases.push_back(untiered);
  }
  cases.push_back({"full-frame detection (no ROI)", 10.0, 0, base, 0.4, false, 1.0});
  cases.push_back({"10 mm/s, filter one_euro", 10.0, 0, base, 0.4, true, 1.0, filters[1]});
  cases.push_back({"10 mm/s, filter alpha_beta", 10.0, 0, base, 0.4, true, 1.0, filters[2]});
  if (!quick) cases.push_back({"1280x960", 10.0, 0, base, 0.4, true, 2.0});

  for (const Case& c : cases) {
    if (!wanted(c.label)) continue;
    MarkerLayout l = layout;
    l.tip_marker_radius = c.tip_marker_mm * 1e-3;
    DefaultRigGeometry g;
    g.width = static_cast<int>(640 * c.scale);
    g.height = static_cast<int>(480 * c.scale);
    g.focal_px *= c.scale;
    const CameraRig r = makeDefaultRig(g);
    const auto truth = circlingSurgeon(l, c.speed_mm_s * 1e-3);
    std::vector<double> times;
    for (int f = 0; f < frames_rendered; ++f) times.push_back(f / 50.0);
    Row row;
    row.source = "rendered";
    row.label = c.label;
    row.noise_px = 0.0;
    row.width = g.width;
    row.height = g.height;
    row.occluded_cams = c.occluded;
    row.speed_mm_s = c.speed_mm_s;
    row.render = c.render;
    row.tip_marker_mm = c.tip_marker_mm;
    row.roi = c.roi;
    EvalOptions opt;
    opt.rendered = true;
    opt.render = c.render;
    opt.roi.use_roi = c.roi;
    opt.occluded_camera = c.occluded ? 2 : -1;
    opt.seed = 21;
    opt.clock = now;
    opt.tracker.filter = c.filter;
    opt.tracker.clean_quality_ratio = c.clean_quality_ratio;
    row.filter = c.filter;
    row.filter_lag_ms = c.filter.type == FilterType::kNone ? 0.0 : 1e3 * measureRampLag(c.filter, 0.010, 50.0);
    row.r = evaluate(r, l, truth, times, opt);
    row.occluded_camera = opt.occluded_camera;
    rows.push_back(row);
  }

  // (3) The hard case: fast eye, fast tips, tips at the back of the eye, with all cameras and with each one occluded
  // (the occluded camera matters: the remaining pair's baseline and the shafts differ). The same frames and seed.
  {
    const FastSurgeonConfig fast;
    const auto truth = fastPosteriorSurgeon(layout, fast);
    std::vector<double> times;
    for (int f = 0; f < frames_fast; ++f) times.push_back(f / 50.0);
    double speed_min = 1e9, speed_max = 0.0;
    for (double t : times) {
      speed_min = std::min(speed_min, eyeAngularSpeed(truth, t));
      speed_max = std::max(speed_max, eyeAngularSpeed(truth, t));
    }
    const std::string name = "fast eye " + num(std::round(100 * speed_min) / 100) + " rad/s, tips 50 mm/s at pole";
    double three_cam_rms = 0.0;
    for (int occluded : {-1, 0, 1, 2}) {
      Row row;
      row.source = "rendered";
      row.label = occluded < 0 ? name + ", 3 cameras" : name + ", camera_" + std::to_string(occluded) + " occluded";
      if (!wanted(row.label)) continue;
      row.motion = "fast_posterior";
      row.occluded_cams = occluded < 0 ? 0 : 1;
      row.occluded_camera = occluded;
      row.speed_mm_s = 1e3 * fast.sweep_speed;
      row.eye_speed_min = speed_min;
      row.eye_speed_max = speed_max;
      EvalOptions opt;
      opt.rendered = true;
      opt.occluded_camera = occluded;
      opt.seed = 23;
      opt.clock = now;
      row.r = evaluate(rig, layout, truth, times, opt);
      if (occluded < 0) three_cam_rms = row.r.tip_rms_um;
      if (occluded >= 0 && three_cam_rms > 0) row.ratio_to_three_cameras = row.r.tip_rms_um / three_cam_rms;
      rows.push_back(row);
    }
    // Sensitivity, not a target: the rig twin exposes all cameras at one stamp, as EyeSi's synchronised cameras do.
    // One camera exposing late shows how much of the budget a trigger skew would take at this speed.
    for (double skew : {0.25e-3, 1e-3}) {
      Row row;
      row.source = "rendered";
      row.label = name + ", camera_1 exposed " + num(1e3 * skew) + " ms late";
      if (!wanted(row.label)) continue;
      row.motion = "fast_posterior";
      row.speed_mm_s = 1e3 * fast.sweep_speed;
      row.eye_speed_min = speed_min;
      row.eye_speed_max = speed_max;
      row.camera_skew_ms = 1e3 * skew;
      EvalOptions opt;
      opt.rendered = true;
      opt.camera_time_offset = {0.0, skew, 0.0};
      opt.seed = 23;
      opt.clock = now;
      row.r = evaluate(rig, layout, truth, times, opt);
      rows.push_back(row);
    }
  }

  std::printf("%-15s %-52s %5s %4s %5s %9s %9s %9s %9s %7s %8s %7s %8s %8s\n", "source", "case", "noise", "occ", "mm/s",
              "tip_rms", "tip_max", "eye_frm", "floor", "ratio", "eye_deg", "detect", "ms_det", "ms_rec");
  for (const Row& row : rows) {
    std::printf("%-15s %-52s %5.2f %4d %5.0f %9.2f %9.2f %9.2f %9s %7s %8.4f %7.3f %8.3f %8.3f\n", row.source.c_str(),
                row.label.c_str(), row.noise_px, row.occluded_cams, row.speed_mm_s, row.r.tip_rms_um, row.r.tip_max_um,
                row.r.tip_eye_rms_um, row.has_floor ? num(row.floor_um).c_str() : "-",
                row.has_floor && row.floor_um > 0 ? num(row.r.tip_rms_um / row.floor_um).c_str() : "-",
                row.r.eye_err_deg, row.r.detect_rate, row.r.ms_detect, row.r.ms_reconstruct);
  }

  std::ofstream file(out);
  if (!file) {
    std::fprintf(stderr, "bench_tracking: cannot write %s\n", out.c_str());
    return 1;
  }
  const CameraModel& cam = rig.cameras[0];
  file << "{\"suite\": \"tracking\", \"command\": \"" << command << "\", \"quick\": " << (quick ? "true" : "false")
       << ",\n \"rig\": {\"cameras\": 3, \"width\": 640, \"height\": 480, \"distance_mm\": 100, \"tilt_deg\": 40, "
       << "\"azimuths_deg\": [90, 210, 330], \"focal_px\": " << num(cam.K(0, 0))
       << ", \"um_per_px_at_centre\": " << num(cam.metresPerPixel(0.1) * 1e6) << "},\n \"rows\": [\n";
  for (std::size_t i = 0; i < rows.size(); ++i) file << "  " << toJson(rows[i]) << (i + 1 < rows.size() ? ",\n" : "\n");
  file << " ]}\n";
  std::printf("wrote %s\n", out.c_str());
  return 0;
}
