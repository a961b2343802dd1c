#include "vrm_sim/world/world.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <limits>
#include <map>
#include <unordered_map>
#include <variant>

#include "vrm_scene/hash.h"
#include "vrm_scene/instrument_model.h"
#include "vrm_scene/meshes/instrument_meshes.h"
#include "vrm_scene/scene_loader.h"
#include "vrm_sim/mge/membrane.h"
#include "vrm_sim/tissue/tissue_simulator.h"
#include "vrm_sim/world/instrument_shapes.h"
#include "vrm_sim/world/tissue_setup.h"

namespace vrm_sim {
namespace world {

namespace {

constexpr double kLiftThreshold = 1e-4;         // m: a node this far from its rest position counts as lifted
constexpr double kPeelLift = 5e-4;              // m: a grasped membrane lifted this far is peeling
constexpr std::uint64_t kLogEveryFrames = 250;  // a repeated message at most every ~5 s at 50 Hz

// The detectors whose deformation vectors drive the tissue response (thesis §4.2.2); the others report only and the
// tissue's own exact capsule test is the response.

}  // namespace

const char* toString(PeelOutcome outcome) {
  switch (outcome) {
    case PeelOutcome::kUntouched:
      return "untouched";
    case PeelOutcome::kGrasped:
      return "grasped";
    case PeelOutcome::kLifted:
      return "lifted";
    case PeelOutcome::kTorn:
      return "torn";
  }
  return "?";
}

MediatorOptions mediatorOptionsFor(const scene::SceneDescription& scene, const WorldOptions& options) {
  MediatorOptions mediator;
  mediator.max_stamp_jump = options.max_stamp_jump;
  mediator.log = options.log;
  for (const auto& instrument : scene.instruments) mediator.slots.insert(scene::toString(instrument.slot));
  return mediator;
}

struct World::Instrument {
  const scene::InstrumentDescription* description = nullptr;
  scene::InstrumentDescription current;                    // the type in use (the scene's or one of its alternatives)
  tissue::InstrumentInput shape;                           // capsule and grasping parameters; pose filled per object
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();  // in frame_id
  std::string frame_id = "eye";
  bool active = false;
  double jaw_angle = 1.0;
  double suction = 0.0;
  double cut_rate = 0.0;
  double injection_flow = 0.0;  // m^3/s
  bool cutting = false;         // vitrector with suction and cutter running
  collision::InstrumentModel model;
  int model_jaw_deg = -1000;  // whole degrees, so tracking noise does not invalidate cached depth images
  std::uint64_t model_version = 0;
};

// One object the instruments are tested against, with a detector per instrument (detectors cache the instrument's
// depth image / BVH, thesis Alg. 4.2 line 4).
struct World::Collider {
  std::string object;
  std::string frame_id;
  std::string detector_name;
  bool produces_deformations = false;  // the detector's deformation vectors are the tissue's response
  collision::CollisionOptions options;
  struct PerInstrument {
    std::unique_ptr<collision::CollisionDetector> detector;
    std::uint64_t model_version = 0;
    std::optional<Eigen::Vector3d> last_tip;  // for the instrument velocity of eq. 5.12
  };
  std::map<std::string, PerInstrument> instruments;
};

struct World::Tissue {
  const scene::ObjectDescription* object = nullptr;
  std::unique_ptr<mge::Membrane> membrane;
  std::unique_ptr<tissue::TissueSimulator> simulator;
  std::string frame_id;
  std::optional<Collider> collider;
  bool detector_response = false;
  std::vector<Eigen::Vector3d> last_positions;
  std::unordered_map<std::uint64_t, Eigen::Vector3d> rest_by_id;
  std::vector<Eigen::Vector3d> rest_by_slot;  // NaN for nodes born after the start (refinement)
  std::uint64_t rest_topology = 0;
  TissueReport report;
  bool ever_grasped = false;
  double peak_lift = 0.0;
  bool peels = false;         // membrane / ILM
  bool reset_pending = true;  // rebuilt (start, RESET): the next frame publishes it even if nothing moves
  std::uint64_t logged_integrator_choice = 0;  // TissueSimulator::integratorChoiceChanges() already logged
  // Subretinal fluid and the needle's puncture (scene tissue fluid_modulus, needle_pierce_radius).
  double fluid_volume = 0.0;                        // m^3 under the sheet
  double injected_outside = 0.0;                    // m^3 the needle injected with its tip not behind the sheet
  std::map<std::string, bool> needle_inside;        // per slot: the needle's tip is behind the sheet
  std::map<std::string, Eigen::Vector3d> puncture;  // per slot inside: where its shaft last settled in the sheet
};

struct World::RigidObject {
  const scene::ObjectDescription* object = nullptr;
  TriangleMesh mesh;
  Collider collider;
  std::unique_ptr<BleedingField> bleeding;  // the retina when the scene simulates bleeding
  std::vector<double> vertex_areas;         // m^2 per vertex (a third of each adjacent triangle), for injured_area
  InjuryReport report;
  // Where the scenario has moved the object (scenario::ObjectPlacement), as a displacement of its scene pose in its
  // frame: the collider keeps the mesh where the scene put it and sees the instruments displaced inversely.
  Eigen::Isometry3d moved = Eigen::Isometry3d::Identity();
};

World::World(scene::SceneDescription scene, WorldOptions options)
    : scene_(std::move(scene)),
      options_(std::move(options)),
      mediator_(mediatorOptionsFor(scene_, options_), [this](InputFrame& frame) { apply(frame); }) {
  if (!options_.clock) {
    options_.clock = [] {
      return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
    };
  }
  if (!(options_.max_frame_time > 0.0)) throw std::invalid_argument("world: max_frame_time must be positive");
  checkSimulationNames(scene_);
  started_ = options_.auto_start;
  buildInstruments();
  buildTissues();
  buildRigidObjects();
  if (scene_.scenario) runner_ = std::make_unique<scenario::ScenarioRunner>(scene_);
}

World::~World() = default;

double World::now() const { return options_.clock(); }

void World::log(Severity severity, const std::string& key, const std::string& message) {
  if (!options_.log) return;
  if (!key.empty()) {
    auto last = logged_at_frame_.find(key);
    if (last != logged_at_frame_.end() && statistics_.frames < last->second + kLogEveryFrames) return;
    logged_at_frame_[key] = statistics_.frames;
  }
  options_.log(severity, message);
}

bool World::simulatesAnything() const {
  if (!tissues_.empty() || runner_) return true;
  return !rigid_.empty();
}

bool World::simulating() const {
  if (paused_ || !running_) return false;
  return runner_ ? runner_->status().state == scenario::State::kRunning : started_;
}

bool World::sessionEnded() const {
  if (!runner_) return !running_;
  const scenario::State state = runner_->status().state;
  return state == scenario::State::kFinished || state == scenario::State::kFailed;
}

std::optional<World::Collider> World::makeCollider(const scene::ObjectDescription& object) const {
  const std::string name = options_.detector_override.empty() ? object.collision.detector : options_.detector_override;
  if (name == "none") return std::nullopt;
  Collider collider;
  collider.object = object.name;
  collider.frame_id = object.frame == scene::ObjectFrame::kEye ? "eye" : "world";
  collider.detector_name = name;
  collider.options.resolution = object.collision.resolution;
  collider.options.max_pixel_size = options_.collision_max_pixel_size;
  // Throws for an unknown name (the loader checks the scene's names; detector_override is the caller's).
  collider.produces_deformations = collision::makeCollisionDetector(name)->producesDeformations();
  return collider;
}

void World::buildInstruments() {
  for (const auto& description : scene_.instruments) {
    auto instrument = std::make_unique<Instrument>();
    instrument->description = &description;
    setInstrumentType(*instrument, description.type);
    instruments_[scene::toString(description.slot)] = std::move(instrument);
  }
}

// The slot's shape for `type`: the scene's parameters for its declared type, the generator defaults for an
// alternative. The collision model is rebuilt on the next query.
void World::setInstrumentType(Instrument& instrument, scene::InstrumentType type) {
  instrument.current = scene::instrumentOfType(*instrument.description, type);
  instrument.shape = tissueShape(instrument.current);
  instrument.model_version = 0;  // collide() rebuilds the collision model before the next query
  instrument.model_jaw_deg = -1000;
}

// Instrument switching (thesis §7: the trainee changes instruments in a trocar): the scene lists which types a slot
// may take; any other type keeps the current one.
bool World::switchInstrument(Instrument& instrument, scene::InstrumentType type) {
  if (type == instrument.current.type) return true;
  const std::string slot = scene::toString(instrument.description->slot);
  if (!scene::allowsType(*instrument.description, type)) {
    log(Severity::kWarning, "switch:" + slot,
        "instrument '" + slot + "': type " + scene::toString(type) +
            " is not allowed in this slot by the scene; keeping " + scene::toString(instrument.current.type));
    return false;
  }
  // An instrument that holds tissue cannot leave its trocar: the switch waits until the jaws let go (the frame
  // says which type is in use, so the view shows the forceps that still holds the membrane).
  const std::size_t index = static_cast<std::size_t>(std::distance(instruments_.begin(), instruments_.find(slot)));
  for (const auto& [name, tissue] : tissues_) {
    if (tissue->simulator && tissue->simulator->isGrasping(index)) {
      log(Severity::kWarning, "switch-grasp:" + slot,
          "instrument '" + slot + "' holds " + name + ": switching to " + scene::toString(type) +
              " refused until it lets go");
      return false;
    }
  }
  log(Severity::kInfo, "", "instrument '" + slot + "' switched to " + scene::toString(type));
  setInstrumentType(instrument, type);
  return true;
}

void World::buildTissues() {
  if (!scene_.simulates(scene::Simulation::kTissue)) return;
  for (const auto& object : scene_.objects) {
    if (!object.isDeformable()) continue;
    auto tissue = std::make_unique<Tissue>();
    tissue->object = &object;
    tissue->frame_id = object.frame == scene::ObjectFrame::kEye ? "eye" : "world";
    tissue->peels = object.role == scene::ObjectRole::kMembrane || object.role == scene::ObjectRole::kIlm;
    if (scene_.simulates(scene::Simulation::kCollision)) tissue->collider = makeCollider(object);
    tissue->detector_response = tissue->collider && tissue->collider->produces_deformations;
    tissues_[object.name] = std::move(tissue);
  }
  resetTissues();
}

// (Re)builds every tissue in its rest state (start and ScenarioCommand RESET).
void World::resetTissues() {
  for (auto& [name, tissue] : tissues_) {
    const scene::ObjectDescription& object = *tissue->object;
    const TriangleMesh mesh = scene::buildMesh(object, scene::MeshFrame::kParent);
    tissue->simulator.reset();
    tissue->membrane = mge::buildMembrane(mesh, membraneOptionsFor(object.tissue, mesh.vertexCount()));
    tissue::TissueConfig config = tissueConfigFor(object.tissue, object.collision);
    if (config.fluid_modulus > 0.0) {
      // The fluid fills the space between the sheet and the wall it rests on: the sphere through its rest nodes.
      double radius = 0.0;
      for (const Eigen::Vector3d& vertex : mesh.vertices) radius += vertex.norm();
      config.fluid_wall_radius = mesh.vertices.empty() ? 0.0 : radius / static_cast<double>(mesh.vertices.size());
    }
    // A frame covers at most max_frame_time: every step of it must run (deterministic frames).
    config.max_steps_per_frame =
        std::max(config.max_steps_per_frame, static_cast<int>(std::ceil(options_.max_frame_time / config.dt)) + 1);
    try {
      tissue->simulator = std::make_unique<tissue::TissueSimulator>(*tissue->membrane, config);
    } catch (const std::invalid_argument& error) {
      throw scene::SceneError(object.location, error.what());
    }
    const std::size_t n = tissue->membrane->nodeCount();
    tissue->last_positions.assign(tissue->membrane->positions(), tissue->membrane->positions() + n);
    tissue->rest_by_id.clear();
    for (std::size_t i = 0; i < n; ++i) {
      tissue->rest_by_id[tissue->membrane->nodeAtSlot(i).id()] = tissue->membrane->positions()[i];
    }
    tissue->rest_by_slot = tissue->last_positions;
    tissue->rest_topology = 1;
    const std::uint64_t version = tissue->report.version;
    tissue->report = TissueReport{};
    tissue->report.object = name;
    tissue->report.frame_id = tissue->frame_id;
    tissue->report.membrane = tissue->membrane.get();
    tissue->report.version = version;
    tissue->reset_pending = true;
    tissue->ever_grasped = false;
    tissue->peak_lift = 0.0;
    tissue->fluid_volume = 0.0;
    tissue->injected_outside = 0.0;
    tissue->needle_inside.clear();
    tissue->puncture.clear();
  }
}

void World::buildRigidObjects() {
  if (!scene_.simulates(scene::Simulation::kCollision)) return;
  for (const auto& object : scene_.objects) {
    if (object.isDeformable()) continue;
    std::optional<Collider> collider = makeCollider(object);
    if (!collider) continue;
    auto rigid = std::make_unique<RigidObject>();
    rigid->object = &object;
    rigid->mesh = scene::buildMesh(object, scene::MeshFrame::kParent);
    rigid->collider = std::move(*collider);
    if (object.role == scene::ObjectRole::kRetina && scene_.simulates(scene::Simulation::kBleeding)) {
      std::vector<Eigen::Vector3d> vertices(rigid->mesh.vertices.begin(), rigid->mesh.vertices.end());
      rigid->bleeding = std::make_unique<BleedingField>(object.name, std::move(vertices), options_.bleeding);
      rigid->report.object = object.name;
      rigid->report.frame_id = rigid->collider.frame_id;
      rigid->report.injury = &rigid->bleeding->field();
      rigid->report.mesh = &rigid->mesh;
      rigid->vertex_areas.assign(rigid->mesh.vertices.size(), 0.0);
      for (const auto& triangle : rigid->mesh.triangles) {
        const std::uint32_t a = triangle[0], b = triangle[1], c = triangle[2];
        const double area = 0.5 * (rigid->mesh.vertices[b] - rigid->mesh.vertices[a])
                                      .cross(rigid->mesh.vertices[c] - rigid->mesh.vertices[a])
                                      .norm();
        for (std::uint32_t v : {a, b, c}) rigid->vertex_areas[v] += area / 3.0;
      }
      last_injuries_.push_back(rigid->report);
    }
    rigid_.push_back(std::move(rigid));
  }
}

// target <- source for the frames the world knows (eye, world); nullopt for any other.
std::optional<Eigen::Isometry3d> World::transform(const std::string& target, const std::string& source) const {
  const std::string& from = source.empty() ? std::string("eye") : source;
  if (from == target) return Eigen::Isometry3d::Identity();
  if (target == "eye" && from == "world") return world_from_eye_.inverse();
  if (target == "world" && from == "eye") return world_from_eye_;
  return std::nullopt;
}

// ---- input frames ----

void World::handle(const ScenarioCommand& command) { mediator_.handle(command); }

WorldStatistics World::statistics() const {
  WorldStatistics statistics = statistics_;
  const Mediator::Unreported unreported = mediator_.unreported();
  statistics.inputs += unreported.inputs;
  statistics.late_inputs += unreported.late_inputs;
  statistics.rejected_inputs += unreported.rejected_inputs;
  return statistics;
}

void World::handle(const InputFrame& recorded) {
  InputFrame frame = recorded;
  // A recorded frame may be corrupt or hostile: the mediator's rules again (a live frame passes them all).
  const auto drop = [this](auto& inputs, auto check, const char* key) {
    const auto bad = std::remove_if(inputs.begin(), inputs.end(), [&](const auto& input) {
      const std::string problem = check(input);
      if (problem.empty()) return false;
      ++statistics_.rejected_inputs;
      log(Severity::kWarning, key, "input frame: " + problem + " ignored");
      return true;
    });
    inputs.erase(bad, inputs.end());
  };
  drop(frame.eye_inputs, checkEye, "frame:eye");
  drop(
      frame.instrument_inputs,
      [this](const InstrumentState& state) {
        return instruments_.count(state.slot) ? checkInstrument(state)
                                              : "instrument of unknown slot '" + state.slot + "'";
      },
      "frame:instrument");
  drop(frame.pedals, checkPedals, "frame:pedals");
  apply(frame);
}

void World::apply(InputFrame& frame) {
  statistics_.inputs += frame.inputs;
  statistics_.late_inputs += frame.late_inputs;
  statistics_.rejected_inputs += frame.rejected_inputs;
  statistics_.input_sequence = frame.sequence;
  if (frame.kind == InputFrame::Kind::kFrame) {
    closeFrame(frame);
    return;
  }
  // Between frames: pedals and commands only (a LOAD of this scene is a RESET; a session switches scenes itself).
  if (!frame.pedals.empty()) pedals_ = frame.pedals.back();
  for (const ScenarioCommand& command : frame.commands) apply(command);
  fillApplied(frame);
  if (input_observer_) input_observer_(frame);
}

void World::fillApplied(InputFrame& frame) const {
  frame.world_from_eye = world_from_eye_;
  frame.eye_valid = eye_valid_;
  frame.instruments.clear();
  for (const auto& [slot, instrument] : instruments_) {
    AppliedInstrument applied;
    applied.slot = slot;
    applied.type = instrument->current.type;
    applied.pose = instrument->pose;
    applied.frame_id = instrument->frame_id;
    applied.jaw_angle = instrument->jaw_angle;
    applied.suction = instrument->suction;
    applied.cut_rate = instrument->cut_rate;
    applied.cutting = instrument->cutting;
    applied.valid = instrument->active;
    applied.delivered = std::any_of(frame.instrument_inputs.begin(), frame.instrument_inputs.end(),
                                    [&slot = slot](const InstrumentState& state) { return state.slot == slot; });
    frame.instruments.push_back(std::move(applied));
  }
}

void World::applyEye(const EyeState& eye) {
  eye_valid_ = eye.valid;
  if (eye.valid) world_from_eye_ = Eigen::Translation3d(eye.rotation_center) * eye.rotation.normalized();
}

void World::refuse(const std::string& message) {
  log(Severity::kWarning, "", message);
  if (runner_) runner_->setMessage(message);
}

void World::apply(const ScenarioCommand& command) {
  using Type = ScenarioCommand::Type;
  const double time = toSeconds(command.stamp);
  std::string refused;
  switch (command.command) {
    case Type::kPause:
      if (runner_) refused = runner_->pause(time, command.stamp);
      if (refused.empty()) paused_ = true;
      break;
    case Type::kResume:
      if (runner_) refused = runner_->resume(time, command.stamp);
      if (refused.empty()) {
        paused_ = false;
        // The clock goes on at the resume: the first frame steps from there, not over the pause (a crash = pause
        // resume, issue 39, would otherwise integrate max_frame_time at once where the trainee's hands moved 20 ms).
        if (last_frame_stamp_ && *last_frame_stamp_ < command.stamp) last_frame_stamp_ = command.stamp;
      }
      break;
    case Type::kStart:
      if (runner_) refused = runner_->start(time, command.stamp);
      if (refused.empty()) {
        running_ = true;
        paused_ = false;
        started_ = true;
      }
      break;
    case Type::kStop:
      if (runner_) {
        refused = runner_->stop(time, command.stamp, command.argument);
      } else {
        running_ = false;
      }
      break;
    case Type::kReset:
      resetTissues();
      for (auto& rigid : rigid_) {
        if (rigid->bleeding) rigid->bleeding->clear();
      }
      paused_ = false;
      running_ = true;
      started_ = options_.auto_start;
      simulation_origin_.reset();
      if (runner_) runner_->reset();
      auto_started_ = false;
      break;
    case Type::kLoad:
      if (command.scenario.empty() || command.scenario == scene_.name) {
        apply(ScenarioCommand{command.stamp, Type::kReset, "", "", command.seed});
      } else {
        log(Severity::kWarning, "",
            "LOAD '" + command.scenario + "': this world runs scene '" + scene_.name +
                "'; another scene needs a new World (world::Session does that; ignored)");
      }
      break;
    case Type::kSelectInstrument: {
      // "slot:type", or "slot:type:settings" for an instrument with console settings (the laser probe's
      // "right:laser_probe:power_mw=250,duration_ms=150": scene::applyInstrumentSettings).
      const auto colon = command.argument.find(':');
      const std::string slot = command.argument.substr(0, colon);
      auto instrument = instruments_.find(slot);
      std::optional<scene::InstrumentType> type;
      std::string settings;
      if (colon != std::string::npos) {
        const auto settings_colon = command.argument.find(':', colon + 1);
        type = scene::instrumentTypeNamed(command.argument.substr(colon + 1, settings_colon - colon - 1));
        if (settings_colon != std::string::npos) settings = command.argument.substr(settings_colon + 1);
      }
      if (instrument == instruments_.end() || !type) {
        log(Severity::kWarning, "",
            "SELECT_INSTRUMENT '" + command.argument +
                "': expected slot:type (e.g. right:vitrector) or slot:type:settings (e.g. "
                "right:laser_probe:power_mw=250,duration_ms=150)");
        break;
      }
      if (!switchInstrument(*instrument->second, *type) || settings.empty()) break;
      const std::string problem = scene::applyInstrumentSettings(instrument->second->current, settings);
      if (problem.empty()) {
        log(Severity::kInfo, "", "instrument '" + slot + "': settings " + settings);
      } else {
        log(Severity::kWarning, "", "SELECT_INSTRUMENT '" + command.argument + "': " + problem + " (settings kept)");
      }
      break;
    }
  }
  if (!refused.empty()) refuse(refused);
}

void World::applyInstrument(const InstrumentState& state) {
  Instrument& instrument = *instruments_.at(state.slot);
  // Invalid tracking: the instrument keeps its last pose but stops interacting (no phantom grasps). The pose of an
  // invalid state is not used: whatever its sender put there (the tracker holds the last valid one, another source
  // may send zeros) is not a measurement.
  if (state.valid) {
    instrument.pose = state.pose();
    instrument.frame_id = state.frame_id.empty() ? "eye" : state.frame_id;
  }
  instrument.jaw_angle = state.valid ? state.jaw_angle : 1.0;
  instrument.active = state.valid;
  instrument.suction = state.valid ? state.suction : 0.0;
  if (state.type) switchInstrument(instrument, *state.type);
  instrument.cut_rate = state.valid ? state.cut_rate : 0.0;
  instrument.injection_flow = state.valid ? state.injection_flow : 0.0;
  instrument.cutting = state.valid && instrument.current.type == scene::InstrumentType::kVitrector &&
                       state.suction > 0.0 && state.cut_rate > 0.0;
}

// ---- one frame ----

void World::closeFrame(InputFrame& frame) {
  const Stamp stamp = frame.stamp;
  double frame_time = 0.0;
  if (last_frame_stamp_) frame_time = std::min(toSeconds(stamp - *last_frame_stamp_), options_.max_frame_time);
  for (const EyeState& eye : frame.eye_inputs) applyEye(eye);
  for (const InstrumentState& state : frame.instrument_inputs) applyInstrument(state);
  if (!frame.pedals.empty()) pedals_ = frame.pedals.back();
  for (const ScenarioCommand& command : frame.commands) apply(command);
  last_frame_stamp_ = stamp;
  if (!frame.missing.empty()) ++statistics_.frames_without_source;
  fillApplied(frame);
  if (input_observer_) input_observer_(frame);
  if (runner_ && options_.auto_start && !auto_started_ && runner_->status().state == scenario::State::kIdle) {
    auto_started_ = true;
    runner_->start(toSeconds(stamp), stamp);
  }
  if (simulating() && !simulation_origin_) simulation_origin_ = stamp;

  FrameResult result;
  result.stamp = stamp;
  result.frame = ++statistics_.frames;
  result.frame_time = frame_time;
  result.paused = !simulating();
  if (!result.paused) ++statistics_.simulated_frames;
  const double start = now();
  for (auto& [name, tissue] : tissues_) {
    if (result.paused) {
      tissue->report.steps = 0;
      tissue->report.fallbacks = 0;
      tissue->report.changed = tissue->reset_pending;
      if (tissue->reset_pending) ++tissue->report.version;
      tissue->reset_pending = false;
      result.tissues.push_back(tissue->report);
      continue;
    }
    stepTissue(*tissue, frame_time, result);
  }
  placeRigidObjects();
  for (auto& rigid : rigid_) {
    if (rigid->bleeding) {
      if (!result.paused) bleed(*rigid, result);
      continue;
    }
    if (!rigid_reports_) continue;
    const double collision_start = now();
    const collision::SurfaceView surface = collision::SurfaceView::of(rigid->mesh);
    const Eigen::Isometry3d unmoved = rigid->moved.inverse();
    for (auto& [slot, instrument] : instruments_) {
      if (!instrument->active) continue;
      const Eigen::Isometry3d pose =
          unmoved * *transform(rigid->collider.frame_id, instrument->frame_id) * instrument->pose;
      collision::CollisionResult hit = collide(rigid->collider, slot, *instrument, pose, surface);
      for (Eigen::Vector3d& point : hit.contact_points) point = rigid->moved * point;
      for (Eigen::Vector3d& normal : hit.contact_normals) normal = rigid->moved.linear() * normal;
      for (Eigen::Vector3d& deformation : hit.deformations) deformation = rigid->moved.linear() * deformation;
      result.collisions.push_back({slot, rigid->object->name, rigid->collider.frame_id, rigid->collider.detector_name,
                                   std::move(hit), surface});
    }
    result.stages.push_back({"collision_" + rigid->object->name, collision_start, now()});
  }
  last_injuries_.clear();
  for (auto& rigid : rigid_) {
    if (rigid->bleeding) last_injuries_.push_back(rigid->report);
  }
  result.injuries = last_injuries_;
  if (runner_) {
    const double scenario_start = now();
    advanceScenario(result);
    result.scenario = &runner_->status();
    result.stages.push_back({"scenario", scenario_start, now()});
  }
  result.wall_time = now() - start;
  statistics_.total_frame_wall_time += result.wall_time;
  statistics_.max_frame_wall_time = std::max(statistics_.max_frame_wall_time, result.wall_time);
  result.state_hash = stateHash();
  if (observer_) observer_(result);
}

void World::stepTissue(Tissue& tissue, double frame_time, FrameResult& result) {
  std::vector<tissue::InstrumentInput> inputs;
  std::vector<Instrument*> sources;
  for (auto& [slot, source] : instruments_) {
    tissue::InstrumentInput input = source->shape;
    input.pose = *transform(tissue.frame_id, source->frame_id) * source->pose;
    input.jaw_angle = source->jaw_angle;
    // The capsule test is the response unless the detector's deformation vectors are (or nothing collides).
    input.collides = source->active && source->shape.collides && tissue.collider && !tissue.detector_response;
    input.can_grasp = source->active && source->shape.can_grasp && scene_.simulates(scene::Simulation::kGrasping);
    input.cuts = source->active && source->cutting && scene_.simulates(scene::Simulation::kCutting);
    holdWithoutJaws(tissue, slot, *source, input);
    inputs.push_back(input);
    sources.push_back(source.get());
  }
  if (tissue.object->tissue.fluid_modulus > 0.0) {
    for (std::size_t k = 0; k < sources.size(); ++k) {
      const Instrument& source = *sources[k];
      if (!source.active || !(source.injection_flow > 0.0)) continue;
      const auto inside = tissue.needle_inside.find(scene::toString(source.description->slot));
      if (inside != tissue.needle_inside.end() && inside->second) {
        tissue.fluid_volume += source.injection_flow * frame_time;
        tissue.simulator->setFluidSource(inputs[k].pose.translation(),
                                         2.0 * tissue.object->tissue.needle_pierce_radius);
      } else {
        tissue.injected_outside += source.injection_flow * frame_time;
      }
    }
    // A torn (or sliced) sheet lets the fluid out: the sheet around the tear is no longer a closed wall.
    if (tissue.report.torn_springs > 0 || tissue.report.cut_nodes > 0) {
      tissue.fluid_volume *= std::exp(-frame_time / tissue.object->tissue.fluid_leak_time);
    }
    tissue.simulator->setFluidVolume(tissue.fluid_volume);
  }
  if (tissue.collider) {
    const double collision_start = now();
    const collision::SurfaceView surface = collision::SurfaceView::of(*tissue.membrane);
    std::vector<tissue::NodeDeformation> deformations;
    for (std::size_t k = 0; k < sources.size(); ++k) {
      Instrument& source = *sources[k];
      const std::string slot = scene::toString(source.description->slot);
      if (!source.active) continue;
      collision::CollisionResult hit = collide(*tissue.collider, slot, source, inputs[k].pose, surface);
      // Velocity of the instrument in the object's frame (v_P of eq. 5.12) from the last query.
      std::optional<Eigen::Vector3d>& last = tissue.collider->instruments[slot].last_tip;
      Eigen::Vector3d velocity = Eigen::Vector3d::Zero();
      if (last && frame_time > 0.0) velocity = (inputs[k].pose.translation() - *last) / frame_time;
      last = inputs[k].pose.translation();
      // An instrument that holds a grasp pushes nothing: its grasped nodes follow it.
      if (tissue.detector_response && source.shape.collides && !tissue.simulator->isGrasping(k)) {
        for (std::size_t i = 0; i < hit.nodes.size(); ++i) {
          tissue::NodeDeformation d;
          d.node = hit.nodes[i];
          d.deformation = hit.deformations[i];
          // Image space: every vector of a query is parallel to the projection direction (Eq. 4.2).
          const double length = d.deformation.norm();
          if (length > 0.0) d.normal = d.deformation / length;
          d.instrument_velocity = velocity;
          deformations.push_back(d);
        }
      }
      result.collisions.push_back(
          {slot, tissue.object->name, tissue.frame_id, tissue.collider->detector_name, std::move(hit), surface});
    }
    if (!deformations.empty()) tissue.simulator->addDeformations(deformations);
    result.stages.push_back({"collision_" + tissue.object->name, collision_start, now()});
  }

  const double tissue_start = now();
  tissue.simulator->setInstruments(inputs);
  const tissue::Clock no_budget = [] { return 0.0; };
  const tissue::FrameReport frame =
      tissue.simulator->advance(frame_time, options_.wall_clock_budget ? options_.clock : no_budget);
  result.stages.push_back({"tissue_" + tissue.object->name, tissue_start, now()});
  if (frame.fallbacks > 0) {
    log(Severity::kWarning, "watchdog:" + tissue.object->name,
        "tissue '" + tissue.object->name + "': watchdog rolled back " + std::to_string(frame.fallbacks) +
            " steps (total " + std::to_string(tissue.simulator->statistics().fallbacks) + ")");
  }
  statistics_.tissue_steps += static_cast<std::uint64_t>(frame.steps);
  if (tissue.simulator->integratorChoiceChanges() != tissue.logged_integrator_choice) {
    tissue.logged_integrator_choice = tissue.simulator->integratorChoiceChanges();
    if (tissue.object->tissue.integrator == tissue::kAutoIntegrator) {
      log(Severity::kInfo, "",
          "tissue '" + tissue.object->name + "': integrator " + tissue.simulator->integratorLabel() +
              " (auto: " + tissue.simulator->integratorChoice().reason + ")");
    }
  }

  mge::Membrane& membrane = *tissue.membrane;
  const tissue::SimulatorStatistics& stats = tissue.simulator->statistics();
  TissueReport& report = tissue.report;
  report.integrator = tissue.simulator->integratorLabel();
  const std::uint64_t topology_version = 1 + stats.topology_changes;
  const std::size_t n = membrane.nodeCount();
  const bool moved = tissue.last_positions.size() != n ||
                     std::memcmp(tissue.last_positions.data(), membrane.positions(), n * sizeof(Eigen::Vector3d)) != 0;
  report.changed = moved || topology_version != report.topology_version || tissue.reset_pending;
  tissue.reset_pending = false;
  if (report.changed) {
    ++report.version;
    tissue.last_positions.assign(membrane.positions(), membrane.positions() + n);
    if (topology_version != tissue.rest_topology) {
      tissue.rest_by_slot.resize(n);
      for (std::size_t i = 0; i < n; ++i) {
        const auto rest = tissue.rest_by_id.find(membrane.nodeAtSlot(i).id());
        tissue.rest_by_slot[i] = rest != tissue.rest_by_id.end()
                                     ? rest->second
                                     : Eigen::Vector3d::Constant(std::numeric_limits<double>::quiet_NaN());
      }
      tissue.rest_topology = topology_version;
    }
    double max_lift = 0.0;
    std::size_t lifted = 0;
    for (std::size_t i = 0; i < n; ++i) {
      const Eigen::Vector3d& rest = tissue.rest_by_slot[i];
      if (!rest.allFinite()) continue;
      const double lift = (membrane.positions()[i] - rest).norm();
      max_lift = std::max(max_lift, lift);
      if (lift > kLiftThreshold) ++lifted;
    }
    report.max_lift = max_lift;
    report.lifted_fraction = n > 0 ? static_cast<double>(lifted) / static_cast<double>(n) : 0.0;
  }
  report.membrane = &membrane;
  report.steps = frame.steps;
  report.fallbacks = frame.fallbacks;
  report.max_strain = frame.max_strain;
  report.grasped_nodes = tissue.simulator->graspedNodes().size();
  report.topology_version = topology_version;
  report.torn_springs = stats.torn_springs;
  report.cut_nodes = stats.cut_nodes;
  report.released_adhesions = stats.released_adhesions;
  report.adhesion_points = tissue.simulator->adhesionPoints();
  report.max_adhesion_force = stats.max_adhesion_force;
  report.adhesion_tears = stats.adhesion_tears;
  report.adhesion_tear_points = &tissue.simulator->adhesionTearPoints();
  if (tissue.object->tissue.fluid_modulus > 0.0) {
    report.fluid_volume = tissue.fluid_volume;
    report.enclosed_volume = tissue.simulator->enclosedVolume();
    report.fluid_pressure = tissue.simulator->fluidPressure();
    report.injected_outside = tissue.injected_outside;
  }
  report.needle_inside = std::any_of(tissue.needle_inside.begin(), tissue.needle_inside.end(),
                                     [](const auto& entry) { return entry.second; });
  if (report.grasped_nodes > 0) {
    tissue.ever_grasped = true;
    tissue.peak_lift = std::max(tissue.peak_lift, report.max_lift);
  }
  if (tissue.peels) {
    if (report.torn_springs > 0) {
      report.outcome = PeelOutcome::kTorn;
    } else if (tissue.ever_grasped && tissue.peak_lift >= kPeelLift) {
      report.outcome = PeelOutcome::kLifted;
    } else if (tissue.ever_grasped) {
      report.outcome = PeelOutcome::kGrasped;
    }
  }
  statistics_.max_strain = std::max(statistics_.max_strain, report.max_strain);
  statistics_.max_grasped_nodes = std::max(statistics_.max_grasped_nodes, report.grasped_nodes);
  result.tissues.push_back(report);
}

// The needle pierces a sheet with needle_pierce_radius (it does not push it): its tip is inside once it went behind the
// sheet near a node — farther from the eye centre than that node — and stays inside until it is back in front. Inside,
// its puncture is where its axis crosses the sheet's sphere there; moved sideways beyond needle_slack from where it
// settled, the shaft slices the sheet (a cut of needle_pierce_radius about the shaft at the sheet, swept along the
// move by the tissue steps), and settles again where it is. The vitrector's suction (cutter off) holds the nodes of a
// sheet with suction_hold_radius within that distance of the shaft's surface at its port.
void World::holdWithoutJaws(Tissue& tissue, const std::string& slot, const Instrument& source,
                            tissue::InstrumentInput& input) {
  const scene::TissueParameters& parameters = tissue.object->tissue;
  if (parameters.needle_pierce_radius > 0.0 && source.current.type == scene::InstrumentType::kNeedle) {
    input.collides = false;
    bool& inside = tissue.needle_inside[slot];
    const Eigen::Vector3d tip = input.pose.translation();
    const Eigen::Vector3d* x = tissue.membrane->positions();
    double nearest = std::numeric_limits<double>::infinity();
    std::size_t closest = 0;
    for (std::size_t i = 0; i < tissue.membrane->nodeCount(); ++i) {
      const double distance = (x[i] - tip).norm();
      if (distance < nearest) nearest = distance, closest = i;
    }
    constexpr double kWithdrawn = 2e-5;  // m in front of the sheet: out again (hysteresis against tracking noise)
    const double sheet_radius = nearest < std::numeric_limits<double>::infinity() ? x[closest].norm() : 0.0;
    const double behind = tip.norm() - sheet_radius;
    // It goes in near the sheet (a slice leaves a gap about the shaft, so not just the pierce radius); inside, the
    // fluid may lift the sheet far off its tip.
    if (!source.active) {
      inside = false;
    } else if (!inside && behind > 0.0 && nearest <= 4.0 * parameters.needle_pierce_radius) {
      inside = true;
    } else if (inside && behind < -kWithdrawn) {
      inside = false;
    }
    if (!inside) {
      tissue.puncture.erase(slot);
    } else {
      const Eigen::Vector3d axis = input.pose.linear().col(2);
      const double b = tip.dot(axis), c = tip.squaredNorm() - sheet_radius * sheet_radius;
      const double discriminant = b * b - c;
      const double back = discriminant >= 0.0 ? std::max(0.0, b - std::sqrt(discriminant)) : 0.0;
      const Eigen::Vector3d crossing = input.pose * Eigen::Vector3d(0.0, 0.0, -back);
      const auto settled = tissue.puncture.try_emplace(slot, crossing).first;
      // In and out along the shaft (or the sheet lifting along it) slices nothing: only the sideways part counts.
      const Eigen::Vector3d moved = crossing - settled->second;
      const double sideways = (moved - moved.dot(axis) * axis).norm();
      if (sideways > parameters.needle_slack && scene_.simulates(scene::Simulation::kCutting)) {
        input.cuts = true;
        input.cut_radius = parameters.needle_pierce_radius;
        input.cut_offset = std::max(0.0, back - parameters.needle_pierce_radius);
        input.cut_length = 2.0 * parameters.needle_pierce_radius;
        settled->second = crossing;
      }
    }
  }
  if (parameters.suction_hold_radius > 0.0 && source.active && !source.cutting &&
      source.current.type == scene::InstrumentType::kVitrector && source.suction >= parameters.suction_hold_level) {
    if (const auto* vitrector = std::get_if<scene::VitrectorParams>(&source.current.params)) {
      // About the shaft at the port's height, whichever way the port faces: the tracker does not see the roll of an
      // instrument (its markers are rings about the shaft), so the port's facing is not an input.
      input.holds = true;
      input.hold_point = Eigen::Vector3d(0.0, 0.0, -(vitrector->port_distance_from_tip + 0.5 * vitrector->port_length));
      input.hold_radius = parameters.suction_hold_radius + 0.5 * vitrector->shaft.diameter;
    }
  }
}

// The scenario moves objects after a frame's collisions (scenario.h placements()): this frame collides them where the
// previous frame's scenario step (or a RESET) left them.
void World::placeRigidObjects() {
  if (!runner_) return;
  for (auto& rigid : rigid_) rigid->moved.setIdentity();
  for (const scenario::ObjectPlacement& placement : runner_->status().placements) {
    for (auto& rigid : rigid_) {
      if (rigid->object->name == placement.name)
        rigid->moved = placement.pose * rigid->object->pose.toIsometry().inverse();
    }
  }
}

void World::bleed(RigidObject& object, FrameResult& result) {
  const double start = now();
  const double time = toSeconds(result.stamp - *simulation_origin_);
  const collision::SurfaceView surface = collision::SurfaceView::of(object.mesh);
  BleedingField& field = *object.bleeding;
  for (auto& [slot, instrument] : instruments_) {
    if (!instrument->active) continue;
    const Eigen::Isometry3d pose = *transform(object.collider.frame_id, instrument->frame_id) * instrument->pose;
    collision::CollisionResult hit = collide(object.collider, slot, *instrument, pose, surface);
    if (hit.colliding) {
      // The deepest deformation vector is how far the tip presses into the retina; detectors without vectors
      // (FCL) report the contact only.
      double depth = 0.0;
      for (const Eigen::Vector3d& deformation : hit.deformations) depth = std::max(depth, deformation.norm());
      // The spot is centred on the footprint (the touched vertices), as wide as it.
      Eigen::Vector3d point = Eigen::Vector3d::Zero();
      double extent = 0.0;
      if (!hit.nodes.empty()) {
        for (std::uint32_t node : hit.nodes) point += object.mesh.vertices[node];
        point /= static_cast<double>(hit.nodes.size());
        for (std::uint32_t node : hit.nodes) extent = std::max(extent, (object.mesh.vertices[node] - point).norm());
      } else if (!hit.contact_points.empty()) {
        for (const Eigen::Vector3d& p : hit.contact_points) point += p;
        point /= static_cast<double>(hit.contact_points.size());
      } else {
        point = pose.translation();
      }
      field.contact(slot, point, depth, false, time, extent);
    }
    // The vitrector aspirates what comes near its port (thesis §7.4: touching the retina makes it bleed).
    if (instrument->current.type == scene::InstrumentType::kVitrector && instrument->suction > 0.0) {
      const auto* vitrector = std::get_if<scene::VitrectorParams>(&instrument->current.params);
      if (vitrector != nullptr) {
        const Eigen::Vector3d port =
            pose * Eigen::Vector3d(0.5 * vitrector->shaft.diameter, 0.0,
                                   -(vitrector->port_distance_from_tip + 0.5 * vitrector->port_length));
        const double distance = field.distanceToSurface(port);
        if (distance < options_.bleeding.aspiration_distance) {
          field.contact(slot, port, options_.bleeding.aspiration_distance - distance, true, time);
        }
      }
    }
    result.collisions.push_back(
        {slot, object.object->name, object.collider.frame_id, object.collider.detector_name, std::move(hit), surface});
  }
  const std::size_t ended_before = result.contacts_ended.size();
  object.report.changed = field.update(time, &result.contacts_ended);
  if (object.report.changed) ++object.report.version;
  object.report.max_injury = field.maxInjury();
  object.report.contacts = field.events().size();
  object.report.in_contact = !field.events().empty() && field.events().back().ongoing;
  if (object.report.changed) {
    double area = 0.0;
    const std::vector<float>& injury = field.field();
    for (std::size_t v = 0; v < injury.size() && v < object.vertex_areas.size(); ++v) {
      if (injury[v] > 0.1f) area += object.vertex_areas[v];
    }
    object.report.injured_area = area;
  }
  for (std::size_t i = ended_before; i < result.contacts_ended.size(); ++i) {
    const ContactEvent& event = result.contacts_ended[i];
    log(Severity::kInfo, "",
        "retina contact by '" + event.instrument + "' for " +
            std::to_string(static_cast<int>(std::lround(1e3 * event.duration()))) + " ms, " +
            std::to_string(static_cast<int>(std::lround(1e6 * event.max_depth))) + " um deep" +
            (event.aspiration ? " (aspiration)" : ""));
  }
  result.stages.push_back({"bleeding_" + object.object->name, start, now()});
}

// The instrument's collision mesh follows its shape: the forceps' jaws open and close (whole degrees, so a noisy
// jaw angle does not invalidate the detectors' cached depth images every frame).
collision::CollisionResult World::collide(Collider& collider, const std::string& slot, Instrument& instrument,
                                          const Eigen::Isometry3d& pose, const collision::SurfaceView& surface) {
  const int jaw_deg = scene::jawStepDeg(instrument.current.type, instrument.jaw_angle);
  if (instrument.model_version == 0 || jaw_deg != instrument.model_jaw_deg) {
    instrument.model = collisionModel(instrument.current, jaw_deg);
    instrument.model_jaw_deg = jaw_deg;
    ++instrument.model_version;
  }
  Collider::PerInstrument& entry = collider.instruments[slot];
  if (!entry.detector) entry.detector = collision::makeCollisionDetector(collider.detector_name, collider.options);
  if (entry.model_version != instrument.model_version) {
    entry.detector->setInstrument(instrument.model);
    entry.model_version = instrument.model_version;
  }
  collision::CollisionResult result = entry.detector->collide(pose, surface);
  if (result.status == collision::CollisionStatus::kBackendUnavailable ||
      result.status == collision::CollisionStatus::kInvalidInput) {
    log(Severity::kWarning, "collision:" + slot + collider.object,
        "collision '" + slot + "' vs '" + collider.object + "' (" + collider.detector_name +
            "): " + collision::toString(result.status));
  }
  return result;
}

// ---- state ----

std::uint64_t World::stateHash() const {
  std::uint64_t hash = kHashSeed;
  for (const auto& [name, tissue] : tissues_) {
    mge::Membrane& membrane = *tissue->membrane;
    const std::size_t n = membrane.nodeCount();
    hash = hashBytes(hash, membrane.positions(), n * sizeof(Eigen::Vector3d));
    hash = hashBytes(hash, membrane.velocities(), n * sizeof(Eigen::Vector3d));
    hash = hashBytes(hash, membrane.restLengths(), membrane.springCount() * sizeof(double));
    const std::uint64_t topology = tissue->report.topology_version;
    hash = hashBytes(hash, &topology, sizeof(topology));
    const std::vector<std::uint32_t>& grasped = tissue->simulator->graspedNodes();
    hash = hashBytes(hash, grasped.data(), grasped.size() * sizeof(std::uint32_t));
    if (tissue->object->tissue.fluid_modulus > 0.0) hash = hashBytes(hash, &tissue->fluid_volume, sizeof(double));
    for (const auto& [slot, inside] : tissue->needle_inside) {
      const std::uint8_t flag = inside ? 1 : 0;
      hash = hashBytes(hash, &flag, 1);
    }
    for (const auto& [slot, point] : tissue->puncture) hash = hashBytes(hash, point.data(), 3 * sizeof(double));
  }
  for (const auto& rigid : rigid_) {
    if (!rigid->bleeding) continue;
    const std::vector<float>& field = rigid->bleeding->field();
    hash = hashBytes(hash, field.data(), field.size() * sizeof(float));
  }
  const std::uint8_t flags[] = {static_cast<std::uint8_t>(paused_), static_cast<std::uint8_t>(running_),
                                static_cast<std::uint8_t>(started_)};
  hash = hashBytes(hash, flags, sizeof(flags));
  if (runner_) runner_->hash(hash);
  return hash;
}

// The scenario sees what this frame produced, in the eye frame (scenario/scenario.h: FrameView).
void World::advanceScenario(const FrameResult& result) {
  scenario::FrameView view;
  view.time = toSeconds(result.stamp);
  view.stamp_ns = result.stamp;
  view.dt = result.frame_time;
  view.world_from_eye = world_from_eye_;
  for (const auto& [slot, instrument] : instruments_) {
    scenario::InstrumentView entry;
    entry.slot = slot;
    entry.type = instrument->current.type;
    entry.valid = instrument->active;
    const Eigen::Isometry3d pose = *transform("eye", instrument->frame_id) * instrument->pose;
    entry.tip = pose.translation();
    entry.axis = pose.linear().col(2);
    entry.orientation = Eigen::Quaterniond(pose.linear());
    entry.jaw_angle = instrument->jaw_angle;
    entry.suction = instrument->suction;
    entry.cut_rate = instrument->cut_rate;
    if (const auto* laser = std::get_if<scene::LaserProbeParams>(&instrument->current.params)) entry.laser = *laser;
    view.instruments.push_back(entry);
  }
  view.pedals = {pedals_.travel, pedals_.reflux, pedals_.instrument_switch};
  for (const auto& [name, tissue] : tissues_) {
    const TissueReport& report = tissue->report;
    scenario::TissueView entry;
    entry.object = name;
    entry.role = tissue->object->role;
    entry.grasped_nodes = report.grasped_nodes;
    entry.max_strain = report.max_strain;
    entry.max_lift = report.max_lift;
    entry.lifted_fraction = report.lifted_fraction;
    entry.torn_springs = report.torn_springs;
    entry.cut_nodes = report.cut_nodes;
    entry.released_adhesions = report.released_adhesions;
    entry.adhesion_points = report.adhesion_points;
    entry.max_adhesion_force = report.max_adhesion_force;
    entry.adhesion_tears = report.adhesion_tears;
    entry.adhesion_tear_points = report.adhesion_tear_points;
    entry.fluid_volume = report.fluid_volume;
    entry.enclosed_volume = report.enclosed_volume;
    entry.fluid_pressure = report.fluid_pressure;
    entry.injected_outside = report.injected_outside;
    entry.needle_inside = report.needle_inside;
    entry.initial_node_count = tissue->rest_by_id.size();
    entry.positions = tissue->membrane->positions();
    entry.node_count = tissue->membrane->nodeCount();
    entry.rest_positions = &tissue->rest_by_slot;
    view.tissues.push_back(entry);
  }
  for (const auto& rigid : rigid_) {
    if (!rigid->bleeding) continue;
    view.retina.simulated = true;
    view.retina.contact_events += rigid->report.contacts;
    view.retina.in_contact = view.retina.in_contact || rigid->report.in_contact;
    view.retina.max_injury = std::max(view.retina.max_injury, rigid->report.max_injury);
    view.retina.injured_area += rigid->report.injured_area;
  }
  runner_->frame(view);
}

std::vector<std::string> World::tissueNames() const {
  std::vector<std::string> names;
  for (const auto& entry : tissues_) names.push_back(entry.first);
  return names;
}

mge::Membrane* World::membrane(const std::string& object) {
  auto it = tissues_.find(object);
  return it == tissues_.end() ? nullptr : it->second->membrane.get();
}

const tissue::TissueSimulator* World::tissueSimulator(const std::string& object) const {
  auto it = tissues_.find(object);
  return it == tissues_.end() ? nullptr : it->second->simulator.get();
}

tissue::TissueSimulator* World::tissueSimulator(const std::string& object) {
  auto it = tissues_.find(object);
  return it == tissues_.end() ? nullptr : it->second->simulator.get();
}

TissueReport World::tissueReport(const std::string& object) const {
  auto it = tissues_.find(object);
  return it == tissues_.end() ? TissueReport{} : it->second->report;
}

const std::vector<float>* World::injury(const std::string& object) const {
  for (const auto& rigid : rigid_) {
    if (rigid->bleeding && rigid->object->name == object) return &rigid->bleeding->field();
  }
  return nullptr;
}

std::vector<ContactEvent> World::contactEvents() const {
  std::vector<ContactEvent> events;
  for (const auto& rigid : rigid_) {
    if (!rigid->bleeding) continue;
    events.insert(events.end(), rigid->bleeding->events().begin(), rigid->bleeding->events().end());
  }
  return events;
}

// ---- checkpoints (issue 39 §1) ----
//
// Everything that carries from one frame into the next (doc/checkpoint_state_inventory.md §2.2-2.9): the session
// flags and clocks, the pedals, each instrument's type, console settings and last input, the collision response's
// last tips, each tissue (TissueSimulator::transferState: membrane, grasps, anchors, fluid, model, integrator) with
// what the World keeps beside it (reports, fluid, the needle's puncture), each bleeding surface, and the scenario.
// Derived data (collision models and detectors, reports' pointers, the injury list) is rebuilt by the next frame as
// after a type switch. Measurements (wall times) are not state.

namespace {
constexpr std::uint32_t kCheckpointVersion = 1;
}  // namespace

std::string World::checkpoint() const {
  StateArchive archive = StateArchive::saver(checkpoint_bytes_ + checkpoint_bytes_ / 8);
  const_cast<World&>(*this).transferState(archive);  // saving reads only
  checkpoint_bytes_ = archive.bytes().size();
  return archive.takeBytes();
}

void World::restoreCheckpoint(const std::string& bytes) {
  StateArchive archive = StateArchive::loader(bytes);
  transferState(archive);
  if (!archive.atEnd()) archive.fail(std::to_string(archive.remaining()) + " bytes left over");
}

void World::transferState(StateArchive& archive) {
  archive.section("vrm_world").expect(kCheckpointVersion, "the checkpoint format version");
  archive.expect(scene_.name, "the scene").expect(instruments_.size(), "the instrument count");
  archive.expect(tissues_.size(), "the tissue count").expect(rigid_.size(), "the rigid object count");
  if (mediator_.pendingFrames() != 0) archive.fail("the World's own mediator holds frames not yet closed");
  archive(world_from_eye_)(eye_valid_)(last_frame_stamp_)(simulation_origin_)(logged_at_frame_)(pedals_);
  archive(paused_)(running_)(started_)(auto_started_);
  archive(statistics_.frames)(statistics_.inputs)(statistics_.simulated_frames)(statistics_.late_inputs);
  archive(statistics_.rejected_inputs)(statistics_.frames_without_source)(statistics_.input_sequence);
  archive(statistics_.tissue_steps)(statistics_.max_strain)(statistics_.max_grasped_nodes);

  archive.section("instruments");
  for (auto& [slot, instrument] : instruments_) {
    archive.expect(slot, "an instrument slot");
    scene::InstrumentType type = instrument->current.type;
    archive(type);
    if (archive.loading() && type != instrument->current.type) setInstrumentType(*instrument, type);
    // The laser probe's console settings (SELECT_INSTRUMENT ...:power_mw=…): the only parameters a session changes.
    if (auto* laser = std::get_if<scene::LaserProbeParams>(&instrument->current.params)) {
      archive(laser->power_mw)(laser->duration_ms)(laser->interval_ms);
    }
    archive(instrument->pose)(instrument->frame_id)(instrument->active)(instrument->jaw_angle)(instrument->suction);
    archive(instrument->cut_rate)(instrument->injection_flow)(instrument->cutting);
  }

  auto last_tips = [&archive](Collider& collider) {
    std::map<std::string, std::optional<Eigen::Vector3d>> tips;
    if (archive.saving()) {
      for (const auto& [slot, entry] : collider.instruments) tips[slot] = entry.last_tip;
    }
    archive(tips);
    if (archive.loading()) {
      for (auto& [slot, tip] : tips) collider.instruments[slot].last_tip = tip;
    }
  };

  archive.section("tissues");
  for (auto& [name, tissue] : tissues_) {
    archive.expect(name, "a tissue");
    tissue->simulator->transferState(archive);
    archive.section("world_tissue");
    archive(tissue->last_positions)(tissue->rest_by_slot)(tissue->rest_topology)(tissue->ever_grasped);
    archive(tissue->peak_lift)(tissue->reset_pending)(tissue->logged_integrator_choice)(tissue->fluid_volume);
    archive(tissue->injected_outside)(tissue->needle_inside)(tissue->puncture);
    TissueReport& report = tissue->report;
    archive(report.steps)(report.fallbacks)(report.integrator)(report.max_strain)(report.grasped_nodes);
    archive(report.changed)(report.version)(report.topology_version)(report.torn_springs)(report.cut_nodes);
    archive(report.released_adhesions)(report.max_lift)(report.lifted_fraction)(report.adhesion_points);
    archive(report.max_adhesion_force)(report.adhesion_tears)(report.fluid_volume)(report.enclosed_volume);
    archive(report.fluid_pressure)(report.injected_outside)(report.needle_inside)(report.outcome);
    bool collider = tissue->collider.has_value();
    archive.expect(collider, "a tissue's collider");
    if (tissue->collider) last_tips(*tissue->collider);
    if (archive.loading()) {
      report.membrane = tissue->membrane.get();
      report.adhesion_tear_points = &tissue->simulator->adhesionTearPoints();
      const std::size_t n = tissue->membrane->nodeCount();
      if (tissue->last_positions.size() != n || tissue->rest_by_slot.size() != n) {
        archive.fail("tissue '" + name + "' positions of another node count");
      }
    }
  }

  archive.section("rigid");
  for (auto& rigid : rigid_) {
    archive.expect(rigid->object->name, "a rigid object");
    archive(rigid->moved);
    bool bleeding = rigid->bleeding != nullptr;
    archive.expect(bleeding, "a bleeding surface");
    if (rigid->bleeding) rigid->bleeding->transferState(archive);
    InjuryReport& report = rigid->report;
    archive(report.changed)(report.version)(report.max_injury)(report.injured_area)(report.contacts);
    archive(report.in_contact);
    last_tips(rigid->collider);
  }

  archive.section("scenario");
  bool scenario = runner_ != nullptr;
  archive.expect(scenario, "a scenario");
  if (runner_) runner_->transferState(archive);
  archive.section("end");
}

}  // namespace world
}  // namespace vrm_sim
