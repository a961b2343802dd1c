#pragma once
// Factories of the tissue model implementations (one per file), listed in tissueModelRegistry().
#include <memory>

#include "vrm_sim/tissue/tissue_model.h"

namespace vrm_sim {
namespace tissue {

std::unique_ptr<TissueModel> makeMassSpringModel(mge::Membrane& membrane, const TissueConfig& config);
std::unique_ptr<TissueModel> makeChainMailModel(mge::Membrane& membrane, const TissueConfig& config);

}  // namespace tissue
}  // namespace vrm_sim
