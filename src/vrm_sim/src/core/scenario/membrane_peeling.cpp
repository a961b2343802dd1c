// A surgical scenario (thesis §7), scored from what the simulation core reports about the tissue (adhesion points,
// tearing, cutting) and the retina (contacts, bleeding).
#include "peel.h"
#include "scenarios.h"

namespace vrm_sim {
namespace scenario {
namespace {

// Membrane peeling: success once the membrane let go of every adhesion point, peeled with the forceps or cut free with
// the vitrector.
class MembranePeeling : public Peel {
 public:
  MembranePeeling(const scene::SceneDescription& scene, Params&& params) : Peel(scene, params, "membrane") {
    params.finish();
  }
};

}  // namespace

std::unique_ptr<Scenario> makeMembranePeeling(const scene::SceneDescription& scene) {
  return std::make_unique<MembranePeeling>(scene, Params(scene));
}

}  // namespace scenario
}  // namespace vrm_sim
