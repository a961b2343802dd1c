// The ChainMail model (Gibson 1997; thesis §5.1, §5.3): inelastic tissue, no integration. Grasped nodes are moved to
// the jaws by ChainMail moves (so the tissue they pull follows), Gibson's elastic relaxation runs, then the pushing
// instruments and the collision library's deformation vectors move nodes; velocities stay zero.
#include <algorithm>
#include <vector>

#include "tissue_models_impl.h"
#include "vrm_sim/mge/membrane.h"
#include "vrm_sim/tissue/chainmail.h"
#include "vrm_sim/tissue/tissue_simulator.h"

namespace vrm_sim {
namespace tissue {

class ChainMailModel : public TissueModel {
 public:
  ChainMailModel(mge::Membrane& membrane, const ChainMailConfig& config) : chainmail_(membrane, config) {}
  const char* name() const override { return "chainmail"; }
  void onTopologyChanged(TissueSimulator& simulator) override;
  bool step(TissueSimulator& simulator) override;
  ChainMail& chainmail() { return chainmail_; }

 private:
  // updateGrasp() put the grasped nodes where the jaws are; put them back and let ChainMail move them there, so the
  // tissue they pull follows. Other grasped nodes are held (they get their own move).
  void followGrasps(TissueSimulator& simulator);
  // Pushing instruments: a node inside a capsule moves to its surface (re-measured before every move, since earlier
  // moves drag nodes along); further rounds catch nodes dragged into the instrument. Records the contacts.
  void pushOutOfInstruments(TissueSimulator& simulator);
  // The collision library's deformation vectors, as ChainMail moves.
  void moveByDeformations(TissueSimulator& simulator);

  ChainMail chainmail_;
  std::vector<Eigen::Vector3d> committed_;  // positions after the last step
};

std::unique_ptr<TissueModel> makeChainMailModel(mge::Membrane& membrane, const TissueConfig& config) {
  return std::make_unique<ChainMailModel>(membrane, config.chainmail);
}

ChainMail* TissueSimulator::chainmail() {
  auto* model = dynamic_cast<ChainMailModel*>(model_.get());
  return model != nullptr ? &model->chainmail() : nullptr;
}

void ChainMailModel::onTopologyChanged(TissueSimulator& simulator) {
  chainmail_.rebuild();
  mge::Membrane& membrane = *simulator.membrane_;
  committed_.assign(membrane.positions(), membrane.positions() + membrane.nodeCount());
}

bool ChainMailModel::step(TissueSimulator& simulator) {
  TissueSimulator& s = simulator;
  followGrasps(s);
  // Elastic relaxation before the instruments push, so that the instruments have the last word.
  for (int k = 0; k < chainmail_.config().relaxation_iterations; ++k) chainmail_.relax(s.constrained_.data());
  pushOutOfInstruments(s);
  moveByDeformations(s);
  // Inelastic: no momentum.
  const std::size_t n = s.membrane_->nodeCount();
  Eigen::Vector3d* v = s.membrane_->velocities();
  for (std::size_t k = 0; k < n; ++k) v[k].setZero();
  Eigen::Vector3d* x = s.membrane_->positions();
  committed_.assign(x, x + n);
  s.topologyBeforeStep();  // cuts and tears at the end of the step
  s.topologyAfterStep();
  return true;
}

void ChainMailModel::followGrasps(TissueSimulator& s) {
  Eigen::Vector3d* x = s.membrane_->positions();
  std::vector<Eigen::Vector3d> targets;
  targets.reserve(s.grasped_nodes_.size());
  for (std::uint32_t node : s.grasped_nodes_) {
    targets.push_back(x[node]);
    x[node] = committed_[node];
  }
  for (std::size_t k = 0; k < s.grasped_nodes_.size(); ++k) {
    const std::uint32_t node = s.grasped_nodes_[k];
    chainmail_.move(node, targets[k] - x[node], s.grasped_.data());
  }
}

void ChainMailModel::pushOutOfInstruments(TissueSimulator& s) {
  const std::size_t n = s.membrane_->nodeCount();
  Eigen::Vector3d* x = s.membrane_->positions();
  s.contacts_.clear();
  for (std::size_t i = 0; i < s.current_instruments_.size(); ++i) {
    const InstrumentInput& instrument = s.current_instruments_[i];
    if (!instrument.collides || !(instrument.radius > 0.0)) continue;
    const Eigen::Vector3d a = instrument.pose * Eigen::Vector3d(0.0, 0.0, -instrument.radius);
    const Eigen::Vector3d b =
        instrument.pose * Eigen::Vector3d(0.0, 0.0, -std::max(instrument.length, instrument.radius));
    for (int round = 0; round < 10; ++round) {
      bool pushed = false;
      for (std::size_t k = 0; k < n; ++k) {
        if (s.constrained_[k]) continue;
        const Eigen::Vector3d axis = b - a;
        const double length2 = axis.squaredNorm();
        const double t = length2 > 0.0 ? std::clamp((x[k] - a).dot(axis) / length2, 0.0, 1.0) : 0.0;
        const Eigen::Vector3d offset = x[k] - (a + t * axis);
        const double distance = offset.norm();
        if (!(distance < instrument.radius) || !(distance > 0.0)) continue;
        const Eigen::Vector3d push = offset * ((instrument.radius - distance) / distance);
        chainmail_.move(static_cast<std::uint32_t>(k), push, s.grasped_.data());
        NodeDeformation contact;
        contact.node = static_cast<std::uint32_t>(k);
        contact.deformation = push;
        contact.normal = offset / distance;
        s.contacts_.push_back(contact);
        pushed = true;
      }
      if (!pushed) break;
    }
  }
}

void ChainMailModel::moveByDeformations(TissueSimulator& s) {
  const std::size_t n = s.membrane_->nodeCount();
  for (const NodeDeformation& deformation : s.external_deformations_) {
    if (deformation.node < n && !s.constrained_[deformation.node]) {
      chainmail_.move(deformation.node, deformation.deformation, s.grasped_.data());
    }
  }
  s.contacts_.insert(s.contacts_.end(), s.external_deformations_.begin(), s.external_deformations_.end());
  s.external_deformations_.clear();
}

}  // namespace tissue
}  // namespace vrm_sim
