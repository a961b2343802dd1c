// A surgical scenario (thesis §7), scored from what the simulation core reports about the tissue (adhesion points,
// tearing, cutting) and the retina (contacts, bleeding).
#include <algorithm>
#include <cmath>
#include <optional>
#include <vector>

#include "common.h"
#include "peel.h"
#include "scenarios.h"

namespace vrm_sim {
namespace scenario {
namespace {

// ILM peeling: the thin, stiff layer on the retina is peeled in a circle (like a capsulorhexis). Besides the peel
// items: the radius of the peeled region (mean distance of the lifted nodes from the ILM's centre) and the peel's
// continuity — the fraction of 16 sectors around the centre the forceps carried the flap through while holding it,
// so a straight pull that lifts the sheet is not a round peel. Success: the peel went round (continuity) and freed
// at least the required fraction of the ILM.
class IlmPeeling : public Peel {
 public:
  IlmPeeling(const scene::SceneDescription& scene, Params&& params) : Peel(scene, params, "ilm") {
    required_continuity_ = params.number("required_continuity", 0.75, 0.0, 1.0);
    required_lift_ = params.number("required_lifted_fraction", 0.3, 0.0, 1.0);
    params.finish();
  }

  bool succeeded() const override { return continuity_ >= required_continuity_ && lifted_fraction_ >= required_lift_; }

  std::vector<Measurement> measurements(double elapsed) const override {
    std::vector<Measurement> items = Peel::measurements(elapsed);
    items.push_back({"peel_radius", radius_, "m"});
    items.push_back({"continuity", continuity_, "1"});
    return items;
  }

  std::string progress() const override {
    return format("peeled %.0f %% of the circle, %.0f %% of the ILM lifted", 100.0 * continuity_,
                  100.0 * lifted_fraction_);
  }

  void hash(std::uint64_t& state) const override {
    Peel::hash(state);
    hashValue(state, continuity_);
    hashValue(state, radius_);
  }

  // centre_ is fixed by the rest positions of the first frame with a shape (they change as the ILM tears), so it is
  // saved rather than rebuilt; its frame only once it exists (uninitialised before).
  void transferState(StateArchive& archive) override {
    Peel::transferState(archive);
    archive.section("ilm_peeling");
    archive(centre_);
    if (centre_) archive(normal_)(u_)(v_);
    for (bool& visited : visited_) archive(visited);
    archive(continuity_)(radius_);
  }

 private:
  static constexpr int kSectors = 16;

  void update(const FrameView& frame, double elapsed) override {
    Peel::update(frame, elapsed);
    const TissueView* tissue = frame.tissue(object_);
    if (tissue == nullptr || tissue->grasped_nodes == 0 || !centre_) return;
    for (const InstrumentView& instrument : frame.instruments) {
      if (!instrument.valid || instrument.type != scene::InstrumentType::kForceps) continue;
      const Eigen::Vector3d d = instrument.tip - *centre_;
      const double angle = std::atan2(d.dot(v_), d.dot(u_));
      visited_[std::clamp(static_cast<int>((angle + kPi) / (2.0 * kPi) * kSectors), 0, kSectors - 1)] = true;
    }
    continuity_ = static_cast<double>(std::count(visited_, visited_ + kSectors, true)) / kSectors;
  }

  void updateShape(const TissueView& tissue) override {
    if (tissue.positions == nullptr || tissue.rest_positions == nullptr) return;
    const std::vector<Eigen::Vector3d>& rest = *tissue.rest_positions;
    if (!centre_) {
      Eigen::Vector3d sum = Eigen::Vector3d::Zero();
      std::size_t count = 0;
      for (const auto& p : rest) {
        if (p.allFinite()) sum += p, ++count;
      }
      if (count == 0) return;
      centre_ = sum / static_cast<double>(count);
      normal_ = centre_->normalized();
      u_ = normal_.unitOrthogonal();
      v_ = normal_.cross(u_);
    }
    const Eigen::Vector3d* x = tissue.positions;
    const std::size_t n = std::min(rest.size(), tissue.node_count);
    double radius_sum = 0.0;
    std::size_t lifted = 0;
    for (std::size_t i = 0; i < n; ++i) {
      if (!rest[i].allFinite() || (x[i] - rest[i]).norm() <= 1e-4) continue;
      const Eigen::Vector3d d = rest[i] - *centre_;
      radius_sum += std::hypot(d.dot(u_), d.dot(v_));
      ++lifted;
    }
    radius_ = lifted > 0 ? radius_sum / static_cast<double>(lifted) : 0.0;
  }

  double required_continuity_ = 0.75, required_lift_ = 0.3;
  std::optional<Eigen::Vector3d> centre_;
  Eigen::Vector3d normal_, u_, v_;
  bool visited_[kSectors] = {};
  double continuity_ = 0.0, radius_ = 0.0;
};

}  // namespace

std::unique_ptr<Scenario> makeIlmPeeling(const scene::SceneDescription& scene) {
  return std::make_unique<IlmPeeling>(scene, Params(scene));
}

}  // namespace scenario
}  // namespace vrm_sim
