#include "vrm_sim/world/session.h"

#include "vrm_sim/scene/scene_loader.h"

namespace vrm_sim {
namespace world {

scene::SceneDescription Session::loadByName(const std::string& scene, const std::string& difficulty) {
  return scene::loadScene(scene, difficulty);
}

Session::Session(scene::SceneDescription scene, WorldOptions options, Loader loader)
    : options_(std::move(options)), loader_(std::move(loader)) {
  world_ = std::make_unique<World>(std::move(scene), options_);
}

void Session::setFrameObserver(FrameObserver observer) {
  frame_observer_ = std::move(observer);
  world_->setFrameObserver(frame_observer_);
}

void Session::handle(const ScenarioCommand& command) {
  if (command.command != ScenarioCommand::Type::kLoad) {
    world_->handle(command);
    return;
  }
  const std::string name = command.scenario.empty() ? world_->scene().source_file : command.scenario;
  std::unique_ptr<World> next;
  try {
    next = std::make_unique<World>(loader_(name, command.argument), options_);
  } catch (const std::exception& error) {
    const std::string message = "LOAD '" + name + "'" +
                                (command.argument.empty() ? "" : " (" + command.argument + ")") +
                                " refused, the current session continues: " + error.what();
    if (options_.log) options_.log(Severity::kWarning, message);
    world_->note(message);
    return;
  }
  world_->flush();  // the old scene's last frame closes; nothing of it runs afterwards
  world_ = std::move(next);
  world_->setFrameObserver(frame_observer_);
  seed_ = command.seed;
  ++loads_;
  if (options_.log) {
    options_.log(Severity::kInfo, "LOAD: scene '" + world_->scene().name + "'" +
                                      (world_->scenarioStatus() && !world_->scenarioStatus()->difficulty.empty()
                                           ? ", difficulty " + world_->scenarioStatus()->difficulty
                                           : ""));
  }
  if (load_observer_) load_observer_(*world_);
}

}  // namespace world
}  // namespace vrm_sim
