#include "retina_sheet.h"

#include <algorithm>
#include <cmath>
#include <vector>

namespace vrm_sim {
namespace scenario {

const scene::ObjectDescription& sheet(Params& params, const std::string& fallback) {
  const scene::ObjectDescription& object = params.object("tissue", fallback);
  if (!object.isDeformable() || object.frame != scene::ObjectFrame::kEye) {
    params.fail("tissue", "object '" + object.name + "' must be deformable (a tissue model) in the eye frame");
  }
  return object;
}

std::string toolOfType(Params& params, const scene::SceneDescription& scene, scene::InstrumentType type) {
  const std::string slot = params.slot("tool", "right");
  const scene::InstrumentDescription* tool =
      scene.findInstrument(slot == "left" ? scene::InstrumentSlot::kLeft : scene::InstrumentSlot::kRight);
  const bool offered = tool->type == type || std::find(tool->alternatives.begin(), tool->alternatives.end(), type) !=
                                                 tool->alternatives.end();
  if (!offered) params.fail("tool", "slot '" + slot + "' must offer a " + scene::toString(type));
  return slot;
}

Lifted liftedPart(const TissueView& tissue, double threshold, double sheet_area) {
  Lifted lifted;
  if (tissue.positions == nullptr || tissue.rest_positions == nullptr || tissue.initial_node_count == 0) return lifted;
  const std::vector<Eigen::Vector3d>& rest = *tissue.rest_positions;
  Eigen::Vector3d weighted = Eigen::Vector3d::Zero();
  double weights = 0.0;
  for (std::size_t i = 0; i < std::min(rest.size(), tissue.node_count); ++i) {
    if (!rest[i].allFinite()) continue;
    const double lift = rest[i].norm() - tissue.positions[i].norm();
    lifted.max_lift = std::max(lifted.max_lift, lift);
    if (!(lift > threshold)) continue;
    ++lifted.nodes;
    weighted += lift * rest[i];
    weights += lift;
  }
  lifted.area = sheet_area * static_cast<double>(lifted.nodes) / static_cast<double>(tissue.initial_node_count);
  lifted.diameter = 2.0 * std::sqrt(lifted.area / kPi);
  if (weights > 0.0) lifted.centre = weighted / weights;
  return lifted;
}

}  // namespace scenario
}  // namespace vrm_sim
