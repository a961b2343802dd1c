// World checkpoints (issue 39 §1): for every shipped scenario scene, its expert session is recorded frame by frame; a
// checkpoint taken after frame K and restored into a World built afresh from the scene, fed the frames after K, must
// reach the state hash of the uninterrupted session after every later frame, end with the same score, and leave a
// checkpoint byte-identical to the uninterrupted one's (which covers what the hash does not: grasp offsets, anchors,
// warm starts, scenario internals). Bad checkpoints are refused.

#include <gtest/gtest.h>

#include <algorithm>
#include <stdexcept>
#include <string>
#include <vector>

#include "vrm_scene/scene_loader.h"
#include "vrm_sim/world/offline.h"
#include "vrm_sim/world/session.h"
#include "vrm_sim/world/world.h"

namespace vrm_sim {
namespace world {
namespace {

struct Recording {
  scene::SceneDescription scene;
  std::vector<InputFrame> frames;
};

WorldOptions quietOptions() {
  WorldOptions options;
  options.log = [](Severity, const std::string&) {};
  return options;
}

// The scene's expert session as the simulation node applies it, as input frames (the journal's content).
Recording record(const std::string& name, double max_seconds) {
  const scene::SceneDescription base = scene::loadScene(scene::shippedScenePath(name));
  Recording recording{scene::withScript(base, "expert"), {}};
  const std::vector<scene::PedalWaypoint>& pedals = scene::findScript(base, "expert").pedals;
  World live(recording.scene, quietOptions());
  live.setInputObserver([&recording](const InputFrame& frame) { recording.frames.push_back(frame); });
  const double seconds =
      std::min(max_seconds, std::max(recording.scene.scriptedDuration(), pedals.empty() ? 0.0 : pedals.back().t) + 1.0);
  const long ticks = std::lround(seconds * 50.0);
  for (long tick = 0; tick <= ticks; ++tick) {
    const double t = static_cast<double>(tick) / 50.0;
    const Stamp stamp = fromSeconds(1000.0 + t);
    for (const InstrumentState& input : scriptedInputsAt(recording.scene, t, stamp)) live.handle(input);
    if (!pedals.empty()) {
      const scene::PedalWaypoint sample = scene::samplePedals(pedals, t);
      PedalState pedal;
      pedal.stamp = stamp;
      pedal.travel = sample.travel;
      pedal.reflux = sample.reflux;
      pedal.instrument_switch = sample.instrument_switch;
      live.handle(pedal);
    }
    live.flush();
  }
  return recording;
}

std::vector<std::string> scenarioScenes() {
  std::vector<std::string> names;
  for (const std::string& name : scene::shippedScenes()) {
    const scene::SceneDescription scene = scene::loadScene(scene::shippedScenePath(name));
    if (scene.scenario && !scene.scenario->scripts.empty()) names.push_back(name);
  }
  return names;
}

class WorldCheckpoint : public ::testing::TestWithParam<std::string> {};

TEST_P(WorldCheckpoint, RestoredWorldContinuesBitForBit) {
  const Recording recording = record(GetParam(), 10.0);
  const std::size_t n = recording.frames.size();
  ASSERT_GT(n, 30u);

  // The uninterrupted session, replayed: its hash after every frame and checkpoints at a few frames.
  const std::vector<std::size_t> at = {1, n / 3, 2 * n / 3, n - 2};
  World reference(recording.scene, quietOptions());
  std::vector<std::uint64_t> hashes;
  std::vector<std::string> checkpoints;
  for (std::size_t k = 0; k < n; ++k) {
    reference.handle(recording.frames[k]);
    hashes.push_back(reference.stateHash());
    if (std::find(at.begin(), at.end(), k + 1) != at.end()) checkpoints.push_back(reference.checkpoint());
  }
  const std::string final_checkpoint = reference.checkpoint();
  ASSERT_TRUE(reference.scenarioStatus() != nullptr);
  // The recording exercised something: the scenario ran.
  EXPECT_NE(reference.scenarioStatus()->state, scenario::State::kIdle);

  for (std::size_t c = 0; c < at.size(); ++c) {
    SCOPED_TRACE("checkpoint after frame " + std::to_string(at[c]) + " of " + std::to_string(n));
    World restored(recording.scene, quietOptions());
    ASSERT_NO_THROW(restored.restoreCheckpoint(checkpoints[c]));
    EXPECT_EQ(restored.stateHash(), hashes[at[c] - 1]);
    EXPECT_EQ(restored.checkpoint(), checkpoints[c]) << "a restored World checkpoints to other bytes";
    for (std::size_t k = at[c]; k < n; ++k) {
      restored.handle(recording.frames[k]);
      ASSERT_EQ(restored.stateHash(), hashes[k]) << "frame " << k + 1 << " after the restore diverged";
    }
    EXPECT_EQ(restored.scenarioStatus()->score.total, reference.scenarioStatus()->score.total);
    EXPECT_EQ(restored.scenarioStatus()->state, reference.scenarioStatus()->state);
    EXPECT_TRUE(restored.checkpoint() == final_checkpoint) << "state outside the hash diverged";
  }
}

INSTANTIATE_TEST_SUITE_P(ShippedScenarios, WorldCheckpoint, ::testing::ValuesIn(scenarioScenes()),
                         [](const ::testing::TestParamInfo<std::string>& info) { return info.param; });

// A Session that LOADed another scene (and difficulty) mid-session: its checkpoint names that scene, and a Session
// built from the start scene, as a restarted node builds it, restores into the LOADed one and goes on bit for bit.
TEST(SessionCheckpoint, ALoadedSceneIsRebuiltAndContinues) {
  const scene::SceneDescription start = scene::loadScene(scene::shippedScenePath("membrane_peeling"));
  const scene::SceneDescription next =
      scene::withScript(scene::loadScene(scene::shippedScenePath("navigation"), "hard"), "expert");
  // The LOADed scene's script drives the instruments: the loader gives the scripted scene for this LOAD.
  const Session::Loader loader = [&next](const std::string& name, const std::string& difficulty) {
    if (name != "navigation" || difficulty != "hard") throw std::invalid_argument("unexpected LOAD " + name);
    return next;
  };
  std::vector<InputFrame> frames;
  {
    Session live(start, quietOptions(), loader);
    live.setInputObserver([&frames](const InputFrame& frame) { frames.push_back(frame); });
    ScenarioCommand load;
    load.stamp = fromSeconds(1000.0);
    load.command = ScenarioCommand::Type::kLoad;
    load.scenario = "navigation";
    load.argument = "hard";
    load.seed = 7;
    live.handle(load);
    for (long tick = 1; tick <= 400; ++tick) {
      const double t = static_cast<double>(tick) / 50.0;
      for (const InstrumentState& input : scriptedInputsAt(next, t, fromSeconds(1000.0 + t))) live.handle(input);
      live.flush();
    }
    ASSERT_EQ(live.loads(), 1u);
  }
  ASSERT_GT(frames.size(), 300u);
  const std::size_t at = frames.size() / 2;
  Session reference(start, quietOptions(), loader);
  std::string checkpoint;
  std::vector<std::uint64_t> hashes;
  for (std::size_t k = 0; k < frames.size(); ++k) {
    reference.handle(frames[k]);
    hashes.push_back(reference.world().stateHash());
    if (k + 1 == at) checkpoint = reference.checkpoint();
  }
  Session restored(start, quietOptions(), loader);
  restored.restoreCheckpoint(checkpoint);
  EXPECT_EQ(restored.world().scene().name, next.name);
  EXPECT_EQ(restored.loads(), 1u);
  EXPECT_EQ(restored.seed(), 7u);
  EXPECT_EQ(restored.nextSequence(), reference.nextSequence());
  for (std::size_t k = at; k < frames.size(); ++k) {
    restored.handle(frames[k]);
    ASSERT_EQ(restored.world().stateHash(), hashes[k]) << "frame " << k + 1;
  }
  EXPECT_EQ(restored.checkpoint(), reference.checkpoint());
}

TEST(WorldCheckpointErrors, BadCheckpointsAreRefused) {
  const Recording recording = record("membrane_peeling", 6.0);
  World source(recording.scene, quietOptions());
  for (const InputFrame& frame : recording.frames) source.handle(frame);
  const std::string bytes = source.checkpoint();
  // Cut short anywhere: refused (never a silent partial state).
  for (std::size_t cut : {std::size_t{0}, std::size_t{10}, bytes.size() / 3, bytes.size() / 2, bytes.size() - 1}) {
    World target(recording.scene, quietOptions());
    EXPECT_THROW(target.restoreCheckpoint(bytes.substr(0, cut)), StateError) << "cut at " << cut;
  }
  // Trailing bytes: refused.
  {
    World target(recording.scene, quietOptions());
    EXPECT_THROW(target.restoreCheckpoint(bytes + "x"), StateError);
  }
  // Another scene: refused by name.
  const scene::SceneDescription other = scene::loadScene(scene::shippedScenePath("navigation"));
  World target(other, quietOptions());
  try {
    target.restoreCheckpoint(bytes);
    ADD_FAILURE() << "accepted";
  } catch (const StateError& error) {
    EXPECT_NE(std::string(error.what()).find("the scene differs"), std::string::npos) << error.what();
  }
}

}  // namespace
}  // namespace world
}  // namespace vrm_sim
