#pragma once
// A session of the VR part: the mediator (world/mediator.h) that turns the device inputs into input frames, and the
// World of the loaded scene that consumes them, replaced as a whole when ScenarioCommand LOAD names another scene or
// difficulty (thesis §2.4: the scenario manager owns the VR objects and simulations; a new scenario
// brings its own, and nothing of the old one keeps running). Every other input goes to the current World unchanged.
// A LOAD that fails (unknown scene, broken YAML, a scene the simulation cannot run) leaves the running session as it
// was and says why in the scenario status and the log. Every frame — a LOAD included — reaches the input observer
// (the simulation node publishes and records it); a replay hands the recorded frames to handle(InputFrame) and
// repeats the session frame by frame. ROS-free; the scenario_manager nodelet wraps it.

#include <functional>
#include <memory>
#include <string>

#include "vrm_sim/world/world.h"

namespace vrm_sim {
namespace world {

class Session {
 public:
  // Loads a scene by name or path with a difficulty level ("" = default); throws scene::SceneError.
  using Loader = std::function<scene::SceneDescription(const std::string& scene, const std::string& difficulty)>;
  // Called after a LOAD replaced the world (the adapters advertise the new scene's topics).
  using LoadObserver = std::function<void(World&)>;

  // The shipped-scene loader (scene::loadScene: a name or a path).
  static scene::SceneDescription loadByName(const std::string& scene, const std::string& difficulty);

  explicit Session(scene::SceneDescription scene, WorldOptions options = {}, Loader loader = loadByName);

  void handle(const EyeState& eye) { mediator_.handle(eye); }
  void handle(const InstrumentState& instrument) { mediator_.handle(instrument); }
  void handle(const PedalState& pedals) { mediator_.handle(pedals); }
  void handle(const ScenarioCommand& command) { mediator_.handle(command); }
  void flush() { mediator_.flush(); }
  // A recorded input frame (replay): applied as the live session applied it.
  void handle(const InputFrame& frame);

  // Every input frame once the World applied its inputs (a LOAD's after the switch): see World::setInputObserver.
  void setInputObserver(InputObserver observer);
  const MediatorStatistics& mediatorStatistics() const { return mediator_.statistics(); }
  // A session restored from its journal after a crash (issue 39) numbers its next frames on from the restored ones,
  // so the recorded frames of both processes form one sequence.
  std::uint64_t nextSequence() const { return mediator_.nextSequence(); }
  void continueSequence(std::uint64_t next) { mediator_.setNextSequence(next); }

  // Checkpoints (issue 39 §1): the World's state (World::checkpoint) with the scene it runs (the start scene or the
  // last LOAD's), the LOAD count and seed, and the next frame number. restoreCheckpoint() on a Session built like the
  // checkpointed one (same start scene, options and loader) rebuilds a LOADed scene first, then the World's state; the
  // frames after the checkpoint then continue it bit for bit (the mediator starts afresh, as after a journal restore:
  // inputs it held at the crash were not applied yet). Throws StateError (see World::restoreCheckpoint), after which
  // the Session must be discarded; scene::SceneError if the LOADed scene no longer loads.
  std::string checkpoint() const;
  // Into `buffer`'s memory (a periodic checkpoint hands back the last one's: see StateArchive::saverInto).
  void checkpoint(std::string& buffer) const;
  void restoreCheckpoint(const std::string& bytes);

  World& world() { return *world_; }
  const World& world() const { return *world_; }
  void setFrameObserver(FrameObserver observer);
  void setLoadObserver(LoadObserver observer) { load_observer_ = std::move(observer); }
  std::uint32_t seed() const { return seed_; }  // of the last LOAD (0 before any)
  std::uint64_t loads() const { return loads_; }

 private:
  void onFrame(InputFrame& frame);
  void load(InputFrame& frame);

  WorldOptions options_;
  Loader loader_;
  std::unique_ptr<World> world_;
  Mediator mediator_;
  FrameObserver frame_observer_;
  InputObserver input_observer_;
  LoadObserver load_observer_;
  std::uint32_t seed_ = 0;
  std::uint64_t loads_ = 0;
  std::string loaded_scene_, loaded_difficulty_;  // the last LOAD's loader arguments (loads_ > 0)
};

}  // namespace world
}  // namespace vrm_sim
