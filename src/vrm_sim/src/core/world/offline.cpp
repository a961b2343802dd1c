#include "vrm_sim/world/offline.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <map>
#include <sstream>
#include <stdexcept>

#include "vrm_scene/instrument_model.h"
#include "vrm_scene/scene_loader.h"
#include "vrm_scene/surface_target.h"
#include "vrm_sim/mge/membrane.h"
#include "vrm_sim/tissue/integrator.h"
#include "vrm_sim/tissue/tissue_simulator.h"
#include "vrm_sim/world/instrument_shapes.h"
#include "vrm_sim/world/session_result.h"

namespace vrm_sim {
namespace world {

namespace {

// SplitMix64 (Steele et al. 2014): a fixed, portable generator, so a seed means the same offsets everywhere.
std::uint64_t splitMix64(std::uint64_t& state) {
  std::uint64_t z = (state += 0x9e3779b97f4a7c15ull);
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
  return z ^ (z >> 31);
}

// In [-1, 1), from the top 53 bits.
double symmetricUnit(std::uint64_t& state) {
  return static_cast<double>(splitMix64(state) >> 11) * (2.0 / 9007199254740992.0) - 1.0;
}

std::string number(double value) {
  if (!std::isfinite(value)) return "null";
  std::ostringstream out;
  out.precision(9);
  out << value;
  return out.str();
}

}  // namespace

std::string jsonString(const std::string& text) {
  std::string out = "\"";
  for (char c : text) {
    if (c == '"' || c == '\\') {
      out += '\\';
      out += c;
    } else if (static_cast<unsigned char>(c) < 0x20) {
      char escaped[8];
      std::snprintf(escaped, sizeof(escaped), "\\u%04x", c);
      out += escaped;
    } else {
      out += c;
    }
  }
  return out + "\"";
}

std::string hashString(std::uint64_t hash) {
  char text[24];
  std::snprintf(text, sizeof(text), "0x%016llx", static_cast<unsigned long long>(hash));
  return text;
}

std::string OfflineResult::json() const {
  std::ostringstream out;
  out << "{\"stable\": " << (stable ? "true" : "false") << ", \"frames\": " << frames << ", \"steps\": " << steps
      << ", \"ms_per_step\": " << number(ms_per_step) << ", \"ms_per_frame\": " << number(ms_per_frame)
      << ", \"ms_per_frame_max\": " << number(ms_per_frame_max) << ", \"max_strain\": " << number(max_strain)
      << ", \"max_grasped_nodes\": " << max_grasped_nodes << ", \"energy_drift\": " << number(energy_drift)
      << ", \"fallbacks\": " << fallbacks << ", \"retina_contacts\": " << retina_contacts
      << ", \"max_injury\": " << number(max_injury) << ", \"integrator_chosen\": [";
  for (std::size_t i = 0; i < integrator_chosen.size(); ++i) {
    out << (i ? ", " : "") << jsonString(integrator_chosen[i]);
  }
  out << "], \"tissues\": [";
  for (std::size_t i = 0; i < tissues.size(); ++i) {
    const OfflineTissueResult& t = tissues[i];
    out << (i ? ", " : "") << "{\"object\": \"" << t.object << "\", \"outcome\": \"" << toString(t.outcome)
        << "\", \"torn_springs\": " << t.torn_springs << ", \"released_adhesions\": " << t.released_adhesions
        << ", \"topology_version\": " << t.topology_version << ", \"max_lift\": " << number(t.max_lift) << "}";
  }
  out << "], \"final_state_hash\": \"" << hashString(final_state_hash) << "\"}";
  return out.str();
}

std::vector<InstrumentState> scriptedInputsAt(const scene::SceneDescription& scene, double t, Stamp stamp) {
  std::vector<InstrumentState> inputs;
  for (const auto& instrument : scene.instruments) {
    if (instrument.path.empty()) continue;
    const tissue::InstrumentInput scripted = scriptedInstrument(scene, instrument, t);
    InstrumentState state;
    state.stamp = stamp;
    state.slot = scene::toString(instrument.slot);
    state.type = instrument.type;
    state.setPose(scripted.pose);
    state.frame_id = "eye";
    state.jaw_angle = scripted.jaw_angle;
    const scene::InstrumentWaypoint sample = scene::samplePath(instrument.path, t);
    if (sample.type) state.type = *sample.type;  // an exchange scripted along the path
    state.suction = sample.suction;
    state.cut_rate = sample.cut_rate_hz;
    state.injection_flow = sample.injection_flow;
    inputs.push_back(state);
  }
  return inputs;
}

std::vector<InstrumentState> scriptedInputs(const scene::SceneDescription& scene, double rate, double seconds,
                                            Stamp start) {
  if (!(rate > 0.0) || !std::isfinite(rate)) throw std::invalid_argument("scriptedInputs: rate must be positive");
  if (!(seconds >= 0.0) || !std::isfinite(seconds)) {
    throw std::invalid_argument("scriptedInputs: seconds must be a non-negative number");
  }
  std::vector<InstrumentState> inputs;
  const long ticks = std::lround(seconds * rate);
  for (long tick = 0; tick <= ticks; ++tick) {
    const double t = static_cast<double>(tick) / rate;
    for (InstrumentState& state : scriptedInputsAt(scene, t, start + fromSeconds(t))) inputs.push_back(state);
  }
  return inputs;
}

OfflineResult runOffline(const scene::SceneDescription& scene_in, const OfflineOptions& options) {
  if (!(options.seconds >= 0.0) || !std::isfinite(options.seconds)) {
    throw std::invalid_argument("tissue_offline: --seconds must be a non-negative number");
  }
  if (!(options.dt >= 0.0) || !std::isfinite(options.dt)) {
    throw std::invalid_argument("tissue_offline: --dt must be positive (or 0 for the scene's)");
  }
  if (!(options.rate > 0.0) || !std::isfinite(options.rate)) {
    throw std::invalid_argument("tissue_offline: --rate must be positive");
  }
  if (!options.integrator.empty()) {
    // The names a scene's `tissue.integrator` accepts ("auto" and the integrators).
    if (!tissue::integratorRegistry().contains(options.integrator)) {
      throw std::invalid_argument("tissue_offline: unknown integrator '" + options.integrator +
                                  "' (known: " + tissue::integratorRegistry().namesJoined() + ")");
    }
  }
  scene::SceneDescription scene = scene_in;
  for (auto& object : scene.objects) {
    if (!object.isDeformable()) continue;
    if (!options.integrator.empty()) object.tissue.integrator = options.integrator;
    if (options.dt > 0.0) object.tissue.dt = options.dt;
  }
  if (!scene.hasDeformableObjects()) {
    scene::SourceLocation where;
    where.file = scene.source_file;
    throw scene::SceneError(where, "the scene has no deformable object to simulate");
  }
  WorldOptions world_options;
  world_options.detector_override = options.detector;
  World world(scene, world_options);

  std::uint64_t seed_state = options.seed;
  std::vector<double> energy_start;
  for (const std::string& name : world.tissueNames()) {
    mge::Membrane& membrane = *world.membrane(name);
    if (options.seed != 0) {
      Eigen::Vector3d* x = membrane.positions();
      const std::uint8_t* fixed = membrane.fixedFlags();
      for (std::size_t i = 0; i < membrane.nodeCount(); ++i) {
        const Eigen::Vector3d offset(symmetricUnit(seed_state), symmetricUnit(seed_state), symmetricUnit(seed_state));
        if (!fixed[i]) x[i] += 1e-6 * offset;
      }
    }
    energy_start.push_back(world.tissueSimulator(name)->totalEnergy());
  }

  OfflineResult result;
  double tissue_wall = 0.0;
  world.setFrameObserver([&](const FrameResult& frame) {
    for (const StageTime& stage : frame.stages) {
      if (stage.stage.rfind("tissue_", 0) == 0) tissue_wall += stage.end - stage.start;
    }
  });
  for (const InstrumentState& input : scriptedInputs(scene, options.rate, options.seconds)) world.handle(input);
  world.flush();

  const WorldStatistics& statistics = world.statistics();
  result.frames = statistics.frames;
  result.steps = statistics.tissue_steps;
  result.max_strain = statistics.max_strain;
  result.max_grasped_nodes = statistics.max_grasped_nodes;
  result.ms_per_frame = statistics.frames > 0 ? 1e3 * statistics.total_frame_wall_time / statistics.frames : 0.0;
  result.ms_per_frame_max = 1e3 * statistics.max_frame_wall_time;
  result.ms_per_step = result.steps > 0 ? 1e3 * tissue_wall / static_cast<double>(result.steps) : 0.0;
  std::size_t index = 0;
  for (const std::string& name : world.tissueNames()) {
    tissue::TissueSimulator& simulator = *world.tissueSimulator(name);
    mge::Membrane& membrane = *world.membrane(name);
    const tissue::SimulatorStatistics& stats = simulator.statistics();
    result.fallbacks += stats.fallbacks;
    result.integrator_chosen.push_back(name + ": " + simulator.integratorLabel());
    bool finite = true;
    for (std::size_t i = 0; i < membrane.nodeCount(); ++i) {
      finite = finite && membrane.positions()[i].allFinite() && membrane.velocities()[i].allFinite();
    }
    result.stable = result.stable && finite && stats.unrecovered == 0;
    result.energy_drift += simulator.totalEnergy() - energy_start[index++];
    const TissueReport report = world.tissueReport(name);
    result.tissues.push_back({name, report.topology_version, report.torn_springs, report.released_adhesions,
                              report.max_lift, report.outcome});
  }
  for (const InjuryReport& injury : world.injuries()) {
    result.retina_contacts += injury.contacts;
    result.max_injury = std::max(result.max_injury, injury.max_injury);
  }
  result.final_state_hash = world.stateHash();
  return result;
}

std::string ScenarioRunResult::json() const {
  const auto quoted = jsonString;
  std::ostringstream out;
  out << "{\"scenario\": " << quoted(scenario) << ", \"type\": " << quoted(type)
      << ", \"difficulty\": " << quoted(difficulty) << ", \"script\": " << quoted(script) << ", \"seed\": " << seed
      << ", \"state\": " << quoted(state) << ", \"message\": " << quoted(message)
      << ", \"total\": " << number(score.total) << ", \"items\": {";
  for (std::size_t i = 0; i < score.items.size(); ++i) {
    out << (i ? ", " : "") << quoted(score.items[i].name) << ": " << number(score.items[i].value);
  }
  out << "}, \"points\": {";
  bool first = true;
  for (const scenario::ScoreItem& item : score.items) {
    if (!(item.weight > 0.0)) continue;
    out << (first ? "" : ", ") << quoted(item.name) << ": " << number(item.points);
    first = false;
  }
  out << "}, \"final_state_hash\": \"" << hashString(final_state_hash) << "\", \"frames\": " << frames
      << ", \"sim_seconds\": " << number(sim_seconds) << ", \"wall_seconds\": " << number(wall_seconds)
      << ", \"ms_per_frame\": " << number(ms_per_frame) << ", \"ms_per_frame_max\": " << number(ms_per_frame_max)
      << ", \"ms_scenario\": " << number(ms_scenario) << ", \"ms_tissue\": " << number(ms_tissue)
      << ", \"ms_collision\": " << number(ms_collision) << ", \"ms_bleeding\": " << number(ms_bleeding)
      << ", \"simulations\": [";
  for (std::size_t i = 0; i < simulations.size(); ++i) out << (i ? ", " : "") << quoted(simulations[i]);
  out << "]";
  if (session_result) {
    std::string text = result::toJson(*session_result);
    while (!text.empty() && text.back() == '\n') text.pop_back();
    out << ", \"result\": " << text;
  }
  out << "}";
  return out.str();
}

ScenarioRunResult runScenario(const scene::SceneDescription& scene, const ScenarioRunOptions& options) {
  if (!scene.scenario) {
    scene::SourceLocation where;
    where.file = scene.source_file;
    throw scene::SceneError(where, "the scene '" + scene.name + "' has no scenario section");
  }
  if (!(options.rate > 0.0) || !std::isfinite(options.rate)) throw std::invalid_argument("--rate must be positive");
  if (!(options.grace >= 0.0) || !std::isfinite(options.grace)) {
    throw std::invalid_argument("grace must be a non-negative number");
  }
  const scene::SceneDescription scripted =
      options.script_file ? scene::withScript(scene, scene::resolveSurfaceTargets(scene, *options.script_file))
                          : scene::withScript(scene, options.script);
  WorldOptions world_options;
  world_options.detector_override = options.detector;
  world_options.auto_start = true;
  World world(scripted, world_options);

  ScenarioRunResult result;
  result.scenario = scene.name;
  result.type = scene.scenario->type;
  result.difficulty = scene.scenario->difficulty;
  result.script = options.script_file ? "file" : options.script;
  result.seed = options.seed;
  std::map<std::string, double> stage_ms;
  world.setFrameObserver([&](const FrameResult& frame) {
    for (const StageTime& stage : frame.stages) {
      const std::string kind = stage.stage.substr(0, stage.stage.find('_'));
      stage_ms[kind] += 1e3 * (stage.end - stage.start);
    }
  });
  // The session's pedal track (issue 37: the laser fires on the pedal); the instruments' paths are in `scripted`.
  const std::vector<scene::PedalWaypoint>& pedals =
      options.script_file ? options.script_file->pedals : scene::findScript(scene, options.script).pedals;
  const auto wall_start = std::chrono::steady_clock::now();
  const double seconds = std::max(scripted.scriptedDuration(), pedals.empty() ? 0.0 : pedals.back().t) + options.grace;
  const long ticks = std::lround(seconds * options.rate);
  for (long tick = 0; tick <= ticks; ++tick) {
    const double t = static_cast<double>(tick) / options.rate;
    // One tick at a time (scriptedInputs of [t, t]), so a long session never holds all its inputs at once.
    for (const InstrumentState& input : scriptedInputsAt(scripted, t, fromSeconds(t))) world.handle(input);
    if (!pedals.empty()) {
      const scene::PedalWaypoint sample = scene::samplePedals(pedals, t);
      PedalState pedal;
      pedal.stamp = fromSeconds(t);
      pedal.travel = sample.travel;
      pedal.reflux = sample.reflux;
      pedal.instrument_switch = sample.instrument_switch;
      pedal.zoom_in = sample.zoom_in;
      pedal.zoom_out = sample.zoom_out;
      pedal.focus_near = sample.focus_near;
      pedal.focus_far = sample.focus_far;
      world.handle(pedal);
    }
    world.flush();
    if (world.scenarioStatus()->state == scenario::State::kFinished ||
        world.scenarioStatus()->state == scenario::State::kFailed) {
      break;
    }
  }
  result.wall_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - wall_start).count();
  const scenario::Status& status = *world.scenarioStatus();
  result.state =
      status.timed_out || status.state == scenario::State::kRunning ? "timeout" : scenario::toString(status.state);
  result.message =
      status.state == scenario::State::kRunning ? "the script ended without completing the task" : status.message;
  result.score = status.score;
  result.sim_seconds = status.elapsed;
  result.frames = world.statistics().frames;
  result.final_state_hash = world.stateHash();
  const double frames = static_cast<double>(std::max<std::uint64_t>(result.frames, 1));
  result.ms_per_frame = 1e3 * world.statistics().total_frame_wall_time / frames;
  result.ms_per_frame_max = 1e3 * world.statistics().max_frame_wall_time;
  auto stage = [&stage_ms, frames](const char* kind) {
    const auto found = stage_ms.find(kind);
    return found == stage_ms.end() ? 0.0 : found->second / frames;
  };
  result.ms_scenario = stage("scenario");
  result.ms_tissue = stage("tissue");
  result.ms_collision = stage("collision");
  result.ms_bleeding = stage("bleeding");
  for (const char* kind : {"tissue", "collision", "bleeding", "scenario"}) {
    if (stage_ms.count(kind) > 0) result.simulations.push_back(kind);
  }
  ResultContext context;
  context.seed = options.seed;
  result.session_result = sessionResult(world, context);
  return result;
}

}  // namespace world
}  // namespace vrm_sim
