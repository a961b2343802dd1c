// SurgeonScript without ROS: a scripted session in the scenes' format (issue 34) played as the device twins play it:
// interpolation, playback, the trocar constraint, the tremor, the shipped scripts and error reporting.

#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <string>
#include <vector>

#include "script_fixtures.h"
#include "vrm_scene/scene_loader.h"
#include "vrm_tracking/scene_trocars.h"
#include "vrm_tracking/surgeon_script.h"

namespace vrm_tracking {
namespace {

namespace scene = vrm_sim::scene;
using testing::playYaml;
using testing::testScene;

constexpr double kDeg = M_PI / 180.0;

// Round numbers, so expected values can be written down by hand. The eye centre is at [0.1, 0.2, 0.3].
const char* kSimple = R"(name: simple
playback: loop
eye:
  - {t: 0.0, rpy_deg: [0.0, 0.0, 0.0]}
  - {t: 2.0, rpy_deg: [0.0, 0.0, 40.0]}
instruments:
  - slot: right
    path:
      - {t: 0.0, tip: [0.0, 0.0, -0.002], jaw_angle_deg: 20.0}
      - {t: 2.0, tip: [0.002, 0.0, -0.006], type: vitrector, roll_deg: 60.0, cut_rate_hz: 30.0}
      - {t: 4.0, tip: [0.0, 0.0, -0.002]}
pedals:
  - {t: 0.0, travel: 0.0, reflux: false}
  - {t: 1.0, travel: 1.0, reflux: true}
microscope:
  - {t: 0.0, focus_distance: 0.2, zoom: 1.0, ambient_light: 0.2, disparity_scale: 1.0}
  - {t: 4.0, focus_distance: 0.19, zoom: 2.0, ambient_light: 0.6}
)";

SurgeonScript simple() { return playYaml(kSimple, testScene(Eigen::Vector3d(0.1, 0.2, 0.3)), "simple.yaml"); }

TEST(SurgeonScript, PlaysTheScenesFormat) {
  const SurgeonScript s = simple();
  EXPECT_EQ(s.name(), "simple");
  EXPECT_EQ(s.playback(), Playback::kLoop);
  EXPECT_DOUBLE_EQ(s.duration(), 4.0);
  ASSERT_EQ(s.tracks().size(), 1u);
  // The scene decides the trocar, the instrument (its forceps in the right slot) and the eye.
  EXPECT_TRUE(s.tracks()[0].trocar.isApprox(Eigen::Vector3d(0.0073485, 0.0042426, 0.0084853), 1e-4));
  EXPECT_EQ(s.tracks()[0].type, scene::InstrumentType::kForceps);
  EXPECT_EQ(s.eye().rotation_center, Eigen::Vector3d(0.1, 0.2, 0.3));
  EXPECT_DOUBLE_EQ(s.eye().radius, 0.012);
  // The microscope track carries omitted keys over (disparity 1 at 4 s).
  EXPECT_DOUBLE_EQ(s.sample(4.0 - 1e-9).microscope.disparity_scale, 1.0);
}

TEST(SurgeonScript, ExactAtWaypointsLinearBetweenStepsForDiscrete) {
  const SurgeonScript s = simple();
  const SurgeonSnapshot a = s.sample(0.0);
  ASSERT_EQ(a.instruments.size(), 1u);
  EXPECT_EQ(a.instruments[0].slot, "right");
  EXPECT_TRUE(a.instruments[0].tip.isApprox(Eigen::Vector3d(0.0, 0.0, -0.002), 1e-15));
  EXPECT_NEAR(a.instruments[0].jaw_angle, 20.0 * kDeg, 1e-15);
  EXPECT_EQ(a.rotation_center, Eigen::Vector3d(0.1, 0.2, 0.3));
  const SurgeonSnapshot mid = s.sample(1.0);
  EXPECT_TRUE(mid.instruments[0].tip.isApprox(Eigen::Vector3d(0.001, 0.0, -0.004), 1e-12));
  EXPECT_NEAR(mid.instruments[0].roll, 30.0 * kDeg, 1e-12);
  EXPECT_NEAR(mid.instruments[0].jaw_angle, 10.0 * kDeg, 1e-12);
  EXPECT_NEAR(mid.instruments[0].cut_rate, 15.0, 1e-12);
  // The exchange steps at its waypoint; the instrument before it is the scene's.
  EXPECT_EQ(mid.instruments[0].type, scene::InstrumentType::kForceps);
  EXPECT_EQ(s.sample(2.0).instruments[0].type, scene::InstrumentType::kVitrector);
  EXPECT_EQ(s.sample(3.0).instruments[0].type, scene::InstrumentType::kVitrector);
  // The eye: slerp, about z by 20 degrees halfway.
  EXPECT_NEAR(
      mid.eye_rotation.angularDistance(Eigen::Quaterniond(Eigen::AngleAxisd(20.0 * kDeg, Eigen::Vector3d::UnitZ()))),
      0.0, 1e-12);
  // Pedal travel linear, buttons step.
  EXPECT_DOUBLE_EQ(s.sample(0.5).pedals.travel, 0.5);
  EXPECT_FALSE(s.sample(0.5).pedals.reflux);
  EXPECT_TRUE(s.sample(1.0).pedals.reflux);
  EXPECT_DOUBLE_EQ(s.sample(3.0).pedals.travel, 1.0);
  EXPECT_NEAR(s.sample(2.0).microscope.zoom, 1.5, 1e-12);
}

TEST(SurgeonScript, SlerpKeepsUnitNorm) {
  const SurgeonScript s = playYaml(R"(
eye:
  - {t: 0.0, rpy_deg: [0, 0, 0]}
  - {t: 1.0, rpy_deg: [40, -30, 20]}
  - {t: 2.0, rpy_deg: [-40, 45, -45]}
)");
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
  // NaN and negative times play the start.
  EXPECT_DOUBLE_EQ(s.sample(std::nan("")).script_time, 0.0);
  EXPECT_DOUBLE_EQ(s.sample(-3.0).script_time, 0.0);
}

void expectTrocarConstraint(const SurgeonScript& s, double t) {
  const SurgeonSnapshot snap = s.sample(t);
  for (std::size_t i = 0; i < snap.instruments.size(); ++i) {
    const InstrumentSample& in = snap.instruments[i];
    const Eigen::Vector3d trocar = s.tracks()[i].trocar;
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
  s.setTremorAmplitude(50e-6);  // the constraint must survive tremor: the shaft follows the trembling tip
  for (double t = 0.0; t < 4.0; t += 0.05) expectTrocarConstraint(s, t);
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

// The one tremor model (the scenes' PathTremor): the script's own, exactly what scenario_offline adds to the tip, and
// the twins' override keeps the script's frequency.
TEST(Tremor, TheScriptsTremorIsTheOfflineTools) {
  const std::string yaml = R"(instruments:
  - slot: right
    path:
      - {t: 0.0, tip: [0.0, 0.0, -0.004]}
      - {t: 2.0, tip: [0.002, 0.0, -0.006]}
    tremor: {amplitude: 2.0e-5, frequency_hz: 9}
)";
  SurgeonScript s = playYaml(yaml);
  const scene::SceneDescription offline = scene::withScript(testScene(), scene::loadScriptFromString(yaml, "t.yaml"));
  const scene::InstrumentDescription& forceps = offline.instruments[1];
  double max_offset = 0.0;
  for (double t = 0.0; t < 2.0; t += 0.013) {
    const Eigen::Vector3d expected = scene::samplePath(forceps.path, t).tip_in_eye + forceps.tremor.offset(t);
    const Eigen::Vector3d tip = s.sample(t).instruments[0].tip;
    EXPECT_LT((tip - expected).norm(), 1e-15) << t;
    max_offset = std::max(max_offset, (tip - scene::samplePath(forceps.path, t).tip_in_eye).cwiseAbs().maxCoeff());
  }
  EXPECT_LE(max_offset, 2e-5 + 1e-15);
  EXPECT_GT(max_offset, 1.5e-5);  // it is actually there
  // Zero crossings of one axis (phase 0) at 9 Hz: at k / 18 s, 35 of them inside (0, 2) s.
  int crossings = 0;
  double previous = s.sample(0.0005).instruments[0].tip.x() - scene::samplePath(forceps.path, 0.0005).tip_in_eye.x();
  for (int i = 1; i < 2000; ++i) {
    const double t = 0.0005 + i * 1e-3;
    const double v = s.sample(t).instruments[0].tip.x() - scene::samplePath(forceps.path, t).tip_in_eye.x();
    if ((v > 0) != (previous > 0)) ++crossings;
    previous = v;
  }
  EXPECT_EQ(crossings, 35);
  // The override sets the amplitude, keeps the frequency; 0 turns it off; a negative one is refused.
  s.setTremorAmplitude(1e-5);
  EXPECT_DOUBLE_EQ(s.session().instruments[0].tremor.amplitude, 1e-5);
  EXPECT_DOUBLE_EQ(s.session().instruments[0].tremor.frequency_hz, 9.0);
  s.setTremorAmplitude(0.0);
  EXPECT_EQ(s.sample(0.37).instruments[0].tip, scene::samplePath(forceps.path, 0.37).tip_in_eye);
  EXPECT_THROW(s.setTremorAmplitude(-1e-6), std::invalid_argument);
  EXPECT_THROW(s.setTremorAmplitude(std::nan("")), std::invalid_argument);
}

// A scene's scripted session plays in the graph as scenario_offline plays it: the same tips, jaws, suction and cut rate
// at every time (the converter that sampled it every 5 ms is gone, issue 34).
TEST(SurgeonScript, AScenesSessionPlaysAsTheOfflineTool) {
  for (const char* name : {"membrane_peeling", "vitrectomy", "navigation"}) {
    const scene::SceneDescription shipped = scene::loadScene(name);
    for (const char* who : {"expert", "novice"}) {
      const SurgeonScript s = playInScene(shipped, loadSession(std::string("scenario:") + who, shipped));
      const scene::SceneDescription offline = scene::withScript(shipped, who);
      for (double t = 0.0; t <= s.duration() + 0.5; t += 0.0371) {
        const SurgeonSnapshot snapshot = s.sample(t);
        for (const InstrumentSample& played : snapshot.instruments) {
          const scene::InstrumentDescription* in_scene = offline.findInstrument(
              played.slot == "left" ? scene::InstrumentSlot::kLeft : scene::InstrumentSlot::kRight);
          ASSERT_NE(in_scene, nullptr);
          const double script_t = snapshot.script_time;
          const scene::InstrumentWaypoint w = scene::samplePath(in_scene->path, script_t);
          EXPECT_LT((played.tip - (w.tip_in_eye + in_scene->tremor.offset(script_t))).norm(), 1e-15)
              << name << " " << who << " t=" << t;
          EXPECT_NEAR(played.jaw_angle, w.jaw_angle_deg * kDeg, 1e-15);
          EXPECT_EQ(played.suction, w.suction);
          EXPECT_EQ(played.cut_rate, w.cut_rate_hz);
          EXPECT_EQ(played.type, in_scene->type);
        }
      }
    }
  }
}

// The shipped scripts (vrm_sim config/scripts) read and play in the default scene with the trocar constraint.
TEST(SurgeonScript, ShippedScriptsPlay) {
  const scene::SceneDescription peeling = scene::loadScene(scene::kDefaultSceneName);
  EXPECT_EQ(scene::shippedScripts(), (std::vector<std::string>{"demo", "membrane_peeling_demo", "navigation_demo"}));
  for (const std::string& name : scene::shippedScripts()) {
    const SurgeonScript s = playInScene(peeling, loadSession(name, peeling));
    EXPECT_EQ(s.name(), name);
    ASSERT_EQ(s.tracks().size(), 2u) << name;
    EXPECT_GT(s.duration(), 10.0) << name;
    for (double t = 0.0; t < s.duration(); t += 0.25) expectTrocarConstraint(s, t);
  }
  EXPECT_EQ(loadSession("navigation_demo", peeling).playback, Playback::kOnce);
  EXPECT_EQ(loadSession("", peeling).name, "demo");  // the default
  try {
    loadSession("no_such_script", peeling);
    FAIL() << "an unknown script name must not load";
  } catch (const ScriptError& e) {
    EXPECT_NE(std::string(e.what()).find("shipped: demo, membrane_peeling_demo, navigation_demo"), std::string::npos)
        << e.what();
  }
  EXPECT_THROW(loadSession("scenario:nobody", peeling), std::invalid_argument);
}

TEST(SurgeonScript, Demo) {
  const scene::SceneDescription peeling = scene::loadScene(scene::kDefaultSceneName);
  const scene::ScriptedSession written = loadSession("", peeling);
  EXPECT_TRUE(written.keep_tip_on_missing_object);
  // In a scene without a membrane the grasp waypoints keep their written tips (the nominal membrane's).
  scene::SurfaceTargetReport report;
  const SurgeonScript demo = playInScene(testScene(), written, &report);
  EXPECT_EQ(report.missing_objects, (std::vector<std::string>{"membrane"}));
  EXPECT_EQ(report.kept_waypoints, 7u);
  // Eye within ±5° (plus slerp slack), seamless loop.
  double max_angle = 0.0;
  for (double t = 0.0; t < demo.duration(); t += 0.1) {
    max_angle = std::max(max_angle, demo.sample(t).eye_rotation.angularDistance(Eigen::Quaterniond::Identity()));
  }
  EXPECT_LT(max_angle, 7.1 * kDeg);
  EXPECT_GT(max_angle, 4.0 * kDeg);
  const SurgeonSnapshot first = demo.sample(0.0);
  const SurgeonSnapshot last = demo.sample(demo.duration() - 1e-9);
  for (std::size_t i = 0; i < first.instruments.size(); ++i) {
    EXPECT_LT((first.instruments[i].tip - last.instruments[i].tip).norm(), 1e-9);
  }
  // The forceps goes 60 um below the nominal membrane (0.3 mm above the retina), closes its jaws there before 6 s,
  // and is back at its start, jaws open, by 14 s.
  double closest = 1.0;
  double first_closed = -1.0;
  for (double t = 0.0; t < demo.duration(); t += 0.05) {
    const SurgeonSnapshot snapshot = demo.sample(t);  // named: a reference into the temporary would dangle
    const InstrumentSample& f = snapshot.instruments[1];
    const double gap = demo.eye().radius - f.tip.norm();
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

// ---- malformed files and unplayable sessions: every message names the file, the line and the field ----

struct BadCase {
  const char* what;
  std::string yaml;
  int line;
  const char* field;  // substring expected in the message
};

std::string withRight(const std::string& path) { return "instruments:\n  - slot: right\n    path:\n" + path; }

TEST(SurgeonScriptErrors, MessagesNameFileLineAndField) {
  const std::vector<BadCase> cases = {
      {"syntax", "eye:\n  - {t: 0.0, rpy_deg: [0, 0, 0]\n  - {t: 1.0}\n", 0, "YAML syntax error"},
      {"times must increase",
       withRight(
           "      - {t: 0.0, tip: [0, 0, 0]}\n      - {t: 2.0, tip: [0, 0, 0]}\n      - {t: 1.0, tip: [0, 0, 0]}\n"),
       6, "instruments[0].path[2].t"},
      {"equal times", "pedals:\n  - {t: 0.0}\n  - {t: 0.0}\n", 3, "pedals[1].t"},
      {"NaN", withRight("      - {t: 0.0, tip: [0, .nan, 0]}\n"), 4, "instruments[0].path[0].tip"},
      {"NaN scalar", "microscope:\n  - {t: 0.0, zoom: .NaN}\n", 2, "microscope[0].zoom"},
      {"tip outside the eye", withRight("      - {t: 0.0, tip: [0, 0, 0]}\n      - {t: 1.0, tip: [0, 0, -0.0135]}\n"),
       5, "instruments[0].path[1].tip"},
      {"unknown type", withRight("      - {t: 0.0, type: scissors, tip: [0, 0, 0]}\n"), 4, "type"},
      {"misspelt key", withRight("      - {t: 0.0, tip: [0, 0, 0], jaw_agnle_deg: 10}\n"), 4, "jaw_agnle_deg"},
      {"radians for degrees", withRight("      - {t: 0.0, tip: [0, 0, 0], jaw_angle: 0.3}\n"), 4, "jaw_angle"},
      {"missing tip", withRight("      - {t: 0.0, roll_deg: 10}\n"), 4, "tip"},
      {"missing t", "eye:\n  - {rpy_deg: [0, 0, 0]}\n", 2, "eye[0]"},
      {"eye in radians as degrees?", "eye:\n  - {t: 0, rpy_deg: [0, 90, 0]}\n", 2, "eye[0].rpy_deg"},
      {"bad vector", withRight("      - {t: 0.0, tip: [0, 0]}\n"), 4, "tip"},
      {"not a number", withRight("      - {t: 0.0, tip: [0, 0, 0], roll_deg: abc}\n"), 4, "roll_deg"},
      {"travel out of range", "pedals:\n  - {t: 0.0}\n  - {t: 1.0, travel: 1.5}\n", 3, "pedals[1].travel"},
      {"bad playback", "playback: sometimes\neye: [{t: 0, rpy_deg: [0, 0, 0]}]\n", 1, "playback"},
      {"no track", "name: nothing\n", 1, "expected at least one track"},
      {"negative time", "eye:\n  - {t: -1.0, rpy_deg: [0, 0, 0]}\n", 2, "eye[0].t"},
      {"slot twice",
       withRight("      - {t: 0.0, tip: [0, 0, 0]}\n") + "  - slot: right\n    path: [{t: 0, tip: [0, 0, 0]}]\n", 5,
       "scripted twice"},
      {"height not a number", withRight("      - {t: 0.0, tip: [0, 0, -0.011], on: membrane, height: high}\n"), 4,
       "instruments[0].path[0].height"},
      {"on an empty name", withRight("      - {t: 0.0, tip: [0, 0, -0.011], on: \"\"}\n"), 4,
       "instruments[0].path[0].on"},
      {"on a list", withRight("      - {t: 0.0, tip: [0, 0, -0.011], on: [membrane]}\n"), 4,
       "instruments[0].path[0].on"},
      {"height without on", withRight("      - {t: 0.0, tip: [0, 0, -0.011], height: 0.0001}\n"), 4,
       "instruments[0].path[0].height"},
      {"misspelt on key", withRight("      - {t: 0.0, tip: [0, 0, -0.011], onn: membrane}\n"), 4, "onn"},
      {"infinite height", withRight("      - {t: 0.0, tip: [0, 0, -0.011], on: membrane, height: .inf}\n"), 4,
       "height"},
      {"an object the scene lacks", withRight("      - {t: 0.0, tip: [0, 0, -0.011], on: membrane}\n"), 4,
       "test_scene"},
  };
  for (const BadCase& c : cases) {
    const std::string path = ::testing::TempDir() + "/bad_script.yaml";
    {
      std::ofstream out(path);
      out << c.yaml;
    }
    try {
      playInScene(testScene(), scene::loadScript(path));
      ADD_FAILURE() << c.what << ": no error";
    } catch (const ScriptError& e) {
      const std::string message = e.what();
      EXPECT_NE(message.find(path + ":"), std::string::npos) << c.what << ": " << message;
      EXPECT_NE(message.find(c.field), std::string::npos) << c.what << ": " << message;
      EXPECT_EQ(e.location().file, path) << c.what;
      if (c.line > 0) {
        EXPECT_EQ(e.location().line, c.line) << c.what << ": " << message;
        EXPECT_NE(message.find(path + ":" + std::to_string(c.line) + ":"), std::string::npos) << message;
      } else {
        EXPECT_GT(e.location().line, 0) << c.what << ": " << message;
      }
    }
  }
}

TEST(SurgeonScriptErrors, MissingFile) {
  try {
    scene::loadScript("/nonexistent/script.yaml");
    FAIL() << "no error";
  } catch (const ScriptError& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent/script.yaml: script file not found"), std::string::npos)
        << e.what();
  }
}

// A slot the scene has no instrument in needs a `type`; a scene without the slot's trocar is an error naming it.
TEST(SurgeonScriptErrors, TheSceneMustHaveTheSlot) {
  scene::SceneDescription no_left = testScene();
  no_left.instruments.erase(no_left.instruments.begin());
  const std::string left = "instruments:\n  - slot: left\n    path: [{t: 0, tip: [0, 0, -0.004]}]\n";
  try {
    playYaml(left, no_left);
    FAIL() << "a slot without an instrument and no type must not play";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("no instrument in slot 'left'"), std::string::npos) << e.what();
  }
  EXPECT_EQ(playYaml("instruments:\n  - slot: left\n    type: hook\n    path: [{t: 0, tip: [0, 0, -0.004]}]\n", no_left)
                .tracks()[0]
                .type,
            scene::InstrumentType::kHook);
  no_left.eye.trocars.clear();
  EXPECT_THROW(playYaml(left, no_left), std::runtime_error);
}

}  // namespace
}  // namespace vrm_tracking
