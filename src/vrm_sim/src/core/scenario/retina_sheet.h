#pragma once
// Shared by the retina layer scenarios (retina_relocation.cpp, posterior_hyaloid.cpp; not installed): the sheet they
// score, the instrument slot that must offer their tool, and how much of the sheet is lifted off the eye wall.
#include <cstddef>
#include <string>

#include "common.h"

namespace vrm_sim {
namespace scenario {

const scene::ObjectDescription& sheet(Params& params, const std::string& fallback);
std::string toolOfType(Params& params, const scene::SceneDescription& scene, scene::InstrumentType type);

// The lifted part of a sheet lying on the eye sphere: its nodes more than `threshold` nearer the eye centre than at
// rest (off the wall; pushed towards the wall does not count), the
// area they stand for (each node an equal share of the sheet's rest area: the ring meshes are close to uniform), its
// equivalent diameter and its centre (the lift-weighted mean of their rest positions).
struct Lifted {
  std::size_t nodes = 0;
  double area = 0.0, diameter = 0.0, max_lift = 0.0;
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
};

Lifted liftedPart(const TissueView& tissue, double threshold, double sheet_area);

}  // namespace scenario
}  // namespace vrm_sim
