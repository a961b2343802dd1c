// The training layer's cost (issue "Training scenarios and scoring"): every shipped scenario played headless through
// the simulation core with its scripted expert and novice (the novice is the hard case: tears, retina contacts,
// drops), at every difficulty level. Per run: simulated seconds per wall second, CPU ms per frame (mean and worst)
// split by stage (scenario logic, tissue, collision, bleeding) and which simulations ran at all. Overheads against
// the targets: the scenario stage's share of a membrane frame (<= 2 %) and a navigation frame against a membrane
// frame (<= 10 %). The score is the scenario's result, not an error: these runs are exact replays of their scripts
// (the tests check that expert outscores novice and that a replay gives the same hash).
// Usage: bench_scenario [--quick] [--out FILE]
#include <algorithm>
#include <cstdio>
#include <fstream>
#include <string>
#include <vector>

#include "bench_cli.h"
#include "vrm_scene/scene_loader.h"
#include "vrm_sim/world/offline.h"

using namespace vrm_sim;

int main(int argc, char** argv) {
  bench::BenchArgs args;
  if (const auto status = bench::parseBenchArgs(
          argc, argv, "bench_scenario", "Every shipped scenario played headless with its expert and novice scripts.",
          "bench/results/scenario.json", &args)) {
    return *status;
  }
  const bool quick = args.quick;
  const std::string out_path = args.out_path;
  const int repeats = quick ? 1 : 3;  // the fastest of `repeats` identical runs: these machines are noisy
  std::printf("bench_scenario (%s): scripted sessions through world::World + scenario, 50 Hz inputs, best of %d\n",
              quick ? "quick" : "full", repeats);
  std::printf("%-17s %-7s %-7s %-9s %6s %6s %9s %8s %8s %9s %8s %8s %8s  %s\n", "scenario", "level", "script", "state",
              "total", "frames", "sim/wall", "ms/frm", "max_ms", "scenario", "tissue", "collide", "bleed",
              "simulations");
  std::string rows;
  double membrane_frame = 0.0, membrane_scenario = 0.0, navigation_frame = 0.0;
  for (const std::string& name : scene::shippedScenes()) {
    const scene::SceneDescription base = scene::loadScene(scene::shippedScenePath(name));
    if (!base.scenario) continue;
    std::vector<std::string> levels = {base.scenario->difficulty};
    if (!quick) levels = base.scenario->difficulty_levels;
    for (const std::string& level : levels) {
      const scene::SceneDescription scene = scene::loadScene(scene::shippedScenePath(name), level);
      for (const std::string script : {"expert", "novice"}) {
        world::ScenarioRunOptions options;
        options.script = script;
        world::ScenarioRunResult best;
        for (int repeat = 0; repeat < repeats; ++repeat) {
          world::ScenarioRunResult run = world::runScenario(scene, options);
          if (repeat == 0 || run.ms_per_frame < best.ms_per_frame) best = run;
        }
        const double sim_per_wall = best.wall_seconds > 0.0 ? best.sim_seconds / best.wall_seconds : 0.0;
        std::string simulations;
        for (const std::string& kind : best.simulations) simulations += (simulations.empty() ? "" : "+") + kind;
        std::printf("%-17s %-7s %-7s %-9s %6.1f %6lu %9.1f %8.3f %8.3f %9.4f %8.3f %8.3f %8.3f  %s\n", name.c_str(),
                    level.c_str(), script.c_str(), best.state.c_str(), best.score.total,
                    static_cast<unsigned long>(best.frames), sim_per_wall, best.ms_per_frame, best.ms_per_frame_max,
                    best.ms_scenario, best.ms_tissue, best.ms_collision, best.ms_bleeding, simulations.c_str());
        if (level == base.scenario->difficulty && script == std::string("expert")) {
          if (name == "membrane_peeling") {
            membrane_frame = best.ms_per_frame;
            membrane_scenario = best.ms_scenario;
          }
          if (name == "navigation") navigation_frame = best.ms_per_frame;
        }
        std::string simulations_json;
        for (const std::string& kind : best.simulations) {
          simulations_json += (simulations_json.empty() ? "\"" : ",\"") + kind + "\"";
        }
        char row[1024];
        std::snprintf(row, sizeof(row),
                      "{\"suite\":\"scenario\",\"scenario\":\"%s\",\"type\":\"%s\",\"difficulty\":\"%s\","
                      "\"script\":\"%s\",\"state\":\"%s\",\"total\":%.2f,\"frames\":%lu,\"sim_seconds\":%.3f,"
                      "\"sim_seconds_per_wall_second\":%.3f,\"ms_per_frame\":%.5f,\"ms_per_frame_max\":%.5f,"
                      "\"ms_scenario\":%.5f,\"ms_tissue\":%.5f,\"ms_collision\":%.5f,\"ms_bleeding\":%.5f,"
                      "\"simulations\":[%s]}",
                      name.c_str(), best.type.c_str(), level.c_str(), script.c_str(), best.state.c_str(),
                      best.score.total, static_cast<unsigned long>(best.frames), best.sim_seconds, sim_per_wall,
                      best.ms_per_frame, best.ms_per_frame_max, best.ms_scenario, best.ms_tissue, best.ms_collision,
                      best.ms_bleeding, simulations_json.c_str());
        rows += (rows.empty() ? "" : ",\n") + std::string(row);
      }
    }
  }
  const double scenario_share = membrane_frame > 0.0 ? membrane_scenario / membrane_frame : 0.0;
  const double navigation_ratio = membrane_frame > 0.0 ? navigation_frame / membrane_frame : 0.0;
  std::printf("scenario stage share of a membrane frame: %.3f %% (target <= 2 %%)\n", 100.0 * scenario_share);
  std::printf("navigation frame / membrane frame: %.2f %% (target <= 10 %%)\n", 100.0 * navigation_ratio);
  std::ofstream out(out_path);
  out << "{\"suite\":\"scenario\",\"command\":\"./scripts/bench.sh" << (quick ? " --quick" : "")
      << " scenario\",\"quick\":" << (quick ? "true" : "false") << ",\"membrane_scenario_share\":" << scenario_share
      << ",\"navigation_over_membrane\":" << navigation_ratio << ",\"rows\":[\n"
      << rows << "\n]}\n";
  return out ? 0 : 1;
}
