#include "vrm_sim/world/session_result.h"

#include "vrm_sim/scenario/result_fields.h"
#include "vrm_sim/world/offline.h"

namespace vrm_sim {
namespace world {

result::SessionResult sessionResult(const World& world, const ResultContext& context) {
  result::SessionResult r;
  r.scene = world.scene().name;
  r.scene_file = world.scene().source_file;
  r.seed = context.seed;
  r.session_ended = world.sessionEnded();
  if (const scenario::Status* status = world.scenarioStatus()) scenario::writeResultFields(*status, &r);
  const WorldStatistics& statistics = world.statistics();
  r.final_state_hash = hashString(world.stateHash());
  r.frames = statistics.frames;
  r.simulated_frames = statistics.simulated_frames;
  r.late_inputs = statistics.late_inputs;
  r.frames_without_source = statistics.frames_without_source;
  r.input_frames = statistics.input_sequence;
  const auto last_stamp = world.lastFrameStamp();
  r.last_frame_stamp = last_stamp ? toSeconds(*last_stamp) : 0.0;
  r.software_version = VRM_SIM_VERSION;
  r.bag = context.bag;
  r.user = context.user;
  r.station = context.station;
  r.in_progress = context.in_progress;
  return r;
}

}  // namespace world
}  // namespace vrm_sim
