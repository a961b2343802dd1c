#pragma once
// The training layer (thesis §2.1-2.3: a scenario is a task with success and failure criteria and a score; §7.4.1:
// abstract scenarios train a skill without anatomy, surgical ones a step of an operation). ROS-free: a scenario sees
// one FrameView per simulation frame — what the simulation core (world/world.h) knows after the frame: instruments,
// pedals, tissues, retina contacts — and turns it into measurements. Time is the frames' input stamps only, so a
// replayed session scores exactly like the live one.
//
// One class per scenario type behind this interface, chosen by the scene's `scenario.type` (makeScenario()); the
// ScenarioRunner (runner.h) adds the state machine, the time limit, the failure rules and the scoring.

#include <Eigen/Geometry>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "vrm_scene/hash.h"
#include "vrm_scene/registry.h"
#include "vrm_scene/scene_description.h"
#include "vrm_sim/state/state_archive.h"

namespace vrm_sim {
namespace scenario {

struct InstrumentView {
  std::string slot;  // "left" | "right"
  scene::InstrumentType type = scene::InstrumentType::kLightPipe;
  bool valid = false;                                               // tracked and interacting
  Eigen::Vector3d tip = Eigen::Vector3d::Zero();                    // m, eye frame
  Eigen::Vector3d axis = -Eigen::Vector3d::UnitZ();                 // unit, eye frame, from the handle towards the tip
  Eigen::Quaterniond orientation = Eigen::Quaterniond::Identity();  // eye <- instrument (its z: `axis`; roll about it)
  double jaw_angle = 1.0;                                           // rad
  double suction = 0.0;                                             // 0..1
  double cut_rate = 0.0;                                            // Hz
  std::optional<scene::LaserProbeParams> laser;  // a laser probe's optics and console settings (issue 37)
};

struct PedalView {
  double travel = 0.0;
  bool reflux = false;
  bool instrument_switch = false;
};

struct TissueView {
  std::string object;
  scene::ObjectRole role = scene::ObjectRole::kMembrane;
  std::size_t grasped_nodes = 0;
  double max_strain = 0.0;
  double max_lift = 0.0;         // m
  double lifted_fraction = 0.0;  // of the nodes, more than 0.1 mm off their rest position
  std::uint64_t torn_springs = 0;
  std::uint64_t cut_nodes = 0;
  std::uint64_t released_adhesions = 0;
  std::size_t adhesion_points = 0;   // holding now
  double max_adhesion_force = 0.0;   // N, largest pull on an adhesion point so far
  std::uint64_t adhesion_tears = 0;  // adhesions that tore the tissue beneath (retina injuries)
  const std::vector<Eigen::Vector3d>* adhesion_tear_points = nullptr;      // eye frame, oldest first
  double fluid_volume = 0.0, enclosed_volume = 0.0, fluid_pressure = 0.0;  // m^3, m^3, Pa (subretinal fluid)
  double injected_outside = 0.0;                                           // m^3 not under the sheet
  bool needle_inside = false;                                              // a needle's tip is behind the sheet
  std::size_t initial_node_count = 0;                                      // at the start (rest)
  const Eigen::Vector3d* positions = nullptr;                              // by node slot, valid during the frame
  std::size_t node_count = 0;
  const std::vector<Eigen::Vector3d>* rest_positions = nullptr;  // by node slot at the start (NaN: born later)
};

struct RetinaView {
  bool simulated = false;          // a bleeding retina in the simulation core (else scenarios test the tip)
  std::size_t contact_events = 0;  // pressure or aspiration contacts so far
  bool in_contact = false;
  double max_injury = 0.0;    // 0..1
  double injured_area = 0.0;  // m^2 of retina with injury above 0.1
};

struct FrameView {
  double time = 0.0;                     // s: the frame's input stamp
  std::optional<std::int64_t> stamp_ns;  // the same, exact (ns), when the caller has it: the running time counts it
  double dt = 0.0;                       // s of simulated time the frame covered
  Eigen::Isometry3d world_from_eye = Eigen::Isometry3d::Identity();
  std::vector<InstrumentView> instruments;
  PedalView pedals;
  std::vector<TissueView> tissues;
  RetinaView retina;

  const InstrumentView* instrument(const std::string& slot) const;
  const TissueView* tissue(const std::string& object) const;
};

// A scene object the scenario moves (a grasped, carried, falling or placed rigid object): its pose after the frame in
// the object's own frame (scene `frame`), replacing its scene pose. The World collides instruments with it there and
// the renderer draws it there (SimulationState.objects).
struct ObjectPlacement {
  std::string name;
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  std::string frame_id = "eye";  // the object's frame

  void transferState(StateArchive& archive) { archive(name)(pose)(frame_id); }
};

// A burn the laser left on the retina (issue 37; the model: scenario/laser.h). The renderer paints it into the fundus
// (SimulationState.burns).
struct LaserBurn {
  Eigen::Vector3d position = Eigen::Vector3d::Zero();  // eye frame, on the retina
  double spot = 0.0;                                   // m: the beam's spot
  double diameter = 0.0;                               // m: the visible lesion (0: none)
  double grade = 0.0;                                  // radiant exposure / that of a moderate burn
  double whiteness = 0.0;                              // 0..1
  double power = 0.0;                                  // W
  double duration = 0.0;                               // s
  double distance = 0.0;                               // m, probe tip to retina along the beam
  double time = 0.0;                                   // s of running time

  void transferState(StateArchive& archive) {
    archive(position)(spot)(diameter)(grade)(whiteness)(power)(duration)(distance)(time);
  }
};

struct Measurement {
  std::string name;
  double value = 0.0;
  std::string unit;
};

class Scenario {
 public:
  virtual ~Scenario() = default;
  // Every item measurements() reports (names and units), so the loader-side checks can reject a scoring or failure
  // rule naming an item the type does not produce.
  virtual std::vector<Measurement> items() const = 0;
  // One running frame; `elapsed` is the running time after it (s, pauses excluded).
  virtual void update(const FrameView& frame, double elapsed) = 0;
  virtual bool succeeded() const = 0;
  virtual std::vector<Measurement> measurements(double elapsed) const = 0;
  // The slot of the instrument a penalty event of `item` is charged to, where the scenario knows it (its working
  // tool's wrong touches, drops, unlit work); "" leaves it to the runner (the instrument nearest the retina).
  virtual std::string penaltySlot(const std::string& item) const {
    (void)item;
    return "";
  }
  // Where a penalty event of `item` happened when it is not at the charged instrument's tip (a laser burn lies where
  // the beam met the retina, millimetres from the probe); nullopt: at the tip.
  virtual std::optional<Eigen::Vector3d> penaltyPosition(const std::string& item) const {
    (void)item;
    return std::nullopt;
  }
  // Where the objects the scenario moves are now (only those; every other object stays at its scene pose).
  virtual std::vector<ObjectPlacement> placements() const { return {}; }
  // The laser burns placed so far (issue 37), oldest first.
  virtual std::vector<LaserBurn> burns() const { return {}; }
  // One line for the trainee, e.g. "target 2 of 4".
  virtual std::string progress() const = 0;
  // Mixes the scenario's state into a state hash (FNV-1a, see hashBytes()).
  virtual void hash(std::uint64_t& state) const = 0;
  // Saves or loads every member that changes after construction (a checkpoint, issue 39 §1): loaded into a scenario
  // built from the same scene, it continues bit for bit like the saved one. Pure, so a new type cannot forget it;
  // what the constructor derives from the scene is not saved — the same scene rebuilds it.
  virtual void transferState(StateArchive& archive) = 0;
};

// Builds the scene's scenario (scene.scenario must be set). Throws scene::SceneError with the location of the
// offending parameter for a missing or wrong parameter or a scene object the type needs but the scene lacks.
std::unique_ptr<Scenario> makeScenario(const scene::SceneDescription& scene);
// The scenario types, one entry per class: the table makeScenario() builds from and the tools list (--list).
using ScenarioFactory = std::unique_ptr<Scenario> (*)(const scene::SceneDescription& scene);
const Registry<ScenarioFactory>& scenarioRegistry();

inline void hashBytes(std::uint64_t& state, const void* data, std::size_t size) {
  state = ::vrm_sim::hashBytes(state, data, size);
}
template <typename T>
void hashValue(std::uint64_t& state, const T& value) {
  hashBytes(state, &value, sizeof(value));
}

}  // namespace scenario
}  // namespace vrm_sim
