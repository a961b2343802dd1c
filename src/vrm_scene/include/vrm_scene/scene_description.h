#pragma once
// Typed description of one training scene (thesis §2: a *scenario* configures one situation: which VR objects,
// which simulations, which instruments). Produced by loadScene() from config/scenes/*.yaml; every field has the
// default stated here, so code can also build a description directly.
//
// Units: SI (metres, kilograms, seconds, newtons); angles in degrees in fields named *_deg.
//
// Scene file schema (every key below is optional unless marked "required"; any other key is an error):
//
//   format_version: 1
//   scene:                                   # required
//     name: membrane_peeling                 # required
//     description: free text
//     kind: surgical                         # required: abstract | surgical (abstract => no deformable objects)
//   eye:
//     radius: 0.012                          # default for the retina and membrane generators' radius
//     centre: [x, y, z]                      # world position of the eye's rotation centre
//     rest_rpy_deg: [r, p, y]
//     trocars:                               # default: left (azimuth 150) and right (azimuth 30), 45 deg off axis
//       - {name: left, angle_from_optical_axis_deg: 45, azimuth_deg: 150}   # on the eye sphere, or
//       - {name: right, position: [x, y, z]}                                 # explicit, eye frame
//   objects:                                 # required, at least one
//     - name: membrane                       # required, unique
//       role: membrane                       # required: retina | membrane | ilm | rigid | abstract_target |
//                                            #           decoration (rigid, abstract_target, decoration: never
//                                            #           deformable)
//       frame: eye                           # eye | world
//       mesh:                                # required: exactly one of generator / file
//         generator: membrane                # see generatorNames(); params are that generator's struct fields
//         params: {diameter: 0.005, ring_count: 16}     # nested struct: shaft: {diameter, length, segments}
//         # file: meshes/thing.obj           # relative to the scene file, then to the package; OBJ/PLY/STL/...
//         # scale: 0.001                     # file only
//       pose: {xyz: [x, y, z], rpy_deg: [r, p, y]}
//       material: {diffuse: [r, g, b, a], specular: [r, g, b], shininess: 16}
//       tissue:                              # absent or model: none = rigid
//         model: mass_spring                 # required: none | tissue::tissueModelRegistry() (mass_spring, chainmail)
//         integrator: auto                   # tissue::integratorRegistry(); auto = chosen per membrane (default)
//         stiffness: 2.0                     # and the other TissueParameters fields by name
//         tear_strain: 1.5                   # > 1: springs longer than 1.5 x rest length tear; 0 = off
//         adhesion_break_force: 1.0e-3       # N: an adhesion spring pulled harder lets go (peels off); 0 = never
//         chainmail: {min_stretch: 0.8, max_stretch: 1.2, max_shear: 0.2, relaxation: 0.0}   # model chainmail only
//         refinement: {levels: 1, radius: 0.001, element_budget: 2000}   # mass_spring only (thesis §5.2.4)
//       collision: {detector: zcoll_f, resolution: 64, epsilon_shell_scale: 1.05}   # collision::detectorRegistry()
//   instruments:
//     - slot: right                          # required: left | right, one instrument per slot
//       type: forceps                        # required: light_pipe | forceps | vitrector | needle | hook |
//                                            #   laser_probe
//       trocar: right                        # default: the slot name; must name an eye trocar
//       params: {jaw_angle_deg: 0}           # the instrument generator's fields
//       alternatives: [vitrector]            # other types the trainee may switch to
//       material: {...}
//       path:                                # scripted motion (tissue_offline, tests), at least one waypoint:
//         - {t: 0.0, tip: [x, y, z], jaw_angle_deg: 30}   # s (increasing), tip in the eye frame, forceps
//                                            # opening (default 0); the shaft points from the trocar to the tip;
//                                            # also suction (0..1) and cut_rate_hz (vitrector), default 0
//       tremor: {amplitude: 2.0e-5, frequency_hz: 10}   # added to the scripted tip (m per axis, Hz); default none
//   simulations: [tissue, collision, grasping, cutting, bleeding]   # required (may be []); lists 'tissue' if
//                                            # and only if some object is deformable
//   scenario:                                # optional: the scene is a training scenario (thesis §2.1-2.3, §7.4.1)
//     type: navigation                       # required: scenario::scenarioRegistry() (checked by makeScenario)
//     description: free text
//     time_limit: 60                         # s of running time (pauses excluded); exceeded = failed; 0 = none
//     params: {targets: [a, b], hold_time: 10}   # the type's parameters: numbers, names or lists of them
//     fail_if: {retina_contacts: 10}         # the scenario fails as soon as a score item reaches the value
//     scoring:                               # score items: 100 points at `best`, 0 at `worst`, linear between
//       time: {weight: 1, best: 20, worst: 90}   # (either order); total = weighted mean, 0..100
//     difficulty:
//       default: medium                      # required with levels
//       levels:                              # named overrides of any scene value, by dotted path; list items
//         easy: {scenario.time_limit: 120, objects.membrane.tissue.adhesion_stiffness: 2.0}   # by name / slot
//         medium: {}
//     scripts:                               # scripted sessions (scenario_offline --script NAME, the twin surgeon)
//       expert:                              # short form: the list of scripted instruments, played once
//         - {slot: right, path: [...], tremor: {...}}   # the instrument path format above
//       demo:                                # full form (also the format of a script file, loadScript):
//         playback: once                     # once | loop (the duration is the last waypoint of any track)
//         missing_objects: error             # error | keep_tip: a waypoint `on` an object the scene lacks
//         instruments:                       # as the short form's list, and per instrument:
//           - slot: right
//             type: forceps                  # default: the scene's instrument in the slot
//             path:                          # waypoint fields besides the above (all linear but `type`):
//               - {t: 0, tip: [x, y, z], roll_deg: 0, injection_flow: 0}   # m^3/s
//               - {t: 9, tip: [...], type: vitrector}      # an instrument exchange: steps at the waypoint
//               - {t: 12, on: membrane, tip: [...], height: -6.0e-5}   # the tip put on a scene object:
//                                            # the closest point of its surface to `tip`, `height` m above it
//             tremor: {amplitude: 2.0e-5, frequency_hz: 10}
//         eye: [{t: 0, rpy_deg: [r, p, y]}]  # world -> eye rotation about the eye centre (slerp); default rest
//         pedals: [{t: 0, travel: 0, reflux: false, instrument_switch: false, zoom_in: false, zoom_out: false,
//                   focus_near: false, focus_far: false}]   # travel linear, buttons step; omitted keys carry over
//         microscope: [{t: 0, focus_distance: 0.2, zoom: 1, ambient_light: 0.5, disparity_scale: 1}]   # linear,
//                                            # omitted keys carry over

#include <Eigen/Geometry>
#include <array>
#include <map>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "vrm_scene/meshes/mesh_generators.h"
#include "vrm_scene/registry.h"
#include "vrm_scene/yaml/yaml_error.h"

namespace vrm_sim {
namespace scene {

// Where a description came from, for error messages after loading (e.g. a mesh file that fails to import).
using SourceLocation = vrm_sim::SourceLocation;

enum class SceneKind { kAbstract, kSurgical };
enum class ObjectRole { kRetina, kMembrane, kIlm, kRigid, kAbstractTarget, kDecoration };
enum class ObjectFrame { kWorld, kEye };
enum class InstrumentType { kLightPipe, kForceps, kVitrector, kNeedle, kHook, kLaserProbe };
enum class InstrumentSlot { kLeft, kRight };
enum class Simulation { kTissue, kCollision, kGrasping, kCutting, kBleeding };

// Names as written in the scene files ("abstract", "retina", "mass_spring", "light_pipe", "left", "tissue", ...).
const char* toString(SceneKind kind);
const char* toString(ObjectRole role);
const char* toString(ObjectFrame frame);
const char* toString(InstrumentType type);
const char* toString(InstrumentSlot slot);
const char* toString(Simulation simulation);

// The instrument types by name (the registry's "factory" is the type itself): the scene schema, toString and the
// surgeon scripts read this table.
const Registry<InstrumentType>& instrumentTypeRegistry();
std::optional<InstrumentType> instrumentTypeNamed(const std::string& name);  // nullopt for an unknown name

// The tissue model of an object that does not deform (`model: none`); the deforming ones are
// tissue::tissueModelRegistry()'s names.
constexpr const char* kRigidTissueModel = "none";

struct Pose {
  Eigen::Vector3d xyz = Eigen::Vector3d::Zero();
  Eigen::Vector3d rpy_deg = Eigen::Vector3d::Zero();  // fixed-axis roll, pitch, yaw (R = Rz Ry Rx)
  Eigen::Isometry3d toIsometry() const;
};

struct Material {
  std::array<double, 4> diffuse_rgba{0.8, 0.8, 0.8, 1.0};
  std::array<double, 3> specular_rgb{0.2, 0.2, 0.2};
  double shininess = 16.0;
};

// Link limits of the ChainMail model (Gibson 1997), multiples of the rest length; see tissue/chainmail.h.
struct ChainMailParameters {
  double min_stretch = 0.8;       // (0, 1]
  double max_stretch = 1.2;       // >= 1
  double max_shear = 0.2;         // >= 0
  double relaxation = 0.0;        // [0, 1]: elastic relaxation per step (0 = purely inelastic)
  int relaxation_iterations = 1;  // sweeps per step
};

// Local refinement at the instruments (thesis §5.2.4); see tissue/refinement.h.
struct RefinementParameters {
  int levels = 0;                        // LOD n in [0, 4]; 0 = off
  double radius = 1e-3;                  // m around the instrument tip
  int element_budget = 2000;             // fine springs in all refined regions
  bool chain_stiffness_scaling = false;  // D(n) = 2^n D (eq. 5.14) instead of D
};

// Mass-spring parameters (thesis §5.1); defaults are a soft epiretinal membrane at the resolution of the default
// membrane patch. Only meaningful for a deforming model.
struct TissueParameters {
  std::string model = kRigidTissueModel;  // kRigidTissueModel or a tissue::tissueModelRegistry() name
  std::string integrator = "auto";        // a tissue::integratorRegistry() name
  // Where the two names were written (empty for defaults): the registries belong to the tissue layer, above this
  // one, so the names are checked where the World is built (world::checkSimulationNames) and point back here.
  SourceLocation model_location;
  SourceLocation integrator_location;
  double stiffness = 2.0;             // N/m, per spring (k in eq. 5.2)
  double damping = 0.01;              // N s/m
  double node_mass = 1e-5;            // kg per node
  double strain_limit = 1.1;          // tau_c of Alg. 5.1 (>= 1): springs are shortened to tau_c * rest length
  double bending_stiffness = 0.0;     // N/m, springs across adjacent triangles
  double adhesion_stiffness = 0.0;    // N/m, springs from the fixed (adhesion) vertices to their rest positions
  double adhesion_break_force = 0.0;  // N; > 0: an adhesion spring pulled harder lets go (peels off); 0 = never
  double time_budget_ms = 2.0;        // integrate until spent (thesis §5.1; EyeSi: 2 ms for 1,500 springs)
  double dt = 1e-3;                   // s per integration step
  bool plastic = false;               // rest length follows the maximum length reached (thesis §5.1)
  double early_stop_force = 0.0;      // N; > 0: a frame ends early once no free node feels more (at rest); 0 = off
  double tear_strain = 0.0;           // > 1: springs longer than tear_strain x rest length break (tearing); 0 = off
  // Adhesion that peels over time (tissue::TissueConfig): an adhesion pulled past adhesion_break_force lets go after
  // adhesion_release_time [s] (0 = at once); past adhesion_tear_force [N] (0 = never) it tears the tissue beneath.
  double adhesion_release_time = 0.0;
  double adhesion_tear_force = 0.0;
  // Subretinal fluid (retina relocation): > 0 [Pa] the needle's injection (InstrumentState.injection_flow) fills the
  // space between this sheet and the eye wall it rests on and lifts it into a bleb; 0 = no fluid. A torn sheet lets
  // the fluid out with the time constant fluid_leak_time [s].
  double fluid_modulus = 0.0;
  double fluid_leak_time = 2.0;
  // > 0 [m]: the needle pierces this sheet (it does not push it); its tip behind the sheet, the fluid it injects enters
  // there (within this distance of the tip), and moving it sideways more than needle_slack [m] slices the sheet along
  // its path (the sheet's nodes within this distance of the shaft where it crosses the sheet): a torn retina.
  double needle_pierce_radius = 0.0;
  double needle_slack = 1e-4;
  // > 0 [m]: the vitrector's suction (at least suction_hold_level, cutter off) holds the nodes within this distance of
  // its shaft's surface at the port (engaging the posterior hyaloid; the port's facing is not tracked); they follow it
  // until the suction drops below the level.
  double suction_hold_radius = 0.0;
  double suction_hold_level = 0.2;
  ChainMailParameters chainmail;    // only with model chainmail
  RefinementParameters refinement;  // only with model mass_spring, no bending springs, no adhesion
  bool isDeformable() const { return model != kRigidTissueModel; }
};

struct CollisionParameters {
  std::string detector = "zcoll_f";   // "none" = the object does not collide; a collision::detectorRegistry() name
  SourceLocation detector_location;   // where it was written, for the check with the World (as for the tissue names)
  int resolution = 64;                // image-space buffer edge in pixels (thesis §4.2.6)
  double epsilon_shell_scale = 1.05;  // detection shell around instruments (thesis §5.1, Fig 5.1)
};

// Exactly one of `generator` (a procedural mesh) and `file` (an imported mesh) is set.
struct MeshSource {
  std::optional<GeneratorParams> generator;
  std::string file;    // absolute path after loading (resolved against the scene file's directory, then the
                       // package directory)
  double scale = 1.0;  // for `file`: e.g. 0.001 for a mesh in millimetres
};

struct ObjectDescription {
  std::string name;
  ObjectRole role = ObjectRole::kRigid;
  MeshSource mesh;
  ObjectFrame frame = ObjectFrame::kEye;
  Pose pose;  // of the object in `frame`
  Material material;
  TissueParameters tissue;  // model kNone = rigid
  CollisionParameters collision;
  SourceLocation location;
  bool isDeformable() const { return tissue.isDeformable(); }
};

// An insertion hole, fixed in the eye frame (thesis §7: the mechanical eye has two trocars).
struct Trocar {
  std::string name;
  Eigen::Vector3d position_in_eye = Eigen::Vector3d::Zero();
};

struct EyeDescription {
  double radius = 0.012;
  Eigen::Vector3d centre_in_world = Eigen::Vector3d::Zero();  // the rotation centre of the mechanical eye
  Eigen::Vector3d rest_rpy_deg = Eigen::Vector3d::Zero();     // eye frame orientation in the world at rest
  // Default: "left" and "right" on the eye sphere 45 deg from the optical axis (pars plana, ~3.5 mm behind the
  // limbus) at azimuths 150 and 30 deg (10 and 2 o'clock as seen through the microscope).
  std::vector<Trocar> trocars;
};

// One timed waypoint of a scripted instrument path. Between waypoints tip and jaw angle are interpolated linearly;
// the shaft always points from the instrument's trocar to the tip (the trocar is the pivot).
struct InstrumentWaypoint {
  double t = 0.0;                                        // s from the start, strictly increasing along a path
  Eigen::Vector3d tip_in_eye = Eigen::Vector3d::Zero();  // m, eye frame
  double jaw_angle_deg = 0.0;                            // forceps opening
  double suction = 0.0;                                  // 0..1 (vitrector aspiration, from the pedal)
  double cut_rate_hz = 0.0;                              // vitrector cutter
  double roll_deg = 0.0;  // about the shaft; 0: the jaws' x along the eye's tangent at the trocar (shaftOrientation)
  double injection_flow = 0.0;  // m^3/s
  // From this waypoint on the slot holds this instrument (an exchange); unset: the previous waypoint's, at the first
  // the scripted instrument's.
  std::optional<InstrumentType> type;
  // The tip written on a scene object (resolveSurfaceTargets, surface_target.h): `tip_in_eye` is the author's point
  // near it until resolved; empty: a plain eye-frame tip.
  std::string on;
  double height = 0.0;  // m above the object's surface (towards the eye centre); negative: below it
  SourceLocation location;
};

// The path at time t: linear between waypoints (tip, jaw, suction, cut rate, roll, injection flow; `type`, `on` and
// `height` are the earlier waypoint's), the first / last waypoint before / after the path (t set to t). The path must
// not be empty.
InstrumentWaypoint samplePath(const std::vector<InstrumentWaypoint>& path, double t);

// A scripted hand's physiological tremor (thesis §1.3: 8-12 Hz), added to the interpolated tip: a sinusoid of
// `amplitude` per axis (phases 0, 120, 240 degrees), so a script states exactly the tremor it tests.
struct PathTremor {
  double amplitude = 0.0;  // m; 0 = none
  double frequency_hz = 10.0;
  Eigen::Vector3d offset(double t) const;
};

struct InstrumentDescription {
  InstrumentSlot slot = InstrumentSlot::kLeft;
  InstrumentType type = InstrumentType::kLightPipe;
  std::string trocar;                          // name of an EyeDescription trocar
  GeneratorParams params = LightPipeParams{};  // the generator matching `type`
  std::vector<InstrumentType> alternatives;    // other instruments the trainee may switch to in this slot (GUI)
  Material material;
  std::vector<InstrumentWaypoint> path;  // scripted motion (tissue_offline); empty = driven by the trainee
  PathTremor tremor;                     // on the scripted path
  SourceLocation location;
};

// ---- training scenarios (the optional `scenario:` section) ----

// A type parameter as written: a number, a name, or a list of either (the scenario type checks what it needs).
struct ScenarioParam {
  std::vector<double> numbers;
  std::vector<std::string> names;
  SourceLocation location;
};

// One score item: 100 points at `best`, 0 at `worst`, linear in between, clamped (best < worst: less is better).
struct ScoringRule {
  std::string item;
  double weight = 1.0;
  double best = 0.0;
  double worst = 1.0;
  SourceLocation location;
};

struct FailureRule {
  std::string item;  // the scenario fails once this score item reaches `at_least`
  double at_least = 1.0;
  SourceLocation location;
};

// One instrument's part of a scripted session.
struct ScriptedInstrument {
  InstrumentSlot slot = InstrumentSlot::kRight;
  std::optional<InstrumentType> type;  // unset: the scene's instrument in the slot
  std::vector<InstrumentWaypoint> path;
  PathTremor tremor;
  SourceLocation location;
};

enum class Playback { kOnce, kLoop };
const char* toString(Playback playback);

// The eye's rotation in the world (world -> eye, about the eye centre) at a time; slerp between waypoints.
struct EyeWaypoint {
  double t = 0.0;
  Eigen::Vector3d rpy_deg = Eigen::Vector3d::Zero();  // fixed-axis roll, pitch, yaw (R = Rz Ry Rx), as Pose
  SourceLocation location;
  Eigen::Quaterniond rotation() const;
};

// The foot pedal: travel linear between waypoints, the buttons step.
struct PedalWaypoint {
  double t = 0.0;
  double travel = 0.0;  // 0..1
  bool reflux = false;
  bool instrument_switch = false;
  bool zoom_in = false;
  bool zoom_out = false;
  bool focus_near = false;
  bool focus_far = false;
  SourceLocation location;
};

// The pedal at time t: travel linear between waypoints, the buttons the earlier waypoint's; released (all zero) for an
// empty track; the first / last waypoint before / after it (t set to t).
PedalWaypoint samplePedals(const std::vector<PedalWaypoint>& pedals, double t);

// The microscope's knobs, linear between waypoints.
struct MicroscopeWaypoint {
  double t = 0.0;
  double focus_distance = 0.2;   // m, objective to focal plane
  double zoom = 1.0;             // magnification (1 = widest field)
  double ambient_light = 0.5;    // 0..1
  double disparity_scale = 1.0;  // 0..1
  SourceLocation location;
};

// One scripted session: the one scripted-motion format (issue 34). A scene's scenario.scripts hold them, a script
// file holds one (loadScript); the offline tools play its instruments in the World, vrm_tracking's device twins play
// all of it (vrm_tracking/surgeon_script.h). Tips are in the eye frame, every shaft pivots at its slot's trocar of the
// scene it plays in.
struct ScriptedSession {
  std::string name;
  Playback playback = Playback::kOnce;
  // A waypoint `on` an object the scene lacks: an error (false, a script written for a scene) or it keeps its
  // written tip (true: a script meant for every scene, e.g. the demo).
  bool keep_tip_on_missing_object = false;
  std::vector<ScriptedInstrument> instruments;
  std::vector<EyeWaypoint> eye;                // empty: at rest
  std::vector<PedalWaypoint> pedals;           // empty: released
  std::vector<MicroscopeWaypoint> microscope;  // empty: the defaults above
  SourceLocation location;

  // s: the last waypoint of any track (0 for none).
  double duration() const;
  const ScriptedInstrument* findInstrument(InstrumentSlot slot) const;
};

struct ScenarioDescription {
  std::string type;  // scenario::scenarioRegistry()
  SourceLocation type_location;
  std::string description;
  double time_limit = 0.0;  // s of running time; 0 = none
  std::map<std::string, ScenarioParam> params;
  std::vector<FailureRule> fail_if;
  std::vector<ScoringRule> scoring;
  std::vector<std::string> difficulty_levels;  // in file order
  std::string difficulty;                      // the level this description was loaded with ("" = no levels)
  std::map<std::string, ScriptedSession> scripts;
  SourceLocation location;

  const ScenarioParam* param(const std::string& name) const;
};

struct SceneDescription {
  std::string name;
  std::string description;
  SceneKind kind = SceneKind::kSurgical;
  EyeDescription eye;
  std::vector<ObjectDescription> objects;
  std::vector<InstrumentDescription> instruments;
  std::set<Simulation> simulations;
  std::optional<ScenarioDescription> scenario;
  std::string source_file;  // absolute path of the YAML file, empty if built in code

  // The loader guarantees: hasDeformableObjects() == simulates(Simulation::kTissue).
  bool hasDeformableObjects() const;
  // s: the last waypoint of the instruments' scripted paths (0 without any).
  double scriptedDuration() const;
  bool simulates(Simulation simulation) const { return simulations.count(simulation) > 0; }
  const ObjectDescription* findObject(const std::string& object_name) const;
  const Trocar* findTrocar(const std::string& trocar_name) const;
  const InstrumentDescription* findInstrument(InstrumentSlot slot) const;
};

// The scene with its instruments following the scripted session `script` (scenario.scripts): each scripted slot's
// path and tremor replaced, every other slot's path cleared. Throws std::invalid_argument naming the known scripts.
// A scripted instrument of another type than the scene's takes that type's generator defaults. Waypoints `on` scene
// objects must be resolved (resolveSurfaceTargets) before; withScript(scene, name) does it.
SceneDescription withScript(const SceneDescription& scene, const std::string& script);
SceneDescription withScript(const SceneDescription& scene, const ScriptedSession& script);
// The scene's scripted session `name`; std::invalid_argument naming the known scripts.
const ScriptedSession& findScript(const SceneDescription& scene, const std::string& name);

// The instrument generator's defaults for a type.
GeneratorParams defaultInstrumentParams(InstrumentType type);
std::vector<Trocar> defaultTrocars(double eye_radius);

}  // namespace scene
}  // namespace vrm_sim
