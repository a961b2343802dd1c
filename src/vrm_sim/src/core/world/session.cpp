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
  loaded_scene_ = name;
  loaded_difficulty_ = command.argument;
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

std::string Session::checkpoint() const {
  std::string bytes;
  checkpoint(bytes);
  return bytes;
}

void Session::checkpoint(std::string& buffer) const {
  StateArchive archive = StateArchive::saverInto(std::move(buffer));
  archive.section("vrm_session");
  std::uint64_t loads = loads_;
  std::uint32_t seed = seed_;
  std::string scene = loaded_scene_, difficulty = loaded_difficulty_;
  std::uint64_t next_sequence = mediator_.nextSequence();
  archive(loads)(seed)(scene)(difficulty)(next_sequence);
  world_->saveState(archive);
  buffer = archive.takeBytes();
}

void Session::restoreCheckpoint(const std::string& bytes) {
  StateArchive archive = StateArchive::loader(bytes);
  archive.section("vrm_session");
  std::uint64_t loads = 0, next_sequence = 0;
  std::uint32_t seed = 0;
  std::string scene, difficulty;
  archive(loads)(seed)(scene)(difficulty)(next_sequence);
  if (loads > 0) {
    world_ = std::make_unique<World>(loader_(scene, difficulty), options_);
    world_->setFrameObserver(frame_observer_);
    world_->setInputObserver(input_observer_);
    mediator_.setSlots(mediatorOptionsFor(world_->scene(), options_).slots);
  }
  world_->loadState(archive);
  if (!archive.atEnd()) archive.fail(std::to_string(archive.remaining()) + " bytes left over");
  loads_ = loads;
  seed_ = seed;
  loaded_scene_ = scene;
  loaded_difficulty_ = difficulty;
  mediator_.setNextSequence(next_sequence);
  if (loads > 0 && load_observer_) load_observer_(*world_);
}

}  // namespace world
}  // namespace vrm_sim
