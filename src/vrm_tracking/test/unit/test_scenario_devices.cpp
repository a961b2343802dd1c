// The device twins' tracks for a scene's scripted session (issue 33): the focus follows the working plane (the
// fundus under the working tip, raised with the tip by at most 0.2 mm, averaged over 0.5 s), the zoom stays fixed, the
// pedal follows the working instrument's suction and presses no buttons. Scripts with round numbers, values by hand.
#include <gtest/gtest.h>

#include <cmath>

#include "script_fixtures.h"
#include "vrm_tracking/scenario_devices.h"

namespace vrm_tracking {
namespace {

// A 12 mm eye centred 1 mm above the world origin; a light pipe (left) that stays put and a vitrector (right) that
// comes down from 6 mm below the centre to 0.5 mm off the retina at x = 1 mm (t = 1 s), cuts there with suction 0.6
// until t = 3 s, moves to x = 5 mm 0.11 mm off the retina (t = 3.2 s; the fundus there is 1.05 mm higher) and lifts
// to 3 mm below the centre (t = 4 s). Objective at z 0.188.
const char* kSession = R"(name: session
playback: once
instruments:
  - slot: left
    path:
      - {t: 0.0, tip: [-0.002, 0.001, -0.006]}
      - {t: 4.0, tip: [-0.002, 0.001, -0.006]}
  - slot: right
    type: vitrector
    path:
      - {t: 0.0, tip: [0.001, 0.0, -0.006], suction: 0.0}
      - {t: 1.0, tip: [0.001, 0.0, -0.0114583], suction: 0.6}
      - {t: 3.0, tip: [0.001, 0.0, -0.0114583], suction: 0.6}
      - {t: 3.2, tip: [0.005, 0.0, -0.0108], suction: 0.6}
      - {t: 4.0, tip: [0.005, 0.0, -0.003], suction: 0.0}
)";

SurgeonScript session() {
  return testing::playYaml(kSession, testing::testScene(Eigen::Vector3d(0.0, 0.0, 0.001)), "session.yaml");
}

// Retina z below x = 1 mm (world): centre z - sqrt(R^2 - x^2).
const double kRetinaZ = 0.001 - std::sqrt(0.012 * 0.012 - 0.001 * 0.001);

TEST(ScenarioFocus, FocusesOnTheWorkingTipClampedToTheWorkingPlane) {
  const SurgeonScript s = session();
  // Working 0.5 mm off the retina, or entering high (6 mm below the centre): the plane 0.2 mm above the fundus
  // under the tip.
  EXPECT_NEAR(scenarioFocusDistance(s.sample(2.0), "right", 0.012), 0.188 - (kRetinaZ + 0.0002), 1e-12);
  EXPECT_NEAR(scenarioFocusDistance(s.sample(0.0), "right", 0.012), 0.188 - (kRetinaZ + 0.0002), 1e-12);
  // Closer than that (0.1 mm): the tip's depth.
  SurgeonSnapshot close = s.sample(2.0);
  close.instruments[1].tip.z() = kRetinaZ - 0.001 + 0.0001;  // world z = eye z + 1 mm
  EXPECT_NEAR(scenarioFocusDistance(close, "right", 0.012), 0.188 - (kRetinaZ + 0.0001), 1e-12);
  // Below the retina (pressed into it): the retina.
  SurgeonSnapshot pressed = s.sample(2.0);
  pressed.instruments[1].tip.z() = -0.0125;
  EXPECT_NEAR(scenarioFocusDistance(pressed, "right", 0.012), 0.188 - kRetinaZ, 1e-12);
  // No such instrument, a tip outside the sphere's footprint, a NaN tip: the posterior pole (0.2 m below the
  // objective for an eye at the origin; here 1 mm higher).
  EXPECT_NEAR(scenarioFocusDistance(s.sample(2.0), "none", 0.012), 0.188 - (0.001 - 0.012), 1e-12);
  SurgeonSnapshot outside = s.sample(2.0);
  outside.instruments[1].tip.x() = 0.013;
  EXPECT_NEAR(scenarioFocusDistance(outside, "right", 0.012), 0.199, 1e-12);
  outside.instruments[1].tip.x() = std::nan("");
  EXPECT_NEAR(scenarioFocusDistance(outside, "right", 0.012), 0.199, 1e-12);
  // Another objective height shifts the distance by as much.
  ScenarioFocusOptions higher;
  higher.objective_z = 0.2;
  EXPECT_NEAR(scenarioFocusDistance(s.sample(2.0), "right", 0.012, higher),
              scenarioFocusDistance(s.sample(2.0), "right", 0.012) + 0.012, 1e-12);
}

TEST(ScenarioFocus, DeviceTracksAreSmoothedFixedZoomAndButtonless) {
  ScenarioFocusOptions following;  // the smoothed plane itself, without holding (refocus_tolerance 0)
  following.refocus_tolerance = 0.0;
  const SurgeonScript s = withScenarioDeviceTracks(session(), "right", following);
  EXPECT_EQ(s.playback(), Playback::kOnce);
  ASSERT_EQ(s.session().instruments.size(), 2u);  // the instruments play as before
  const double working = 0.188 - (kRetinaZ + 0.0002);
  // Entering, the tip is at x = 1 mm from t = 0: the fundus under it does not move, nor does the focus. A focus that
  // followed the tip would lag it: here the plane the averaging holds still.
  const double entering = working;
  // Settled after half a second of work; the average lags the tip's descent.
  EXPECT_NEAR(s.sample(2.0).microscope.focus_distance, working, 1e-9);
  EXPECT_NEAR(s.sample(2.99).microscope.focus_distance, working, 1e-9);
  EXPECT_NEAR(s.sample(0.0).microscope.focus_distance, entering, 1e-9);
  // Moved over to x = 5 mm: the focus follows the fundus there, lagging by the 0.5 s average.
  const double moved = 0.188 - (0.001 - std::sqrt(0.012 * 0.012 - 0.005 * 0.005) + 0.0002);
  const double lagging = s.sample(3.2).microscope.focus_distance;
  EXPECT_LT(lagging, working - 1e-5);
  EXPECT_GT(lagging, moved + 1e-5);
  EXPECT_NEAR(s.sample(3.8).microscope.focus_distance, moved, 1e-9);
  // The focus never jumps: the 1.05 mm step of the fundus spreads over the 0.5 s average, < 0.11 mm per 50 ms tick.
  for (double t = 0.0; t < 4.5; t += 0.05) {
    const SurgeonSnapshot a = s.sample(t), b = s.sample(t + 0.05);
    EXPECT_LT(std::abs(b.microscope.focus_distance - a.microscope.focus_distance), 1.1e-4) << t;
    EXPECT_DOUBLE_EQ(a.microscope.zoom, 1.5) << t;
    EXPECT_FALSE(a.pedals.zoom_in || a.pedals.zoom_out || a.pedals.focus_near || a.pedals.focus_far) << t;
    EXPECT_FALSE(a.pedals.reflux || a.pedals.instrument_switch) << t;
  }
  // The pedal is the vitrector's suction.
  EXPECT_NEAR(s.sample(2.0).pedals.travel, 0.6, 1e-12);
  EXPECT_NEAR(s.sample(0.0).pedals.travel, 0.0, 1e-12);
  // A pure function of the script time: built twice, sampled anywhere, the same.
  const SurgeonScript again = withScenarioDeviceTracks(session(), "right", following);
  for (double t : {0.0, 0.37, 1.234, 2.9, 10.0}) {
    EXPECT_EQ(again.sample(t).microscope.focus_distance, s.sample(t).microscope.focus_distance) << t;
  }
}

// The default track holds the focus while the plane stays within refocus_tolerance (0.1 mm) of it and refocuses when
// it leaves: the microscope's cameras stay still between refocuses, so the renderer keeps its static retina layer.
TEST(ScenarioFocus, FocusHoldsUntilThePlaneMovesAway) {
  ScenarioFocusOptions following;
  following.refocus_tolerance = 0.0;
  const SurgeonScript held = withScenarioDeviceTracks(session(), "right");
  const SurgeonScript plane = withScenarioDeviceTracks(session(), "right", following);
  const double tolerance = ScenarioFocusOptions{}.refocus_tolerance;
  int moves = 0, ticks = 0;
  for (double t = 0.0; t < 4.5; t += 0.05, ++ticks) {
    const double focus = held.sample(t).microscope.focus_distance;
    EXPECT_LE(std::abs(focus - plane.sample(t).microscope.focus_distance), tolerance + 1e-12) << t;
    if (held.sample(t + 0.05).microscope.focus_distance != focus) ++moves;
  }
  // The plane moves 1.05 mm in all (x = 1 -> 5 mm): at most ~11 refocus ramps of one tick each, not 90 creeping ticks.
  EXPECT_LE(moves, 12) << ticks;
  EXPECT_GE(moves, 1);
  EXPECT_NEAR(held.sample(2.5).microscope.focus_distance, 0.188 - (kRetinaZ + 0.0002), 1e-9);  // steady: exact
}

TEST(ScenarioFocus, BadOptionsAreErrors) {
  ScenarioFocusOptions bad;
  bad.step = 0.0;
  EXPECT_THROW(withScenarioDeviceTracks(session(), "right", bad), std::invalid_argument);
  bad = ScenarioFocusOptions{};
  bad.window = -1.0;
  EXPECT_THROW(withScenarioDeviceTracks(session(), "right", bad), std::invalid_argument);
}

}  // namespace
}  // namespace vrm_tracking
