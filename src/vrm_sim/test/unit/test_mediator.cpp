// The mediator on its own (world/mediator.h): no physics, no scene — device inputs in, input frames out. Each case
// states what a consumer of the frames must be able to rely on.
#include <gtest/gtest.h>

#include <algorithm>
#include <vector>

#include "vrm_sim/world/mediator.h"

namespace vrm_sim {
namespace world {
namespace {

constexpr Stamp kTick = 20'000'000;  // 50 Hz

EyeState eyeAt(Stamp stamp) {
  EyeState eye;
  eye.stamp = stamp;
  return eye;
}

InstrumentState instrumentAt(Stamp stamp, const std::string& slot = "right", double x = 0.0) {
  InstrumentState state;
  state.stamp = stamp;
  state.slot = slot;
  state.tip_position = Eigen::Vector3d(x, 0.0, 0.0);
  return state;
}

struct Recorder {
  std::vector<InputFrame> frames;
  Mediator mediator;
  explicit Recorder(MediatorOptions options = {})
      : mediator(std::move(options), [this](InputFrame& frame) { frames.push_back(frame); }) {}
  std::vector<Stamp> stamps(InputFrame::Kind kind = InputFrame::Kind::kFrame) const {
    std::vector<Stamp> result;
    for (const InputFrame& frame : frames) {
      if (frame.kind == kind) result.push_back(frame.stamp);
    }
    return result;
  }
  bool has(const std::vector<std::string>& names, const std::string& name) const {
    return std::find(names.begin(), names.end(), name) != names.end();
  }
};

TEST(Mediator, FramesCloseInStampOrderWhateverOrderTheirInputsArriveIn) {
  Recorder out;
  // Tick 1 from both sources, then tick 3's eye before tick 2's, tick 2's instrument last.
  out.mediator.handle(eyeAt(1 * kTick));
  out.mediator.handle(instrumentAt(1 * kTick));
  out.mediator.handle(eyeAt(2 * kTick));
  out.mediator.handle(eyeAt(3 * kTick));
  out.mediator.handle(instrumentAt(2 * kTick));
  out.mediator.handle(instrumentAt(3 * kTick));
  out.mediator.flush();
  EXPECT_EQ(out.stamps(), (std::vector<Stamp>{1 * kTick, 2 * kTick, 3 * kTick}));
  for (std::size_t i = 0; i < out.frames.size(); ++i) {
    EXPECT_EQ(out.frames[i].sequence, i + 1);
    EXPECT_EQ(out.frames[i].eye_inputs.size(), 1u);
    EXPECT_EQ(out.frames[i].instrument_inputs.size(), 1u);
    EXPECT_TRUE(out.frames[i].missing.empty()) << "frame " << i;
  }
  EXPECT_EQ(out.mediator.statistics().late_inputs, 0u);
}

TEST(Mediator, AFrameWaitsForEverySourceThatDeliveredBefore) {
  Recorder out;
  out.mediator.handle(eyeAt(1 * kTick));
  out.mediator.handle(instrumentAt(1 * kTick));
  out.mediator.handle(eyeAt(2 * kTick));  // closes frame 1 (first frame: a later stamp arrived)
  ASSERT_EQ(out.stamps().size(), 1u);
  out.mediator.handle(eyeAt(3 * kTick));  // frame 2 still waits for the instrument
  EXPECT_EQ(out.stamps().size(), 1u);
  out.mediator.handle(instrumentAt(2 * kTick));
  EXPECT_EQ(out.stamps(), (std::vector<Stamp>{1 * kTick, 2 * kTick}));
}

TEST(Mediator, ASilentSourceHoldsFramesBackForAtMostReorderFramesAndIsWaitedForAgainOnceBack) {
  MediatorOptions options;
  options.reorder_frames = 2;
  Recorder out(options);
  Stamp t = 0;
  for (int i = 0; i < 5; ++i) {  // both sources, 0.1 s
    t += kTick;
    out.mediator.handle(eyeAt(t));
    out.mediator.handle(instrumentAt(t));
  }
  const std::size_t before_silence = out.stamps().size();
  // The instrument falls silent for 1 s (50 ticks): frames must keep closing, at most reorder_frames behind.
  const Stamp silence_start = t;
  for (int i = 0; i < 50; ++i) {
    t += kTick;
    out.mediator.handle(eyeAt(t));
    ASSERT_GE(static_cast<Stamp>(out.stamps().size()), static_cast<Stamp>(before_silence) + i + 1 - 3)
        << "frames held back by a silent source at tick " << i;
  }
  const auto silenced = std::find_if(out.frames.begin(), out.frames.end(),
                                     [&](const InputFrame& frame) { return !frame.silenced.empty(); });
  ASSERT_NE(silenced, out.frames.end());
  EXPECT_EQ(silenced->silenced, std::vector<std::string>{"instrument:right"});
  EXPECT_EQ(silenced->stamp, silence_start + kTick);  // the first frame it missed
  EXPECT_TRUE(out.has(silenced->missing, "instrument:right"));
  EXPECT_EQ(out.mediator.statistics().silenced, 1u);
  // Back: it delivers again and is waited for again (the eye runs one tick ahead; its frame waits).
  t += kTick;
  out.mediator.handle(instrumentAt(t));
  out.mediator.handle(eyeAt(t));
  const std::size_t closed = out.stamps().size();
  out.mediator.handle(eyeAt(t + kTick));
  out.mediator.handle(eyeAt(t + 2 * kTick));
  EXPECT_EQ(out.stamps().size(), closed) << "the instrument that is back must be waited for again";
  out.mediator.handle(instrumentAt(t + kTick));
  EXPECT_EQ(out.stamps().size(), closed + 1);
  EXPECT_EQ(out.frames.back().instrument_inputs.size(), 1u);
  EXPECT_GT(out.mediator.statistics().frames_without_source, 0u);
  EXPECT_LE(out.mediator.statistics().frames_without_source, 50u);
}

TEST(Mediator, AnInputOlderThanTheLastFrameIsLateAppliedFirstInTheNextFrameAndCounted) {
  Recorder out;
  Stamp t = 0;
  for (int i = 0; i < 3; ++i) {
    t += kTick;
    out.mediator.handle(eyeAt(t));
    out.mediator.handle(instrumentAt(t));
  }
  // The instrument stops for 3 ticks (the frames close without it), then its tick-4 state arrives late.
  for (int i = 0; i < 4; ++i) out.mediator.handle(eyeAt(t + (i + 1) * kTick));
  const Stamp last_closed = out.stamps().back();
  ASSERT_GE(last_closed, t + kTick);
  out.mediator.handle(instrumentAt(t + kTick, "right", 0.001));
  EXPECT_EQ(out.mediator.statistics().late_inputs + out.mediator.unreported().late_inputs, 1u);
  out.mediator.handle(eyeAt(t + 5 * kTick));
  out.mediator.flush();
  const auto with_late =
      std::find_if(out.frames.begin(), out.frames.end(), [](const InputFrame& frame) { return !frame.late.empty(); });
  ASSERT_NE(with_late, out.frames.end());
  EXPECT_GT(with_late->stamp, last_closed);
  ASSERT_FALSE(with_late->instrument_inputs.empty());
  EXPECT_EQ(with_late->instrument_inputs.front().tip_position.x(), 0.001);
  EXPECT_EQ(with_late->late_inputs, 1u);
}

TEST(Mediator, ABurstOfQueuedInputsClosesEveryFrameInOrder) {
  Recorder out;
  out.mediator.handle(eyeAt(kTick));
  out.mediator.handle(instrumentAt(kTick));
  // 40 ticks of the eye arrive at once (the callback queue held them), then the instrument's 40.
  for (int i = 2; i <= 41; ++i) out.mediator.handle(eyeAt(i * kTick));
  for (int i = 2; i <= 41; ++i) out.mediator.handle(instrumentAt(i * kTick));
  out.mediator.flush();
  std::vector<Stamp> expected;
  for (int i = 1; i <= 41; ++i) expected.push_back(i * kTick);
  // The eye ran ahead by more than reorder_frames: the instrument was declared silent, its states came late and
  // the frames closed without it. What matters: every frame closes once, in order, and the count says so.
  const std::vector<Stamp> stamps = out.stamps();
  EXPECT_TRUE(std::is_sorted(stamps.begin(), stamps.end()));
  EXPECT_EQ(std::adjacent_find(stamps.begin(), stamps.end()), stamps.end());
  EXPECT_EQ(stamps, expected);
  std::uint64_t late = 0;
  for (const InputFrame& frame : out.frames) late += frame.late_inputs;
  EXPECT_EQ(late, out.mediator.statistics().late_inputs);
}

TEST(Mediator, AFutureStampIsHeldBackAndIgnoredWhileTheOtherSourcesGoOn) {
  MediatorOptions options;
  options.max_stamp_jump = 1.0;
  Recorder out(options);
  Stamp t = 0;
  for (int i = 0; i < 3; ++i) {
    t += kTick;
    out.mediator.handle(eyeAt(t));
    out.mediator.handle(instrumentAt(t));
  }
  out.mediator.handle(instrumentAt(t + fromSeconds(1000.0)));  // a clock gone wrong
  for (int i = 0; i < 5; ++i) {
    t += kTick;
    out.mediator.handle(eyeAt(t));
    out.mediator.handle(instrumentAt(t));
  }
  out.mediator.flush();
  for (Stamp stamp : out.stamps()) EXPECT_LE(stamp, t) << "a frame closed at the future stamp";
  EXPECT_EQ(out.mediator.statistics().late_inputs, 0u);
  EXPECT_GE(out.mediator.statistics().rejected_inputs, 1u);
  const bool held =
      std::any_of(out.frames.begin(), out.frames.end(), [](const InputFrame& frame) { return frame.held_back > 0; });
  EXPECT_FALSE(held) << "the held input must be dropped once the source delivers normally again";
}

TEST(Mediator, ARealGapEveryHasSourceJumpedIsFollowed) {
  Recorder out;
  Stamp t = 0;
  for (int i = 0; i < 3; ++i) {
    t += kTick;
    out.mediator.handle(eyeAt(t));
    out.mediator.handle(instrumentAt(t));
  }
  t += fromSeconds(5.0);  // the input paused for 5 s
  for (int i = 0; i < 20; ++i) {
    t += kTick;
    out.mediator.handle(eyeAt(t));
    out.mediator.handle(instrumentAt(t));
  }
  out.mediator.flush();
  EXPECT_EQ(out.stamps().back(), t);
  EXPECT_GE(out.stamps().size(), 20u);
}

TEST(Mediator, TwoSourcesAtDifferentRatesCloseAFrameAtEveryStampOfEither) {
  Recorder out;
  // Eye at 100 Hz, instrument at 50 Hz: the instrument's stamps are every other eye stamp.
  const Stamp half = kTick / 2;
  for (int i = 0; i <= 20; ++i) {
    out.mediator.handle(eyeAt(i * half));
    if (i % 2 == 0) out.mediator.handle(instrumentAt(i * half));
  }
  out.mediator.flush();
  const std::vector<Stamp> stamps = out.stamps();
  EXPECT_EQ(stamps.size(), 21u);
  EXPECT_TRUE(std::is_sorted(stamps.begin(), stamps.end()));
  // An eye-only stamp closes once the instrument delivered a later one: never a late input, never silenced.
  EXPECT_EQ(out.mediator.statistics().late_inputs, 0u);
  EXPECT_EQ(out.mediator.statistics().silenced, 0u);
  std::size_t with_instrument = 0;
  for (const InputFrame& frame : out.frames) with_instrument += frame.instrument_inputs.size();
  EXPECT_EQ(with_instrument, 11u);
}

TEST(Mediator, TheNoWaitPolicyClosesAFrameAsSoonAsALaterStampArrives) {
  MediatorOptions options;
  options.policy = WaitPolicy::kNoWait;
  Recorder out(options);
  out.mediator.handle(eyeAt(kTick));
  out.mediator.handle(instrumentAt(kTick));
  out.mediator.handle(eyeAt(2 * kTick));
  ASSERT_EQ(out.stamps().size(), 1u);
  // The instrument is slow: the eye's next stamp closes frame 2 without it; its tick-2 state is late, applied first
  // in frame 3.
  out.mediator.handle(eyeAt(3 * kTick));
  EXPECT_EQ(out.stamps(), (std::vector<Stamp>{kTick, 2 * kTick}));
  EXPECT_TRUE(out.has(out.frames.back().missing, "instrument:right"));
  out.mediator.handle(instrumentAt(2 * kTick));
  out.mediator.handle(instrumentAt(3 * kTick));  // frame 3 is complete: closes at once
  EXPECT_EQ(out.stamps().back(), 3 * kTick);
  EXPECT_EQ(out.frames.back().instrument_inputs.size(), 2u);
  EXPECT_EQ(out.frames.back().late, std::vector<std::string>{"instrument:right"});
}

TEST(Mediator, TheNoWaitPolicyStopsExpectingASourceThatLeftAndExpectsItAgainOnceBack) {
  MediatorOptions options;
  options.policy = WaitPolicy::kNoWait;
  Recorder out(options);
  Stamp t = 0;
  for (int i = 0; i < 3; ++i) {
    t += kTick;
    out.mediator.handle(eyeAt(t));
    out.mediator.handle(instrumentAt(t));
  }
  // The instrument leaves. After reorder_frames frames without it, each eye state closes its own frame at once.
  for (int i = 0; i < 5; ++i) {
    t += kTick;
    out.mediator.handle(eyeAt(t));
  }
  EXPECT_EQ(out.stamps().back(), t) << "a frame waits for a source that left";
  EXPECT_EQ(out.mediator.statistics().silenced, 1u);
  // Back: expected again (its frame closes only once it delivered, or the next stamp arrives).
  t += kTick;
  out.mediator.handle(instrumentAt(t));
  t += kTick;
  out.mediator.handle(eyeAt(t));
  EXPECT_LT(out.stamps().back(), t) << "the instrument that is back is not waited for";
  out.mediator.handle(instrumentAt(t));
  EXPECT_EQ(out.stamps().back(), t);
}

TEST(Mediator, StateInputsGoIntoTheFirstFrameAtOrAfterTheirStampOrAFrameOfTheirOwn) {
  Recorder out;
  out.mediator.handle(eyeAt(kTick));
  PedalState pedals;
  pedals.stamp = 2 * kTick;
  pedals.travel = 0.5;
  out.mediator.handle(pedals);
  ScenarioCommand start;
  start.stamp = kTick + 1;
  out.mediator.handle(start);
  out.mediator.handle(eyeAt(2 * kTick));  // closes frame 1 (the first frame: a later stamp), then frame 2 (complete)
  out.mediator.handle(eyeAt(3 * kTick));  // waits for the pedals, which delivered up to 2 ticks only
  ASSERT_EQ(out.stamps().size(), 2u);
  EXPECT_TRUE(out.frames[0].pedals.empty());
  EXPECT_EQ(out.frames[1].pedals.size(), 1u);
  EXPECT_EQ(out.frames[1].commands.size(), 1u);
  // Nothing pending and older than the last frame: a kState frame of its own, at once.
  out.mediator.flush();
  ScenarioCommand pause;
  pause.stamp = kTick;
  pause.command = ScenarioCommand::Type::kPause;
  out.mediator.handle(pause);
  ASSERT_EQ(out.frames.back().kind, InputFrame::Kind::kState);
  EXPECT_EQ(out.frames.back().commands.size(), 1u);
}

TEST(Mediator, AFrameWaitsForThePedalsSoItsPedalStateDoesNotDependOnArrivalOrder) {
  // The pedals at 100 Hz with a phase of their own, the poses at 50 Hz; in one delivery the pedal state of a tick
  // comes after the poses of the next tick. Both deliveries must give every frame the same pedal state.
  const auto deliver = [](bool pedals_late) {
    Recorder out;
    for (int k = 1; k <= 20; ++k) {
      const Stamp t = k * kTick;
      PedalState before, at;
      before.stamp = t - kTick / 2 - 1000;
      before.travel = 0.01 * k;
      at.stamp = t - 1000;
      at.travel = 0.01 * k + 0.005;
      out.mediator.handle(before);
      if (!pedals_late) out.mediator.handle(at);
      out.mediator.handle(eyeAt(t));
      out.mediator.handle(instrumentAt(t));
      if (pedals_late) out.mediator.handle(at);
    }
    out.mediator.flush();
    std::vector<double> travel;
    double last = 0.0;
    for (const InputFrame& frame : out.frames) {
      if (!frame.pedals.empty()) last = frame.pedals.back().travel;
      if (frame.kind == InputFrame::Kind::kFrame) travel.push_back(last);
    }
    return travel;
  };
  EXPECT_EQ(deliver(false), deliver(true));
}

TEST(Mediator, GarbageForASlotNoDeviceServesDoesNotHoldFramesBack) {
  Recorder out;
  InstrumentState garbage = instrumentAt(0, "left");
  garbage.tip_position.x() = std::nan("");
  for (int k = 1; k <= 10; ++k) {
    out.mediator.handle(eyeAt(k * kTick));
    out.mediator.handle(instrumentAt(k * kTick));
    garbage.stamp = (k - 1) * kTick;  // a hostile stream one tick behind, for a slot nobody plays
    out.mediator.handle(garbage);
  }
  // Every frame closed as soon as its poses were in: never waited for "instrument:left", never declared it silent.
  EXPECT_EQ(out.stamps().size(), 10u);
  EXPECT_EQ(out.mediator.statistics().silenced, 0u);
  EXPECT_EQ(out.mediator.statistics().frames_without_source, 0u);
}

TEST(Mediator, APedalStateNewerThanTheStampMinusThePedalPeriodMeansNoWait) {
  Recorder out;
  // Pedals at 100 Hz, 3 ms before each pose tick and 7 ms after it: a frame needs no later pedal state than the one
  // 3 ms before its stamp, so it closes with its poses.
  for (int k = 1; k <= 10; ++k) {
    PedalState before, after;
    before.stamp = k * kTick - 3'000'000;
    after.stamp = k * kTick + 7'000'000;
    out.mediator.handle(before);
    out.mediator.handle(eyeAt(k * kTick));
    out.mediator.handle(instrumentAt(k * kTick));
    if (k >= 3) {
      EXPECT_EQ(out.stamps().back(), k * kTick) << "frame " << k << " waited for the pedals";
    }
    out.mediator.handle(after);
  }
}

TEST(Mediator, ALoadClosesEverythingPendingAndIsAFrameOfItsOwn) {
  Recorder out;
  out.mediator.handle(eyeAt(kTick));
  out.mediator.handle(instrumentAt(kTick));
  out.mediator.handle(eyeAt(2 * kTick));
  ScenarioCommand load;
  load.stamp = 2 * kTick;
  load.command = ScenarioCommand::Type::kLoad;
  load.scenario = "navigation";
  out.mediator.handle(load);
  ASSERT_GE(out.frames.size(), 3u);
  EXPECT_EQ(out.frames.back().kind, InputFrame::Kind::kLoad);
  EXPECT_EQ(out.stamps(), (std::vector<Stamp>{kTick, 2 * kTick}));
  for (std::size_t i = 0; i < out.frames.size(); ++i) EXPECT_EQ(out.frames[i].sequence, i + 1);
}

TEST(Mediator, RejectedInputsAreCountedAndNeverEnterAFrame) {
  MediatorOptions options;
  options.slots = {"left", "right"};
  Recorder out(options);
  out.mediator.handle(eyeAt(kTick));
  InstrumentState nan_pose = instrumentAt(kTick);
  nan_pose.tip_position.x() = std::nan("");
  out.mediator.handle(nan_pose);
  out.mediator.handle(instrumentAt(kTick, "third_hand"));
  InstrumentState far = instrumentAt(kTick, "left");
  far.tip_position.x() = 1e300;
  out.mediator.handle(far);
  EyeState bad_eye = eyeAt(2 * kTick);
  bad_eye.rotation.coeffs() *= 2.0;
  out.mediator.handle(bad_eye);
  out.mediator.flush();
  std::uint64_t rejected = 0;
  for (const InputFrame& frame : out.frames) {
    rejected += frame.rejected_inputs;
    EXPECT_TRUE(frame.instrument_inputs.empty());
  }
  EXPECT_EQ(rejected, 4u);
  // The rejected eye state still counted as delivered: its stamp opens no frame.
  EXPECT_EQ(out.stamps(), (std::vector<Stamp>{kTick}));
}

}  // namespace
}  // namespace world
}  // namespace vrm_sim
