// The simulation core's frame cost against its accuracy (issue "One simulation core"): a scene's scripted path fed to
// world::World at the device rate, as the graph does, per collision detector and motion speed (the fast case: the
// same path 4x faster). Error: final membrane node positions against a converged reference of the same inputs
// (tissue dt / 8, inputs at 8x the rate). Reports mean / p95 / max ms per frame, the stage split, simulated seconds
// per wall second and whether two runs give the same state hash.
// Usage: bench_world [--quick] [--out FILE]
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <string>
#include <vector>

#include "bench_cli.h"
#include "vrm_sim/mge/membrane.h"
#include "vrm_sim/scene/scene_loader.h"
#include "vrm_sim/world/offline.h"
#include "vrm_sim/world/world.h"

using namespace vrm_sim;

namespace {

struct Run {
  std::vector<double> frame_ms;
  double tissue_ms = 0.0, collision_ms = 0.0, bleeding_ms = 0.0, wall_s = 0.0, sim_s = 0.0;
  std::uint64_t hash = 0;
  std::size_t max_grasped = 0;
  std::string outcome;
  std::vector<Eigen::Vector3d> positions;
  std::uint64_t topology = 1;
};

scene::SceneDescription variant(const scene::SceneDescription& base, double speed, double dt_scale) {
  scene::SceneDescription scene = base;
  for (auto& instrument : scene.instruments) {
    for (auto& waypoint : instrument.path) waypoint.t /= speed;
  }
  for (auto& object : scene.objects) {
    if (object.isDeformable()) object.tissue.dt *= dt_scale;
  }
  return scene;
}

Run run(const scene::SceneDescription& scene, const std::string& detector, double rate) {
  world::WorldOptions options;
  options.detector_override = detector;
  world::World world(scene, options);
  Run result;
  world.setFrameObserver([&](const world::FrameResult& frame) {
    result.frame_ms.push_back(1e3 * frame.wall_time);
    for (const auto& stage : frame.stages) {
      const double ms = 1e3 * (stage.end - stage.start);
      if (stage.stage.rfind("tissue_", 0) == 0) result.tissue_ms += ms;
      if (stage.stage.rfind("collision_", 0) == 0) result.collision_ms += ms;
      if (stage.stage.rfind("bleeding_", 0) == 0) result.bleeding_ms += ms;
    }
  });
  const double seconds = scene.scriptedDuration() + 0.1;
  const auto inputs = world::scriptedInputs(scene, rate, seconds);
  const auto start = std::chrono::steady_clock::now();
  for (const auto& input : inputs) world.handle(input);
  world.flush();
  result.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  result.sim_s = seconds;
  result.hash = world.stateHash();
  result.max_grasped = world.statistics().max_grasped_nodes;
  const std::string name = world.tissueNames().front();
  const world::TissueReport report = world.tissueReport(name);
  result.outcome = world::toString(report.outcome);
  result.topology = report.topology_version;
  mge::Membrane& membrane = *world.membrane(name);
  result.positions.assign(membrane.positions(), membrane.positions() + membrane.nodeCount());
  return result;
}

double percentile(std::vector<double> values, double fraction) {
  if (values.empty()) return 0.0;
  std::sort(values.begin(), values.end());
  return values[std::min(values.size() - 1, static_cast<std::size_t>(fraction * (values.size() - 1) + 0.5))];
}

}  // namespace

int main(int argc, char** argv) {
  const auto args = bench::parseBenchArgs(argc, argv, "bench/results/world.json");
  if (!args) return 2;
  const bool quick = args->quick;
  const std::string out_path = args->out_path;
  const scene::SceneDescription base = scene::loadScene(scene::shippedScenePath("membrane_peeling"));
  const double rate = 50.0;
  const std::vector<std::string> detectors =
      quick ? std::vector<std::string>{"zcoll_f"} : std::vector<std::string>{"zcoll_f", "geometric", "zcoll_f_gl"};
  const std::vector<double> speeds = quick ? std::vector<double>{1.0} : std::vector<double>{1.0, 4.0};
  std::string rows;
  std::printf("bench_world (%s): membrane_peeling scripted peel through world::World at %.0f Hz\n",
              quick ? "quick" : "full", rate);
  std::printf("%-11s %5s %7s %7s %7s %7s %7s %7s %8s %9s %9s %6s %s\n", "detector", "speed", "frames", "mean_ms",
              "p95_ms", "max_ms", "tissue", "collide", "sim/wall", "err_rms", "err_max", "same#", "outcome");
  for (const std::string& detector : detectors) {
    for (double speed : speeds) {
      const scene::SceneDescription scene = variant(base, speed, 1.0);
      const Run first = run(scene, detector, rate);
      const Run second = run(scene, detector, rate);
      // Converged reference of the same motion: dt / 8 and 8x the input rate.
      const Run reference = quick ? first : run(variant(base, speed, 0.125), detector, 8.0 * rate);
      double error_rms = 0.0, error_max = 0.0;
      const bool comparable =
          reference.topology == first.topology && reference.positions.size() == first.positions.size();
      if (comparable) {
        for (std::size_t i = 0; i < first.positions.size(); ++i) {
          const double e = (first.positions[i] - reference.positions[i]).norm();
          error_rms += e * e;
          error_max = std::max(error_max, e);
        }
        error_rms = std::sqrt(error_rms / std::max<std::size_t>(first.positions.size(), 1));
      }
      const double frames = static_cast<double>(first.frame_ms.size());
      double mean = 0.0;
      for (double ms : first.frame_ms) mean += ms / frames;
      const double p95 = percentile(first.frame_ms, 0.95), max = percentile(first.frame_ms, 1.0);
      const double sim_per_wall = first.sim_s / first.wall_s;
      std::printf("%-11s %5.1f %7zu %7.3f %7.3f %7.3f %7.3f %7.3f %8.1f %9.2e %9.2e %6s %s\n", detector.c_str(), speed,
                  first.frame_ms.size(), mean, p95, max, first.tissue_ms / frames, first.collision_ms / frames,
                  sim_per_wall, comparable ? error_rms : NAN, comparable ? error_max : NAN,
                  first.hash == second.hash ? "yes" : "NO", first.outcome.c_str());
      char row[1024];
      std::snprintf(row, sizeof(row),
                    "{\"suite\":\"world\",\"scene\":\"membrane_peeling\",\"detector\":\"%s\",\"speed\":%.1f,"
                    "\"rate_hz\":%.0f,\"frames\":%zu,\"ms_per_frame\":%.4f,\"p95_ms\":%.4f,\"max_ms\":%.4f,"
                    "\"ms_tissue\":%.4f,\"ms_collision\":%.4f,\"ms_bleeding\":%.4f,"
                    "\"sim_seconds_per_wall_second\":%.2f,\"error_rms_m\":%s,\"error_max_m\":%s,"
                    "\"deterministic\":%s,\"max_grasped_nodes\":%zu,\"outcome\":\"%s\"}",
                    detector.c_str(), speed, rate, first.frame_ms.size(), mean, p95, max, first.tissue_ms / frames,
                    first.collision_ms / frames, first.bleeding_ms / frames, sim_per_wall,
                    comparable && !quick ? std::to_string(error_rms).c_str() : "null",
                    comparable && !quick ? std::to_string(error_max).c_str() : "null",
                    first.hash == second.hash ? "true" : "false", first.max_grasped, first.outcome.c_str());
      rows += (rows.empty() ? "" : ",\n") + std::string(row);
    }
  }
  std::ofstream out(out_path);
  out << "{\"suite\":\"world\",\"command\":\"./scripts/bench.sh" << (quick ? " --quick" : "")
      << " world\",\"quick\":" << (quick ? "true" : "false") << ",\"rows\":[\n"
      << rows << "\n]}\n";
  return out ? 0 : 1;
}
