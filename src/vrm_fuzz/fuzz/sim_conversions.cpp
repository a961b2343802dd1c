// vrm_sim's message handlers without the simulation core: every message through the conversions and checks of
// scenario_manager, scene_manager and the renderer's GL-free path (sim_messages.h), at full speed. Same input format
// as sim_messages (the first byte, the scene there, is skipped).
#include "sim_messages.h"

VRM_FUZZ_TARGET(sim_conversions) { return vrm_fuzz_sim::runSimMessages(data, size, /*with_world=*/false); }
