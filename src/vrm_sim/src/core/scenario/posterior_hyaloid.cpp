// The retina's own layers (issue 38). posterior_hyaloid (EyeSi's vitreoretinal programme): the vitrector's suction
// engages the posterior hyaloid, stained so it can be seen, and lifting it detaches it from the retina; pulled too
// hard where it adheres, it tears the retina beneath.
#include <algorithm>
#include <optional>
#include <string>
#include <vector>

#include "common.h"
#include "retina_sheet.h"
#include "scenarios.h"

namespace vrm_sim {
namespace scenario {
namespace {

// posterior_hyaloid: engage the posterior hyaloid (`tissue`, a sheet with suction_hold_radius) with the vitrector's
// suction in `tool` and lift it off the retina until `required_detached_fraction` of it stands off its rest position;
// adhesions that tore the retina (adhesion_tear_force) are retina injuries.
class PosteriorHyaloid : public Scenario {
 public:
  PosteriorHyaloid(const scene::SceneDescription& scene, Params&& params) : contacts_(scene.eye.radius) {
    const scene::ObjectDescription& hyaloid = sheet(params, "hyaloid");
    if (!(hyaloid.tissue.suction_hold_radius > 0.0)) {
      params.fail("tissue", "object '" + hyaloid.name + "' needs suction_hold_radius (a hyaloid the suction engages)");
    }
    object_ = hyaloid.name;
    tool_ = toolOfType(params, scene, scene::InstrumentType::kVitrector);
    required_ = params.number("required_detached_fraction", 0.7, 0.05, 1.0);
    lift_threshold_ = params.number("lift_threshold", 1e-4, 1e-6, 2e-3);
    params.finish();
  }

  std::vector<Measurement> items() const override { return measurements(0.0); }

  void update(const FrameView& frame, double) override {
    contacts_.update(frame);
    damage_ = frame.retina.max_injury;
    const TissueView* tissue = frame.tissue(object_);
    if (tissue == nullptr) return;
    const Lifted lifted = liftedPart(*tissue, lift_threshold_, 1.0);
    detached_ = std::max(detached_, lifted.area);  // the fraction of the sheet (area 1): once off, it stays off
    injuries_ = tissue->adhesion_tears;
    if (tissue->adhesion_tear_points != nullptr && !tissue->adhesion_tear_points->empty()) {
      last_injury_ = tissue->adhesion_tear_points->back();
    }
    released_ = tissue->released_adhesions;
    max_force_ = tissue->max_adhesion_force;
    engaged_ = engaged_ || tissue->grasped_nodes > 0;
  }

  bool succeeded() const override { return detached_ >= required_; }

  std::string penaltySlot(const std::string& item) const override {
    return item == "retina_injuries" || item == "retina_damage" ? tool_ : "";
  }

  std::optional<Eigen::Vector3d> penaltyPosition(const std::string& item) const override {
    if (item == "retina_injuries") return last_injury_;
    return std::nullopt;
  }

  std::vector<Measurement> measurements(double) const override {
    return {{"detached_fraction", detached_, "1"},
            {"retina_injuries", static_cast<double>(injuries_), "1"},
            {"released_adhesions", static_cast<double>(released_), "1"},
            {"max_adhesion_force", max_force_, "N"},
            {"retina_damage", damage_, "1"},
            {"retina_contacts", static_cast<double>(contacts_.count()), "1"}};
  }

  std::string progress() const override {
    return format("%.0f %% of the hyaloid detached%s%s", 100.0 * detached_, engaged_ ? "" : " (not engaged yet)",
                  injuries_ > 0 ? " - retina torn!" : "");
  }

  void hash(std::uint64_t& state) const override {
    hashValue(state, detached_);
    hashValue(state, injuries_);
    hashValue(state, released_);
    hashValue(state, max_force_);
    hashValue(state, damage_);
    contacts_.hash(state);
  }

  void transferState(StateArchive& archive) override {
    archive.section("posterior_hyaloid");
    archive(detached_)(max_force_)(damage_)(injuries_)(released_)(last_injury_)(engaged_)(contacts_);
  }

 private:
  std::string object_, tool_;
  double required_ = 0.7, lift_threshold_ = 1e-4;
  double detached_ = 0.0, max_force_ = 0.0, damage_ = 0.0;
  std::uint64_t injuries_ = 0, released_ = 0;
  std::optional<Eigen::Vector3d> last_injury_;
  bool engaged_ = false;
  RetinaContacts contacts_;
};

}  // namespace

std::unique_ptr<Scenario> makePosteriorHyaloid(const scene::SceneDescription& scene) {
  return std::make_unique<PosteriorHyaloid>(scene, Params(scene));
}

}  // namespace scenario
}  // namespace vrm_sim
