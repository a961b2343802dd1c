// vrm_sim's message handlers through the simulation core (world::Session); see sim_messages.h.
#include "sim_messages.h"

VRM_FUZZ_TARGET(sim_messages) { return vrm_fuzz_sim::runSimMessages(data, size, /*with_world=*/true); }
