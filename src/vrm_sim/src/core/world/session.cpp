#include "vrm_sim/world/session.h"

#include "vrm_scene/scene_loader.h"

namespace vrm_sim {
namespace world {

scene::SceneDescription Session::loadByName(const std::string& scene, const std::string& difficulty) {
  return scene::loadScene(scene, difficulty);
}

Session::Session(scene::SceneDescription scene, WorldOptions options, Loader loader)
    : options_(std::move(options)),
      loader_(std::move(loader)),
      world_(std::make_unique<World>(std::move(scene), options_)),
      mediator_(mediatorOptionsFor(world_->scene(), options_), [this](InputFrame& frame) { onFrame(frame); }) {}

void Session::setFrameObserver(FrameObserver observer) {
  frame_observer_ = std::move(observer);
  world_->setFrameObserver(frame_observer_);
}

void Session::setInputObserver(InputObserver observer) {
  input_observer_ = std::move(observer);
  world_->setInputObserver(input_observer_);
}

void Session::handle(const InputFrame& frame) {
  if (frame.kind == InputFrame::Kind::kLoad) {
    InputFrame copy = frame;
    load(copy);
    return;
  }
  world_->handle(frame);
}

void Session::onFrame(InputFrame& frame) {
  if (frame.kind == InputFrame::Kind::kLoad) {
    load(frame);
  } else {
    world_->handle(frame);
  }
}

void Session::load(InputFrame& frame) {
  if (frame.commands.empty() || frame.commands.front().command != ScenarioCommand::Type::kLoad) return;
  const ScenarioCommand& command = frame.commands.front();
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
    // Recorded all the same: a replay tries the same LOAD and is refused the same way.
    world_->fillApplied(frame);
    if (input_observer_) input_observer_(frame);
    return;
  }
  world_ = std::move(next);
  world_->setFrameObserver(frame_observer_);
  world_->setInputObserver(input_observer_);
  mediator_.setSlots(mediatorOptionsFor(world_->scene(), options_).slots);
  seed_ = command.seed;
  ++loads_;
  if (options_.log) {
    options_.log(Severity::kInfo, "LOAD: scene '" + world_->scene().name + "'" +
                                      (world_->scenarioStatus() && !world_->scenarioStatus()->difficulty.empty()
                                           ? ", difficulty " + world_->scenarioStatus()->difficulty
                                           : ""));
  }
  world_->fillApplied(frame);
  if (input_observer_) input_observer_(frame);
  if (load_observer_) load_observer_(*world_);
}

}  // namespace world
}  // namespace vrm_sim
