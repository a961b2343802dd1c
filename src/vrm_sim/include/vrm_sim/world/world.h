#pragma once
// The simulation core of the VR part (thesis §2.4: VR objects, simulations and the scenario behind the mediators):
// one ROS-free World that owns the loaded scene, its deformable tissues, the colliders of every object, the
// instruments and the session state, and advances one *frame* per input tick. The scenario_manager nodelet, the offline
// tools (tissue_offline, and the replay tools built on it) and the tests all drive this one class through the same
// handle() calls — the cartographer_ros pattern of one handler path for live and recorded input.
//
// Frames. The World consumes input frames (world/mediator.h): the mediator groups the device inputs by stamp and
// decides which inputs belong to a frame, which came late and which source fell silent; the World applies a frame's
// inputs (eye first, then the instruments in the given order, then pedals and commands in stamp order) and closes
// it (collision → tissue step → bleeding → scenario → hash → observer). A session (world/session.h) owns the
// mediator and publishes every frame; a replay feeds the recorded frames, so both apply the same sequence. handle()
// of a device input goes through the World's own mediator (offline tools, tests) with the same rules.
// The simulated time of a frame is the stamp difference to the previous frame (capped by max_frame_time); tissue
// steps are fixed-Δt substeps of it (the time budget is a step count, never wall time, unless wall_clock_budget is
// set). With the default options no wall clock enters the result, so the same input sequence gives the same state
// bit for bit (stateHash()), live, replayed from a bag or offline.
// The world advances only while its session runs: a scenario from START (or the first frame with auto_start) until
// it finishes, fails or is stopped; a scene without a scenario from the start (or START without auto_start) until
// STOP. Frames outside that window are still assembled (instruments move, collisions can be reported) but change no
// hashed state, so the final state of a session does not depend on how long its inputs went on before or after it.
//
// Frames of reference: each object lives in the eye or the world frame (scene `frame`); instrument poses arrive in
// "eye" or "world" and are moved into each object's frame with the eye pose of the frame they belong to.

#include <Eigen/Geometry>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "vrm_scene/scene_description.h"
#include "vrm_sim/collision/collision_detector.h"
#include "vrm_sim/scenario/runner.h"
#include "vrm_sim/world/bleeding.h"
#include "vrm_sim/world/inputs.h"
#include "vrm_sim/world/mediator.h"

namespace vrm_sim {
namespace mge {
class Membrane;
}
namespace tissue {
class TissueSimulator;
struct SimulatorStatistics;
struct InstrumentInput;
}  // namespace tissue

namespace world {

// ---- outputs ----

// How a peel went (scene objects with role membrane / ilm): torn as soon as one stretch spring tore.
enum class PeelOutcome { kUntouched, kGrasped, kLifted, kTorn };
const char* toString(PeelOutcome outcome);

struct TissueReport {
  std::string object;
  std::string frame_id;  // "eye" | "world"
  const mge::Membrane* membrane = nullptr;
  int steps = 0;           // this frame
  int fallbacks = 0;       // watchdog rollbacks this frame
  std::string integrator;  // in use, with its substeps per dt ("symplectic_euler x2"; TissueSimulator::integratorLabel)
  double max_strain = 0.0;  // after this frame
  std::size_t grasped_nodes = 0;
  bool changed = false;                  // positions or topology changed this frame
  std::uint64_t version = 1;             // +1 per changed frame
  std::uint64_t topology_version = 1;    // 1 + topology changes
  std::uint64_t torn_springs = 0;        // so far
  std::uint64_t cut_nodes = 0;           // so far
  std::uint64_t released_adhesions = 0;  // adhesion points pulled off so far
  double max_lift = 0.0;                 // m: largest distance of a node from its rest position
  double lifted_fraction = 0.0;          // nodes more than 0.1 mm from their rest position
  std::size_t adhesion_points = 0;       // adhesion springs still holding
  double max_adhesion_force = 0.0;       // N, largest pull on an adhesion point so far
  std::uint64_t adhesion_tears = 0;      // adhesions that tore the tissue beneath (adhesion_tear_force) so far
  const std::vector<Eigen::Vector3d>* adhesion_tear_points = nullptr;  // where, in frame_id
  // Subretinal fluid (scene fluid_modulus > 0; else 0): injected volume under the sheet, the volume the sheet
  // encloses, the pressure of the last step, and what the needle injected with its tip not behind the sheet.
  double fluid_volume = 0.0, enclosed_volume = 0.0, fluid_pressure = 0.0, injected_outside = 0.0;  // m^3, Pa
  bool needle_inside = false;  // a needle's tip is behind the sheet (needle_pierce_radius)
  PeelOutcome outcome = PeelOutcome::kUntouched;
};

struct InjuryReport {
  std::string object;  // the retina
  std::string frame_id;
  const std::vector<float>* injury = nullptr;  // per vertex, 0..1
  const TriangleMesh* mesh = nullptr;          // the object's (rigid) surface the field lives on
  bool changed = false;
  std::uint64_t version = 1;
  double max_injury = 0.0;
  double injured_area = 0.0;  // m^2 of the surface with injury above 0.1
  std::size_t contacts = 0;   // contact events so far
  bool in_contact = false;    // a contact event is ongoing
};

// One instrument vs one object in this frame (reported for tissues and the bleeding retina always, for other rigid
// objects only while setRigidReports(true)).
struct CollisionRecord {
  std::string instrument;  // slot
  std::string object;
  std::string frame_id;
  std::string detector;
  collision::CollisionResult result;
  collision::SurfaceView surface;  // valid until the next frame
};

struct StageTime {
  std::string stage;              // collision_<object>, tissue_<object>, bleeding, collision_rigid
  double start = 0.0, end = 0.0;  // by WorldOptions::clock (measurement only)
};

struct FrameResult {
  Stamp stamp = 0;
  std::uint64_t frame = 0;  // 1, 2, ...
  double frame_time = 0.0;  // s of simulated time covered
  bool paused = false;
  std::vector<TissueReport> tissues;
  std::vector<InjuryReport> injuries;
  std::vector<CollisionRecord> collisions;
  std::vector<ContactEvent> contacts_ended;  // retina contact events that ended in this frame
  std::vector<StageTime> stages;
  double wall_time = 0.0;  // s, by WorldOptions::clock
  std::uint64_t state_hash = 0;
  const scenario::Status* scenario = nullptr;  // the scene's scenario after this frame (null: the scene has none)
};

struct WorldStatistics {
  std::uint64_t frames = 0;
  std::uint64_t inputs = 0;
  std::uint64_t simulated_frames = 0;       // frames in which the world advanced (the session ran)
  std::uint64_t late_inputs = 0;            // frame sources older than the last closed frame
  std::uint64_t rejected_inputs = 0;        // non-finite values, unknown slot or frame
  std::uint64_t frames_without_source = 0;  // frames closed while a known source had not delivered (it fell silent)
  std::uint64_t input_sequence = 0;         // of the last input frame applied
  std::uint64_t tissue_steps = 0;
  double max_strain = 0.0;
  std::size_t max_grasped_nodes = 0;
  double max_frame_wall_time = 0.0;  // s
  double total_frame_wall_time = 0.0;
};

using Clock = std::function<double()>;  // s, monotonic
using FrameObserver = std::function<void(const FrameResult&)>;
using InputObserver = std::function<void(const InputFrame&)>;

struct WorldOptions {
  std::string detector_override;  // non-empty: this collision detector for every object
  double collision_max_pixel_size = 0.0;
  double max_frame_time = 0.05;  // s: a longer gap between stamps (start, pause of the input) is capped
  // s: a frame source whose stamp is this far ahead of every source's newest is held back as implausible (one
  // future stamp would otherwise close a frame there and make every real input late) until every known source has
  // jumped likewise (a real gap: the input paused, a device restarted); one this far behind the last frame is
  // rejected as stale (issue 14).
  double max_stamp_jump = 1.0;
  // Measurement only (stage times, frame wall time); the default is a steady clock. Never decides a result unless
  // wall_clock_budget is set.
  Clock clock;
  // true: each tissue frame stops integrating when its time_budget_ms of wall time is spent (thesis §5.1), which
  // makes the result depend on the machine's speed. false (default): every frame integrates its whole simulated
  // time (bounded by max_frame_time), deterministic; over-budget frames are only counted.
  bool wall_clock_budget = false;
  BleedingParameters bleeding;
  Log log;
  // A scene with a scenario: true starts it with the first frame (and again with the first frame after a RESET), as
  // a scripted or replayed session expects; false waits for ScenarioCommand START (the console). Until it runs, the
  // world is frozen like in PAUSE.
  bool auto_start = true;
};

// The mediator set-up for a scene: its slots, the world's stamp-jump limit and log.
MediatorOptions mediatorOptionsFor(const scene::SceneDescription& scene, const WorldOptions& options);

class World {
 public:
  // Builds tissues, colliders and instruments from `scene`. Throws scene::SceneError / std::invalid_argument for a
  // scene the simulation cannot run.
  World(scene::SceneDescription scene, WorldOptions options = {});
  ~World();
  World(const World&) = delete;
  World& operator=(const World&) = delete;

  // Device inputs through the World's own mediator (offline tools, tests); a session feeds frames instead.
  void handle(const EyeState& eye) { mediator_.handle(eye); }
  void handle(const InstrumentState& instrument) { mediator_.handle(instrument); }
  void handle(const PedalState& pedals) { mediator_.handle(pedals); }
  void handle(const ScenarioCommand& command);
  // End of input: closes the pending frames, if any.
  void flush() { mediator_.flush(); }

  // One closed input frame (a session's mediator, or a recorded one in a replay): its inputs are checked again (a
  // recorded frame may be corrupt) and applied, and a kFrame steps the world. A kLoad frame is the session's
  // business: here it only resets when it names this scene.
  void handle(const InputFrame& frame);

  // Called after every kFrame (synchronously, from handle() / flush()).
  void setFrameObserver(FrameObserver observer) { observer_ = std::move(observer); }
  // Called for every input frame once its inputs are applied — before the frame's collision, tissue and scenario run
  // — with the applied eye and instrument states filled in (what the simulation node publishes and records).
  void setInputObserver(InputObserver observer) { input_observer_ = std::move(observer); }
  // The applied eye and instrument states now (what a frame's applied fields hold).
  void fillApplied(InputFrame& frame) const;
  // Whether rigid objects without bleeding are collided too (only for reports; never changes the state).
  void setRigidReports(bool enabled) { rigid_reports_ = enabled; }

  const scene::SceneDescription& scene() const { return scene_; }
  // Counted from the frames applied, plus what the World's own mediator counted since its last frame.
  WorldStatistics statistics() const;
  std::uint64_t frame() const { return statistics_.frames; }
  std::optional<Stamp> lastFrameStamp() const { return last_frame_stamp_; }
  // The World's own mediator (handle() of device inputs): its numbering continues a session's.
  Mediator& mediator() { return mediator_; }
  bool paused() const { return paused_; }
  bool simulatesAnything() const;
  // FNV-1a over every tissue's node positions, velocities and rest lengths, its topology version and grasped
  // nodes, every injury field, and the session flags: equal inputs give an equal hash, bit for bit.
  std::uint64_t stateHash() const;

  std::vector<std::string> tissueNames() const;
  mge::Membrane* membrane(const std::string& object);
  const tissue::TissueSimulator* tissueSimulator(const std::string& object) const;
  tissue::TissueSimulator* tissueSimulator(const std::string& object);
  TissueReport tissueReport(const std::string& object) const;
  const std::vector<float>* injury(const std::string& object) const;
  const std::vector<InjuryReport>& injuries() const { return last_injuries_; }
  std::vector<ContactEvent> contactEvents() const;  // all retina contact events so far
  const PedalState& pedals() const { return pedals_; }
  // The scenario's state and score; null for a scene without a scenario section.
  const scenario::Status* scenarioStatus() const { return runner_ ? &runner_->status() : nullptr; }
  // A message for the trainee in the scenario status (e.g. a refused command); no effect without a scenario.
  void note(const std::string& message) {
    if (runner_) runner_->setMessage(message);
  }
  // Checkpoints (issue 39 §1): the World's whole state at a frame boundary, as bytes for this build, and its restore
  // into a World built from the same scene and options (a fresh one: a session's World after a crash). After a
  // restore, the frames that followed the checkpoint give the states the original reached, bit for bit. Throws
  // StateError where a state cannot be checkpointed yet (local refinement, the chainmail model, frames pending in the
  // World's own mediator) and, on restore, for bytes of another scene or build or cut short; the World is then
  // half restored and must be discarded (the caller restores from the journal instead).
  std::string checkpoint() const;
  void restoreCheckpoint(const std::string& bytes);
  // The same, into / from a caller's archive (a Session's checkpoint around it; a reused buffer).
  void saveState(StateArchive& archive) const { const_cast<World&>(*this).transferState(archive); }
  void loadState(StateArchive& archive) { transferState(archive); }

  // Whether the world advances (tissue, bleeding) in the next frame: not while paused or before the scenario starts.
  bool simulating() const;
  // The session is over: its scenario finished or failed (a STOP included), or a scene without a scenario was
  // stopped. Nothing changes the state any more until a RESET.
  bool sessionEnded() const;

 private:
  struct Instrument;
  struct Collider;
  struct Tissue;
  struct RigidObject;

  void buildInstruments();
  void buildTissues();
  void buildRigidObjects();
  void placeRigidObjects();
  void resetTissues();
  std::optional<Collider> makeCollider(const scene::ObjectDescription& object) const;
  // Repeated warnings (same key) at most every kLogEveryFrames frames; an empty key is never throttled.
  void log(Severity severity, const std::string& key, const std::string& message);
  void transferState(StateArchive& archive);

  void apply(InputFrame& frame);
  void applyEye(const EyeState& eye);
  void applyInstrument(const InstrumentState& state);
  void closeFrame(InputFrame& frame);
  void apply(const ScenarioCommand& command);
  void setInstrumentType(Instrument& instrument, scene::InstrumentType type);
  bool switchInstrument(Instrument& instrument, scene::InstrumentType type);
  std::optional<Eigen::Isometry3d> transform(const std::string& target, const std::string& source) const;
  void stepTissue(Tissue& tissue, double frame_time, FrameResult& result);
  void holdWithoutJaws(Tissue& tissue, const std::string& slot, const Instrument& source,
                       tissue::InstrumentInput& input);
  void bleed(RigidObject& object, FrameResult& result);
  void advanceScenario(const FrameResult& result);
  void refuse(const std::string& message);
  collision::CollisionResult collide(Collider& collider, const std::string& slot, Instrument& instrument,
                                     const Eigen::Isometry3d& pose, const collision::SurfaceView& surface);
  double now() const;

  scene::SceneDescription scene_;
  WorldOptions options_;
  std::map<std::string, std::unique_ptr<Instrument>> instruments_;
  std::map<std::string, std::unique_ptr<Tissue>> tissues_;
  std::vector<std::unique_ptr<RigidObject>> rigid_;
  Eigen::Isometry3d world_from_eye_ = Eigen::Isometry3d::Identity();
  bool eye_valid_ = false;

  Mediator mediator_;
  std::optional<Stamp> last_frame_stamp_;
  std::optional<Stamp> simulation_origin_;  // stamp of the first frame the world advanced in (bleeding's clock)
  std::map<std::string, std::uint64_t> logged_at_frame_;
  PedalState pedals_;
  bool paused_ = false;
  bool running_ = true;
  bool started_ = true;  // a scene without a scenario: START seen (or auto_start)
  bool rigid_reports_ = false;
  std::unique_ptr<scenario::ScenarioRunner> runner_;
  bool auto_started_ = false;

  FrameObserver observer_;
  InputObserver input_observer_;
  WorldStatistics statistics_;
  std::vector<InjuryReport> last_injuries_;
  mutable std::size_t checkpoint_bytes_ = 0;  // the last checkpoint's size, reserved for the next
};

}  // namespace world
}  // namespace vrm_sim
