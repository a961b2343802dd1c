#include "vrm_sim/world/mediator.h"

#include <algorithm>
#include <cmath>

namespace vrm_sim {
namespace world {

namespace {

// Plausibility of the device inputs (issue 14): anything outside is a broken or hostile message, not a pose.
constexpr double kMaxInputDistance = 1.0;  // m from the eye (or the world origin) — the eye is 24 mm across
constexpr double kUnitTolerance = 1e-3;    // |‖q‖ − 1| of a rotation quaternion
constexpr double kMaxJawAngle = M_PI;      // rad
constexpr double kMaxCutRate = 1e4;        // Hz (vitrectors cut at up to ~170 Hz)
constexpr double kMaxPedalTravel = 1.5;
constexpr double kMaxInjectionFlow = 1e-6;  // m^3/s: 1 ml/s, far beyond any syringe through a 41 G cannula
constexpr double kGapConfirmation = 0.25;  // s of input time every source must go on after a jump far ahead

const std::string kEyeSource = "eye";
const std::string kPedalSource = "pedals";
std::string instrumentSource(const std::string& slot) { return "instrument:" + slot; }

}  // namespace

Stamp fromSeconds(double seconds) { return static_cast<Stamp>(std::llround(seconds * 1e9)); }

void InstrumentState::setPose(const Eigen::Isometry3d& pose) {
  tip_position = pose.translation();
  tip_orientation = Eigen::Quaterniond(pose.rotation());
}

Eigen::Isometry3d InstrumentState::pose() const {
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.linear() = tip_orientation.normalized().toRotationMatrix();
  pose.translation() = tip_position;
  return pose;
}

std::string checkEye(const EyeState& eye) {
  const bool ok = eye.rotation.coeffs().allFinite() && eye.rotation_center.allFinite() &&
                  eye.rotation_center.norm() < kMaxInputDistance &&
                  std::abs(eye.rotation.norm() - 1.0) < kUnitTolerance;
  return ok ? "" : "eye_state with a non-finite or non-unit rotation";
}

std::string checkInstrument(const InstrumentState& state) {
  if (!state.frame_id.empty() && state.frame_id != "eye" && state.frame_id != "world") {
    return "instrument_state '" + state.slot + "' in unknown frame '" + state.frame_id + "' (eye or world expected)";
  }
  const double norm = state.tip_orientation.norm();
  const bool ok = state.tip_position.allFinite() && state.tip_position.norm() < kMaxInputDistance &&
                  std::isfinite(norm) && std::abs(norm - 1.0) < kUnitTolerance && std::isfinite(state.jaw_angle) &&
                  std::abs(state.jaw_angle) <= kMaxJawAngle && std::isfinite(state.suction) && state.suction >= 0.0 &&
                  state.suction <= 1.0 && std::isfinite(state.cut_rate) && state.cut_rate >= 0.0 &&
                  state.cut_rate <= kMaxCutRate && std::isfinite(state.injection_flow) && state.injection_flow >= 0.0 &&
                  state.injection_flow <= kMaxInjectionFlow;
  return ok ? "" : "instrument_state '" + state.slot + "' with non-finite or implausible values";
}

std::string checkPedals(const PedalState& pedals) {
  return std::isfinite(pedals.travel) && std::abs(pedals.travel) <= kMaxPedalTravel ? ""
                                                                                    : "pedals with a non-finite travel";
}

Mediator::Mediator(MediatorOptions options, Sink sink) : options_(std::move(options)), sink_(std::move(sink)) {
  if (!sink_) throw std::invalid_argument("mediator: no sink for its frames");
}

void Mediator::log(Severity severity, const std::string& key, const std::string& message) {
  if (!options_.log) return;
  if (!key.empty()) {
    auto last = logged_at_frame_.find(key);
    if (last != logged_at_frame_.end() && statistics_.frames < last->second + options_.log_every_frames) return;
    logged_at_frame_[key] = statistics_.frames;
  }
  options_.log(severity, message);
}

void Mediator::handle(const EyeState& eye) {
  ++inputs_;
  const std::string problem = checkEye(eye);
  if (!problem.empty()) {
    ++rejected_inputs_;
    log(Severity::kWarning, "eye:nonfinite", problem + " ignored");
  }
  // A rejected eye state still counts as delivered, so its frame does not wait for it.
  acceptSource(eye.stamp, kEyeSource, problem.empty() ? &eye : nullptr, nullptr);
}

void Mediator::handle(const InstrumentState& state) {
  ++inputs_;
  if (!options_.slots.empty() && options_.slots.count(state.slot) == 0) {
    ++rejected_inputs_;
    log(Severity::kWarning, "slot:" + state.slot,
        "instrument_state for slot '" + state.slot + "', which the scene does not have, ignored");
    return;
  }
  const std::string problem = checkInstrument(state);
  if (!problem.empty()) {
    ++rejected_inputs_;
    log(Severity::kWarning, "nonfinite:" + state.slot, problem + " ignored");
  }
  acceptSource(state.stamp, instrumentSource(state.slot), nullptr, problem.empty() ? &state : nullptr);
}

void Mediator::handle(const PedalState& pedals) {
  ++inputs_;
  const std::string problem = checkPedals(pedals);
  if (!problem.empty()) {
    ++rejected_inputs_;
    log(Severity::kWarning, "pedals:nonfinite", problem + " ignored");
    return;
  }
  buffered_pedals_.push_back(pedals);
  // The pedals are a source a frame waits for (kWait): the frame at S takes the newest pedal state up to S, and
  // closing it before that state arrived would make the pedal values of a frame depend on arrival order.
  if (options_.policy == WaitPolicy::kWait) {
    Stamp& latest = known_sources_[kPedalSource];
    // The pedals' period (the shortest step between their stamps): a frame at S already has the newest pedal state
    // up to S once a pedal state newer than S - period arrived, so it does not wait for the next one.
    if (latest > 0 && pedals.stamp > latest) {
      const Stamp step = pedals.stamp - latest;
      pedal_period_ = pedal_period_ > 0 ? std::min(pedal_period_, step) : step;
    }
    latest = std::max(latest, pedals.stamp);
    closeReadyFrames();
  }
  // Nothing pending that would take it, and its frame has passed: it takes effect now, as a frame of its own.
  if (last_frame_stamp_ && pedals.stamp <= *last_frame_stamp_ && pending_.empty()) {
    InputFrame frame;
    frame.kind = InputFrame::Kind::kState;
    frame.stamp = *last_frame_stamp_;
    takeStateInputs(*last_frame_stamp_, frame);
    emit(frame);
  }
}

void Mediator::handle(const ScenarioCommand& command) {
  ++inputs_;
  if (command.command == ScenarioCommand::Type::kLoad) {
    // The old scene's frames close first; nothing of them reaches the new one.
    flush();
    InputFrame frame;
    frame.kind = InputFrame::Kind::kLoad;
    frame.stamp = command.stamp;
    frame.commands.push_back(command);
    emit(frame);
    return;
  }
  buffered_commands_.push_back(command);
  if (last_frame_stamp_ && command.stamp <= *last_frame_stamp_ && pending_.empty()) {
    InputFrame frame;
    frame.kind = InputFrame::Kind::kState;
    frame.stamp = *last_frame_stamp_;
    takeStateInputs(*last_frame_stamp_, frame);
    emit(frame);
  }
}

void Mediator::flush() {
  while (!pending_.empty()) {
    const Stamp stamp = pending_.begin()->first;
    Pending inputs = std::move(pending_.begin()->second);
    pending_.erase(pending_.begin());
    closeFrame(stamp, std::move(inputs), {});
  }
  // State inputs no frame took (newer than the last one): they still happened.
  if (!buffered_pedals_.empty() || !buffered_commands_.empty()) {
    InputFrame frame;
    frame.kind = InputFrame::Kind::kState;
    Stamp newest = last_frame_stamp_.value_or(0);
    for (const PedalState& pedals : buffered_pedals_) newest = std::max(newest, pedals.stamp);
    for (const ScenarioCommand& command : buffered_commands_) newest = std::max(newest, command.stamp);
    frame.stamp = newest;
    takeStateInputs(newest, frame);
    emit(frame);
  }
}

void Mediator::acceptSource(Stamp stamp, const std::string& source, const EyeState* eye,
                            const InstrumentState* instrument) {
  switch (classifyStamp(stamp, source)) {
    case StampCheck::kStale:
      return;
    case StampCheck::kAhead:
      held_back_.push_back({stamp, source, eye ? std::optional<EyeState>(*eye) : std::nullopt,
                            instrument ? std::optional<InstrumentState>(*instrument) : std::nullopt});
      if (held_back_.size() > kMaxHeldBack) {
        ++rejected_inputs_;
        held_back_.erase(held_back_.begin());
      }
      return;
    case StampCheck::kGap: {
      // Every source jumped: the inputs held back so far are the first of the new stretch.
      std::vector<HeldInput> held;
      held.swap(held_back_);
      for (const HeldInput& input : held) {
        assembleSource(input.stamp, input.source, input.eye ? &*input.eye : nullptr,
                       input.instrument ? &*input.instrument : nullptr);
      }
      break;
    }
    case StampCheck::kNormal:
      if (!held_back_.empty()) {
        rejected_inputs_ += static_cast<std::uint32_t>(held_back_.size());
        log(Severity::kWarning, "stamp:ahead",
            std::to_string(held_back_.size()) + " inputs with stamps far ahead of the others ignored");
        held_back_.clear();
      }
      break;
  }
  assembleSource(stamp, source, eye, instrument);
}

void Mediator::assembleSource(Stamp stamp, const std::string& source, const EyeState* eye,
                              const InstrumentState* instrument) {
  // A rejected input of a source the frames already wait for counts as delivered (its frame need not wait for it);
  // garbage alone never makes a source one to wait for (a hostile stream for a slot no device serves would hold
  // every frame back until the source is declared silent, again and again).
  const bool usable = eye != nullptr || instrument != nullptr;
  if (usable || known_sources_.count(source) > 0) {
    Stamp& latest = known_sources_[source];
    latest = std::max(latest, stamp);
  }
  if (last_frame_stamp_ && stamp <= *last_frame_stamp_) {
    ++late_inputs_;  // its state takes effect in the next frame
    if (eye) late_.eye = *eye;
    if (instrument) late_.instruments[instrument->slot] = *instrument;
    if (std::find(late_sources_.begin(), late_sources_.end(), source) == late_sources_.end()) {
      late_sources_.push_back(source);
    }
  } else if (eye || instrument || pending_.count(stamp) > 0) {
    Pending& frame = pending_[stamp];
    if (eye) frame.eye = *eye;
    if (instrument) frame.instruments[instrument->slot] = *instrument;
  }  // a rejected input at a new stamp opens no frame: a flood of garbage must not make the world step for it
  closeReadyFrames();
}

Mediator::StampCheck Mediator::classifyStamp(Stamp stamp, const std::string& source) {
  const Stamp jump = fromSeconds(options_.max_stamp_jump);
  if (last_frame_stamp_ && stamp < *last_frame_stamp_ - jump) {
    ++rejected_inputs_;
    log(Severity::kWarning, "stamp:stale:" + source,
        source + " delivered a stamp " + std::to_string(toSeconds(*last_frame_stamp_ - stamp)) +
            " s older than the last frame; ignored");
    return StampCheck::kStale;
  }
  if (known_sources_.empty()) return StampCheck::kNormal;
  Stamp newest = known_sources_.begin()->second;
  for (const auto& known : known_sources_) newest = std::max(newest, known.second);
  if (stamp <= newest + jump) {
    jumped_sources_.clear();
    return StampCheck::kNormal;
  }
  // A real gap (the input paused, a device restarted) moves every source, and each goes on at its rate from there;
  // garbage stamps interleave with the devices' normal ones, which clear the count. So the jump is followed once
  // every known source has delivered far-ahead stamps spanning kGapConfirmation of input time, none normal between.
  auto [span, inserted] = jumped_sources_.try_emplace(source, stamp, stamp);
  if (!inserted) {
    span->second.first = std::min(span->second.first, stamp);
    span->second.second = std::max(span->second.second, stamp);
  }
  const Stamp confirmation = fromSeconds(kGapConfirmation);
  const bool every_source_jumped = std::all_of(known_sources_.begin(), known_sources_.end(), [&](const auto& known) {
    if (known.first == kPedalSource) return true;  // a state source: its stamps are not checked for jumps
    const auto jumped = jumped_sources_.find(known.first);
    return jumped != jumped_sources_.end() && jumped->second.second - jumped->second.first >= confirmation;
  });
  if (every_source_jumped) {
    jumped_sources_.clear();
    log(Severity::kInfo, "stamp:gap",
        "the input resumed " + std::to_string(toSeconds(stamp - newest)) + " s later (every source jumped)");
    return StampCheck::kGap;
  }
  log(Severity::kWarning, "stamp:ahead:" + source,
      source + " delivered a stamp " + std::to_string(toSeconds(stamp - newest)) +
          " s ahead of the other inputs; held back until every source has jumped likewise");
  return StampCheck::kAhead;
}

bool Mediator::delivered(const std::string& source, Stamp newest, Stamp stamp) const {
  if (newest >= stamp) return true;
  return source == kPedalSource && pedal_period_ > 0 && newest + pedal_period_ > stamp;
}

void Mediator::closeReadyFrames() {
  while (!pending_.empty()) {
    const Stamp stamp = pending_.begin()->first;
    const bool complete = std::all_of(known_sources_.begin(), known_sources_.end(), [&](const auto& source) {
      return delivered(source.first, source.second, stamp);
    });
    bool ready;
    if (!last_frame_stamp_) {
      // The first frame cannot know its sources yet: it closes when a later stamp arrives.
      ready = pending_.size() > 1;
    } else if (options_.policy == WaitPolicy::kNoWait) {
      ready = complete || pending_.size() > 1;
    } else {
      ready = complete;
    }
    if (!ready && options_.policy == WaitPolicy::kWait && pending_.size() > 1) {
      // The pedals hold a frame back one frame at most: a later pose stamp has arrived, so the view goes on without
      // the pedal state (the frame names them missing; they are waited for again from the next frame).
      ready = std::all_of(known_sources_.begin(), known_sources_.end(), [&](const auto& source) {
        return source.first == kPedalSource || delivered(source.first, source.second, stamp);
      });
    }
    std::vector<std::string> silenced;
    if (!ready && options_.policy == WaitPolicy::kWait && pending_.size() > options_.reorder_frames) {
      // A source fell silent: do not hold the view back for it any longer.
      ready = true;
      for (auto source = known_sources_.begin(); source != known_sources_.end();) {
        if (!delivered(source->first, source->second, stamp)) {
          log(Severity::kWarning, "silent:" + source->first,
              source->first + " stopped delivering; frames close without it until it is back");
          silenced.push_back(source->first);
          ++statistics_.silenced;
          source = known_sources_.erase(source);
        } else {
          ++source;
        }
      }
    }
    if (ready && options_.policy == WaitPolicy::kNoWait) {
      // A source that missed more than reorder_frames frames in a row is not expected any longer: else every frame
      // would wait for the next stamp of another source to close it (a whole input period of latency).
      for (auto source = known_sources_.begin(); source != known_sources_.end();) {
        if (delivered(source->first, source->second, stamp)) {
          missed_frames_.erase(source->first);
          ++source;
        } else if (++missed_frames_[source->first] > options_.reorder_frames) {
          log(Severity::kInfo, "silent:" + source->first,
              source->first + " stopped delivering; frames close without waiting for it until it is back");
          silenced.push_back(source->first);
          ++statistics_.silenced;
          missed_frames_.erase(source->first);
          source = known_sources_.erase(source);
        } else {
          ++source;
        }
      }
    }
    if (!ready) return;
    Pending inputs = std::move(pending_.begin()->second);
    pending_.erase(pending_.begin());
    closeFrame(stamp, std::move(inputs), std::move(silenced));
  }
}

void Mediator::closeFrame(Stamp stamp, Pending inputs, std::vector<std::string> silenced) {
  InputFrame frame;
  frame.kind = InputFrame::Kind::kFrame;
  frame.stamp = stamp;
  // Late inputs first (their state held since the previous frame), then this frame's: eye, then the slots in order.
  if (late_.eye) frame.eye_inputs.push_back(std::move(*late_.eye));
  if (inputs.eye) frame.eye_inputs.push_back(std::move(*inputs.eye));
  for (auto& [slot, state] : late_.instruments) frame.instrument_inputs.push_back(std::move(state));
  for (auto& [slot, state] : inputs.instruments) frame.instrument_inputs.push_back(std::move(state));
  late_ = Pending{};
  frame.late = std::move(late_sources_);
  late_sources_.clear();
  // Sources known before this frame that had not delivered its stamp (silenced ones included).
  for (const auto& [source, newest] : known_sources_) {
    if (!delivered(source, newest, stamp)) frame.missing.push_back(source);
  }
  for (const std::string& source : silenced) frame.missing.push_back(source);
  std::sort(frame.missing.begin(), frame.missing.end());
  frame.silenced = std::move(silenced);
  frame.held_back = static_cast<std::uint32_t>(held_back_.size());
  takeStateInputs(stamp, frame);
  last_frame_stamp_ = stamp;
  if (!frame.missing.empty()) ++statistics_.frames_without_source;
  emit(frame);
}

void Mediator::takeStateInputs(Stamp up_to, InputFrame& frame) {
  auto by_stamp = [](const auto& a, const auto& b) { return a.stamp < b.stamp; };
  std::stable_sort(buffered_pedals_.begin(), buffered_pedals_.end(), by_stamp);
  std::stable_sort(buffered_commands_.begin(), buffered_commands_.end(), by_stamp);
  auto pedal = buffered_pedals_.begin();
  for (; pedal != buffered_pedals_.end() && pedal->stamp <= up_to; ++pedal) frame.pedals.push_back(*pedal);
  buffered_pedals_.erase(buffered_pedals_.begin(), pedal);
  auto command = buffered_commands_.begin();
  for (; command != buffered_commands_.end() && command->stamp <= up_to; ++command) frame.commands.push_back(*command);
  buffered_commands_.erase(buffered_commands_.begin(), command);
}

void Mediator::emit(InputFrame& frame) {
  frame.sequence = next_sequence_++;
  frame.inputs = inputs_;
  frame.late_inputs = late_inputs_;
  frame.rejected_inputs = rejected_inputs_;
  statistics_.inputs += inputs_;
  statistics_.late_inputs += late_inputs_;
  statistics_.rejected_inputs += rejected_inputs_;
  inputs_ = late_inputs_ = rejected_inputs_ = 0;
  ++statistics_.frames;
  sink_(frame);
}

}  // namespace world
}  // namespace vrm_sim
