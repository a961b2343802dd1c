// Every shipped training scenario, played offline through the simulation core (what scenario_offline prints): the
// scripted expert finishes with a higher total than the scripted novice, and the novice triggers the penalties it was
// written to trigger. Plus the scenario section's loader errors, difficulty levels, LOAD at run time (world::Session)
// and "model only what a scene needs" (no tissue stage in the navigation scenario).
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <memory>

#include "vrm_scene/scene_loader.h"
#include "vrm_sim/scenario/factor_groups.h"
#include "vrm_sim/scenario/runner.h"
#include "vrm_sim/scenario/scenario.h"
#include "vrm_sim/world/offline.h"
#include "vrm_sim/world/session.h"

namespace vrm_sim {
namespace {

using scene::loadScene;
using scene::shippedScenePath;

const std::vector<std::string>& scenarioNames() {
  static const std::vector<std::string> names = {"navigation",        "trajectory",          "pick_and_place",
                                                 "steady_hold",       "object_manipulation", "bimanual",
                                                 "membrane_peeling",  "ilm_peeling",         "vitrectomy",
                                                 "laser_coagulation", "retina_relocation",   "posterior_hyaloid"};
  return names;
}

double item(const world::ScenarioRunResult& result, const std::string& name) {
  const scenario::ScoreItem* entry = result.score.item(name);
  EXPECT_NE(entry, nullptr) << result.scenario << " has no item " << name;
  return entry ? entry->value : std::nan("");
}

struct Runs {
  world::ScenarioRunResult expert, novice;
};

const Runs& runs(const std::string& name) {
  static std::map<std::string, Runs> cache;
  auto found = cache.find(name);
  if (found != cache.end()) return found->second;
  const scene::SceneDescription scene = loadScene(shippedScenePath(name));
  world::ScenarioRunOptions options;
  Runs result;
  options.script = "expert";
  result.expert = world::runScenario(scene, options);
  options.script = "novice";
  result.novice = world::runScenario(scene, options);
  return cache.emplace(name, result).first->second;
}

TEST(Scenarios, EveryShippedScenarioIsListedAndEveryDifficultyLevelLoads) {
  std::vector<std::string> with_scenario;
  for (const std::string& name : scene::shippedScenes()) {
    const scene::SceneDescription scene = loadScene(shippedScenePath(name));
    if (!scene.scenario) continue;
    with_scenario.push_back(name);
    ASSERT_GE(scene.scenario->difficulty_levels.size(), 3u) << name;
    for (const std::string& level : scene.scenario->difficulty_levels) {
      const scene::SceneDescription leveled = loadScene(shippedScenePath(name), level);
      EXPECT_EQ(leveled.scenario->difficulty, level);
      EXPECT_NO_THROW(world::World world(leveled)) << name << " at " << level;
    }
    EXPECT_EQ(scene.scenario->scripts.count("expert"), 1u) << name;
    EXPECT_EQ(scene.scenario->scripts.count("novice"), 1u) << name;
  }
  std::sort(with_scenario.begin(), with_scenario.end());
  std::vector<std::string> expected = scenarioNames();
  std::sort(expected.begin(), expected.end());
  EXPECT_EQ(with_scenario, expected);
}

class EveryScenario : public ::testing::TestWithParam<std::string> {};

TEST_P(EveryScenario, ExpertFinishesAndOutscoresTheNovice) {
  const Runs& result = runs(GetParam());
  EXPECT_EQ(result.expert.state, "finished") << result.expert.json();
  EXPECT_GT(result.expert.score.total, 0.0);
  EXPECT_GT(result.expert.score.total, result.novice.score.total + 10.0)
      << "expert " << result.expert.json() << "\nnovice " << result.novice.json();
  EXPECT_EQ(item(result.expert, "completed"), 1.0);
}

TEST_P(EveryScenario, ReplayingTheSameScriptScoresIdentically) {
  const scene::SceneDescription scene = loadScene(shippedScenePath(GetParam()));
  const world::ScenarioRunResult again = world::runScenario(scene, world::ScenarioRunOptions{});
  EXPECT_EQ(again.final_state_hash, runs(GetParam()).expert.final_state_hash);
  EXPECT_EQ(again.score.total, runs(GetParam()).expert.score.total);
}

// Issue 35: the factor groups re-express the total (their weighted mean), and the penalty events explain every point
// the penalty items lost — in the run's score and in its session result alike.
TEST_P(EveryScenario, GroupsAddUpToTheTotalAndEventsExplainThePenaltyPoints) {
  for (const world::ScenarioRunResult* run : {&runs(GetParam()).expert, &runs(GetParam()).novice}) {
    SCOPED_TRACE(run->script);
    const scenario::Score& score = run->score;
    double weighted = 0.0, weights = 0.0, item_weights = 0.0, penalty_loss = 0.0;
    for (const scenario::GroupScore& group : score.groups) {
      weighted += group.weight * group.points;
      weights += group.weight;
      EXPECT_NE(group.name, "microscope_handling") << "no shipped scenario operates the microscope";
    }
    ASSERT_GT(weights, 0.0);
    EXPECT_NEAR(weighted / weights, score.total, 1e-9);
    for (const scenario::ScoreItem& item : score.items) {
      const scenario::ItemRole* role = scenario::itemRole(item.name);
      ASSERT_NE(role, nullptr) << item.name << " has no factor group";
      item_weights += item.weight;
      if (role->penalty_kind != nullptr) penalty_loss += item.weight * (100.0 - item.points);
    }
    EXPECT_DOUBLE_EQ(weights, item_weights);
    ASSERT_TRUE(run->session_result.has_value());
    const result::SessionResult& result = *run->session_result;
    ASSERT_EQ(result.groups.size(), score.groups.size());
    EXPECT_EQ(result.events_dropped, 0u);
    double explained = 0.0;
    for (const result::PenaltyEvent& event : result.events) {
      explained += event.points;
      EXPECT_GE(event.points, -1e-12) << event.kind;
      EXPECT_FALSE(event.slot.empty()) << event.kind << " at " << event.time << " s has no instrument";
      EXPECT_TRUE(std::isfinite(event.position[0])) << event.kind;
      EXPECT_GE(event.time, 0.0);
      EXPECT_LE(event.time, result.elapsed + 1e-9);
    }
    EXPECT_NEAR(explained, penalty_loss / item_weights, 1e-6) << run->json();
  }
  // The novices were written to make mistakes: their results say which.
  EXPECT_FALSE(runs(GetParam()).novice.session_result->events.empty()) << runs(GetParam()).novice.json();
}

INSTANTIATE_TEST_SUITE_P(Shipped, EveryScenario, ::testing::ValuesIn(scenarioNames()));

// Every shipped scene at every level runs a scenario whose every item is in the factor-group table (the runner refuses
// one that is not, naming the item: a new item cannot go unscored).
TEST(Scenarios, EveryShippedItemHasAFactorGroup) {
  for (const std::string& name : scene::shippedScenes()) {
    const scene::SceneDescription scene = loadScene(shippedScenePath(name));
    if (!scene.scenario) continue;
    for (const std::string& level : scene.scenario->difficulty_levels) {
      const scenario::ScenarioRunner runner(loadScene(shippedScenePath(name), level));
      for (const scenario::ScoreItem& item : runner.status().score.items) {
        EXPECT_NE(scenario::itemRole(item.name), nullptr) << name << " at " << level << ": " << item.name;
      }
    }
  }
}

TEST(Scenarios, NovicesTriggerThePenaltiesTheyWereWrittenFor) {
  const Runs& navigation = runs("navigation");
  EXPECT_GE(item(navigation.novice, "wrong_touches"), 1.0);
  EXPECT_GE(item(navigation.novice, "retina_contacts"), 1.0);
  EXPECT_EQ(item(navigation.expert, "wrong_touches"), 0.0);
  EXPECT_EQ(item(navigation.expert, "retina_contacts"), 0.0);

  const Runs& trajectory = runs("trajectory");
  EXPECT_GT(item(trajectory.novice, "mean_deviation"), 2.0 * item(trajectory.expert, "mean_deviation"));
  EXPECT_GE(item(trajectory.novice, "retina_contacts"), 1.0);

  const Runs& pick = runs("pick_and_place");
  EXPECT_GE(item(pick.novice, "drops"), 1.0);
  EXPECT_GE(item(pick.novice, "retina_contacts"), 1.0);
  EXPECT_EQ(item(pick.expert, "drops"), 0.0);

  // Issue 36: boxes, rings and key-and-lock; the hand-over between two forceps.
  const Runs& manipulation = runs("object_manipulation");
  for (const char* penalty : {"object_drops", "object_impacts", "post_collisions", "retina_contacts"}) {
    EXPECT_GE(item(manipulation.novice, penalty), 1.0) << penalty;
    EXPECT_EQ(item(manipulation.expert, penalty), 0.0) << penalty;
  }
  EXPECT_GT(item(manipulation.novice, "max_key_force"), 0.005);  // the unrolled key pushed 0.26 mm off the slot
  EXPECT_EQ(item(manipulation.expert, "max_key_force"), 0.0);
  EXPECT_EQ(item(manipulation.expert, "tasks_done"), 3.0);
  EXPECT_LT(item(manipulation.expert, "orientation_error"), 1.0);
  const Runs& bimanual = runs("bimanual");
  for (const char* penalty : {"object_drops", "object_impacts", "instrument_collisions", "retina_contacts"}) {
    EXPECT_GE(item(bimanual.novice, penalty), 1.0) << penalty;
    EXPECT_EQ(item(bimanual.expert, penalty), 0.0) << penalty;
  }
  EXPECT_EQ(item(bimanual.expert, "handovers"), 3.0);

  const Runs& hold = runs("steady_hold");
  EXPECT_GE(item(hold.novice, "exits"), 1.0);
  EXPECT_GT(item(hold.novice, "tremor_band_power"), 10.0 * item(hold.expert, "tremor_band_power"));

  const Runs& membrane = runs("membrane_peeling");
  EXPECT_TRUE(item(membrane.novice, "torn_springs") >= 1.0 || item(membrane.novice, "retina_contacts") >= 1.0);
  EXPECT_EQ(item(membrane.expert, "detached_fraction"), 1.0);

  const Runs& ilm = runs("ilm_peeling");
  EXPECT_TRUE(item(ilm.novice, "torn_springs") >= 1.0 || item(ilm.novice, "retina_contacts") >= 1.0);
  EXPECT_GT(item(ilm.expert, "continuity"), item(ilm.novice, "continuity"));

  // Issue 37: the novice's weak, strong, doubled, off-row and vessel shots; the expert's row is clean. Each injury
  // event lies where its burn is, millimetres from the probe's tip.
  const Runs& laser = runs("laser_coagulation");
  for (const char* penalty : {"weak_burns", "strong_burns", "burn_overlaps", "off_row_burns", "vessel_burns"}) {
    EXPECT_GE(item(laser.novice, penalty), 1.0) << penalty;
    EXPECT_EQ(item(laser.expert, penalty), 0.0) << penalty;
  }
  EXPECT_LT(item(laser.expert, "spacing_error"), 0.05);
  EXPECT_GT(item(laser.novice, "spacing_error"), 0.15);
  ASSERT_TRUE(laser.novice.session_result.has_value());
  int vessel_events = 0;
  for (const result::PenaltyEvent& event : laser.novice.session_result->events) {
    if (event.item != "vessel_burns") continue;
    ++vessel_events;
    EXPECT_EQ(event.kind, "vessel_hit_by_laser");
    const Eigen::Vector3d position(event.position[0], event.position[1], event.position[2]);
    ASSERT_TRUE(position.allFinite());
    EXPECT_NEAR(position.norm(), 0.012, 1e-5) << "a burn lies on the retina, not at the probe's tip";
  }
  EXPECT_EQ(vessel_events, 1);

  // Issue 38: the relocation novice injects into the vitreous, pushes the needle into the wall and slices the retina
  // with a sideways jerk; the expert's still needle raises the bleb on target. The hyaloid novice yanks (adhesions
  // tear the retina, each an event at its adhesion) and aspirates the retina; the expert peels.
  const Runs& relocation = runs("retina_relocation");
  for (const char* penalty : {"retina_tears", "injected_outside", "retina_contacts"}) {
    EXPECT_GT(item(relocation.novice, penalty), 0.0) << penalty;
    EXPECT_EQ(item(relocation.expert, penalty), 0.0) << penalty;
  }
  EXPECT_LT(item(relocation.expert, "size_error"), 0.05);
  EXPECT_LT(item(relocation.expert, "site_error"), 5e-5);
  const Runs& hyaloid = runs("posterior_hyaloid");
  EXPECT_GE(item(hyaloid.novice, "retina_injuries"), 3.0);
  EXPECT_EQ(item(hyaloid.expert, "retina_injuries"), 0.0);
  EXPECT_GT(item(hyaloid.novice, "retina_damage"), 0.5);
  EXPECT_EQ(item(hyaloid.expert, "retina_damage"), 0.0);
  int traction_events = 0;
  for (const result::PenaltyEvent& event : hyaloid.novice.session_result->events) {
    if (event.item != "retina_injuries") continue;
    ++traction_events;
    const Eigen::Vector3d position(event.position[0], event.position[1], event.position[2]);
    EXPECT_NEAR(position.norm(), 0.012 - 2e-4, 1e-5) << "an injury lies at its adhesion on the hyaloid's rest sheet";
  }
  EXPECT_GE(traction_events, 1);

  const Runs& vitrectomy = runs("vitrectomy");
  EXPECT_GE(item(vitrectomy.novice, "warnings"), 1.0);
  EXPECT_GT(item(vitrectomy.novice, "retina_damage"), item(vitrectomy.expert, "retina_damage"));

  // Bimanual (issue 33): the experts' light pipe lights the work throughout; each novice works outside its cone.
  for (const std::string name : {"membrane_peeling", "ilm_peeling", "vitrectomy"}) {
    EXPECT_EQ(item(runs(name).expert, "unlit_work"), 0.0) << name;
    EXPECT_GE(item(runs(name).novice, "unlit_work"), 0.5) << name;
    const scenario::ScoreItem* novice = runs(name).novice.score.item("unlit_work");
    ASSERT_NE(novice, nullptr) << name;
    EXPECT_GT(novice->weight, 0.0) << name << ": unlit_work is not scored";
    EXPECT_LT(novice->points, 100.0) << name;
  }
}

// Model only what a scene needs: the abstract scenarios never run a mass-spring step or a tissue collision.
TEST(Scenarios, NavigationRunsNoTissueStage) {
  for (const std::string name :
       {"navigation", "trajectory", "pick_and_place", "steady_hold", "object_manipulation", "bimanual"}) {
    const Runs& result = runs(name);
    for (const world::ScenarioRunResult* run : {&result.expert, &result.novice}) {
      EXPECT_EQ(std::count(run->simulations.begin(), run->simulations.end(), "tissue"), 0) << run->json();
      EXPECT_EQ(run->ms_tissue, 0.0);
      EXPECT_EQ(std::count(run->simulations.begin(), run->simulations.end(), "scenario"), 1) << run->json();
    }
  }
  // And frame by frame, in the core itself.
  world::World world(loadScene(shippedScenePath("navigation")));
  bool tissue_stage = false;
  std::uint64_t frames = 0;
  world.setFrameObserver([&](const world::FrameResult& frame) {
    ++frames;
    for (const world::StageTime& stage : frame.stages)
      tissue_stage = tissue_stage || stage.stage.rfind("tissue", 0) == 0;
  });
  const scene::SceneDescription scripted = scene::withScript(world.scene(), "expert");
  for (const world::InstrumentState& input : world::scriptedInputs(scripted, 50.0, 2.0)) world.handle(input);
  world.flush();
  EXPECT_EQ(frames, 101u);
  EXPECT_FALSE(tissue_stage);
  EXPECT_TRUE(world.tissueNames().empty());
}

TEST(ScenarioSection, StrictLoaderReportsFileLineColumnAndField) {
  const std::string base = R"(scene: {name: t, kind: abstract}
objects: [{name: retina, role: retina, mesh: {generator: retina, params: {ring_count: 30}}}]
instruments: [{slot: right, type: needle}]
simulations: []
)";
  auto error_of = [&](const std::string& scenario, const std::string& difficulty = "") -> std::string {
    try {
      // What a session does: load, then build the scenario (its type is checked by the scenario registry).
      const scene::SceneDescription scene = scene::loadSceneFromString(base + scenario, "t.yaml", difficulty);
      if (scene.scenario) scenario::makeScenario(scene);
    } catch (const scene::SceneError& error) {
      return error.what();
    }
    return "";
  };
  std::string message = error_of("scenario: {type: steady_hold, timelimit: 3}\n");
  EXPECT_NE(message.find("t.yaml:5:"), std::string::npos) << message;
  EXPECT_NE(message.find("scenario.timelimit: unknown key (did you mean 'time_limit'?)"), std::string::npos) << message;
  message = error_of("scenario: {type: steady_hold, time_limit: soon}\n");
  EXPECT_NE(message.find("scenario.time_limit: expected a non-negative number, got 'soon'"), std::string::npos)
      << message;
  message = error_of("scenario: {type: steady_hol}\n");
  EXPECT_NE(message.find("t.yaml:5:"), std::string::npos) << message;
  EXPECT_NE(message.find("scenario.type: unknown scenario type 'steady_hol' (did you mean 'steady_hold'?)"),
            std::string::npos)
      << message;
  message = error_of("scenario:\n  type: steady_hold\n  scoring: {time: {weight: 1, best: 3, worst: 3}}\n");
  EXPECT_NE(message.find("best and worst must differ"), std::string::npos) << message;
  const std::string levels = R"(scenario:
  type: steady_hold
  params: {centre: [0, 0, -0.01]}
  difficulty:
    default: easy
    levels:
      easy: {scenario.params.radius: 0.0002}
      hard: {scenario.params.radius: 0.00005, objects.retina.mesh.params.ring_count: 20}
)";
  EXPECT_EQ(error_of(levels), "");
  EXPECT_EQ(error_of(levels, "hard"), "");
  message = error_of(levels, "extreme");
  EXPECT_NE(message.find("unknown difficulty level 'extreme'"), std::string::npos) << message;
  EXPECT_NE(message.find("levels: easy, hard"), std::string::npos) << message;
  // A level's path that does not resolve fails even while another level is loaded, at its own line.
  message = error_of(levels + "      broken: {objects.retna.mesh.params.ring_count: 20}\n");
  EXPECT_NE(message.find("t.yaml:13:"), std::string::npos) << message;
  EXPECT_NE(message.find("no item named 'retna'"), std::string::npos) << message;
  // An override whose value is wrong fails like the written value would, pointing at the override.
  message = error_of(levels + "      bad: {objects.retina.mesh.params.ring_count: -3}\n", "bad");
  EXPECT_NE(message.find("t.yaml:13:"), std::string::npos) << message;
  EXPECT_NE(message.find("ring_count"), std::string::npos) << message;
  message = error_of("", "easy");
  EXPECT_NE(message.find("no scenario section"), std::string::npos) << message;
}

TEST(ScenarioSection, DifficultyOverridesTheSceneValues) {
  const scene::SceneDescription medium = loadScene(shippedScenePath("membrane_peeling"));
  const scene::SceneDescription hard = loadScene(shippedScenePath("membrane_peeling"), "hard");
  EXPECT_EQ(medium.scenario->difficulty, "medium");
  EXPECT_EQ(hard.scenario->difficulty, "hard");
  const scene::ObjectDescription& soft = *medium.findObject("membrane");
  const scene::ObjectDescription& stiff = *hard.findObject("membrane");
  EXPECT_NE(soft.tissue.adhesion_stiffness, stiff.tissue.adhesion_stiffness);
  EXPECT_NE(medium.scenario->time_limit, hard.scenario->time_limit);
}

TEST(Session, LoadSwitchesTheSceneAndABrokenLoadKeepsTheSession) {
  std::vector<std::string> log;
  world::WorldOptions options;
  options.log = [&log](world::Severity, const std::string& message) { log.push_back(message); };
  world::Session session(loadScene(shippedScenePath("membrane_peeling")), options);
  ASSERT_FALSE(session.world().tissueNames().empty());
  const scene::SceneDescription membrane_expert = scene::withScript(session.world().scene(), "expert");
  for (const world::InstrumentState& input : world::scriptedInputs(membrane_expert, 50.0, 0.5)) session.handle(input);
  const std::uint64_t frames = session.world().frame();
  ASSERT_GT(frames, 10u);

  // A broken YAML, an unknown scene, an unknown level: refused, the membrane session goes on untouched.
  const std::string broken = std::string(VRM_SCENE_SOURCE_DIR) + "/test/data/scenes/syntax_error.yaml";
  for (const auto& [scene_name, level] : std::vector<std::pair<std::string, std::string>>{
           {broken, ""}, {"no_such_scene", ""}, {"navigation", "impossible"}}) {
    session.handle(
        world::ScenarioCommand{world::fromSeconds(0.6), world::ScenarioCommand::Type::kLoad, scene_name, level, 7});
    EXPECT_EQ(session.world().scene().name, "membrane_peeling");
    ASSERT_NE(session.world().scenarioStatus(), nullptr);
    EXPECT_NE(session.world().scenarioStatus()->message.find("refused"), std::string::npos)
        << session.world().scenarioStatus()->message;
  }
  EXPECT_EQ(session.world().frame(), frames);
  EXPECT_EQ(session.world().scenarioStatus()->state, scenario::State::kRunning);

  // LOAD navigation (hard): a new world without tissue; nothing of the membrane runs.
  int loaded = 0;
  session.setLoadObserver([&loaded](world::World&) { ++loaded; });
  session.handle(
      world::ScenarioCommand{world::fromSeconds(1.0), world::ScenarioCommand::Type::kLoad, "navigation", "hard", 42});
  EXPECT_EQ(loaded, 1);
  EXPECT_EQ(session.seed(), 42u);
  EXPECT_EQ(session.world().scene().name, "navigation");
  EXPECT_EQ(session.world().scenarioStatus()->difficulty, "hard");
  EXPECT_TRUE(session.world().tissueNames().empty());
  EXPECT_EQ(session.world().frame(), 0u);
}

// The tool's interface (exit codes, one JSON line, file:line:col errors) as other tools rely on it.
std::pair<int, std::string> run(const std::string& arguments) {
  const std::string command = std::string(VRM_SCENARIO_OFFLINE_BINARY) + " " + arguments + " 2>&1";
  FILE* pipe = popen(command.c_str(), "r");
  std::string output;
  std::array<char, 4096> buffer{};
  while (fgets(buffer.data(), buffer.size(), pipe) != nullptr) output += buffer.data();
  const int status = pclose(pipe);
  return {WEXITSTATUS(status), output};
}

TEST(ScenarioOffline, InterfaceExitCodesAndJson) {
  auto [code, output] = run("--scene navigation --script expert --seed 3");
  EXPECT_EQ(code, 0) << output;
  for (const char* field :
       {"\"scenario\": \"navigation\"", "\"difficulty\": ", "\"state\": \"finished\"", "\"total\": ", "\"items\": {",
        "\"final_state_hash\": \"0x", "\"sim_seconds\": ", "\"wall_seconds\": ", "\"seed\": 3",
        // The run's session result (issue 34), as a live session writes it.
        "\"result\": {\"scene\": \"navigation\", \"scene_file\": "}) {
    EXPECT_NE(output.find(field), std::string::npos) << field << " missing in " << output;
  }
  std::tie(code, output) = run("--list");
  EXPECT_EQ(code, 0);
  for (const std::string& name : scenarioNames()) EXPECT_NE(output.find(name + "\n"), std::string::npos) << output;
  std::tie(code, output) =
      run("--scene " + std::string(VRM_SCENE_SOURCE_DIR) + "/test/data/scenes/typo_in_tissue.yaml");
  EXPECT_EQ(code, 1) << output;
  EXPECT_NE(output.find("typo_in_tissue.yaml:"), std::string::npos) << output;
  std::tie(code, output) = run("--scene navigation --difficulty impossible");
  EXPECT_EQ(code, 1) << output;
  std::tie(code, output) = run("--scene navigation --script nobody");
  EXPECT_EQ(code, 1) << output;
  EXPECT_NE(output.find("expert"), std::string::npos) << output;  // names the scripts it has
  std::tie(code, output) = run("--scene");
  EXPECT_EQ(code, 2) << output;
  std::tie(code, output) = run("--bogus 1");
  EXPECT_EQ(code, 2) << output;
  std::tie(code, output) = run("");
  EXPECT_EQ(code, 2) << output;
}

}  // namespace
}  // namespace vrm_sim
