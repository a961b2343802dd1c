#pragma once
// The mediator between the I/O part and the VR part (thesis §2.4): device inputs in, consistent input frames out. It
// knows no physics, no GL and no ROS; the World (world/world.h) consumes its frames only, the simulation node
// publishes every frame (vrm_msgs/InputFrame) and the session bag records it, so a replay feeds the very frames the
// live session closed — every decision that depended on arrival order or on a source falling silent is in the record.
//
// Frames. Inputs carry their stamps (ns, from header.stamp; nothing here reads a clock):
//   * eye and instrument states are *frame sources* ("eye", "instrument:<slot>"): all of them that carry the same
//     stamp S belong to the frame at S. Every source delivers in stamp order (one topic is one FIFO), so with the
//     kWait policy frame S is complete — and closes — as soon as every known source has delivered at S or later. A
//     source that falls silent holds frames back for at most `reorder_frames` later frames; then the oldest frame
//     closes without it (the frame names it in `missing`, the source is `silenced`) and it is not waited for until it
//     delivers again. The very first frame, whose sources are not known yet, closes when a later stamp arrives;
//     flush() closes whatever is pending. With the kNoWait policy (a consumer that must never wait, like the rig
//     twin upstream of tracking) a frame closes as soon as it is complete or any later stamp arrives, and a source
//     that missed more than `reorder_frames` frames in a row is not expected until it delivers again (so a hand that
//     left does not make every frame wait for the next stamp).
//     A source state older than the last closed frame is *late*: it is applied first in the next frame and counted.
//     A stamp more than max_stamp_jump ahead of every source is held back as implausible until every known source has
//     jumped likewise (a real gap: the input paused, a device restarted); one that far behind the last frame is
//     rejected as stale.
//   * pedal states and scenario commands are *state inputs*: they go into the first frame with a stamp >= theirs, in
//     stamp order. The pedals ("pedals") are also a source the kWait policy waits for like the poses (a frame takes
//     the pedal state of its stamp, whenever it arrives), though they never open a frame — but only when a pedal
//     state may still be missing: with one newer than the frame's stamp minus the pedals' period (the shortest step
//     between their stamps) there is none between it and the frame. One that arrives when nothing is pending and its stamp is not newer than the last frame is a frame
//     of its own (kind kState), so a console's START takes effect without waiting for the next pose. A LOAD closes
//     everything pending and is a frame of its own (kind kLoad): the session switches scenes there.
// Inputs with non-finite or implausible values, an unknown slot or frame are rejected (counted; a rejected source
// state still counts as delivered, so its frame does not wait for it).

#include <Eigen/Geometry>
#include <cstdint>
#include <functional>
#include <map>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "vrm_sim/world/inputs.h"

namespace vrm_sim {
namespace world {

// One slot as the World applied it in a frame: what renderer, tf and markers draw.
struct AppliedInstrument {
  std::string slot;
  scene::InstrumentType type = scene::InstrumentType::kForceps;
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();  // in frame_id
  std::string frame_id = "eye";
  double jaw_angle = 1.0;
  double suction = 0.0;
  double cut_rate = 0.0;
  bool cutting = false;
  bool valid = false;      // tracked and interacting
  bool delivered = false;  // an input of this slot is applied in this frame
};

struct InputFrame {
  enum class Kind { kFrame, kState, kLoad };
  Kind kind = Kind::kFrame;
  Stamp stamp = 0;
  std::uint64_t sequence = 0;  // 1, 2, ... per mediator
  // In the order the World applies them: a late input first, then this frame's (by slot).
  std::vector<EyeState> eye_inputs;
  std::vector<InstrumentState> instrument_inputs;
  std::vector<PedalState> pedals;         // stamp order
  std::vector<ScenarioCommand> commands;  // stamp order
  std::vector<std::string> missing;       // known sources that had not delivered this stamp
  std::vector<std::string> late;          // sources with a late input applied in this frame
  std::vector<std::string> silenced;      // sources declared silent as this frame closed
  std::uint32_t held_back = 0;            // inputs with stamps far ahead, held back when this frame closed
  // Counts since the previous frame, so the World's statistics are the same live and replayed.
  std::uint32_t inputs = 0;
  std::uint32_t late_inputs = 0;
  std::uint32_t rejected_inputs = 0;
  // Filled by the World after the frame's inputs are applied.
  Eigen::Isometry3d world_from_eye = Eigen::Isometry3d::Identity();
  bool eye_valid = false;
  std::vector<AppliedInstrument> instruments;  // every slot, in slot order
};

enum class WaitPolicy { kWait, kNoWait };

struct MediatorOptions {
  WaitPolicy policy = WaitPolicy::kWait;
  std::size_t reorder_frames = 2;  // kWait: frames a silent source may hold back
  double max_stamp_jump = 1.0;     // s (see the top of the file)
  std::set<std::string> slots;     // the scene's instrument slots; empty: any slot
  Log log;
  // Repeated warnings (same key) at most every this many frames.
  std::uint64_t log_every_frames = 250;
};

struct MediatorStatistics {
  std::uint64_t frames = 0;  // frames emitted, every kind
  std::uint64_t inputs = 0;
  std::uint64_t late_inputs = 0;
  std::uint64_t rejected_inputs = 0;
  std::uint64_t frames_without_source = 0;  // frames closed while a known source had not delivered
  std::uint64_t silenced = 0;               // times a source was declared silent
};

// Why an input cannot be applied ("" = it can): non-finite or implausible values (1e300 is finite, and would put an
// instrument anywhere). The World checks replayed frames with the same rules.
std::string checkEye(const EyeState& eye);
std::string checkInstrument(const InstrumentState& state);
std::string checkPedals(const PedalState& pedals);

class Mediator {
 public:
  using Sink = std::function<void(InputFrame&)>;

  Mediator(MediatorOptions options, Sink sink);

  void handle(const EyeState& eye);
  void handle(const InstrumentState& instrument);
  void handle(const PedalState& pedals);
  void handle(const ScenarioCommand& command);
  // End of input: closes every pending frame (state inputs newer than the last frame go into a final kState frame).
  void flush();

  // A scene switch changes the slots an instrument state may name.
  void setSlots(std::set<std::string> slots) { options_.slots = std::move(slots); }
  // The sequence number of the next frame (a session continues a mediator's numbering across restarts).
  std::uint64_t nextSequence() const { return next_sequence_; }
  void setNextSequence(std::uint64_t sequence) { next_sequence_ = sequence; }

  const MediatorStatistics& statistics() const { return statistics_; }
  // Inputs counted since the last frame emitted (they go into the next frame's counts).
  struct Unreported {
    std::uint32_t inputs = 0, late_inputs = 0, rejected_inputs = 0;
  };
  Unreported unreported() const { return {inputs_, late_inputs_, rejected_inputs_}; }
  std::optional<Stamp> lastFrameStamp() const { return last_frame_stamp_; }
  std::size_t pendingFrames() const { return pending_.size(); }

 private:
  struct Pending {
    std::optional<EyeState> eye;
    std::map<std::string, InstrumentState> instruments;  // by slot
  };
  enum class StampCheck { kNormal, kStale, kAhead, kGap };

  void acceptSource(Stamp stamp, const std::string& source, const EyeState* eye, const InstrumentState* instrument);
  void assembleSource(Stamp stamp, const std::string& source, const EyeState* eye, const InstrumentState* instrument);
  StampCheck classifyStamp(Stamp stamp, const std::string& source);
  void closeReadyFrames();
  void closeFrame(Stamp stamp, Pending inputs, std::vector<std::string> silenced);
  void takeStateInputs(Stamp up_to, InputFrame& frame);
  void emit(InputFrame& frame);
  void log(Severity severity, const std::string& key, const std::string& message);

  MediatorOptions options_;
  Sink sink_;
  std::map<Stamp, Pending> pending_;                               // frames not closed yet, by stamp
  std::map<std::string, Stamp> known_sources_;                     // the newest stamp each waited-for source delivered
  std::map<std::string, std::pair<Stamp, Stamp>> jumped_sources_;  // first and last far-ahead stamp per source
  struct HeldInput {
    Stamp stamp;
    std::string source;
    std::optional<EyeState> eye;
    std::optional<InstrumentState> instrument;
  };
  static constexpr std::size_t kMaxHeldBack = 256;
  std::vector<HeldInput> held_back_;
  // Whether `source`, newest stamp `newest`, has delivered what the frame at `stamp` needs.
  bool delivered(const std::string& source, Stamp newest, Stamp stamp) const;
  Stamp pedal_period_ = 0;  // ns, 0 = not known yet
  std::map<std::string, std::size_t> missed_frames_;  // kNoWait: frames in a row closed without the source
  Pending late_;  // inputs older than the last frame, for the next one
  std::vector<std::string> late_sources_;
  std::optional<Stamp> last_frame_stamp_;
  std::vector<PedalState> buffered_pedals_;
  std::vector<ScenarioCommand> buffered_commands_;
  std::uint64_t next_sequence_ = 1;
  // Counts since the last frame emitted.
  std::uint32_t inputs_ = 0, late_inputs_ = 0, rejected_inputs_ = 0;
  std::map<std::string, std::uint64_t> logged_at_frame_;
  MediatorStatistics statistics_;
};

}  // namespace world
}  // namespace vrm_sim
