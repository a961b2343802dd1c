// The retina's layers (issue 38): speed against error of the subretinal fluid and the hyaloid's adhesions. Each
// case plays a shipped scripted session headless (world::runScenario) with the tissue's step dt varied; the error is
// the case's outcome against the same session at the reference dt (dt / 4 of the finest tested, a converged run):
// the bleb's equivalent diameter (retina_relocation) or the detached fraction and the retina injuries
// (posterior_hyaloid). Cases: the experts (kind), the novices (hard: a yank of the needle inside the retina, full
// suction on the retina and a yank of the hyaloid), and injection at ten times the novice's flow (10 ul/s).
// Usage: bench_retina [--quick] [--out FILE]
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <string>
#include <vector>

#include "bench_cli.h"
#include "vrm_scene/scene_loader.h"
#include "vrm_sim/world/offline.h"

using namespace vrm_sim;

namespace {

struct Case {
  std::string name, scene, script, kind, outcome;
  double flow_scale = 1.0;  // injection flows of the script times this
};

double item(const world::ScenarioRunResult& run, const std::string& name) {
  for (const auto& entry : run.score.items) {
    if (entry.name == name) return entry.value;
  }
  return std::nan("");
}

world::ScenarioRunResult play(const Case& c, double dt) {
  scene::SceneDescription scene = scene::loadScene(scene::shippedScenePath(c.scene));
  for (auto& object : scene.objects) {
    if (object.isDeformable()) object.tissue.dt = dt;
  }
  scene::ScriptedSession script = scene::findScript(scene, c.script);
  for (auto& instrument : script.instruments) {
    for (auto& waypoint : instrument.path) waypoint.injection_flow *= c.flow_scale;
  }
  world::ScenarioRunOptions options;
  options.script_file = script;
  return world::runScenario(scene, options);
}

}  // namespace

int main(int argc, char** argv) {
  bench::BenchArgs args;
  if (const auto status =
          bench::parseBenchArgs(argc, argv, "bench_retina",
                                "Subretinal fluid and hyaloid adhesion: ms per frame against the outcome's error.",
                                "bench/results/retina.json", &args)) {
    return *status;
  }
  const std::vector<Case> cases = {
      {"relocation_expert", "retina_relocation", "expert", "kind", "bleb_diameter"},
      {"relocation_novice", "retina_relocation", "novice", "hard: yank inside, full flow", "bleb_diameter"},
      {"relocation_flood", "retina_relocation", "novice", "hard: 10 ul/s", "bleb_diameter", 10.0},
      {"hyaloid_expert", "posterior_hyaloid", "expert", "kind", "detached_fraction"},
      {"hyaloid_novice", "posterior_hyaloid", "novice", "hard: suction on the retina, yank", "detached_fraction"},
  };
  const std::vector<double> dts = args.quick ? std::vector<double>{1e-3} : std::vector<double>{2e-3, 1e-3, 5e-4};
  const double reference_dt = *std::min_element(dts.begin(), dts.end()) / 4.0;
  std::printf("bench_retina (%s): outcome error against dt = %.2g s (reference)\n", args.quick ? "quick" : "full",
              reference_dt);
  std::printf("%-18s %-8s %9s %8s %8s %8s  %-17s %10s %10s %9s %8s\n", "case", "dt", "ms/frm", "max_ms", "tissue",
              "total", "outcome", "value", "reference", "error", "injuries");
  std::string rows;
  double worst_ms = 0.0;
  for (const Case& c : cases) {
    const world::ScenarioRunResult reference = play(c, reference_dt);
    const double reference_value = item(reference, c.outcome);
    for (const double dt : dts) {
      const world::ScenarioRunResult run = play(c, dt);
      const double value = item(run, c.outcome);
      const double error = c.outcome == "bleb_diameter" && reference_value > 0.0
                               ? std::abs(value - reference_value) / reference_value
                               : std::abs(value - reference_value);
      const double injuries = c.scene == "posterior_hyaloid" ? item(run, "retina_injuries") : item(run, "retina_tears");
      const double reference_injuries =
          c.scene == "posterior_hyaloid" ? item(reference, "retina_injuries") : item(reference, "retina_tears");
      worst_ms = std::max(worst_ms, run.ms_per_frame_max);
      std::printf("%-18s %-8.2g %9.3f %8.3f %8.3f %8.1f  %-17s %10.4g %10.4g %9.3g %4.0f/%.0f\n", c.name.c_str(), dt,
                  run.ms_per_frame, run.ms_per_frame_max, run.ms_tissue, run.score.total, c.outcome.c_str(), value,
                  reference_value, error, injuries, reference_injuries);
      char row[1400];
      std::snprintf(row, sizeof(row),
                    "{\"suite\":\"retina\",\"case\":\"%s\",\"scene\":\"%s\",\"script\":\"%s\",\"kind\":\"%s\","
                    "\"dt\":%.6g,\"reference_dt\":%.6g,\"state\":\"%s\",\"total\":%.3f,\"frames\":%lu,"
                    "\"ms_per_frame\":%.5f,\"ms_per_frame_max\":%.5f,\"ms_tissue\":%.5f,\"outcome\":\"%s\","
                    "\"value\":%.8g,\"reference\":%.8g,\"error\":%.6g,\"error_kind\":\"%s\",\"injuries\":%.0f,"
                    "\"reference_injuries\":%.0f}",
                    c.name.c_str(), c.scene.c_str(), c.script.c_str(), c.kind.c_str(), dt, reference_dt,
                    run.state.c_str(), run.score.total, static_cast<unsigned long>(run.frames), run.ms_per_frame,
                    run.ms_per_frame_max, run.ms_tissue, c.outcome.c_str(), value, reference_value, error,
                    c.outcome == "bleb_diameter" ? "relative" : "absolute", injuries, reference_injuries);
      rows += (rows.empty() ? "\n  " : ",\n  ") + std::string(row);
    }
  }
  std::printf("worst frame of any case: %.2f ms\n", worst_ms);
  std::ofstream out(args.out_path);
  out << "{\"suite\":\"retina\",\"command\":\"rosrun vrm_sim bench_retina" << (args.quick ? " --quick" : "")
      << "\",\"quick\":" << (args.quick ? "true" : "false") << ",\"worst_ms_per_frame\":" << worst_ms << ",\"rows\":["
      << rows << "\n]}\n";
  if (!out) {
    std::fprintf(stderr, "bench_retina: cannot write %s\n", args.out_path.c_str());
    return 1;
  }
  std::printf("wrote %s\n", args.out_path.c_str());
  return 0;
}
