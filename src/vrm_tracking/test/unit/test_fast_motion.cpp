// Tracking accuracy at speed (issue 15): rendered images of the hard case — the eye turning at >= 0.8 rad/s
// (±12°), both tips sweeping at 50 mm/s 2 mm in front of the retina at the posterior pole — through detection, ROI
// tracking and reconstruction. Guards the benchmark's bounds on a 1.2 s sequence: tip RMS <= 15 µm and max <= 60 µm
// with three cameras, and <= 1.5× that RMS with any one camera occluded under the same motion.

#include <gtest/gtest.h>

#include <cmath>

#include "vrm_tracking/evaluation.h"

namespace vrm_tracking {
namespace {

constexpr double kPi = 3.14159265358979323846;

std::vector<double> frameTimes(int frames) {
  std::vector<double> times;
  for (int f = 0; f < frames; ++f) times.push_back(f / 50.0);  // the cameras' 50 Hz
  return times;
}

EvalOptions renderedOptions(int occluded_camera) {
  EvalOptions opt;
  opt.rendered = true;  // default RenderConfig: 4 ms exposure with motion blur, sensor noise, clutter, shafts
  opt.occluded_camera = occluded_camera;
  opt.seed = 23;
  return opt;
}

TEST(FastPosteriorSurgeon, IsAsFastAndAsDeepAsTheCaseClaims) {
  const MarkerLayout layout = makeDefaultLayout();
  const FastSurgeonConfig config;
  const auto truth = fastPosteriorSurgeon(layout, config);
  double max_tilt = 0.0;
  for (double t = 0.0; t < 2.0; t += 0.005) {
    EXPECT_GE(eyeAngularSpeed(truth, t), 0.8) << "t = " << t;
    const SurgeonSnapshot s = truth(t);
    // Tilt of the optical axis (eye z) from its rest direction: the cone's half angle, at most the amplitude.
    const Eigen::Vector3d axis = s.eye_rotation.normalized() * Eigen::Vector3d::UnitZ();
    max_tilt = std::max(max_tilt, std::acos(std::clamp(axis.z(), -1.0, 1.0)));
    ASSERT_EQ(s.instruments.size(), 2u);
    for (const InstrumentSample& inst : s.instruments) {
      // Near the posterior pole: within 3 mm of the axis, 1.5–2.5 mm in front of the 12 mm retina.
      EXPECT_LT(inst.tip.head<2>().norm(), 0.003);
      EXPECT_GT(12e-3 - inst.tip.norm(), 1.5e-3);
      EXPECT_LT(12e-3 - inst.tip.norm(), 2.5e-3);
      // Eye-frame tip speed: 50 mm/s everywhere but within 1 ms of a reversal.
      const SurgeonSnapshot a = truth(t - 5e-4), b = truth(t + 5e-4);
      for (std::size_t i = 0; i < a.instruments.size(); ++i) {
        if (a.instruments[i].slot != inst.slot) continue;
        const double speed = (b.instruments[i].tip - a.instruments[i].tip).norm() / 1e-3;
        if (speed > 0.9 * config.sweep_speed) EXPECT_NEAR(speed, config.sweep_speed, 1e-6);
      }
    }
  }
  EXPECT_NEAR(max_tilt, config.eye_amplitude, 0.2 * config.eye_amplitude);
  EXPECT_GT(config.eye_amplitude, 11.9 * kPi / 180.0);
}

class FastMotion : public testing::Test {
 protected:
  FastMotion() : rig_(makeDefaultRig()), layout_(makeDefaultLayout()), truth_(fastPosteriorSurgeon(layout_)) {}
  CameraRig rig_;
  MarkerLayout layout_;
  std::function<SurgeonSnapshot(double)> truth_;
};

TEST_F(FastMotion, ThreeCamerasStayWithinTheBounds) {
  const EvalResult r = evaluate(rig_, layout_, truth_, frameTimes(60), renderedOptions(-1));
  EXPECT_EQ(r.track_rate, 1.0);
  EXPECT_GE(r.detect_rate, 0.99);
  EXPECT_LE(r.tip_rms_um, 15.0);
  EXPECT_LE(r.tip_max_um, 60.0);
  // In the eye frame (what the simulation uses) the eye-rotation error adds to it: the same bounds hold.
  EXPECT_LE(r.tip_eye_rms_um, 15.0);
  EXPECT_LE(r.eye_err_max_deg, 0.1);
}

TEST_F(FastMotion, OneOccludedCameraCostsAtMostHalfAgain) {
  const std::vector<double> times = frameTimes(60);
  const EvalResult all = evaluate(rig_, layout_, truth_, times, renderedOptions(-1));
  ASSERT_GT(all.tip_rms_um, 0.0);
  for (int occluded = 0; occluded < 3; ++occluded) {
    const EvalResult r = evaluate(rig_, layout_, truth_, times, renderedOptions(occluded));
    EXPECT_EQ(r.track_rate, 1.0) << "camera_" << occluded << " occluded";
    EXPECT_LE(r.tip_rms_um, 1.5 * all.tip_rms_um) << "camera_" << occluded << " occluded";
    EXPECT_LE(r.tip_max_um, 60.0) << "camera_" << occluded << " occluded";
  }
}

}  // namespace
}  // namespace vrm_tracking
