// The one scripted-motion format (issue 34): a scene's scenario.scripts and a script file are the same
// ScriptedSession, read by the strict reader (file:line:column, typo hints), sampled by samplePath, resolved onto the
// scene's objects by resolveSurfaceTargets and played by the offline tools.

#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <string>
#include <vector>

#include "vrm_scene/scene_loader.h"
#include "vrm_scene/surface_target.h"
#include "vrm_sim/world/offline.h"

namespace vrm_sim {
namespace {

using scene::InstrumentType;
using scene::ScriptedSession;

const char* kFull = R"(name: full
playback: loop
missing_objects: keep_tip
instruments:
  - slot: right
    type: vitrector
    path:
      - {t: 0.0, tip: [0.001, 0.0, -0.006], jaw_angle_deg: 20, roll_deg: 10}
      - {t: 2.0, tip: [0.003, 0.0, -0.008], type: forceps, roll_deg: 30, injection_flow: 1.0e-9, suction: 0.5}
      - {t: 3.0, on: membrane, tip: [0.003, 0.001, -0.011], height: -6.0e-5}
    tremor: {amplitude: 1.0e-5, frequency_hz: 9}
eye:
  - {t: 0.0, rpy_deg: [0, 0, 0]}
  - {t: 4.0, rpy_deg: [2, -3, 0]}
pedals:
  - {t: 0.0, travel: 0.2, zoom_in: true}
  - {t: 1.0, travel: 0.4}
  - {t: 2.0, zoom_in: false}
microscope:
  - {t: 0.0, focus_distance: 0.2, zoom: 1.5, ambient_light: 0.3, disparity_scale: 0.9}
  - {t: 5.0, zoom: 2.0}
)";

TEST(ScriptedSessions, TheFullFormReadsEveryTrack) {
  const ScriptedSession s = scene::loadScriptFromString(kFull, "/tmp/full_script.yaml");
  EXPECT_EQ(s.name, "full");
  EXPECT_EQ(s.playback, scene::Playback::kLoop);
  EXPECT_TRUE(s.keep_tip_on_missing_object);
  EXPECT_DOUBLE_EQ(s.duration(), 5.0);
  ASSERT_EQ(s.instruments.size(), 1u);
  const scene::ScriptedInstrument& right = s.instruments[0];
  EXPECT_EQ(right.slot, scene::InstrumentSlot::kRight);
  EXPECT_EQ(right.type, InstrumentType::kVitrector);
  EXPECT_DOUBLE_EQ(right.tremor.frequency_hz, 9.0);
  ASSERT_EQ(right.path.size(), 3u);
  EXPECT_EQ(right.path[1].type, InstrumentType::kForceps);
  EXPECT_EQ(right.path[2].on, "membrane");
  EXPECT_DOUBLE_EQ(right.path[2].height, -6e-5);
  EXPECT_EQ(right.path[2].location.line, 10);
  EXPECT_EQ(right.path[2].location.file, "/tmp/full_script.yaml");
  // Pedals and microscope carry omitted keys over; a path's waypoint does not (its fields default to 0).
  EXPECT_TRUE(s.pedals[1].zoom_in);
  EXPECT_DOUBLE_EQ(s.pedals[2].travel, 0.4);
  EXPECT_FALSE(s.pedals[2].zoom_in);
  EXPECT_DOUBLE_EQ(s.microscope[1].ambient_light, 0.3);
  EXPECT_DOUBLE_EQ(s.microscope[1].disparity_scale, 0.9);
  EXPECT_DOUBLE_EQ(right.path[2].roll_deg, 0.0);
  // The eye's rpy is Pose's convention (R = Rz Ry Rx).
  const Eigen::Quaterniond expected = Eigen::AngleAxisd(-3.0 * M_PI / 180.0, Eigen::Vector3d::UnitY()) *
                                      Eigen::AngleAxisd(2.0 * M_PI / 180.0, Eigen::Vector3d::UnitX());
  EXPECT_LT(s.eye[1].rotation().angularDistance(expected), 1e-15);
  // Without `name` a file is named by its stem.
  EXPECT_EQ(scene::loadScriptFromString("eye: [{t: 0, rpy_deg: [0, 0, 0]}]\n", "/x/y/calm.yaml").name, "calm");
}

TEST(ScriptedSessions, SamplePathInterpolatesAndStepsTheExchange) {
  const ScriptedSession s = scene::loadScriptFromString(kFull, "full.yaml");
  const std::vector<scene::InstrumentWaypoint>& path = s.instruments[0].path;
  const scene::InstrumentWaypoint before = scene::samplePath(path, -1.0);
  EXPECT_EQ(before.tip_in_eye, path[0].tip_in_eye);
  EXPECT_FALSE(before.type.has_value());  // the scripted instrument's until the first exchange
  const scene::InstrumentWaypoint mid = scene::samplePath(path, 1.0);
  EXPECT_TRUE(mid.tip_in_eye.isApprox(Eigen::Vector3d(0.002, 0.0, -0.007), 1e-15));
  EXPECT_DOUBLE_EQ(mid.roll_deg, 20.0);
  EXPECT_DOUBLE_EQ(mid.jaw_angle_deg, 10.0);
  EXPECT_DOUBLE_EQ(mid.injection_flow, 0.5e-9);
  EXPECT_DOUBLE_EQ(mid.suction, 0.25);
  EXPECT_FALSE(mid.type.has_value());
  EXPECT_EQ(scene::samplePath(path, 2.0).type, InstrumentType::kForceps);
  EXPECT_EQ(scene::samplePath(path, 2.5).type, InstrumentType::kForceps);
  EXPECT_EQ(scene::samplePath(path, 9.0).type, InstrumentType::kForceps);  // held after the path
  EXPECT_DOUBLE_EQ(scene::samplePath(path, 2.5).t, 2.5);
}

// A scene's short form (the list of instruments) and the full form are the same session.
TEST(ScriptedSessions, TheShortFormIsTheInstrumentsOfTheFullForm) {
  const scene::SceneDescription peeling = scene::loadScene("membrane_peeling");
  const ScriptedSession& expert = scene::findScript(peeling, "expert");
  EXPECT_EQ(expert.name, "expert");
  EXPECT_EQ(expert.playback, scene::Playback::kOnce);
  EXPECT_FALSE(expert.keep_tip_on_missing_object);
  EXPECT_TRUE(expert.eye.empty() && expert.pedals.empty() && expert.microscope.empty());
  ASSERT_EQ(expert.instruments.size(), 2u);  // the light pipe (issue 33) and the forceps
  EXPECT_THROW(scene::findScript(peeling, "nobody"), std::invalid_argument);
}

// Every shipped scene's sessions and every shipped script file read and play offline.
TEST(ScriptedSessions, ShippedScriptsAndScenesRead) {
  EXPECT_EQ(scene::shippedScripts(), (std::vector<std::string>{"demo", "membrane_peeling_demo", "navigation_demo"}));
  for (const std::string& name : scene::shippedScripts()) {
    const ScriptedSession script = scene::loadScript(name);
    EXPECT_EQ(script.name, name);
    EXPECT_EQ(script.instruments.size(), 2u) << name;
    EXPECT_FALSE(script.eye.empty()) << name;
    EXPECT_FALSE(script.pedals.empty()) << name;
    EXPECT_FALSE(script.microscope.empty()) << name;
  }
  EXPECT_TRUE(scene::loadScript("demo").keep_tip_on_missing_object);
  EXPECT_EQ(scene::loadScript("navigation_demo").playback, scene::Playback::kOnce);
}

// scenario_offline --script FILE: the file's waypoints on scene objects are resolved onto the scene's surfaces, so the
// membrane_peeling_demo's grasp lands on the shipped membrane offline as it does in the graph.
TEST(ScriptedSessions, AScriptFilePlaysOfflineWithItsTargetsResolved) {
  const scene::SceneDescription peeling = scene::loadScene("membrane_peeling");
  world::ScenarioRunOptions options;
  options.script_file = scene::loadScript("membrane_peeling_demo");
  options.grace = 0.5;
  const world::ScenarioRunResult result = world::runScenario(peeling, options);
  EXPECT_EQ(result.script, "file");
  EXPECT_GT(result.frames, 0u);
  // An object the scene lacks: the waypoint's file, line and field.
  const scene::SceneDescription navigation = scene::loadScene("navigation");
  try {
    world::runScenario(navigation, options);
    FAIL() << "a waypoint on an object the scene lacks must not play";
  } catch (const YamlError& error) {
    EXPECT_NE(std::string(error.what()).find("membrane_peeling_demo.yaml:"), std::string::npos) << error.what();
    EXPECT_NE(std::string(error.what()).find("has no object 'membrane'"), std::string::npos) << error.what();
    EXPECT_NE(error.location().field.find(".on"), std::string::npos) << error.what();
  }
}

struct BadScript {
  const char* what;
  std::string yaml;
  int line;
  const char* message;  // substring expected after "file:line:column: "
};

TEST(ScriptedSessions, MalformedScriptsNameFileLineColumnAndField) {
  const std::string path = ::testing::TempDir() + "/bad_session.yaml";
  const std::vector<BadScript> cases = {
      {"typo", "playbak: once\neye: [{t: 0, rpy_deg: [0, 0, 0]}]\n", 1, "did you mean 'playback'"},
      {"list at the top", "- {slot: right, path: []}\n", 1, "expected a scripted session"},
      {"no track", "name: empty\n", 1, "expected at least one track"},
      {"unknown slot", "instruments:\n  - slot: middle\n    path: [{t: 0, tip: [0, 0, 0]}]\n", 2, "slot"},
      {"empty path", "instruments:\n  - slot: right\n    path: []\n", 3, "expected at least one waypoint"},
      {"times", "pedals:\n  - {t: 1}\n  - {t: 1}\n", 3, "waypoint times must increase"},
      {"button not a bool", "pedals:\n  - {t: 0, zoom_in: maybe}\n", 2, "zoom_in"},
      {"zoom zero", "microscope:\n  - {t: 0, zoom: 0}\n", 2, "zoom"},
      {"missing_objects", "missing_objects: ignore\neye: [{t: 0, rpy_deg: [0, 0, 0]}]\n", 1, "missing_objects"},
      {"radians as degrees", "instruments:\n  - slot: right\n    path: [{t: 0, tip: [0, 0, 0], roll: 1.5}]\n", 3,
       "did you mean 'roll_deg', in deg?"},
      {"height alone", "instruments:\n  - slot: right\n    path:\n      - {t: 0, tip: [0, 0, -0.011], height: 0.001}\n",
       4, "write `on: OBJECT` with it"},
      {"height too far",
       "instruments:\n  - slot: right\n    path:\n      - {t: 0, tip: [0, 0, -0.011], on: membrane, height: 0.02}\n", 4,
       "height"},
      {"format version", "format_version: 2\neye: [{t: 0, rpy_deg: [0, 0, 0]}]\n", 1, "format_version"},
  };
  for (const BadScript& c : cases) {
    {
      std::ofstream out(path);
      out << c.yaml;
    }
    try {
      scene::loadScript(path);
      ADD_FAILURE() << c.what << ": no error";
    } catch (const YamlError& error) {
      const std::string message = error.what();
      EXPECT_EQ(message.rfind(path + ":" + std::to_string(c.line) + ":", 0), 0u) << c.what << ": " << message;
      EXPECT_NE(message.find(c.message), std::string::npos) << c.what << ": " << message;
    }
  }
  EXPECT_THROW(scene::loadScript("/nonexistent/session.yaml"), YamlError);
}

// An instrument's own path (tissue_offline plays it as written) takes neither exchanges nor tips on objects.
TEST(ScriptedSessions, AnInstrumentsOwnPathRefusesExchangesAndTargets) {
  std::ifstream in(scene::shippedScenePath("membrane_peeling"));
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const std::string needle = "      - {t: 0.0, tip: [0.004230, 0.000623, -0.008225], jaw_angle_deg: 30.0}";
  const std::size_t at = text.find(needle);
  ASSERT_NE(at, std::string::npos) << "membrane_peeling's forceps path changed";
  std::string with_exchange = text;
  with_exchange.replace(at, needle.size(),
                        "      - {t: 0.0, tip: [0.004230, 0.000623, -0.008225], jaw_angle_deg: 30.0, type: hook}");
  try {
    scene::loadSceneFromString(with_exchange, "exchange.yaml");
    FAIL() << "an exchange in an instrument's own path must be refused";
  } catch (const YamlError& error) {
    EXPECT_NE(std::string(error.what()).find("script them in scenario.scripts"), std::string::npos) << error.what();
  }
}

}  // namespace
}  // namespace vrm_sim
