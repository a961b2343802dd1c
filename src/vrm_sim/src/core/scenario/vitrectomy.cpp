// A surgical scenario (thesis §7), scored from what the simulation core reports about the tissue (adhesion points,
// tearing, cutting) and the retina (contacts, bleeding).
#include <cmath>
#include <string>
#include <vector>

#include "common.h"
#include "scenarios.h"

namespace vrm_sim {
namespace scenario {
namespace {

// A vitrectomy step: the vitrector, with suction and cutter from the pedal, removes the tissue in front of its port.
// Its port facing the retina closer than the warning distance warns (each approach once); with suction there the
// retina is damaged (the core's aspiration injury). Success: the required fraction of the tissue removed.
class Vitrectomy : public Scenario {
 public:
  Vitrectomy(const scene::SceneDescription& scene, Params&& params)
      : eye_radius_(scene.eye.radius),
        contacts_(scene.eye.radius),
        unlit_(scene, params, params.slot("tool", "right")) {
    object_ = deformableObject(params, "tissue", "vitreous").name;
    tool_ = params.slot("tool", "right");
    warning_distance_ = params.number("warning_distance", 5e-4, 0.0, 5e-3);
    facing_cos_ = std::cos(params.number("facing_angle_deg", 60.0, 0.0, 180.0) * kPi / 180.0);
    required_removed_ = params.number("required_removed_fraction", 0.8, 0.0, 1.0);
    params.finish();
  }

  std::vector<Measurement> items() const override { return measurements(0.0); }

  void update(const FrameView& frame, double) override {
    contacts_.update(frame);
    unlit_.update(frame);
    damage_ = frame.retina.max_injury;
    damaged_area_ = frame.retina.injured_area;
    const TissueView* tissue = frame.tissue(object_);
    if (tissue != nullptr && tissue->initial_node_count > 0) {
      removed_ = static_cast<double>(tissue->cut_nodes) / static_cast<double>(tissue->initial_node_count);
    }
    const InstrumentView* tool = frame.instrument(tool_);
    if (tool == nullptr || !tool->valid || tool->type != scene::InstrumentType::kVitrector) {
      warnings_.update(false);
      return;
    }
    const double clearance = eye_radius_ - tool->tip.norm();
    const bool facing = tool->tip.norm() > 0.0 && tool->axis.dot(tool->tip.normalized()) >= facing_cos_;
    warnings_.update(facing ? clearance : 1.0, warning_distance_, 1.2 * warning_distance_);
  }

  bool succeeded() const override { return removed_ >= required_removed_; }

  std::string penaltySlot(const std::string& item) const override {
    return item == "warnings" || item == "unlit_work" ? tool_ : "";
  }

  std::vector<Measurement> measurements(double) const override {
    return {{"removed_fraction", removed_, "1"},
            {"warnings", static_cast<double>(warnings_.count()), "1"},
            {"retina_damage", damage_, "1"},
            {"damaged_area", damaged_area_, "m^2"},
            {"retina_contacts", static_cast<double>(contacts_.count()), "1"},
            {"unlit_work", unlit_.seconds(), "s"}};
  }

  std::string progress() const override {
    return format("%.0f %% of the tissue removed%s", 100.0 * removed_, warnings_.inContact() ? " - too close!" : "");
  }

  void hash(std::uint64_t& state) const override {
    hashValue(state, removed_);
    hashValue(state, warnings_.count());
    hashValue(state, damage_);
    contacts_.hash(state);
    unlit_.hash(state);
  }

  void transferState(StateArchive& archive) override {
    archive.section("vitrectomy");
    archive(removed_)(damage_)(damaged_area_)(warnings_)(contacts_)(unlit_);
  }

 private:
  std::string object_, tool_;
  double eye_radius_, warning_distance_ = 5e-4, facing_cos_ = 0.5, required_removed_ = 0.8;
  double removed_ = 0.0, damage_ = 0.0, damaged_area_ = 0.0;
  ContactCounter warnings_;
  RetinaContacts contacts_;
  UnlitWork unlit_;
};

}  // namespace

std::unique_ptr<Scenario> makeVitrectomy(const scene::SceneDescription& scene) {
  return std::make_unique<Vitrectomy>(scene, Params(scene));
}

}  // namespace scenario
}  // namespace vrm_sim
