// SurgeonScript without ROS: interpolation, playback, the trocar constraint, tremor and error reporting.

#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <string>
#include <vector>

#include "vrm_tracking/surgeon_script.h"

namespace vrm_tracking {
namespace {

const std::string kSourceDir = VRM_TRACKING_SOURCE_DIR;

// Two-keyframe script with round numbers, so expected values can be written down by hand.
const char* kSimple = R"(name: simple
playback: loop
eye:
  radius: 0.012
  margin: 0.001
  rotation_center: [0.1, 0.2, 0.3]
eye_track:
  - {t: 0.0, rpy: [0.0, 0.0, 0.0]}
  - {t: 2.0, rpy: [0.0, 0.0, 1.0]}
instruments:
  right:
    trocar: [0.0, 0.008, 0.008]
    keyframes:
      - {t: 0.0, type: forceps, tip: [0.0, 0.0, -0.002], jaw_angle: 0.4, roll: 0.0}
      - {t: 2.0, type: vitrector, tip: [0.002, 0.0, -0.006], jaw_angle: 0.0, roll: 1.0, cut_rate: 30.0}
      - {t: 4.0, tip: [0.0, 0.0, -0.002]}
pedal_track:
  - {t: 0.0, travel: 0.0, reflux: false}
  - {t: 1.0, travel: 1.0, reflux: true}
microscope_track:
  - {t: 0.0, focus_distance: 0.2, zoom: 1.0, ambient_light: 0.2, disparity_scale: 1.0}
  - {t: 4.0, focus_distance: 0.19, zoom: 2.0, ambient_light: 0.6, disparity_scale: 0.5}
)";

SurgeonScript simple() { return SurgeonScript::fromYamlString(kSimple, "simple.yaml"); }

TEST(SurgeonScript, ParsesSimpleScript) {
  const SurgeonScript s = simple();
  EXPECT_EQ(s.name(), "simple");
  EXPECT_EQ(s.playback(), Playback::kLoop);
  EXPECT_DOUBLE_EQ(s.duration(), 4.0);
  ASSERT_EQ(s.definition().instruments.size(), 1u);
  EXPECT_EQ(s.definition().instruments[0].slot, "right");
  // Unspecified fields carry over from the previous keyframe.
  EXPECT_EQ(s.definition().instruments[0].keyframes[2].type, vrm_sim::scene::InstrumentType::kVitrector);
  EXPECT_DOUBLE_EQ(s.definition().instruments[0].keyframes[2].cut_rate, 30.0);
}

TEST(SurgeonScript, ExactAtKeyframes) {
  const SurgeonScript s = simple();
  const SurgeonSnapshot a = s.sample(0.0);
  ASSERT_EQ(a.instruments.size(), 1u);
  EXPECT_TRUE(a.instruments[0].tip.isApprox(Eigen::Vector3d(0.0, 0.0, -0.002), 1e-15));
  EXPECT_DOUBLE_EQ(a.instruments[0].jaw_angle, 0.4);
  EXPECT_EQ(a.instruments[0].type, vrm_sim::scene::InstrumentType::kForceps);
  EXPECT_TRUE(a.eye_rotation.isApprox(Eigen::Quaterniond::Identity()));
  EXPECT_TRUE(a.rotation_center.isApprox(Eigen::Vector3d(0.1, 0.2, 0.3)));

  const SurgeonSnapshot b = s.sample(2.0);
  EXPECT_EQ((b.instruments[0].tip - Eigen::Vector3d(0.002, 0.0, -0.006)).norm(), 0.0);
  EXPECT_DOUBLE_EQ(b.instruments[0].roll, 1.0);
  EXPECT_DOUBLE_EQ(b.instruments[0].cut_rate, 30.0);
  EXPECT_EQ(b.instruments[0].type, vrm_sim::scene::InstrumentType::kVitrector);
  const Eigen::Quaterniond yaw1(Eigen::AngleAxisd(1.0, Eigen::Vector3d::UnitZ()));
  EXPECT_LT(b.eye_rotation.angularDistance(yaw1), 1e-12);

  EXPECT_DOUBLE_EQ(s.sample(1.0).pedals.travel, 1.0);
  EXPECT_TRUE(s.sample(1.0).pedals.reflux);
  EXPECT_DOUBLE_EQ(s.sample(0.0).microscope.zoom, 1.0);
}

TEST(SurgeonScript, LinearAtMidpointsStepForDiscrete) {
  const SurgeonScript s = simple();
  const SurgeonSnapshot m = s.sample(1.0);
  EXPECT_TRUE(m.instruments[0].tip.isApprox(Eigen::Vector3d(0.001, 0.0, -0.004), 1e-12));
  EXPECT_NEAR(m.instruments[0].jaw_angle, 0.2, 1e-15);
  EXPECT_NEAR(m.instruments[0].roll, 0.5, 1e-15);
  EXPECT_NEAR(m.instruments[0].cut_rate, 15.0, 1e-12);
  // Step: the instrument in hand is the previous keyframe's until the next keyframe time.
  EXPECT_EQ(m.instruments[0].type, vrm_sim::scene::InstrumentType::kForceps);
  EXPECT_EQ(s.sample(1.999).instruments[0].type, vrm_sim::scene::InstrumentType::kForceps);
  // Slerp midpoint of a 1 rad yaw is a 0.5 rad yaw.
  const Eigen::Quaterniond yaw_half(Eigen::AngleAxisd(0.5, Eigen::Vector3d::UnitZ()));
  EXPECT_LT(m.eye_rotation.angularDistance(yaw_half), 1e-12);

  const SurgeonSnapshot p = s.sample(0.5);
  EXPECT_NEAR(p.pedals.travel, 0.5, 1e-15);
  EXPECT_FALSE(p.pedals.reflux);  // boolean steps at t = 1
  EXPECT_NEAR(s.sample(2.0).microscope.zoom, 1.5, 1e-12);
  EXPECT_NEAR(s.sample(2.0).microscope.focus_distance, 0.195, 1e-12);
  EXPECT_NEAR(s.sample(2.0).microscope.disparity_scale, 0.75, 1e-12);
  // Tracks that ended hold their last value (the pedal track ends at 1 s, the script at 4 s).
  EXPECT_DOUBLE_EQ(s.sample(3.0).pedals.travel, 1.0);
}

TEST(SurgeonScript, SlerpKeepsUnitNorm) {
  const SurgeonScript s = SurgeonScript::fromYamlString(R"(
eye_track:
  - {t: 0.0, quaternion: {w: 1, x: 0, y: 0, z: 0}}
  - {t: 1.0, quaternion: {w: 0.3, x: 0.5, y: -0.6, z: 0.2}}
  - {t: 2.0, rpy_deg: [170, -80, 30]}
)",
                                                        "slerp.yaml");
  for (int i = 0; i <= 200; ++i) {
    const double t = 2.0 * i / 200.0;
    EXPECT_NEAR(s.sample(t).eye_rotation.norm(), 1.0, 1e-12) << "t=" << t;
  }
}

TEST(SurgeonScript, LoopWrapsAndOnceHolds) {
  SurgeonScript s = simple();
  const SurgeonSnapshot a = s.sample(1.25);
  const SurgeonSnapshot b = s.sample(1.25 + 3 * s.duration());
  EXPECT_NEAR(b.script_time, 1.25, 1e-12);
  EXPECT_TRUE(a.instruments[0].tip.isApprox(b.instruments[0].tip, 1e-12));
  EXPECT_FALSE(b.finished);
  EXPECT_NEAR(s.sample(4.0).script_time, 0.0, 1e-12);

  s.setPlayback(Playback::kOnce);
  const SurgeonSnapshot end = s.sample(100.0);
  EXPECT_TRUE(end.finished);
  EXPECT_DOUBLE_EQ(end.script_time, 4.0);
  EXPECT_TRUE(end.instruments[0].tip.isApprox(Eigen::Vector3d(0.0, 0.0, -0.002)));
  EXPECT_FALSE(s.sample(3.9).finished);
}

void expectTrocarConstraint(const SurgeonScript& s, double t) {
  const SurgeonSnapshot snap = s.sample(t);
  for (std::size_t i = 0; i < snap.instruments.size(); ++i) {
    const InstrumentSample& in = snap.instruments[i];
    const Eigen::Vector3d trocar = s.definition().instruments[i].trocar;
    EXPECT_NEAR(in.shaft_axis.norm(), 1.0, 1e-12);
    EXPECT_NEAR(in.insertion_depth, (in.tip - trocar).norm(), 1e-15);
    // The shaft line passes through the trocar: tip - depth * axis == trocar, and the trocar is collinear.
    EXPECT_LT((in.tip - in.insertion_depth * in.shaft_axis - trocar).norm(), 1e-15);
    EXPECT_LT((trocar - in.tip).cross(in.shaft_axis).norm(), 1e-15);
    // The tip frame's +z is the shaft and its roll matches.
    EXPECT_LT((in.orientation * Eigen::Vector3d::UnitZ() - in.shaft_axis).norm(), 1e-12);
    const Eigen::Quaterniond unrolled = shaftOrientation(trocar, in.shaft_axis, 0.0);
    const Eigen::Vector3d x0 = unrolled * Eigen::Vector3d::UnitX();
    const Eigen::Vector3d x = in.orientation * Eigen::Vector3d::UnitX();
    EXPECT_NEAR(std::atan2(x0.cross(x).dot(in.shaft_axis), x0.dot(x)), std::remainder(in.roll, 2 * M_PI), 1e-9);
  }
}

TEST(SurgeonScript, ShaftPassesThroughTrocar) {
  SurgeonScript s = simple();
  for (double t = 0.0; t < 4.0; t += 0.05) expectTrocarConstraint(s, t);
  s.setTremor(50e-6, 3);  // the constraint must survive tremor: the shaft follows the trembling tip
  for (double t = 0.0; t < 4.0; t += 0.05) expectTrocarConstraint(s, t);
  const SurgeonScript demo = SurgeonScript::builtin("demo");
  for (double t = 0.0; t < demo.duration(); t += 0.1) expectTrocarConstraint(demo, t);
}

TEST(SurgeonScript, ShaftOrientationIsContinuousForVerticalShaft) {
  // A shaft pointing straight at the posterior pole is where an eye-axis reference would flip.
  const Eigen::Vector3d trocar(0.0, 0.008, 0.008);
  const Eigen::Vector3d below = Eigen::Vector3d(0.0, 0.008, -0.004);
  Eigen::Quaterniond previous;
  for (int i = -10; i <= 10; ++i) {
    const Eigen::Vector3d tip = below + Eigen::Vector3d(1e-5 * i, 1e-5 * i, 0.0);
    const Eigen::Quaterniond q = shaftOrientation(trocar, (tip - trocar).normalized(), 0.0);
    if (i > -10) {
      EXPECT_LT(q.angularDistance(previous), 1e-2);
    }
    previous = q;
  }
}

TEST(Tremor, DeterministicPerSeedAndBounded) {
  SurgeonScript a = simple();
  SurgeonScript b = simple();
  SurgeonScript c = simple();
  SurgeonScript none = simple();
  a.setTremor(20e-6, 42);
  b.setTremor(20e-6, 42);
  c.setTremor(20e-6, 43);
  double max_offset = 0.0;
  double max_diff_c = 0.0;
  for (double t = 0.0; t < 2.0; t += 0.013) {
    const Eigen::Vector3d ta = a.sample(t).instruments[0].tip;
    EXPECT_EQ(ta, b.sample(t).instruments[0].tip) << "same seed must give the same tremor";
    const Eigen::Vector3d offset = ta - none.sample(t).instruments[0].tip;
    max_offset = std::max(max_offset, offset.cwiseAbs().maxCoeff());
    max_diff_c = std::max(max_diff_c, (ta - c.sample(t).instruments[0].tip).norm());
  }
  EXPECT_LE(max_offset, 20e-6 + 1e-12);
  EXPECT_GT(max_offset, 5e-6);  // it is actually there
  EXPECT_GT(max_diff_c, 1e-6);  // another seed is another tremor
  // Sampling order does not matter: a pure function of t.
  const Eigen::Vector3d later = a.sample(1.7).instruments[0].tip;
  a.sample(0.3);
  EXPECT_EQ(later, a.sample(1.7).instruments[0].tip);
}

TEST(Tremor, FrequencyBand) {
  // Zero crossings of one axis over 10 s: 8–10 Hz components give roughly 160–200 crossings.
  const Tremor tremor(1e-5, 11, 1);
  int crossings = 0;
  double prev = tremor.offset(0, 0.0).x();
  for (int i = 1; i <= 100000; ++i) {
    const double v = tremor.offset(0, i * 1e-4).x();
    if ((v > 0) != (prev > 0)) ++crossings;
    prev = v;
  }
  EXPECT_GT(crossings, 140);
  EXPECT_LT(crossings, 220);
}

// The shipped files leave their trocars to the scene (test_scene_trocars plays them with one); given trocars here,
// they play with the trocar constraint.
TEST(SurgeonScript, ShippedTrajectoriesParse) {
  for (const char* file : {"membrane_peeling_demo.yaml", "navigation_demo.yaml"}) {
    ScriptDefinition d = SurgeonScript::definitionFromFile(kSourceDir + "/config/trajectories/" + file);
    ASSERT_EQ(d.instruments.size(), 2u) << file;
    for (InstrumentTrack& track : d.instruments) {
      EXPECT_TRUE(track.trocar_from_scene) << file << ": " << track.slot;
      track.trocar = Eigen::Vector3d(track.slot == "left" ? -0.0073485 : 0.0073485, 0.0042426, 0.0084853);
      track.trocar_from_scene = false;
    }
    const SurgeonScript s(d);
    EXPECT_GT(s.duration(), 10.0) << file;
    for (double t = 0.0; t < s.duration(); t += 0.25) expectTrocarConstraint(s, t);
  }
  EXPECT_EQ(SurgeonScript::definitionFromFile(kSourceDir + "/config/trajectories/navigation_demo.yaml").playback,
            Playback::kOnce);
}

// A script that leaves a trocar to the scene cannot be played without one: the error names the file and the slot.
TEST(SurgeonScript, TrocarLeftToTheSceneIsAClearErrorWithoutOne) {
  const std::string path = kSourceDir + "/config/trajectories/navigation_demo.yaml";
  try {
    SurgeonScript::fromFile(path);
    FAIL() << "a script without trocars must not play without a scene";
  } catch (const ScriptError& e) {
    const std::string message = e.what();
    EXPECT_NE(message.find("navigation_demo.yaml"), std::string::npos) << message;
    EXPECT_EQ(e.field(), "instruments.left.trocar") << message;
    EXPECT_NE(message.find("comes from the scene"), std::string::npos) << message;
  }
}

TEST(SurgeonScript, BuiltinDemo) {
  const SurgeonScript demo = SurgeonScript::load("");
  EXPECT_EQ(demo.name(), "demo");
  EXPECT_EQ(SurgeonScript::load("builtin:demo").name(), "demo");
  EXPECT_THROW(SurgeonScript::load("builtin:nope"), std::invalid_argument);
  // Eye within ±5° (plus slerp slack), seamless loop.
  double max_angle = 0.0;
  for (double t = 0.0; t < demo.duration(); t += 0.1) {
    max_angle = std::max(max_angle, demo.sample(t).eye_rotation.angularDistance(Eigen::Quaterniond::Identity()));
  }
  EXPECT_LT(max_angle, 7.1 * M_PI / 180.0);
  EXPECT_GT(max_angle, 4.0 * M_PI / 180.0);
  const SurgeonSnapshot first = demo.sample(0.0);
  const SurgeonSnapshot last = demo.sample(demo.duration() - 1e-9);
  for (std::size_t i = 0; i < first.instruments.size(); ++i) {
    EXPECT_LT((first.instruments[i].tip - last.instruments[i].tip).norm(), 1e-9);
  }
  // Without a scene the forceps plays its written tips: it goes 60 um below the nominal membrane (0.3 mm above the
  // retina), closes its jaws there before 6 s, and is back at its start, jaws open, by 14 s.
  EXPECT_TRUE(demo.definition().targets_optional);
  double closest = 1.0;
  double first_closed = -1.0;
  for (double t = 0.0; t < demo.duration(); t += 0.05) {
    const SurgeonSnapshot snapshot = demo.sample(t);  // named: a reference into the temporary would dangle
    const InstrumentSample& f = snapshot.instruments[1];
    const double gap = demo.definition().eye.radius - f.tip.norm();
    closest = std::min(closest, gap);
    if (first_closed < 0.0 && f.jaw_angle == 0.0) {
      first_closed = t;
      EXPECT_LT(gap, 0.0003) << "jaws closed above the nominal membrane";
    }
  }
  EXPECT_NEAR(closest, 0.0003 - 0.00006, 1e-6);
  EXPECT_GT(first_closed, 0.0);
  EXPECT_LE(first_closed, 6.0);
  const InstrumentSample back = demo.sample(14.0).instruments[1];
  EXPECT_LT((back.tip - first.instruments[1].tip).norm(), 1e-12);
  EXPECT_GT(back.jaw_angle, 0.3);
}

// ---- keyframes written on scene objects (`on`, `height`); resolution itself: test_scene_trocars ----

TEST(SurgeonScript, SurfaceTargetsParseAndPlayTheWrittenTipWithoutAScene) {
  const SurgeonScript s = SurgeonScript::fromYamlString(R"(instruments:
  right:
    trocar: [0.0, 0.008, 0.008]
    type: forceps
    keyframes:
      - {t: 0.0, tip: [0.0, 0.0, -0.005], jaw_angle: 0.35}
      - {t: 1.0, on: membrane, tip: [0.0033, 0.001, -0.0112], height: -0.00006}
      - {t: 2.0, jaw_angle: 0.0}
      - {t: 3.0, on: retina, height: 0.0005}
      - {t: 4.0, on: membrane}
      - {t: 5.0, tip: [0.0, 0.0, -0.005]}
)",
                                                        "targets.yaml");
  const std::vector<InstrumentKeyframe>& keys = s.definition().instruments.at(0).keyframes;
  ASSERT_EQ(keys.size(), 6u);
  EXPECT_FALSE(keys[0].target.active());
  EXPECT_EQ(keys[1].target.object, "membrane");
  EXPECT_DOUBLE_EQ(keys[1].target.height, -0.00006);
  EXPECT_EQ(keys[1].target.written_tip, Eigen::Vector3d(0.0033, 0.001, -0.0112));
  EXPECT_FALSE(keys[1].target.resolved);
  // Not resolved (no scene): the written tip plays.
  EXPECT_EQ(keys[1].tip, keys[1].target.written_tip);
  EXPECT_LT((s.sample(1.0).instruments[0].tip - Eigen::Vector3d(0.0033, 0.001, -0.0112)).norm(), 1e-15);
  // Neither tip nor on: the whole position carries over, target included.
  EXPECT_EQ(keys[2].target.object, "membrane");
  EXPECT_DOUBLE_EQ(keys[2].target.height, -0.00006);
  EXPECT_EQ(keys[2].tip, keys[1].tip);
  // `on` without tip: another object from the previous written tip; height defaults to 0 with a new `on`.
  EXPECT_EQ(keys[3].target.object, "retina");
  EXPECT_DOUBLE_EQ(keys[3].target.height, 0.0005);
  EXPECT_EQ(keys[3].target.written_tip, keys[1].target.written_tip);
  EXPECT_DOUBLE_EQ(keys[4].target.height, 0.0);
  // A plain tip ends the target.
  EXPECT_FALSE(keys[5].target.active());
  EXPECT_EQ(surfaceTargetObjects(s.definition()), (std::vector<std::string>{"membrane", "retina"}));
  EXPECT_TRUE(surfaceTargetObjects(simple().definition()).empty());
  EXPECT_FALSE(s.definition().targets_optional);  // a file is written for its scene
}

// ---- malformed files: every message names the file and the line ----

struct BadCase {
  const char* what;
  std::string yaml;
  int line;
  const char* field;  // substring expected in the message
};

std::string withRight(const std::string& keyframes, const std::string& trocar = "[0.0, 0.008, 0.008]") {
  return "instruments:\n  right:\n    trocar: " + trocar + "\n    type: forceps\n    keyframes:\n" + keyframes;
}

TEST(SurgeonScriptErrors, MessagesNameFileLineAndField) {
  const std::vector<BadCase> cases = {
      {"syntax", "eye_track:\n  - {t: 0.0, rpy: [0, 0, 0]\n  - {t: 1.0}\n", 0, "YAML syntax error"},
      {"times must increase",
       withRight("      - {t: 0.0, tip: [0, 0, 0]}\n      - {t: 2.0, tip: [0, 0, 0]}\n      - {t: 1.0}\n"), 8,
       "instruments.right.keyframes[2].t"},
      {"equal times", "pedal_track:\n  - {t: 0.0}\n  - {t: 0.0}\n", 3, "pedal_track[1].t"},
      {"NaN", withRight("      - {t: 0.0, tip: [0, .nan, 0]}\n"), 6, "instruments.right.keyframes[0].tip[1]"},
      {"NaN scalar", "microscope_track:\n  - {t: 0.0, zoom: .NaN}\n", 2, "microscope_track[0].zoom"},
      {"tip outside the eye", withRight("      - {t: 0.0, tip: [0, 0, 0]}\n      - {t: 1.0, tip: [0, 0, -0.0135]}\n"),
       7, "instruments.right.keyframes[1].tip"},
      {"unknown type", withRight("      - {t: 0.0, type: scissors, tip: [0, 0, 0]}\n"), 6, "type"},
      {"misspelt key", withRight("      - {t: 0.0, tip: [0, 0, 0], jaw_agnle: 0.1}\n"), 6, "jaw_agnle"},
      {"missing tip", withRight("      - {t: 0.0, roll: 0.1}\n"), 6, "tip"},
      {"missing t", "eye_track:\n  - {rpy: [0, 0, 0]}\n", 2, "eye_track[0].t"},
      {"bad vector", withRight("      - {t: 0.0, tip: [0, 0]}\n"), 6, "tip"},
      {"not a number", withRight("      - {t: 0.0, tip: [0, 0, 0], roll: abc}\n"), 6, "roll"},
      {"trocar off the sphere", withRight("      - {t: 0.0, tip: [0, 0, 0]}\n", "[0.0, 0.0, 0.002]"), 2, "trocar"},
      {"travel out of range", "pedal_track:\n  - {t: 0.0}\n  - {t: 1.0, travel: 1.5}\n", 3, "pedal_track[1].travel"},
      {"bad playback", "name: x\nplayback: sometimes\n", 2, "playback"},
      {"zero quaternion", "eye_track:\n  - {t: 0.0, quaternion: {w: 0, x: 0, y: 0, z: 0}}\n", 2, "quaternion"},
      {"negative time", "eye_track:\n  - {t: -1.0, rpy: [0, 0, 0]}\n", 2, "eye_track[0].t"},
      {"height not a number", withRight("      - {t: 0.0, tip: [0, 0, -0.011], on: membrane, height: high}\n"), 6,
       "instruments.right.keyframes[0].height"},
      {"height a list", withRight("      - {t: 0.0, tip: [0, 0, -0.011], on: membrane, height: [0.1]}\n"), 6,
       "instruments.right.keyframes[0].height"},
      {"on an empty name", withRight("      - {t: 0.0, tip: [0, 0, -0.011]}\n      - {t: 1.0, on: \"\"}\n"), 7,
       "instruments.right.keyframes[1].on"},
      {"on without a name", withRight("      - {t: 0.0, tip: [0, 0, -0.011], on: }\n"), 6,
       "instruments.right.keyframes[0].on"},
      {"on a list", withRight("      - {t: 0.0, tip: [0, 0, -0.011], on: [membrane]}\n"), 6,
       "instruments.right.keyframes[0].on"},
      {"height without on", withRight("      - {t: 0.0, tip: [0, 0, -0.011], height: 0.0001}\n"), 6,
       "instruments.right.keyframes[0].height"},
      {"on without any tip", withRight("      - {t: 0.0, on: membrane}\n"), 6, "instruments.right.keyframes[0].tip"},
      {"misspelt on key", withRight("      - {t: 0.0, tip: [0, 0, -0.011], onn: membrane}\n"), 6, "onn"},
      {"infinite height", withRight("      - {t: 0.0, tip: [0, 0, -0.011], on: membrane, height: .inf}\n"), 6,
       "height"},
  };
  for (const BadCase& c : cases) {
    const std::string path = testing::TempDir() + "/bad_script.yaml";
    {
      std::ofstream out(path);
      out << c.yaml;
    }
    try {
      SurgeonScript::fromFile(path);
      ADD_FAILURE() << c.what << ": no error";
    } catch (const ScriptError& e) {
      const std::string message = e.what();
      EXPECT_NE(message.find(path + ":"), std::string::npos) << c.what << ": " << message;
      EXPECT_NE(message.find(c.field), std::string::npos) << c.what << ": " << message;
      EXPECT_EQ(e.source(), path) << c.what;
      if (c.line > 0) {
        EXPECT_EQ(e.line(), c.line) << c.what << ": " << message;
        EXPECT_NE(message.find(path + ":" + std::to_string(c.line) + ":"), std::string::npos) << message;
      } else {
        EXPECT_GT(e.line(), 0) << c.what << ": " << message;
      }
    }
  }
}

TEST(SurgeonScriptErrors, MissingFile) {
  try {
    SurgeonScript::fromFile("/nonexistent/script.yaml");
    FAIL() << "no error";
  } catch (const ScriptError& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent/script.yaml"), std::string::npos);
  }
}

}  // namespace
}  // namespace vrm_tracking
