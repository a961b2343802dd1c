// The scenario layer's measurements and scoring against hand-computed values, and the runner's timing edge cases.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <memory>

#include "vrm_scene/scene_loader.h"
#include "vrm_sim/scenario/light_cone.h"
#include "vrm_sim/scenario/metrics.h"
#include "vrm_sim/scenario/runner.h"

namespace vrm_sim {
namespace scenario {
namespace {

TEST(ScenarioMetrics, PathLengthOfAKnownPolyline) {
  // 3-4-5 triangle legs plus a 12 mm vertical segment: 3 + 4 + 12 mm.
  const std::vector<Eigen::Vector3d> points = {{0, 0, 0}, {0.003, 0, 0}, {0.003, 0.004, 0}, {0.003, 0.004, 0.012}};
  EXPECT_NEAR(pathLength(points), 0.019, 1e-15);
  EXPECT_EQ(pathLength({}), 0.0);
  EXPECT_EQ(pathLength({{1, 2, 3}}), 0.0);
}

TEST(ScenarioMetrics, BandPowerOfASyntheticTenHertzSine) {
  // A = 20 µm on x at 10 Hz, 50 Hz sampling for 10 s (10 Hz is a DFT bin): one-sided power A^2 / 2 in [8, 12] Hz.
  const double amplitude = 2e-5, rate = 50.0;
  std::vector<Eigen::Vector3d> samples;
  for (int i = 0; i < 500; ++i) {
    const double t = i / rate;
    samples.emplace_back(0.001 + amplitude * std::sin(2 * M_PI * 10.0 * t), 0.002, -0.01);
  }
  EXPECT_NEAR(bandPower(samples, rate, 8.0, 12.0), amplitude * amplitude / 2.0, 1e-6 * amplitude * amplitude);
  // Outside the band: nothing; a band beyond Nyquist: nothing.
  EXPECT_NEAR(bandPower(samples, rate, 2.0, 6.0), 0.0, 1e-9 * amplitude * amplitude);
  EXPECT_EQ(bandPower(samples, rate, 30.0, 40.0), 0.0);
  // A slow drift (1 Hz) of 1 mm does not leak into the tremor band.
  for (int i = 0; i < 500; ++i) samples[i].y() += 1e-3 * std::sin(2 * M_PI * 1.0 * i / rate);
  EXPECT_NEAR(bandPower(samples, rate, 8.0, 12.0), amplitude * amplitude / 2.0, 1e-6 * amplitude * amplitude);
  // Degenerate input.
  EXPECT_EQ(bandPower({}, rate, 8, 12), 0.0);
  EXPECT_EQ(bandPower(samples, 0.0, 8, 12), 0.0);
}

TEST(ScenarioMetrics, RmsDistanceAndDeviationFromAKnownPath) {
  EXPECT_NEAR(rmsDistance({{3, 0, 0}, {0, 4, 0}}, Eigen::Vector3d::Zero()), std::sqrt(12.5), 1e-12);
  // An L-shaped path: 10 mm along x, then 10 mm along y.
  const std::vector<Eigen::Vector3d> path = {{0, 0, 0}, {0.01, 0, 0}, {0.01, 0.01, 0}};
  PolylineProjection p = projectOnPolyline(path, {0.004, 0.001, 0});
  EXPECT_NEAR(p.distance, 0.001, 1e-15);
  EXPECT_NEAR(p.arc, 0.004, 1e-15);
  p = projectOnPolyline(path, {0.012, 0.006, 0.0005});
  EXPECT_NEAR(p.distance, std::hypot(0.002, 0.0005), 1e-15);
  EXPECT_NEAR(p.arc, 0.016, 1e-15);
  p = projectOnPolyline(path, {-0.003, -0.004, 0});  // before the start: the first point
  EXPECT_NEAR(p.distance, 0.005, 1e-15);
  EXPECT_EQ(p.arc, 0.0);
}

TEST(ScenarioMetrics, RunningStatsAndContactHysteresis) {
  RunningStats stats;
  for (double v : {2.0, 4.0, 4.0, 4.0, 5.0, 5.0, 7.0, 9.0}) stats.add(v);
  EXPECT_DOUBLE_EQ(stats.mean(), 5.0);
  EXPECT_DOUBLE_EQ(stats.max(), 9.0);
  EXPECT_NEAR(stats.coefficientOfVariation(), std::sqrt(32.0 / 7.0) / 5.0, 1e-12);
  EXPECT_EQ(RunningStats{}.coefficientOfVariation(), 0.0);

  ContactCounter counter;
  // Tremor across the entry threshold (50 µm) within the exit threshold (100 µm) is one contact.
  for (double distance : {2e-4, 4e-5, 6e-5, 4e-5, 9e-5, 1.5e-4, 3e-5, 2e-4}) counter.update(distance, 5e-5, 1e-4);
  EXPECT_EQ(counter.count(), 2u);
  EXPECT_FALSE(counter.inContact());
}

TEST(ScenarioScoring, ItemsAreLinearBetweenBestAndWorstAndClamped) {
  scene::ScoringRule less_is_better{"time", 1.0, 20.0, 60.0, {}};
  EXPECT_DOUBLE_EQ(itemPoints(less_is_better, 20.0), 100.0);
  EXPECT_DOUBLE_EQ(itemPoints(less_is_better, 40.0), 50.0);
  EXPECT_DOUBLE_EQ(itemPoints(less_is_better, 90.0), 0.0);
  EXPECT_DOUBLE_EQ(itemPoints(less_is_better, 5.0), 100.0);
  EXPECT_DOUBLE_EQ(itemPoints(less_is_better, std::nan("")), 0.0);
  scene::ScoringRule more_is_better{"completed", 3.0, 1.0, 0.0, {}};
  EXPECT_DOUBLE_EQ(itemPoints(more_is_better, 1.0), 100.0);
  EXPECT_DOUBLE_EQ(itemPoints(more_is_better, 0.0), 0.0);
  // Weighted mean: (1 * 50 + 3 * 100) / 4; unscored items are reported with weight 0.
  const Score score = computeScore({less_is_better, more_is_better},
                                   {{"time", 40.0, "s"}, {"completed", 1.0, "1"}, {"path_length", 0.02, "m"}});
  EXPECT_DOUBLE_EQ(score.total, 87.5);
  ASSERT_EQ(score.items.size(), 3u);
  EXPECT_EQ(score.item("path_length")->weight, 0.0);
  EXPECT_DOUBLE_EQ(score.item("time")->points, 50.0);
}

// A minimal steady-hold scenario, driven with hand-made frames.
scene::SceneDescription holdScene(const std::string& extra = "", const std::string& extra_scoring = "") {
  return scene::loadSceneFromString(R"(
scene: {name: hold_test, kind: abstract}
objects:
  - {name: retina, role: retina, mesh: {generator: retina}, collision: {detector: none}}
instruments:
  - {slot: right, type: needle}
simulations: []
scenario:
  type: steady_hold
  time_limit: 20
  params: {centre: [0.0, 0.0, -0.010], radius: 0.0001, hold_time: 5})" +
                                        extra + R"(
  scoring:
    time: {weight: 1, best: 5, worst: 20})" +
                                        extra_scoring + R"(
)",
                                    "hold_test.yaml");
}

FrameView frameAt(double time, const Eigen::Vector3d& tip) {
  FrameView frame;
  frame.time = time;
  frame.dt = 0.02;
  InstrumentView needle;
  needle.slot = "right";
  needle.type = scene::InstrumentType::kNeedle;
  needle.valid = true;
  needle.tip = tip;
  frame.instruments.push_back(needle);
  return frame;
}

TEST(ScenarioRunner, PausedTimeIsExcludedAndCommandsFollowTheStateMachine) {
  ScenarioRunner runner(holdScene());
  const Eigen::Vector3d outside(0.0, 0.0, -0.009);
  EXPECT_EQ(runner.status().state, State::kIdle);
  runner.frame(frameAt(0.5, outside));  // idle: time does not run
  EXPECT_EQ(runner.status().elapsed, 0.0);
  EXPECT_NE(runner.pause(0.6), "");  // nothing to pause
  EXPECT_EQ(runner.start(1.0), "");
  EXPECT_NE(runner.start(1.1).find("refused"), std::string::npos);  // START while running
  runner.frame(frameAt(2.0, outside));
  runner.frame(frameAt(3.0, outside));
  EXPECT_EQ(runner.pause(3.5), "");
  runner.frame(frameAt(4.0, outside));  // paused: excluded
  runner.frame(frameAt(7.0, outside));
  EXPECT_DOUBLE_EQ(runner.status().elapsed, 2.5);
  EXPECT_EQ(runner.resume(8.0), "");
  runner.frame(frameAt(9.0, outside));
  EXPECT_DOUBLE_EQ(runner.status().elapsed, 3.5);
  EXPECT_EQ(runner.stop(9.5), "");
  EXPECT_EQ(runner.status().state, State::kFailed);
  EXPECT_DOUBLE_EQ(runner.status().elapsed, 4.0);
  EXPECT_NE(runner.start(10.0).find("RESET"), std::string::npos);  // an ended session needs a RESET
  runner.reset();
  EXPECT_EQ(runner.status().state, State::kIdle);
  EXPECT_EQ(runner.status().elapsed, 0.0);
}

TEST(ScenarioRunner, HoldSucceedsAfterHoldTimeAndTimeLimitFails) {
  ScenarioRunner runner(holdScene());
  runner.start(0.0);
  const Eigen::Vector3d centre(0.0, 0.0, -0.010);
  double t = 0.0;
  for (; t < 2.0; t += 0.02) runner.frame(frameAt(t, centre + Eigen::Vector3d(0, 0, 0.0005)));  // outside
  for (; runner.running() && t < 10.0; t += 0.02) runner.frame(frameAt(t, centre + Eigen::Vector3d(2e-5, 0, 0)));
  EXPECT_EQ(runner.status().state, State::kFinished);
  EXPECT_NEAR(runner.status().elapsed, 7.0, 0.03);  // 2 s to get there + 5 s hold
  EXPECT_NEAR(runner.status().score.item("tip_rms")->value, 2e-5, 1e-12);
  EXPECT_EQ(runner.status().score.item("completed")->value, 1.0);

  ScenarioRunner late(holdScene());
  late.start(0.0);
  for (t = 0.0; late.running() && t < 30.0; t += 0.02) late.frame(frameAt(t, centre + Eigen::Vector3d(0, 0, 0.001)));
  EXPECT_EQ(late.status().state, State::kFailed);
  EXPECT_TRUE(late.status().timed_out);
  EXPECT_NEAR(late.status().elapsed, 20.0, 0.03);
}

TEST(ScenarioRunner, FailIfRuleEndsTheSession) {
  ScenarioRunner runner(holdScene("\n  fail_if: {exits: 2}"));
  runner.start(0.0);
  const Eigen::Vector3d centre(0.0, 0.0, -0.010), away(0.0, 0.0, -0.009);
  double t = 0.0;
  for (int exit = 0; exit < 3 && runner.running(); ++exit) {
    runner.frame(frameAt(t += 0.02, centre));
    runner.frame(frameAt(t += 0.02, away));
  }
  EXPECT_EQ(runner.status().state, State::kFailed);
  EXPECT_FALSE(runner.status().timed_out);
  EXPECT_NE(runner.status().message.find("exits"), std::string::npos) << runner.status().message;
}

// Issue 35: each exit from the hold zone is a penalty event charged to the tool, costing exactly its item's share of
// the total's drop; the factor groups' weighted mean is the total.
TEST(ScenarioRunner, EveryExitIsAPenaltyEventThatExplainsThePointsLost) {
  ScenarioRunner runner(holdScene("", "\n    exits: {weight: 2, best: 0, worst: 5}"));
  runner.start(0.0);
  const Eigen::Vector3d centre(0.0, 0.0, -0.010), away(0.0, 0.0, -0.009);
  double t = 0.0;
  for (int exit = 0; exit < 7; ++exit) {
    runner.frame(frameAt(t += 0.02, centre));
    runner.frame(frameAt(t += 0.02, away + Eigen::Vector3d(1e-4 * exit, 0, 0)));
  }
  const Status& status = runner.status();
  ASSERT_EQ(status.events.size(), 7u);
  EXPECT_EQ(status.events_dropped, 0u);
  double lost = 0.0;
  for (std::size_t i = 0; i < status.events.size(); ++i) {
    const PenaltyEvent& event = status.events[i];
    EXPECT_EQ(event.kind, "left_hold_zone");
    EXPECT_EQ(event.item, "exits");
    EXPECT_EQ(event.slot, "right");
    EXPECT_EQ(event.instrument, "needle");
    EXPECT_TRUE(event.position.isApprox(away + Eigen::Vector3d(1e-4 * i, 0, 0))) << event.position.transpose();
    EXPECT_NEAR(event.time, 0.04 * (i + 1), 1e-9);
    // 20 points of the item per exit, weight 2 of 3: 13.33 of the total, until the item is at its worst (5 exits).
    EXPECT_NEAR(event.points, i < 5 ? 2.0 * 20.0 / 3.0 : 0.0, 1e-9) << i;
    lost += event.points;
  }
  EXPECT_NEAR(lost, 2.0 * (100.0 - status.score.item("exits")->points) / 3.0, 1e-9);
  // Groups: efficiency (time, weight 1) and instrument handling (exits, weight 2); the rest are not scored here.
  ASSERT_EQ(status.score.groups.size(), 2u);
  EXPECT_EQ(status.score.groups[0].name, "efficiency");
  EXPECT_EQ(status.score.groups[1].name, "instrument_handling");
  EXPECT_EQ(status.score.groups[1].weight, 2.0);
  EXPECT_NEAR((status.score.groups[0].points + 2.0 * status.score.groups[1].points) / 3.0, status.score.total, 1e-12);
  runner.reset();
  EXPECT_TRUE(runner.status().events.empty());
}

ScoreItem scored(const std::string& name, double value, double points, double weight = 1.0) {
  return ScoreItem{name, value, "1", weight, points};
}

TEST(PenaltyLog, CountsGiveAnEventPerRiseContinuousItemsOnePerRunAndTheLogIsBounded) {
  PenaltyLog log;
  std::vector<PenaltyEvent> events;
  std::size_t dropped = 0;
  InstrumentView forceps;
  forceps.slot = "left";
  forceps.type = scene::InstrumentType::kForceps;
  forceps.tip = Eigen::Vector3d(0.001, 0.002, -0.011);
  const auto instrument = [&](const std::string&) { return &forceps; };
  // Weights 1 + 1 + 2 = 4: bleeding's share of a drop of its points by 10 is 2.5 of the total.
  const auto table = [](double bleeding, double bleeding_points, double contacts, double contact_points) {
    return std::vector<ScoreItem>{scored("bleeding_area", bleeding, bleeding_points),
                                  scored("retina_contacts", contacts, contact_points), scored("time", 1, 50, 2)};
  };
  std::vector<ScoreItem> before = table(0, 100, 0, 100);
  const std::vector<std::vector<ScoreItem>> frames = {
      table(1e-6, 90, 0, 100), table(2e-6, 80, 1, 75),  // bleeding starts; a touch
      table(3e-6, 70, 1, 75),                           // bleeding goes on: the same event
      table(3e-6, 70, 1, 75),                           // stops
      table(4e-6, 60, 2, 50),                           // over 1 s later: a second bleeding, a second touch
  };
  const double times[] = {0.1, 0.2, 0.3, 0.4, 1.5};
  for (std::size_t i = 0; i < frames.size(); ++i) {
    log.record(before, frames[i], times[i], instrument, events, dropped);
    before = frames[i];
  }
  ASSERT_EQ(events.size(), 4u);
  EXPECT_EQ(events[0].kind, "bleeding");
  EXPECT_NEAR(events[0].points, 3 * 10.0 / 4.0, 1e-12);  // three rising frames, one event
  EXPECT_NEAR(events[0].time, 0.1, 1e-12);
  EXPECT_EQ(events[1].kind, "retina_touched");
  EXPECT_NEAR(events[1].points, 25.0 / 4.0, 1e-12);
  EXPECT_EQ(events[1].slot, "left");
  EXPECT_EQ(events[1].instrument, "forceps");
  EXPECT_TRUE(events[1].position.isApprox(forceps.tip));
  EXPECT_EQ(events[2].kind, "bleeding");
  EXPECT_NEAR(events[2].time, 1.5, 1e-12);
  EXPECT_EQ(events[3].kind, "retina_touched");
  // Without an instrument: no slot, no position.
  log.record(
      before, table(4e-6, 60, 3, 25), 1.6, [](const std::string&) { return nullptr; }, events, dropped);
  ASSERT_EQ(events.size(), 5u);
  EXPECT_EQ(events[4].slot, "");
  EXPECT_FALSE(events[4].position.allFinite());

  // Bounded: past kMaxEvents the events are counted, not kept.
  before = table(0, 100, 0, 100);
  events.clear();
  log.reset();
  for (int touch = 1; touch <= 250; ++touch) {
    const std::vector<ScoreItem> after = table(0, 100, touch, 0);
    log.record(before, after, touch, instrument, events, dropped);
    before = after;
  }
  EXPECT_EQ(events.size(), PenaltyLog::kMaxEvents);
  EXPECT_EQ(dropped, 50u);
}

TEST(FactorGroups, EveryItemOfEveryScenarioTypeHasAGroupAndAGroupWithoutScoredItemsIsOmitted) {
  for (const ItemRole& role : itemRoles()) {
    EXPECT_TRUE(std::any_of(std::begin(kFactorGroups), std::end(kFactorGroups),
                            [&](const char* group) { return std::string(group) == role.group; }))
        << role.item << ": unknown group " << role.group;
  }
  const std::vector<ScoreItem> items = {scored("completed", 1, 100, 3), scored("time", 40, 50, 1),
                                        scored("retina_contacts", 1, 75, 2), scored("path_length", 0.02, 0, 0)};
  const std::vector<GroupScore> groups = groupScores(items);
  ASSERT_EQ(groups.size(), 3u);  // efficiency: time only (path_length is not scored); no microscope handling
  EXPECT_EQ(groups[0].name, "target_achievement");
  EXPECT_EQ(groups[1].name, "efficiency");
  EXPECT_EQ(groups[1].points, 50.0);
  EXPECT_EQ(groups[2].name, "tissue_treatment");
  EXPECT_EQ(groups[2].weight, 2.0);
  EXPECT_EQ(itemRole("no_such_item"), nullptr);
}

TEST(ScenarioRunner, RulesNamingUnknownItemsOrParamsAreErrorsWithTheirLocation) {
  try {
    ScenarioRunner runner(holdScene("\n  fail_if: {exitz: 2}"));
    FAIL() << "accepted an unknown item";
  } catch (const scene::SceneError& error) {
    EXPECT_NE(std::string(error.what()).find("hold_test.yaml:"), std::string::npos) << error.what();
    EXPECT_NE(std::string(error.what()).find("exitz"), std::string::npos) << error.what();
  }
  try {
    ScenarioRunner runner(scene::loadSceneFromString(R"(
scene: {name: hold_test, kind: abstract}
objects: [{name: retina, role: retina, mesh: {generator: retina}}]
instruments: [{slot: right, type: needle}]
simulations: []
scenario: {type: steady_hold, params: {centre: [0, 0, -0.01], holdtime: 3}}
)",
                                                     "typo.yaml"));
    FAIL() << "accepted an unknown parameter";
  } catch (const scene::SceneError& error) {
    const std::string message = error.what();
    EXPECT_NE(message.find("typo.yaml:6:"), std::string::npos) << message;
    EXPECT_NE(message.find("scenario.params.holdtime"), std::string::npos) << message;
    EXPECT_NE(message.find("hold_time"), std::string::npos) << message;  // what it has instead
  }
}

// The one lit rule (issue 33): inside the cone up to its half-angle, not outside it, never behind the tip, never
// without a direction (point at the tip, zero axis) and never with an unknown (NaN) pose.
TEST(LightCone, InsideOutsideBehindDegenerateAndNaN) {
  const double cone_cos = lightConeCos(kLightConeHalfAngleDeg);
  EXPECT_NEAR(cone_cos, std::cos(25.0 * M_PI / 180.0), 1e-15);
  const Eigen::Vector3d tip(0.0, 0.0, -0.005), down(0.0, 0.0, -1.0);
  const auto at = [&](double angle_deg) {  // 5 mm from the tip, angle_deg off the axis
    const double a = angle_deg * M_PI / 180.0;
    return Eigen::Vector3d(tip + 0.005 * Eigen::Vector3d(std::sin(a), 0.0, -std::cos(a)));
  };
  EXPECT_TRUE(litByLightPipe(tip, down, at(0.0), cone_cos));
  EXPECT_TRUE(litByLightPipe(tip, down, at(24.9), cone_cos));
  EXPECT_FALSE(litByLightPipe(tip, down, at(25.1), cone_cos));
  EXPECT_FALSE(litByLightPipe(tip, down, at(60.0), cone_cos));
  EXPECT_FALSE(litByLightPipe(tip, down, at(180.0), cone_cos));            // behind the tip
  EXPECT_FALSE(litByLightPipe(tip, down, at(110.0), lightConeCos(90.0)));  // behind, even with a 90 deg cone
  // A non-unit axis means its direction.
  EXPECT_TRUE(litByLightPipe(tip, 3.0 * down, at(20.0), cone_cos));
  EXPECT_FALSE(litByLightPipe(tip, 3.0 * down, at(30.0), cone_cos));
  // Degenerate: the point at the tip, a zero axis; unknown: NaN axis, tip or point.
  const double nan = std::nan("");
  EXPECT_FALSE(litByLightPipe(tip, down, tip, cone_cos));
  EXPECT_FALSE(litByLightPipe(tip, Eigen::Vector3d::Zero(), at(0.0), cone_cos));
  EXPECT_FALSE(litByLightPipe(tip, Eigen::Vector3d(nan, 0.0, -1.0), at(0.0), cone_cos));
  EXPECT_FALSE(litByLightPipe(Eigen::Vector3d(nan, 0.0, 0.0), down, at(0.0), cone_cos));
  EXPECT_FALSE(litByLightPipe(tip, down, Eigen::Vector3d(0.0, nan, -0.01), cone_cos));
}

// unlit_work of a surgical scenario (membrane peeling, the shipped scene: light pipe left, forceps right, 12 mm eye),
// driven with hand-made frames of 20 ms: it counts the frames the forceps works (tip in the posterior half, within
// 1.5 mm of the retina) outside the light pipe's 25 deg cone, and nothing else.
struct UnlitCase {
  bool tool_valid = true;
  Eigen::Vector3d tool_tip{0.0, 0.0, -0.0115};  // 0.5 mm off the retina at the posterior pole
  bool light_valid = true;
  double aim_off_deg = 0.0;  // the light's axis this far off the direction to the forceps' tip
  bool nan_axis = false;
};

double unlitWork(const UnlitCase& c, int frames = 10) {
  const std::unique_ptr<Scenario> scenario =
      makeScenario(scene::loadScene(scene::shippedScenePath("membrane_peeling")));
  const Eigen::Vector3d light_tip(-0.002, 0.001, -0.006);
  const Eigen::Vector3d to_tool = (c.tool_tip - light_tip).normalized();
  const Eigen::Vector3d aside = to_tool.cross(Eigen::Vector3d::UnitY()).normalized();
  const double a = c.aim_off_deg * M_PI / 180.0;
  for (int i = 0; i < frames; ++i) {
    FrameView frame;
    frame.time = 0.02 * (i + 1);
    frame.dt = 0.02;
    InstrumentView light, forceps;
    light.slot = "left";
    light.type = scene::InstrumentType::kLightPipe;
    light.valid = c.light_valid;
    light.tip = light_tip;
    light.axis = c.nan_axis ? Eigen::Vector3d(std::nan(""), 0.0, -1.0)
                            : Eigen::Vector3d(std::cos(a) * to_tool + std::sin(a) * aside);
    forceps.slot = "right";
    forceps.type = scene::InstrumentType::kForceps;
    forceps.valid = c.tool_valid;
    forceps.tip = c.tool_tip;
    frame.instruments = {light, forceps};
    scenario->update(frame, frame.time);
  }
  for (const Measurement& m : scenario->measurements(0.2)) {
    if (m.name == "unlit_work") {
      EXPECT_EQ(m.unit, "s");
      return m.value;
    }
  }
  ADD_FAILURE() << "membrane_peeling reports no unlit_work";
  return std::nan("");
}

TEST(UnlitWork, CountsWorkOutsideTheConeOnly) {
  UnlitCase lit;
  EXPECT_EQ(unlitWork(lit), 0.0);
  UnlitCase edge;
  edge.aim_off_deg = 20.0;  // inside the 25 deg cone
  EXPECT_EQ(unlitWork(edge), 0.0);
  UnlitCase away;
  away.aim_off_deg = 40.0;
  EXPECT_NEAR(unlitWork(away), 0.2, 1e-12);  // ten frames of 20 ms
  EXPECT_NEAR(unlitWork(away, 25), 0.5, 1e-12);
  UnlitCase dark;
  dark.light_valid = false;  // a light pipe that is not tracked lights nothing
  EXPECT_NEAR(unlitWork(dark), 0.2, 1e-12);
  UnlitCase unknown;
  unknown.nan_axis = true;
  EXPECT_NEAR(unlitWork(unknown), 0.2, 1e-12);
  // Not working: the forceps lifted 2 mm off the retina, at the front of the eye near its trocar, or not tracked.
  UnlitCase lifted = away;
  lifted.tool_tip = Eigen::Vector3d(0.0, 0.0, -0.010);
  EXPECT_EQ(unlitWork(lifted), 0.0);
  UnlitCase front = away;
  front.tool_tip = Eigen::Vector3d(0.0074, 0.0042, 0.0080);  // 0.6 mm inside the right trocar (z > 0)
  EXPECT_EQ(unlitWork(front), 0.0);
  UnlitCase untracked = away;
  untracked.tool_valid = false;
  EXPECT_EQ(unlitWork(untracked), 0.0);
}

// The light pipe and the working instrument must be different slots.
TEST(UnlitWork, TheLightMustNotBeTheTool) {
  scene::SceneDescription scene = scene::loadScene(scene::shippedScenePath("vitrectomy"));
  EXPECT_NO_THROW(makeScenario(scene));
  scene.scenario->params["light"].names = {"right"};
  EXPECT_THROW(makeScenario(scene), scene::SceneError);
}

}  // namespace
}  // namespace scenario
}  // namespace vrm_sim
