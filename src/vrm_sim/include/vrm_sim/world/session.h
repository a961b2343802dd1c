#pragma once
// A session of the VR part: the World of the loaded scene, replaced as a whole when ScenarioCommand LOAD names
// another scene or difficulty (thesis §2.4: the scenario manager owns the VR objects and simulations; a new scenario
// brings its own, and nothing of the old one keeps running). Every other input goes to the current World unchanged.
// A LOAD that fails (unknown scene, broken YAML, a scene the simulation cannot run) leaves the running session as it
// was and says why in the scenario status and the log. ROS-free; the scenario_manager nodelet wraps it.

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

  void handle(const EyeState& eye) { world_->handle(eye); }
  void handle(const InstrumentState& instrument) { world_->handle(instrument); }
  void handle(const PedalState& pedals) { world_->handle(pedals); }
  void handle(const ScenarioCommand& command);
  void flush() { world_->flush(); }

  World& world() { return *world_; }
  const World& world() const { return *world_; }
  void setFrameObserver(FrameObserver observer);
  void setLoadObserver(LoadObserver observer) { load_observer_ = std::move(observer); }
  std::uint32_t seed() const { return seed_; }  // of the last LOAD (0 before any)
  std::uint64_t loads() const { return loads_; }

 private:
  WorldOptions options_;
  Loader loader_;
  std::unique_ptr<World> world_;
  FrameObserver frame_observer_;
  LoadObserver load_observer_;
  std::uint32_t seed_ = 0;
  std::uint64_t loads_ = 0;
};

}  // namespace world
}  // namespace vrm_sim
