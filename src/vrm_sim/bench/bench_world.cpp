// The simulation core's frame cost against its accuracy (issue "One simulation core"): a scene's scripted path fed to
// world::World at the device rate, as the graph does, per collision detector and motion speed (the fast case: the
// same path 4x faster). Error: final membrane node positions against a converged reference of the same inputs
// (tissue dt / 8, inputs at 8x the rate). Reports mean / p95 / max ms per frame, the stage split, simulated seconds
// per wall second and whether two runs give the same state hash.
// The mediator's part of a frame (issue 31: device inputs -> input frames -> vrm_msgs/InputFrame): the same inputs
// plus an eye state per tick, delivered in order, with one source lagging a tick, in a 40-tick burst, with a source
// silent for 1 s, and with the eye at 100 Hz; per case ns per input and µs per frame for the mediator alone and for
// filling the published message, and how far the frames are from the in-order assembly (frames whose inputs differ,
// late inputs, frames without a source) — the error the reordering costs.
// Usage: bench_world [--quick] [--out FILE]
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "bench_cli.h"
#include "vrm_scene/scene_loader.h"
#include "vrm_sim/conversions.h"
#include "vrm_sim/mge/membrane.h"
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

// ---- the mediator ----

struct Delivery {
  std::optional<world::EyeState> eye;
  std::optional<world::InstrumentState> instrument;
};

// The device inputs of `scene`'s scripted path at `rate`, with an eye state per tick (at eye_rate), in the order the
// case delivers them.
std::vector<Delivery> deliveries(const scene::SceneDescription& scene, double rate, double eye_rate,
                                 const std::string& pattern) {
  const double seconds = scene.scriptedDuration() + 0.1;
  std::vector<std::vector<Delivery>> eye_ticks, instrument_ticks;
  const world::Stamp period = world::fromSeconds(1.0 / rate), eye_period = world::fromSeconds(1.0 / eye_rate);
  const auto instruments = world::scriptedInputs(scene, rate, seconds);
  const world::Stamp end = instruments.empty() ? 0 : instruments.back().stamp;
  // One list of deliveries per instrument tick; the eye's ticks fall into the instrument tick at or after them.
  const std::size_t ticks = static_cast<std::size_t>(end / period) + 1;
  eye_ticks.resize(ticks);
  instrument_ticks.resize(ticks);
  for (world::Stamp t = 0; t <= end; t += eye_period) {
    world::EyeState eye;
    eye.stamp = t;
    eye.rotation_center = Eigen::Vector3d(0.0, 0.0, 0.03);
    eye_ticks[std::min<std::size_t>(ticks - 1, (t + period - 1) / period)].push_back({eye, std::nullopt});
  }
  for (const auto& input : instruments) {
    instrument_ticks[std::min<std::size_t>(ticks - 1, input.stamp / period)].push_back({std::nullopt, input});
  }
  const std::size_t silent_from = ticks / 2, silent_to = ticks / 2 + static_cast<std::size_t>(rate);
  std::vector<Delivery> order;
  if (pattern == "burst") {
    // The simulation node was blocked: 40 ticks of eye states wait in the queue before the instruments' 40.
    for (std::size_t first = 0; first < ticks; first += 40) {
      for (std::size_t k = first; k < std::min(ticks, first + 40); ++k) {
        order.insert(order.end(), eye_ticks[k].begin(), eye_ticks[k].end());
      }
      for (std::size_t k = first; k < std::min(ticks, first + 40); ++k) {
        order.insert(order.end(), instrument_ticks[k].begin(), instrument_ticks[k].end());
      }
    }
    return order;
  }
  for (std::size_t k = 0; k < ticks; ++k) {
    order.insert(order.end(), eye_ticks[k].begin(), eye_ticks[k].end());
    if (pattern == "lag_1_tick") {
      if (k > 0) order.insert(order.end(), instrument_ticks[k - 1].begin(), instrument_ticks[k - 1].end());
      if (k + 1 == ticks) order.insert(order.end(), instrument_ticks[k].begin(), instrument_ticks[k].end());
      continue;
    }
    for (const Delivery& delivery : instrument_ticks[k]) {
      if (pattern == "silent_1s" && k >= silent_from && k < silent_to && delivery.instrument->slot == "right") {
        continue;
      }
      order.push_back(delivery);
    }
  }
  return order;
}

struct MediatorRun {
  std::vector<world::InputFrame> frames;
  double mediator_s = 0.0, message_s = 0.0;
  std::size_t inputs = 0;
  world::MediatorStatistics statistics;
};

MediatorRun runMediator(const std::vector<Delivery>& order, int repeats) {
  MediatorRun result;
  for (int repeat = 0; repeat < repeats; ++repeat) {
    std::vector<world::InputFrame> frames;
    frames.reserve(order.size());
    world::Mediator mediator({}, [&frames](world::InputFrame& frame) { frames.push_back(frame); });
    const auto start = std::chrono::steady_clock::now();
    for (const Delivery& delivery : order) {
      if (delivery.eye) mediator.handle(*delivery.eye);
      if (delivery.instrument) mediator.handle(*delivery.instrument);
    }
    mediator.flush();
    result.mediator_s += std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    // The message the simulation node fills and publishes per frame (the World's applied slots included).
    vrm_msgs::InputFrame message;
    const auto fill_start = std::chrono::steady_clock::now();
    for (world::InputFrame& frame : frames) {
      frame.instruments.resize(2);
      fillInputFrame(frame, "world", "eye", message);
    }
    result.message_s += std::chrono::duration<double>(std::chrono::steady_clock::now() - fill_start).count();
    result.statistics = mediator.statistics();
    result.frames = std::move(frames);
  }
  result.mediator_s /= repeats;
  result.message_s /= repeats;
  result.inputs = order.size();
  return result;
}

// Frames whose inputs differ from the reference assembly (the in-order delivery of the same inputs).
std::size_t framesThatDiffer(const MediatorRun& run, const MediatorRun& reference) {
  std::map<world::Stamp, const world::InputFrame*> by_stamp;
  for (const world::InputFrame& frame : reference.frames) {
    if (frame.kind == world::InputFrame::Kind::kFrame) by_stamp[frame.stamp] = &frame;
  }
  std::size_t differ = 0;
  for (const world::InputFrame& frame : run.frames) {
    if (frame.kind != world::InputFrame::Kind::kFrame) continue;
    const auto match = by_stamp.find(frame.stamp);
    if (match == by_stamp.end() || match->second->eye_inputs.size() != frame.eye_inputs.size() ||
        match->second->instrument_inputs.size() != frame.instrument_inputs.size()) {
      ++differ;
      continue;
    }
    for (std::size_t i = 0; i < frame.instrument_inputs.size(); ++i) {
      if (frame.instrument_inputs[i].stamp != match->second->instrument_inputs[i].stamp ||
          frame.instrument_inputs[i].slot != match->second->instrument_inputs[i].slot) {
        ++differ;
        break;
      }
    }
  }
  return differ;
}

std::string benchMediator(const scene::SceneDescription& scene, bool quick) {
  const int repeats = quick ? 3 : 30;
  std::printf("\nmediator: membrane_peeling's scripted inputs + eye states, %d repeats per case\n", repeats);
  std::printf("%-11s %7s %7s %9s %9s %9s %7s %7s %9s\n", "case", "inputs", "frames", "ns/input", "us/frame",
              "msg_us/fr", "late", "w/o_src", "differ");
  const std::vector<std::string> cases = {"in_order", "lag_1_tick", "burst", "silent_1s", "eye_100hz"};
  const MediatorRun reference = runMediator(deliveries(scene, 50.0, 50.0, "in_order"), 1);
  std::string rows;
  for (const std::string& name : cases) {
    const double eye_rate = name == "eye_100hz" ? 100.0 : 50.0;
    const MediatorRun run = runMediator(deliveries(scene, 50.0, eye_rate, name), repeats);
    std::size_t frames = 0;
    for (const auto& frame : run.frames) frames += frame.kind == world::InputFrame::Kind::kFrame;
    const double ns_per_input = 1e9 * run.mediator_s / std::max<std::size_t>(run.inputs, 1);
    const double us_per_frame = 1e6 * run.mediator_s / std::max<std::size_t>(frames, 1);
    const double message_us = 1e6 * run.message_s / std::max<std::size_t>(run.frames.size(), 1);
    // At 100 Hz the eye has stamps of its own: frames there are not comparable with the 50 Hz reference.
    const std::string differ = name == "eye_100hz" ? "null" : std::to_string(framesThatDiffer(run, reference));
    std::printf("%-11s %7zu %7zu %9.1f %9.2f %9.2f %7lu %7lu %9s\n", name.c_str(), run.inputs, frames, ns_per_input,
                us_per_frame, message_us, static_cast<unsigned long>(run.statistics.late_inputs),
                static_cast<unsigned long>(run.statistics.frames_without_source), differ.c_str());
    char row[768];
    std::snprintf(row, sizeof(row),
                  "{\"suite\":\"world\",\"part\":\"mediator\",\"case\":\"%s\",\"inputs\":%zu,\"frames\":%zu,"
                  "\"ns_per_input\":%.2f,\"us_per_frame\":%.3f,\"message_fill_us_per_frame\":%.3f,"
                  "\"late_inputs\":%lu,\"frames_without_source\":%lu,\"frames_differing_from_in_order\":%s,"
                  "\"repeats\":%d}",
                  name.c_str(), run.inputs, frames, ns_per_input, us_per_frame, message_us,
                  static_cast<unsigned long>(run.statistics.late_inputs),
                  static_cast<unsigned long>(run.statistics.frames_without_source), differ.c_str(), repeats);
    rows += (rows.empty() ? "" : ",\n") + std::string(row);
  }
  return rows;
}

}  // namespace

int main(int argc, char** argv) {
  bench::BenchArgs args;
  if (const auto status = bench::parseBenchArgs(argc, argv, "bench_world",
                                                "The simulation core's frame cost against its accuracy per detector.",
                                                "bench/results/world.json", &args)) {
    return *status;
  }
  const bool quick = args.quick;
  const std::string out_path = args.out_path;
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
  rows += ",\n" + benchMediator(base, quick);
  std::ofstream out(out_path);
  out << "{\"suite\":\"world\",\"command\":\"./scripts/bench.sh" << (quick ? " --quick" : "")
      << " world\",\"quick\":" << (quick ? "true" : "false") << ",\"rows\":[\n"
      << rows << "\n]}\n";
  return out ? 0 : 1;
}
