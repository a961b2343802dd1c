#include "vrm_tracking/evaluation.h"

#include <Eigen/Dense>
#include <algorithm>
#include <array>
#include <cmath>
#include <random>

#include "vrm_tracking/triangulation.h"

namespace vrm_tracking {

namespace {
constexpr double kPi = 3.14159265358979323846;

double angleDeg(const Eigen::Quaterniond& a, const Eigen::Quaterniond& b) {
  return a.normalized().angularDistance(b.normalized()) * 180.0 / kPi;
}
}  // namespace

std::function<SurgeonSnapshot(double)> circlingSurgeon(const MarkerLayout& layout, double speed) {
  return [layout, speed](double t) {
    SurgeonSnapshot s;
    s.rotation_center = layout.rotation_center;
    s.eye_rotation = Eigen::AngleAxisd(5.0 * kPi / 180.0 * std::sin(2 * kPi * 0.3 * t), Eigen::Vector3d::UnitX()) *
                     Eigen::AngleAxisd(4.0 * kPi / 180.0 * std::cos(2 * kPi * 0.2 * t), Eigen::Vector3d::UnitY());
    const double radius = 0.003;
    // speed 0: a golden-angle jump per 20 ms sample, so static frames still cover the circle.
    const double phase = speed > 0.0 ? speed / radius * t : 2.39996 * std::round(t * 50.0);
    for (std::size_t i = 0; i < layout.instruments.size(); ++i) {
      const double sign = i % 2 == 0 ? -1.0 : 1.0;
      const double ph = phase + kPi * static_cast<double>(i);
      InstrumentSample inst;
      inst.slot = layout.instruments[i].slot;
      inst.trocar = layout.instruments[i].trocar;
      inst.tip = Eigen::Vector3d(sign * 0.002 + radius * std::cos(ph), radius * std::sin(ph),
                                 -0.006 + 0.3 * radius * std::sin(2.0 * ph) / 2.0);
      inst.shaft_axis = (inst.tip - inst.trocar).normalized();
      inst.insertion_depth = (inst.tip - inst.trocar).norm();
      inst.orientation = shaftOrientation(inst.trocar, inst.shaft_axis, 0.0);
      s.instruments.push_back(inst);
    }
    return s;
  };
}

std::function<SurgeonSnapshot(double)> fastPosteriorSurgeon(const MarkerLayout& layout,
                                                            const FastSurgeonConfig& config) {
  return [layout, config](double t) {
    SurgeonSnapshot s;
    s.rotation_center = layout.rotation_center;
    const double w = 2.0 * kPi * config.eye_frequency;
    s.eye_rotation = Eigen::AngleAxisd(config.eye_amplitude * std::sin(w * t), Eigen::Vector3d::UnitX()) *
                     Eigen::AngleAxisd(config.eye_amplitude * std::cos(w * t), Eigen::Vector3d::UnitY());
    const double leg = 2.0 * config.sweep_half_length / std::max(1e-9, config.sweep_speed);  // s per one-way pass
    for (std::size_t i = 0; i < layout.instruments.size(); ++i) {
      const double sign = i % 2 == 0 ? -1.0 : 1.0;
      // Triangle wave in [0, 1) per period 2·leg, shifted by 10 ms so the reversals fall between 50 Hz samples.
      const double phase = (t - 0.010) / (2.0 * leg) + (i % 2 == 0 ? 0.0 : 0.5);
      const double frac = phase - std::floor(phase);
      const double tri = frac < 0.5 ? 4.0 * frac - 1.0 : 3.0 - 4.0 * frac;  // -1 .. 1, slope ±4 per period
      InstrumentSample inst;
      inst.slot = layout.instruments[i].slot;
      inst.trocar = layout.instruments[i].trocar;
      inst.tip = Eigen::Vector3d(sign * 0.0015, config.sweep_half_length * tri, config.tip_depth);
      inst.shaft_axis = (inst.tip - inst.trocar).normalized();
      inst.insertion_depth = (inst.tip - inst.trocar).norm();
      inst.orientation = shaftOrientation(inst.trocar, inst.shaft_axis, 0.0);
      s.instruments.push_back(inst);
    }
    return s;
  };
}

double eyeAngularSpeed(const std::function<SurgeonSnapshot(double)>& truth, double t, double dt) {
  const Eigen::Quaterniond a = truth(t - dt).eye_rotation.normalized(), b = truth(t + dt).eye_rotation.normalized();
  return a.angularDistance(b) / (2.0 * dt);
}

std::function<SurgeonSnapshot(double)> randomFastSurgeon(const MarkerLayout& layout, std::uint32_t seed,
                                                         const RandomFastConfig& config) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  auto uniform = [&](double lo, double hi) { return lo + (hi - lo) * u01(rng); };
  // Eye: angle_k(t) = sum_j A_kj sin(2π f_kj t + φ_kj); the roll about z is kept smaller (it is the eye's torsion).
  struct Wave {
    double amplitude, frequency, phase;
  };
  std::array<std::array<Wave, 2>, 3> waves;
  for (int k = 0; k < 3; ++k) {
    const double scale = k == 2 ? 0.4 : 1.0;
    waves[k][0] = {scale * uniform(0.5, 1.0), uniform(0.5, 1.0), uniform(0.0, 2 * kPi)};
    waves[k][1] = {scale * uniform(0.2, 0.5), uniform(1.5, 3.0), uniform(0.0, 2 * kPi)};
  }
  auto rotation = [](const std::array<std::array<Wave, 2>, 3>& w, double gain, double t) {
    double angle[3];
    for (int k = 0; k < 3; ++k) {
      angle[k] = 0.0;
      for (const Wave& x : w[k]) angle[k] += gain * x.amplitude * std::sin(2 * kPi * x.frequency * t + x.phase);
    }
    return Eigen::Quaterniond(Eigen::AngleAxisd(angle[0], Eigen::Vector3d::UnitX()) *
                              Eigen::AngleAxisd(angle[1], Eigen::Vector3d::UnitY()) *
                              Eigen::AngleAxisd(angle[2], Eigen::Vector3d::UnitZ()));
  };
  // Peak angular speed at unit gain on a 1 ms grid, then the gain that puts it at the drawn fraction of the limit.
  double peak = 0.0;
  for (double t = 0.0; t <= config.duration; t += 1e-3) {
    peak = std::max(peak, rotation(waves, 1.0, t).angularDistance(rotation(waves, 1.0, t + 1e-4)) / 1e-4);
  }
  const double gain = peak > 0.0 ? uniform(0.85, 1.0) * config.max_eye_speed / peak : 0.0;

  // Tips: legs between waypoints, per instrument, covering [-0.1 s, duration + 0.1 s].
  struct Leg {
    double t0, t1;
    Eigen::Vector3d a, b;
  };
  std::vector<std::vector<Leg>> legs(layout.instruments.size());
  for (std::size_t i = 0; i < layout.instruments.size(); ++i) {
    const double side = i % 2 == 0 ? -1.0 : 1.0;
    auto waypoint = [&]() {
      return Eigen::Vector3d(side * uniform(0.0005, 0.003), uniform(-0.003, 0.003), uniform(-0.0105, -0.008));
    };
    Eigen::Vector3d a = waypoint();
    double t = -0.1;  // the first leg is already under way at t = 0
    while (t < config.duration + 0.1) {
      Eigen::Vector3d b = waypoint();
      for (int tries = 0; tries < 20 && (b - a).norm() < 0.0015; ++tries) b = waypoint();
      const double speed = uniform(0.5, 1.0) * config.max_tip_speed;
      const double t1 = t + (b - a).norm() / speed;
      legs[i].push_back({t, t1, a, b});
      a = b;
      t = t1;
    }
  }
  return [layout, waves, gain, legs, rotation](double t) {
    SurgeonSnapshot s;
    s.rotation_center = layout.rotation_center;
    s.eye_rotation = rotation(waves, gain, t);
    for (std::size_t i = 0; i < layout.instruments.size(); ++i) {
      const std::vector<Leg>& path = legs[i];
      std::size_t n = 0;
      while (n + 1 < path.size() && t >= path[n].t1) ++n;
      const Leg& leg = path[n];
      const double f = std::clamp((t - leg.t0) / std::max(1e-9, leg.t1 - leg.t0), 0.0, 1.0);
      InstrumentSample inst;
      inst.slot = layout.instruments[i].slot;
      inst.trocar = layout.instruments[i].trocar;
      inst.tip = leg.a + f * (leg.b - leg.a);
      inst.shaft_axis = (inst.tip - inst.trocar).normalized();
      inst.insertion_depth = (inst.tip - inst.trocar).norm();
      inst.orientation = shaftOrientation(inst.trocar, inst.shaft_axis, 0.0);
      s.instruments.push_back(inst);
    }
    return s;
  };
}

double peakTipSpeed(const std::function<SurgeonSnapshot(double)>& truth, const std::vector<double>& times, double dt) {
  double peak = 0.0;
  for (double t : times) {
    const SurgeonSnapshot a = truth(t - dt), b = truth(t + dt);
    for (std::size_t i = 0; i < a.instruments.size() && i < b.instruments.size(); ++i) {
      peak = std::max(peak, (b.instruments[i].tip - a.instruments[i].tip).norm() / (2.0 * dt));
    }
  }
  return peak;
}

EvalResult evaluate(const CameraRig& rig, const MarkerLayout& layout,
                    const std::function<SurgeonSnapshot(double)>& truth, const std::vector<double>& times,
                    const EvalOptions& options) {
  EvalResult result;
  std::mt19937 rng(options.seed);
  std::normal_distribution<double> noise(0.0, 1.0);
  RenderConfig render = options.render;
  render.seed = options.seed;
  const RigRenderer renderer(rig, layout, render);
  const MarkerDetector detector(layout.classes);
  std::vector<RoiTracker> roi;
  for (std::size_t c = 0; c < rig.size(); ++c) roi.emplace_back(&detector, options.roi);
  PoseTracker tracker(options.tracker_rig ? *options.tracker_rig : rig, layout, options.tracker);

  double tip2 = 0.0, tip_eye2 = 0.0, eye2 = 0.0, t_detect = 0.0, t_rec = 0.0, t_render = 0.0;
  long scored_frames = 0, tips = 0, tips_valid = 0, visible = 0, detected = 0, camera_frames = 0, full_frames = 0;
  std::vector<double> render_each, detect_each;                                     // per camera triple (s)
  std::vector<std::vector<Eigen::Vector3d>> tip_errors(layout.instruments.size());  // world, per layout slot
  cv::Mat image;
  for (std::size_t f = 0; f < times.size(); ++f) {
    const double t = times[f];
    const SurgeonSnapshot snap = truth(t);
    WorldScene scene = worldSceneFromSnapshot(snap, layout);
    if (options.rendered && options.motion) {
      setVelocities(worldSceneFromSnapshot(truth(t - 1e-3), layout), worldSceneFromSnapshot(truth(t + 1e-3), layout),
                    2e-3, &scene);
    }
    std::vector<CameraObservations> frame;
    const double render_before = t_render, detect_before = t_detect;
    const bool scored = static_cast<int>(f) >= options.occlusion_start_frame;
    for (std::size_t c = 0; c < rig.size(); ++c) {
      if (static_cast<int>(c) == options.occluded_camera && scored) continue;
      CameraObservations obs;
      obs.camera = c;
      if (!options.rendered) {
        for (const ProjectedMarker& p : renderer.project(c, scene)) {
          if (!p.visible) continue;
          ++visible;
          ++detected;
          Blob b;
          b.class_id = p.class_id;
          b.u = p.pixel.x() + options.noise_px * noise(rng);
          b.v = p.pixel.y() + options.noise_px * noise(rng);
          b.quality = 1.0;
          obs.blobs.push_back(b);
        }
      } else {
        std::vector<ProjectedMarker> projected;
        const double offset = c < options.camera_time_offset.size() ? options.camera_time_offset[c] : 0.0;
        WorldScene late;
        if (offset != 0.0) {
          late = worldSceneFromSnapshot(truth(t + offset), layout);
          if (options.motion) {
            setVelocities(worldSceneFromSnapshot(truth(t + offset - 1e-3), layout),
                          worldSceneFromSnapshot(truth(t + offset + 1e-3), layout), 2e-3, &late);
          }
        }
        const double r0 = options.clock ? options.clock() : 0.0;
        renderer.render(c, offset != 0.0 ? late : scene, f, &image, &projected);
        if (options.clock) t_render += options.clock() - r0;
        DetectionStats stats;
        const double t0 = options.clock ? options.clock() : 0.0;
        obs.blobs = roi[c].process(image, &stats);
        if (options.clock) t_detect += options.clock() - t0;
        ++camera_frames;
        full_frames += stats.full_frame;
        for (const ProjectedMarker& p : projected) {
          if (!p.visible) continue;
          ++visible;
          for (const Blob& b : obs.blobs) {
            if (b.class_id == p.class_id && std::hypot(b.u - p.pixel.x(), b.v - p.pixel.y()) < 3.0) {
              ++detected;
              break;
            }
          }
        }
      }
      frame.push_back(std::move(obs));
    }
    render_each.push_back(t_render - render_before);
    detect_each.push_back(t_detect - detect_before);
    const double t0 = options.clock ? options.clock() : 0.0;
    const TrackingResult r = tracker.update(frame, t);
    if (options.clock) t_rec += options.clock() - t0;

    if (!scored) continue;
    ++scored_frames;
    const double e = angleDeg(r.eye.rotation, snap.eye_rotation);
    eye2 += e * e;
    result.eye_err_max_deg = std::max(result.eye_err_max_deg, e);
    const Eigen::Quaterniond q = snap.eye_rotation.normalized();
    for (const InstrumentSample& s : snap.instruments) {
      for (const InstrumentEstimate& est : r.instruments) {
        if (est.slot != s.slot) continue;
        ++tips;
        if (!est.valid) {
          int reporting = 0;
          for (const InstrumentMarker& slot : layout.instruments) {
            if (slot.slot != s.slot) continue;
            for (const CameraObservations& obs : frame) {
              reporting += std::any_of(obs.blobs.begin(), obs.blobs.end(),
                                       [&slot](const Blob& b) { return b.class_id == slot.class_id; });
            }
          }
          result.tips_invalid_seen += reporting >= 2;
          continue;
        }
        ++tips_valid;
        const Eigen::Vector3d world_true = snap.rotation_center + q * s.tip;
        const Eigen::Vector3d world_est = r.eye.rotation_center + r.eye.rotation.normalized() * est.tip;
        const double ew = (world_est - world_true).norm() * 1e6;
        for (std::size_t i = 0; i < layout.instruments.size(); ++i) {
          if (layout.instruments[i].slot == s.slot) tip_errors[i].push_back(world_est - world_true);
        }
        const double ee = (est.tip - s.tip).norm() * 1e6;
        tip2 += ew * ew;
        tip_eye2 += ee * ee;
        result.tip_max_um = std::max(result.tip_max_um, ew);
        result.tip_eye_max_um = std::max(result.tip_eye_max_um, ee);
      }
    }
  }
  result.frames = static_cast<int>(scored_frames);
  result.tips_scored = static_cast<int>(tips);
  double jitter2 = 0.0;
  long jitter_n = 0;
  for (const std::vector<Eigen::Vector3d>& errors : tip_errors) {
    if (errors.empty()) continue;
    Eigen::Vector3d mean = Eigen::Vector3d::Zero();
    for (const Eigen::Vector3d& e : errors) mean += e / static_cast<double>(errors.size());
    for (const Eigen::Vector3d& e : errors) jitter2 += (e - mean).squaredNorm();
    jitter_n += static_cast<long>(errors.size());
  }
  if (jitter_n > 0) result.tip_jitter_um = std::sqrt(jitter2 / jitter_n) * 1e6;
  if (tips_valid > 0) {
    result.tip_rms_um = std::sqrt(tip2 / tips_valid);
    result.tip_eye_rms_um = std::sqrt(tip_eye2 / tips_valid);
  }
  if (!times.empty()) {
    result.eye_err_deg = std::sqrt(eye2 / std::max(1L, scored_frames));
    result.ms_detect = 1e3 * t_detect / times.size();
    result.ms_reconstruct = 1e3 * t_rec / times.size();
    result.ms_render = 1e3 * t_render / times.size();
    // Nearest-rank 99th percentile.
    auto p99 = [](std::vector<double> v) {
      std::sort(v.begin(), v.end());
      return v[std::min(v.size() - 1, static_cast<std::size_t>(std::ceil(0.99 * v.size())) - 1)];
    };
    result.ms_render_p99 = 1e3 * p99(render_each);
    result.ms_render_max = 1e3 * *std::max_element(render_each.begin(), render_each.end());
    result.ms_detect_p99 = 1e3 * p99(detect_each);
  }
  result.detect_rate = visible > 0 ? static_cast<double>(detected) / visible : 0.0;
  result.track_rate = tips > 0 ? static_cast<double>(tips_valid) / tips : 0.0;
  result.full_frame_rate = camera_frames > 0 ? static_cast<double>(full_frames) / camera_frames : 0.0;
  return result;
}

double idealFloorUm(const CameraRig& rig, const std::vector<Eigen::Vector3d>& points, double noise_px,
                    const std::vector<std::size_t>& cameras, int trials, std::uint32_t seed, double* crlb_um) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> noise(0.0, noise_px);
  double sum2 = 0.0, crlb2 = 0.0;
  long n = 0;
  for (const Eigen::Vector3d& p : points) {
    std::vector<PixelObservation> exact;
    Eigen::MatrixXd J(2 * cameras.size(), 3);
    for (std::size_t i = 0; i < cameras.size(); ++i) {
      PixelObservation o;
      o.camera = cameras[i];
      rig.cameras[cameras[i]].project(p, &o.pixel);
      exact.push_back(o);
      for (int k = 0; k < 3; ++k) {
        Eigen::Vector3d xp = p, xm = p;
        xp(k) += 1e-7;
        xm(k) -= 1e-7;
        Eigen::Vector2d pp, pm;
        rig.cameras[cameras[i]].project(xp, &pp);
        rig.cameras[cameras[i]].project(xm, &pm);
        J.block<2, 1>(2 * i, k) = (pp - pm) / 2e-7;
      }
    }
    // Cramér-Rao: covariance σ² (JᵀJ)⁻¹ of any unbiased estimator from these centroids.
    crlb2 += noise_px * noise_px * (J.transpose() * J).inverse().trace();
    for (int trial = 0; trial < trials; ++trial) {
      std::vector<PixelObservation> obs = exact;
      for (PixelObservation& o : obs) o.pixel += Eigen::Vector2d(noise(rng), noise(rng));
      // Gauss-Newton from the truth: the least-squares optimum without any initialisation or outlier effects.
      Eigen::Vector3d x = p;
      for (int it = 0; it < 5; ++it) {
        Eigen::VectorXd r(2 * obs.size());
        for (std::size_t i = 0; i < obs.size(); ++i) {
          Eigen::Vector2d px;
          rig.cameras[obs[i].camera].project(x, &px);
          r.segment<2>(2 * i) = px - obs[i].pixel;
        }
        x -= (J.transpose() * J).ldlt().solve(J.transpose() * r);
      }
      sum2 += (x - p).squaredNorm();
      ++n;
    }
  }
  if (crlb_um) *crlb_um = points.empty() ? 0.0 : std::sqrt(crlb2 / points.size()) * 1e6;
  return n > 0 ? std::sqrt(sum2 / n) * 1e6 : 0.0;
}

}  // namespace vrm_tracking
