#include "vrm_sim/tissue/tissue_model.h"

#include <limits>
#include <string>

#include "tissue_models_impl.h"

namespace vrm_sim {
namespace tissue {

double TissueModel::strainBound() const { return std::numeric_limits<double>::infinity(); }

void TissueModel::transferState(StateArchive& archive, TissueSimulator& /*simulator*/) {
  archive.fail(std::string("the ") + name() +
               " tissue model cannot be checkpointed (its session restores from the journal)");
}

const Registry<TissueModelFactory>& tissueModelRegistry() {
  static const Registry<TissueModelFactory> registry(
      "tissue model",
      {{"mass_spring", makeMassSpringModel,
        "springs and masses integrated with `integrator`, strain limit, watchdog (thesis §5.1)"},
       {"chainmail", makeChainMailModel,
        "inelastic links that drag their neighbours within limits, no integration (Gibson 1997, thesis §5.3)"}});
  return registry;
}

}  // namespace tissue
}  // namespace vrm_sim
