// The retina's own layers (issue 38). retina_relocation (thesis §7): the needle pierces the retina and injects fluid
// under it, which detaches it into a bleb; moving the needle while it is inside tears the retina.
#include <algorithm>
#include <cmath>
#include <string>
#include <variant>
#include <vector>

#include "common.h"
#include "retina_sheet.h"
#include "scenarios.h"
#include "vrm_scene/meshes/eye_meshes.h"

namespace vrm_sim {
namespace scenario {
namespace {

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

  void transferState(StateArchive& archive) override {
    archive.section("retina_relocation");
    archive(diameter_)(peak_diameter_)(site_error_)(bleb_offset_)(max_lift_)(fluid_)(outside_)(torn_);
    archive(needle_inside_)(entered_)(contacts_);
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

}  // namespace

std::unique_ptr<Scenario> makeRetinaRelocation(const scene::SceneDescription& scene) {
  return std::make_unique<RetinaRelocation>(scene, Params(scene));
}

}  // namespace scenario
}  // namespace vrm_sim
