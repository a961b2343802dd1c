// Tremor and motion metrics on synthetic trajectories with known injected tremor.

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "vrm_scene/scene_loader.h"
#include "vrm_tracking/motion_metrics.h"
#include "vrm_tracking/scene_trocars.h"
#include "vrm_tracking/surgeon_script.h"

namespace vrm_tracking {
namespace {

std::vector<double> times(double duration, double rate) {
  std::vector<double> t;
  for (int i = 0; i <= static_cast<int>(duration * rate); ++i) t.push_back(i / rate);
  return t;
}

Eigen::Vector3d circle(double t) {  // 4 mm radius at 0.25 Hz: 6.28 mm/s, a slow deliberate motion
  return 0.004 * Eigen::Vector3d(std::cos(2 * M_PI * 0.25 * t), std::sin(2 * M_PI * 0.25 * t), 0.0);
}

TEST(MotionMetrics, PathAndSpeedOfACircle) {
  const auto t = times(4.0, 50.0);
  std::vector<Eigen::Vector3d> p;
  for (double ti : t) p.push_back(circle(ti));
  const MotionMetrics m = motionMetrics(t, p);
  EXPECT_NEAR(m.path_length, 2 * M_PI * 0.004, 1e-5);  // one revolution
  EXPECT_NEAR(m.mean_speed, 2 * M_PI * 0.004 * 0.25, 1e-5);
  EXPECT_NEAR(m.max_speed, 2 * M_PI * 0.004 * 0.25, 1e-5);
  EXPECT_LT(m.tremor_rms, 0.5e-6);  // no tremor: < 0.5 µm leaks into 8-12 Hz
}

TEST(MotionMetrics, RecoversInjectedTremorAmplitude) {
  const auto t = times(10.0, 50.0);
  for (const double amplitude : {10e-6, 30e-6}) {
    std::vector<Eigen::Vector3d> p;
    for (double ti : t) {
      // 9.3 Hz along x (RMS amplitude/√2) and 10.7 Hz along z (same): total RMS = amplitude.
      p.push_back(circle(ti) +
                  amplitude * Eigen::Vector3d(std::sin(2 * M_PI * 9.3 * ti), 0.0, std::cos(2 * M_PI * 10.7 * ti)));
    }
    const MotionMetrics m = motionMetrics(t, p);
    EXPECT_NEAR(m.tremor_rms, amplitude, 0.05 * amplitude);
  }
}

TEST(MotionMetrics, MeasuresTheScriptedSurgeonsTremor) {
  // The scripted surgeon's tremor (§1.3: 8-12 Hz, bounded per axis by the amplitude) is all in the band.
  const vrm_sim::scene::SceneDescription peeling = vrm_sim::scene::loadScene(vrm_sim::scene::kDefaultSceneName);
  SurgeonScript script = playInScene(peeling, loadSession("", peeling));
  std::vector<double> t = times(8.0, 50.0);
  std::vector<Eigen::Vector3d> with, without;
  for (double ti : t) without.push_back(script.sample(ti).instruments[0].tip);
  script.setTremorAmplitude(40e-6);
  for (double ti : t) with.push_back(script.sample(ti).instruments[0].tip);
  const double base = motionMetrics(t, without).tremor_rms, tremor = motionMetrics(t, with).tremor_rms;
  EXPECT_LT(base, 2e-6);
  EXPECT_GT(tremor, 10e-6);
  EXPECT_LT(tremor, 40e-6 * std::sqrt(3.0));
}

TEST(MotionMetrics, DegenerateInput) {
  EXPECT_EQ(motionMetrics({}, {}).path_length, 0.0);
  EXPECT_EQ(motionMetrics({0, 1}, {Eigen::Vector3d::Zero(), Eigen::Vector3d::Ones()}).tremor_rms, 0.0);
}

}  // namespace
}  // namespace vrm_tracking
