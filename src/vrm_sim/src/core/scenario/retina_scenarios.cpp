// The retina's own layers (issue 38). retina_relocation (thesis §7): the needle pierces the retina and injects fluid
// under it, which detaches it into a bleb; moving the needle while it is inside tears the retina. posterior_hyaloid
// (EyeSi's vitreoretinal programme): the vitrector's suction engages the posterior hyaloid, stained so it can be seen,
// and lifting it detaches it from the retina; pulled too hard where it adheres, it tears the retina beneath.
#include <algorithm>
#include <cmath>
#include <variant>

#include "common.h"
#include "scenarios.h"
#include "vrm_scene/meshes/eye_meshes.h"

namespace vrm_sim {
namespace scenario {
namespace {

constexpr double kPi = 3.14159265358979323846;

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

// The lifted part of a sheet lying on the eye sphere: its nodes more than `threshold` nearer the eye centre than at
// rest (off the wall; pushed towards the wall does not count), the
// area they stand for (each node an equal share of the sheet's rest area: the ring meshes are close to uniform), its
// equivalent diameter and its centre (the lift-weighted mean of their rest positions).
struct Lifted {
  std::size_t nodes = 0;
  double area = 0.0, diameter = 0.0, max_lift = 0.0;
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
};

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

// Rest area of a membrane-generator sheet: the spherical cap of its diameter (measured along the surface).
double capArea(const scene::ObjectDescription& object, double eye_radius) {
  const auto* membrane = object.mesh.generator ? std::get_if<scene::MembraneParams>(&*object.mesh.generator) : nullptr;
  if (membrane == nullptr) return 0.0;
  const double radius = eye_radius - membrane->height_above_retina;
  const double polar = 0.5 * membrane->diameter / radius;
  return 2.0 * kPi * radius * radius * (1.0 - std::cos(polar));
}

// retina_relocation: raise a bleb of `target_diameter` (equivalent diameter of the detached area) at the target site
// (`target_offset_deg` from the posterior pole towards `target_azimuth_deg`) with the needle in `tool`, without tearing
// the retina (`tissue`, a sheet with fluid_modulus and needle_pierce_radius). Done once the bleb reached
// (1 - size_tolerance) of the target and the needle is out of it again. site_error: the puncture's distance from the
// target; bleb_offset: the bleb's centre's (a bleb does not grow evenly round its puncture).
class RetinaRelocation : public Scenario {
 public:
  RetinaRelocation(const scene::SceneDescription& scene, Params&& params) : contacts_(scene.eye.radius) {
    const scene::ObjectDescription& retina = sheet(params, "retina_patch");
    if (!(retina.tissue.fluid_modulus > 0.0) || !(retina.tissue.needle_pierce_radius > 0.0)) {
      params.fail("tissue",
                  "object '" + retina.name + "' needs fluid_modulus and needle_pierce_radius (a retina to detach)");
    }
    object_ = retina.name;
    tool_ = toolOfType(params, scene, scene::InstrumentType::kNeedle);
    target_diameter_ = params.number("target_diameter", 2.5e-3, 2e-4, 1e-2);
    size_tolerance_ = params.number("size_tolerance", 0.15, 0.01, 0.9);
    const double offset = params.number("target_offset_deg", 0.0, 0.0, 80.0);
    const double azimuth = params.number("target_azimuth_deg", 0.0, -360.0, 360.0);
    lift_threshold_ = params.number("lift_threshold", 5e-5, 1e-6, 1e-3);
    params.finish();
    sheet_area_ = capArea(retina, scene.eye.radius);
    target_site_ = scene.eye.radius * scene::posteriorPoleRotation(offset, azimuth) * Eigen::Vector3d(0.0, 0.0, -1.0);
  }

  std::vector<Measurement> items() const override { return measurements(0.0); }

  void update(const FrameView& frame, double) override {
    contacts_.update(frame);
    const TissueView* tissue = frame.tissue(object_);
    if (tissue == nullptr) return;
    const Lifted bleb = liftedPart(*tissue, lift_threshold_, sheet_area_);
    diameter_ = bleb.diameter;
    peak_diameter_ = std::max(peak_diameter_, diameter_);
    max_lift_ = bleb.max_lift;
    if (bleb.nodes > 0) bleb_offset_ = (bleb.centre.normalized() * target_site_.norm() - target_site_).norm();
    torn_ = tissue->torn_springs + tissue->cut_nodes;
    fluid_ = tissue->fluid_volume;
    outside_ = tissue->injected_outside;
    needle_inside_ = tissue->needle_inside;
    const InstrumentView* needle = frame.instrument(tool_);
    if (needle_inside_ && !entered_ && needle != nullptr) {
      // Where the needle went in: the injection site, on the wall's sphere.
      site_error_ = (needle->tip.normalized() * target_site_.norm() - target_site_).norm();
    }
    if (needle_inside_) entered_ = true;
  }

  bool succeeded() const override {
    return entered_ && !needle_inside_ && diameter_ >= (1.0 - size_tolerance_) * target_diameter_;
  }

  std::string penaltySlot(const std::string& item) const override {
    return item == "retina_tears" || item == "injected_outside" ? tool_ : "";
  }

  std::vector<Measurement> measurements(double) const override {
    return {{"bleb_diameter", diameter_, "m"},
            {"size_error",
             target_diameter_ > 0.0 ? std::abs(peak_diameter_ - target_diameter_) / target_diameter_ : 0.0, "1"},
            {"site_error", site_error_, "m"},
            {"bleb_offset", bleb_offset_, "m"},
            {"bleb_height", max_lift_, "m"},
            {"retina_tears", static_cast<double>(torn_), "1"},
            {"fluid_volume", fluid_, "m^3"},
            {"injected_outside", outside_, "m^3"},
            {"retina_contacts", static_cast<double>(contacts_.count()), "1"}};
  }

  std::string progress() const override {
    return format("bleb %.1f of %.1f mm%s%s", 1e3 * diameter_, 1e3 * target_diameter_,
                  needle_inside_ ? ", needle under the retina" : "", torn_ > 0 ? " (torn)" : "");
  }

  void hash(std::uint64_t& state) const override {
    hashValue(state, diameter_);
    hashValue(state, peak_diameter_);
    hashValue(state, site_error_);
    hashValue(state, bleb_offset_);
    hashValue(state, torn_);
    hashValue(state, fluid_);
    hashValue(state, outside_);
    hashValue(state, entered_);
    contacts_.hash(state);
  }

 private:
  std::string object_, tool_;
  double target_diameter_ = 2.5e-3, size_tolerance_ = 0.15, lift_threshold_ = 5e-5, sheet_area_ = 0.0;
  Eigen::Vector3d target_site_ = Eigen::Vector3d::Zero();
  double diameter_ = 0.0, peak_diameter_ = 0.0, site_error_ = 0.0, bleb_offset_ = 0.0, max_lift_ = 0.0, fluid_ = 0.0,
         outside_ = 0.0;
  std::uint64_t torn_ = 0;
  bool needle_inside_ = false, entered_ = false;
  RetinaContacts contacts_;
};

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

std::unique_ptr<Scenario> makeRetinaRelocation(const scene::SceneDescription& scene) {
  return std::make_unique<RetinaRelocation>(scene, Params(scene));
}
std::unique_ptr<Scenario> makePosteriorHyaloid(const scene::SceneDescription& scene) {
  return std::make_unique<PosteriorHyaloid>(scene, Params(scene));
}

}  // namespace scenario
}  // namespace vrm_sim
