// The session result (issue 34): the one writer and reader read the committed reference results (real
// scenario_manager output), keep the text format the hand-written writer had, refuse malformed files naming the key,
// and crash recovery rewrites the struct. Plain gtest, no master.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>

#include "../test_files.h"
#include "vrm_scene/scene_loader.h"
#include "vrm_sim/result/session_result.h"
#include "vrm_sim/world/offline.h"
#include "vrm_sim/world/session_result.h"
#include "vrm_sim/world/world.h"

namespace vrm_sim {
namespace result {

// gtest prints a result as its JSON.
void PrintTo(const SessionResult& result, std::ostream* out) { *out << toJson(result); }

namespace {

namespace fs = std::filesystem;

const fs::path kBags = fs::path(VRM_SIM_SOURCE_DIR) / "test" / "bags";

std::vector<fs::path> referenceResults() {
  std::vector<fs::path> paths;
  for (const auto& entry : fs::directory_iterator(kBags)) {
    const std::string name = entry.path().filename().string();
    if (name.size() > 12 && name.compare(name.size() - 12, 12, ".result.json") == 0) paths.push_back(entry.path());
  }
  std::sort(paths.begin(), paths.end());
  return paths;
}

// The message of the ResultError `read` throws ("" if it does not throw).
template <typename F>
std::string errorOf(F read) {
  try {
    read();
  } catch (const ResultError& error) {
    return error.what();
  }
  return "";
}

struct TempDir {
  fs::path path = fs::temp_directory_path() / ("session_result_test_" + std::to_string(::getpid()));
  TempDir() { fs::create_directories(path); }
  ~TempDir() { fs::remove_all(path); }
};

SessionResult scenarioResult() {
  SessionResult r;
  r.scene = "navigation";
  r.scene_file = "/x/navigation.yaml";
  r.scenario = "navigation";
  r.difficulty = "medium";
  r.seed = 3;
  r.state = "running";
  r.message = "touch the \"lit\" target\n";
  r.start_stamp = 1795558746.26302;
  r.elapsed = 7.0;
  r.total = 62.5;
  r.items = {{"targets_touched", 2, "1", 1, 50}, {"hold", std::nan(""), "s", 0.5, INFINITY}};
  r.groups = {{"target_achievement", 50, 1}};
  PenaltyEvent touch;
  touch.time = 2.5;
  touch.kind = "retina_touched";
  touch.item = "retina_contacts";
  touch.slot = "right";
  touch.instrument = "needle";
  touch.position[0] = 0.001;
  touch.position[1] = -0.0005;
  touch.position[2] = -0.0119;
  touch.points = 12.5;
  PenaltyEvent unplaced;  // no instrument tracked: no slot, no position
  unplaced.time = 3;
  unplaced.kind = "bleeding";
  unplaced.item = "bleeding_area";
  unplaced.points = 0.25;
  r.events = {touch, unplaced};
  r.events_dropped = 4;
  r.final_state_hash = "0x86ecb04502376b15";
  r.frames = 390;
  r.simulated_frames = 350;
  r.input_frames = 391;
  r.last_frame_stamp = 1795558753.26302;
  r.software_version = "vrm_sim 0.1.0";
  r.station = "sim1";
  r.in_progress = true;
  return r;
}

// The text the hand-written writer (scenario_manager's resultJson before issue 34) produced for the same session:
// same keys in the same order, ", " / ": ", 15 significant digits, integral numbers without ".0", NaN/inf as null.
TEST(SessionResult, WritesTheFormatOfTheHandWrittenWriter) {
  EXPECT_EQ(toJson(scenarioResult()),
            R"({"scene": "navigation", "scene_file": "/x/navigation.yaml", "scenario": "navigation", )"
            R"("difficulty": "medium", "seed": 3, "state": "running", "session_ended": false, "timed_out": false, )"
            R"("message": "touch the \"lit\" target\n", "start_stamp": 1795558746.26302, "end_stamp": 0, )"
            R"("elapsed": 7, "total": 62.5, "items": [{"name": "targets_touched", "value": 2, "unit": "1", )"
            R"("weight": 1, "points": 50}, {"name": "hold", "value": null, "unit": "s", "weight": 0.5, )"
            R"("points": null}], "groups": [{"name": "target_achievement", "points": 50, "weight": 1}], )"
            R"("events": [{"time": 2.5, "kind": "retina_touched", "item": "retina_contacts", "slot": "right", )"
            R"("instrument": "needle", "position": [0.001, -0.0005, -0.0119], "points": 12.5}, {"time": 3, )"
            R"("kind": "bleeding", "item": "bleeding_area", "slot": "", "instrument": "", )"
            R"("position": [null, null, null], "points": 0.25}], "events_dropped": 4, )"
            R"("final_state_hash": "0x86ecb04502376b15", "frames": 390, "simulated_frames": 350, )"
            R"("late_inputs": 0, "frames_without_source": 0, "input_frames": 391, )"
            R"("last_frame_stamp": 1795558753.26302, "software_version": "vrm_sim 0.1.0", "bag": null, )"
            R"("user": null, "station": "sim1", "in_progress": true})"
            "\n");
  // Without a scenario: its keys are null or absent, as before.
  SessionResult free;
  free.scene = "free";
  free.final_state_hash = "0x0000000000000001";
  free.session_ended = true;
  free.bag = "/b/s.bag";
  free.user = "anna";
  EXPECT_EQ(toJson(free),
            R"({"scene": "free", "scene_file": "", "scenario": null, "difficulty": null, "seed": 0, "state": null, )"
            R"("session_ended": true, "total": null, "final_state_hash": "0x0000000000000001", "frames": 0, )"
            R"("simulated_frames": 0, "late_inputs": 0, "frames_without_source": 0, "input_frames": 0, )"
            R"("last_frame_stamp": 0, "software_version": "", "bag": "/b/s.bag", "user": "anna", "station": "", )"
            R"("in_progress": false})"
            "\n");
}

TEST(SessionResult, RoundTripKeepsEveryFieldAndNaN) {
  SessionResult written = scenarioResult();
  const SessionResult read = resultFromJson(toJson(written), "round trip");
  written.items[1].points = kUnknown;  // infinity has no JSON either: null, read back as NaN
  EXPECT_EQ(read, written);
  EXPECT_TRUE(std::isnan(read.items[1].value));
  EXPECT_TRUE(std::isnan(read.items[1].points));  // infinity is written null too: read back as NaN
  EXPECT_EQ(read.message, "touch the \"lit\" target\n");
  EXPECT_EQ(toJson(read), toJson(written));
  // Issue 35's keys: the groups, the events (an unknown position stays NaN) and the dropped count survive.
  ASSERT_EQ(read.events.size(), 2u);
  EXPECT_EQ(read.events[0].instrument, "needle");
  EXPECT_DOUBLE_EQ(read.events[0].position[2], -0.0119);
  EXPECT_TRUE(std::isnan(read.events[1].position[0]));
  EXPECT_EQ(read.events_dropped, 4u);
  ASSERT_EQ(read.groups.size(), 1u);
  EXPECT_EQ(read.groups[0].name, "target_achievement");
  // A result written before issue 35 has none of them: empty, not an error.
  const SessionResult older = resultFromJson(
      R"({"scene": "s", "final_state_hash": "0x1", "frames": 2, "scenario": "navigation", "items": []})", "older");
  EXPECT_TRUE(older.groups.empty());
  EXPECT_TRUE(older.events.empty());
  EXPECT_EQ(older.events_dropped, 0u);
}

// Every committed reference result (real scenario_manager output of an older version: no input_frames, user,
// station, in_progress) reads, carries the hash its replay must reproduce, and is written back with the same values
// for every key it had.
TEST(SessionResult, ReadsTheReferenceResults) {
  const auto paths = referenceResults();
  ASSERT_GE(paths.size(), 3u);
  for (const fs::path& path : paths) {
    SCOPED_TRACE(path.string());
    const SessionResult r = readResultFile(path.string());
    const nlohmann::json original = nlohmann::json::parse(test::readText(path));
    const std::string expected_path = path.string().substr(0, path.string().size() - 12) + ".expected.json";
    const nlohmann::json expected = nlohmann::json::parse(test::readText(expected_path));
    EXPECT_EQ(r.final_state_hash, expected["final_state_hash"].get<std::string>());
    EXPECT_EQ(r.state.value_or(""), expected["state"].get<std::string>());
    EXPECT_DOUBLE_EQ(r.total, expected["score_total"].get<double>());
    EXPECT_EQ(r.simulated_frames, expected["simulated_frames"].get<std::uint64_t>());
    EXPECT_FALSE(r.items.empty());
    EXPECT_FALSE(r.in_progress);
    EXPECT_FALSE(r.user.has_value());
    const nlohmann::json rewritten = nlohmann::json::parse(toJson(r));
    for (const auto& [key, value] : original.items()) {
      EXPECT_EQ(rewritten.at(key), value) << key;
    }
    EXPECT_EQ(resultFromJson(toJson(r), "rewritten"), r);
  }
}

TEST(SessionResult, MalformedResultsNameTheSourceAndTheKey) {
  const std::string whole = test::readText(referenceResults().front());
  // Truncated (a copy cut off mid-write).
  EXPECT_NE(errorOf([&] {
              resultFromJson(whole.substr(0, whole.size() / 2), "cut.result.json");
            }).find("cut.result.json: malformed result JSON"),
            std::string::npos);
  EXPECT_NE(errorOf([&] { resultFromJson("", "empty"); }).find("empty: malformed"), std::string::npos);
  EXPECT_NE(errorOf([&] { resultFromJson("[1, 2]", "array"); }).find("array: the result JSON is not an object"),
            std::string::npos);
  // NaN written as nan (what the hand-written writer did before null): not JSON.
  std::string with_nan = toJson(scenarioResult());
  with_nan.replace(with_nan.find("\"total\": 62.5"), 13, "\"total\": nan");
  EXPECT_NE(errorOf([&] { resultFromJson(with_nan, "nan.json"); }).find("nan.json: malformed"), std::string::npos);
  // Missing or empty required keys.
  for (const std::string key : {"scene", "final_state_hash", "frames"}) {
    nlohmann::json object = nlohmann::json::parse(whole);
    object.erase(key);
    const std::string error = errorOf([&] { resultFromJson(object.dump(), "r.json"); });
    EXPECT_NE(error.find("r.json: result field \"" + key + "\" is missing (required)"), std::string::npos) << error;
    object[key] = nullptr;
    EXPECT_NE(errorOf([&] { resultFromJson(object.dump(), "r.json"); }).find("\"" + key + "\""), std::string::npos);
  }
  // Wrong types: the key is named, nothing is read as zero.
  const auto withField = [&](const std::string& key, const nlohmann::json& value) {
    nlohmann::json object = nlohmann::json::parse(whole);
    object[key] = value;
    return errorOf([&] { resultFromJson(object.dump(), "typed.json"); });
  };
  EXPECT_NE(withField("frames", "390").find("\"frames\" is not a number"), std::string::npos);
  EXPECT_NE(withField("frames", 3.5).find("\"frames\" is not a non-negative integer"), std::string::npos);
  EXPECT_NE(withField("seed", -1).find("\"seed\""), std::string::npos);
  EXPECT_NE(withField("seed", 5000000000ull).find("\"seed\" is out of range"), std::string::npos);
  EXPECT_NE(withField("scene", 4).find("\"scene\" is not a string"), std::string::npos);
  EXPECT_NE(withField("total", "high").find("\"total\" is not a number"), std::string::npos);
  EXPECT_NE(withField("session_ended", 1).find("\"session_ended\" is not true or false"), std::string::npos);
  EXPECT_NE(withField("items", nlohmann::json::object()).find("\"items\" is not an array"), std::string::npos);
  EXPECT_NE(withField("items", nlohmann::json::parse(R"([{"name": "t", "value": "x"}])")).find("items[0].\"value\""),
            std::string::npos);
  EXPECT_NE(withField("items", nlohmann::json::parse(R"([{"value": 1}])")).find("items[0].\"name\""),
            std::string::npos);
  // A float-formatted count is still a count; an unknown key (a newer writer's) is ignored.
  EXPECT_EQ(withField("frames", 390.0), "");
  EXPECT_EQ(withField("late_inputs", nlohmann::json::parse("-0")), "");  // a signed zero is a count (as in Python)
  nlohmann::json newer = nlohmann::json::parse(whole);
  newer["a_key_from_the_future"] = {{"nested", true}};
  newer["frames"] = 390.0;
  EXPECT_EQ(resultFromJson(newer.dump(), "newer").frames, 390u);
}

// The malformed corpus the Python reader (scripts/session_result.py) is tested against too: both name the same key.
TEST(SessionResult, MalformedCorpusGivesTheExpectedErrors) {
  const fs::path folder = fs::path(VRM_SIM_SOURCE_DIR) / "test" / "results" / "malformed";
  const nlohmann::json expected = nlohmann::json::parse(test::readText(folder / "expected_errors.json"));
  std::size_t cases = 0;
  for (const auto& entry : fs::directory_iterator(folder)) {
    const std::string name = entry.path().filename().string();
    if (name == "expected_errors.json") continue;
    SCOPED_TRACE(name);
    ASSERT_TRUE(expected.contains(name)) << "a malformed case without its expected error";
    const std::string error = errorOf([&] { readResultFile(entry.path().string()); });
    EXPECT_NE(error.find(entry.path().string() + ": "), std::string::npos) << error;
    EXPECT_NE(error.find(expected[name].get<std::string>()), std::string::npos) << error;
    ++cases;
  }
  EXPECT_EQ(cases, expected.size());
  EXPECT_GE(cases, 10u);
}

// Crash recovery (issue 14) rewrites the struct: the kept copy is a complete result, marked interrupted.
TEST(SessionResult, CrashRecoveryRewritesTheStruct) {
  TempDir dir;
  const std::string path = (dir.path / "s.result.json").string();
  writeResultFile(path, scenarioResult());
  EXPECT_FALSE(fs::exists(path + ".tmp"));
  const SessionResult provisional = readResultFile(path);
  ASSERT_TRUE(provisional.in_progress);
  const std::string kept = interruptedPath(path);
  EXPECT_EQ(kept, (dir.path / "s.interrupted.result.json").string());
  writeResultFile(kept, interrupted(provisional));
  EXPECT_EQ(interruptedPath(path), (dir.path / "s.interrupted-2.result.json").string());
  const SessionResult recovered = readResultFile(kept);
  EXPECT_FALSE(recovered.in_progress);
  EXPECT_TRUE(recovered.interrupted);
  EXPECT_EQ(recovered.state, std::string("interrupted"));
  EXPECT_EQ(recovered.final_state_hash, provisional.final_state_hash);
  EXPECT_EQ(recovered.items, provisional.items);
  const std::string text = test::readText(kept);
  EXPECT_NE(text.find("\"in_progress\": false, \"interrupted\": true}"), std::string::npos) << text;
  // A paused session stays paused; only "running" becomes "interrupted".
  SessionResult paused = scenarioResult();
  paused.state = "paused";
  EXPECT_EQ(interrupted(paused).state, std::string("paused"));
  // An unwritable place is an error naming it.
  EXPECT_NE(errorOf([&] { writeResultFile((dir.path / "no" / "r.json").string(), paused); }).find("no/r.json"),
            std::string::npos);
  EXPECT_NE(errorOf([&] { readResultFile((dir.path / "missing.json").string()); }).find("missing.json: cannot read"),
            std::string::npos);
}

// The one builder the scenario_manager and session_replay use: the World's state, hash and counters.
TEST(SessionResult, BuiltFromTheWorld) {
  world::World world(scene::loadScene("navigation"));
  world::ResultContext context;
  context.seed = 9;
  context.bag = "/b/s.bag";
  context.station = "sim1";
  context.in_progress = true;
  const SessionResult r = world::sessionResult(world, context);
  EXPECT_EQ(r.scene, "navigation");
  EXPECT_EQ(r.scene_file, world.scene().source_file);
  EXPECT_EQ(r.final_state_hash, world::hashString(world.stateHash()));
  EXPECT_EQ(r.scenario, std::string("navigation"));
  EXPECT_EQ(r.state, std::string("idle"));
  EXPECT_EQ(r.seed, 9u);
  EXPECT_EQ(r.bag, std::string("/b/s.bag"));
  EXPECT_FALSE(r.user.has_value());
  EXPECT_EQ(r.station, "sim1");
  EXPECT_TRUE(r.in_progress);
  EXPECT_EQ(r.frames, 0u);
  EXPECT_EQ(r.software_version, VRM_SIM_VERSION);
  // Numbers carry 15 significant digits (66.66666666666667 is written 66.6666666666667): the text is a fixed point.
  EXPECT_EQ(toJson(resultFromJson(toJson(r), "built")), toJson(r));
}

}  // namespace
}  // namespace result
}  // namespace vrm_sim
