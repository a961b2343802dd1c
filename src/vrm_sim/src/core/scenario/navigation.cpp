// An abstract scenario of thesis §7.4.1 (a skill without anatomy). Geometry in the eye frame; the retina is the eye
// sphere unless the core simulates it.
#include <optional>
#include <string>
#include <vector>

#include "common.h"
#include "scenarios.h"
#include "vrm_sim/scenario/light_cone.h"

namespace vrm_sim {
namespace scenario {
namespace {

// Touch the targets in the given order with the tool's tip while the light pipe illuminates the target (bimanual).
class Navigation : public Scenario {
 public:
  explicit Navigation(const scene::SceneDescription& scene) : contacts_(scene.eye.radius) {
    Params params(scene);
    for (const std::string& name : params.names("targets")) {
      const scene::ObjectDescription* object = scene.findObject(name);
      if (object == nullptr) params.fail("targets", "the scene has no object '" + name + "'");
      targets_.push_back(sphereOf(*object, params, "targets"));
    }
    tool_ = params.slot("tool", "right");
    light_ = params.name("light", "left");
    if (light_ != "none") light_ = params.slot("light", "left");
    tolerance_ = params.number("touch_tolerance", 1e-4, 0.0, 2e-3);
    cone_cos_ = lightConeCos(params.number("light_cone_deg", kLightConeHalfAngleDeg, 1.0, 90.0));
    params.finish();
    touching_.resize(targets_.size());
  }

  std::vector<Measurement> items() const override { return measurements(0.0); }

  void update(const FrameView& frame, double) override {
    contacts_.update(frame);
    const InstrumentView* tool = frame.instrument(tool_);
    if (tool == nullptr || !tool->valid) return;
    if (last_tip_) path_length_ += (tool->tip - *last_tip_).norm();
    last_tip_ = tool->tip;
    const InstrumentView* light = light_ == "none" ? nullptr : frame.instrument(light_);
    for (std::size_t i = 0; i < targets_.size(); ++i) {
      const Sphere& target = targets_[i];
      const double gap = (tool->tip - target.centre).norm() - target.radius;
      if (!touching_[i].update(gap, tolerance_, 2.0 * tolerance_ + 5e-5)) continue;
      if (i == next_) {
        if (lit(light, target)) {
          ++next_;
        } else {
          ++unlit_touches_;
        }
      } else if (i > next_) {
        ++wrong_touches_;
      }
    }
  }

  bool succeeded() const override { return next_ == targets_.size(); }

  std::string penaltySlot(const std::string& item) const override {
    return item == "wrong_touches" || item == "unlit_touches" ? tool_ : "";
  }

  std::vector<Measurement> measurements(double) const override {
    return {{"targets_touched", static_cast<double>(next_), "1"},
            {"path_length", path_length_, "m"},
            {"wrong_touches", static_cast<double>(wrong_touches_), "1"},
            {"unlit_touches", static_cast<double>(unlit_touches_), "1"},
            {"retina_contacts", static_cast<double>(contacts_.count()), "1"}};
  }

  std::string progress() const override {
    if (succeeded()) return "all targets touched";
    return format("target %zu of %zu: %s", next_ + 1, targets_.size(), targets_[next_].name.c_str());
  }

  void hash(std::uint64_t& state) const override {
    hashValue(state, next_);
    hashValue(state, path_length_);
    hashValue(state, wrong_touches_);
    hashValue(state, unlit_touches_);
    contacts_.hash(state);
  }

  // last_tip_ is the start of the next path increment; touching_ holds each target's hysteresis.
  void transferState(StateArchive& archive) override {
    archive.section("navigation").expect(targets_.size(), "the number of targets");
    archive(touching_)(next_)(wrong_touches_)(unlit_touches_)(path_length_)(last_tip_)(contacts_);
  }

 private:
  bool lit(const InstrumentView* light, const Sphere& target) const {
    if (light_ == "none") return true;
    if (light == nullptr || !light->valid) return false;
    return litByLightPipe(light->tip, light->axis, target.centre, cone_cos_);
  }

  std::vector<Sphere> targets_;
  std::vector<ContactCounter> touching_;
  std::string tool_, light_;
  double tolerance_ = 1e-4, cone_cos_ = 0.9;
  std::size_t next_ = 0, wrong_touches_ = 0, unlit_touches_ = 0;
  double path_length_ = 0.0;
  std::optional<Eigen::Vector3d> last_tip_;
  RetinaContacts contacts_;
};

}  // namespace

std::unique_ptr<Scenario> makeNavigation(const scene::SceneDescription& scene) {
  return std::make_unique<Navigation>(scene);
}

}  // namespace scenario
}  // namespace vrm_sim
