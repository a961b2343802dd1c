// EyeSi's bimanual hand-over (issue 36). Rigid objects only (no tissue simulation): the body is rigid_body.h's, its
// placement goes to the World (collision) and the renderer (SimulationState.objects). Geometry in the eye frame.
#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include "common.h"
#include "rigid_object_params.h"
#include "scenarios.h"
#include "vrm_sim/collision/primitives.h"
#include "vrm_sim/scenario/rigid_body.h"

namespace vrm_sim {
namespace scenario {
namespace {

constexpr double kShaftLength = 0.02;  // m of instrument shaft inside the eye, from the tip back to the trocar side

// Retina contacts of the instrument shafts is RetinaContacts; this counts the shafts of the two instruments touching
// each other: the segments (tip back along the axis) closer than two shaft radii (enter) / plus 50 µm (leave).
class InstrumentCollisions {
 public:
  InstrumentCollisions(std::string first, std::string second, double shaft_radius)
      : first_(std::move(first)), second_(std::move(second)), shaft_radius_(shaft_radius) {}
  void update(const FrameView& frame) {
    const InstrumentView* a = frame.instrument(first_);
    const InstrumentView* b = frame.instrument(second_);
    if (a == nullptr || b == nullptr || !a->valid || !b->valid || !a->tip.allFinite() || !b->tip.allFinite()) return;
    const double distance = std::sqrt(collision::segmentSegmentDistanceSquared(
        a->tip - kShaftLength * a->axis, a->tip, b->tip - kShaftLength * b->axis, b->tip));
    closest_ = std::min(closest_, distance - 2.0 * shaft_radius_);
    counter_.update(distance, 2.0 * shaft_radius_, 2.0 * shaft_radius_ + 5e-5);
  }
  std::size_t count() const { return counter_.count(); }
  double closest() const { return std::isfinite(closest_) ? std::max(0.0, closest_) : 0.0; }
  void hash(std::uint64_t& state) const {
    const std::size_t count = counter_.count();
    hashValue(state, count);
  }
  void transferState(StateArchive& archive) { archive(closest_)(counter_); }

 private:
  std::string first_, second_;
  double shaft_radius_;
  double closest_ = std::numeric_limits<double>::infinity();
  ContactCounter counter_;
};

// Pass an object from one forceps to the other `handovers` times: the receiving forceps grasps it while the giving
// one still holds it, then the giver lets go. Letting go while the other does not hold it is a drop (it falls onto the
// retina and must be picked up again).
class Bimanual : public Scenario {
 public:
  explicit Bimanual(const scene::SceneDescription& scene)
      : contacts_(scene.eye.radius),
        collisions_("left", "right", 0.0),
        body_("", Eigen::Isometry3d::Identity(), RigidBodyOptions{}) {
    Params params(scene);
    const scene::ObjectDescription& object = params.object("object", "cube");
    const auto& size = generatorOf<scene::BoxParams>(object, params, "object", "box").size;
    RigidBodyOptions options = bodyOptions(scene, params);
    options.half_extents = 0.5 * size;
    first_ = params.slot("first", "right");
    second_ = params.slot("second", "left");
    if (first_ == second_) params.fail("second", "the two forceps must be in different slots");
    required_ = static_cast<std::size_t>(params.number("handovers", 3.0, 1.0, 50.0));
    release_height_ = params.number("release_height", 5e-4, 0.0, 0.01);
    collisions_ = InstrumentCollisions(first_, second_, params.number("shaft_radius", 3.2e-4, 0.0, 2e-3));
    params.finish();
    for (const scene::InstrumentDescription& instrument : scene.instruments) {
      if (instrument.type != scene::InstrumentType::kForceps &&
          (toString(instrument.slot) == first_ || toString(instrument.slot) == second_)) {
        throw scene::SceneError(scene.scenario->type_location, "bimanual needs forceps in both slots; slot '" +
                                                                   std::string(toString(instrument.slot)) + "' has a " +
                                                                   toString(instrument.type));
      }
    }
    body_ = RigidBody(object.name, object.pose.toIsometry(), options);
  }

  std::vector<Measurement> items() const override { return measurements(0.0); }

  void update(const FrameView& frame, double) override {
    contacts_.update(frame);
    collisions_.update(frame);
    const std::string holder = body_.holder();
    const std::vector<std::string> dropped = body_.update(frame, {first_, second_});
    if (!dropped.empty()) {
      ++drops_;
      last_holder_ = dropped.front();
      release_radius_ = body_.centre().norm();
    } else if (!holder.empty() && !body_.holder().empty() && body_.holder() != holder) {
      ++handovers_;  // the giver let go while the receiver held on
    }
    if (body_.fall(frame) && body_.options().eye_radius - release_radius_ > release_height_) ++impacts_;
  }

  bool succeeded() const override { return handovers_ >= required_; }

  std::string penaltySlot(const std::string& item) const override { return item == "object_drops" ? last_holder_ : ""; }

  std::vector<Measurement> measurements(double) const override {
    return {{"handovers", static_cast<double>(handovers_), "1"},
            {"object_drops", static_cast<double>(drops_), "1"},
            {"object_impacts", static_cast<double>(impacts_), "1"},
            {"instrument_collisions", static_cast<double>(collisions_.count()), "1"},
            {"retina_contacts", static_cast<double>(contacts_.count()), "1"}};
  }

  std::vector<ObjectPlacement> placements() const override { return {body_.placement()}; }

  std::string progress() const override {
    if (succeeded()) return "all hand-overs done";
    const std::string count = format("hand-over %zu of %zu: ", handovers_ + 1, required_);
    if (!body_.held()) return count + "grasp the cube";
    if (body_.holderCount() == 2) return count + "let go with the " + body_.holder() + " forceps";
    return count + "grasp it with the " + (body_.holder() == first_ ? second_ : first_) + " forceps";
  }

  void hash(std::uint64_t& state) const override {
    body_.hash(state);
    hashValue(state, handovers_);
    hashValue(state, drops_);
    hashValue(state, impacts_);
    collisions_.hash(state);
    contacts_.hash(state);
  }

  // last_holder_ and release_radius_ are not hashed: they charge the next drop and judge the next landing.
  void transferState(StateArchive& archive) override {
    archive.section("bimanual");
    archive(contacts_)(collisions_)(body_)(last_holder_)(handovers_)(drops_)(impacts_)(release_radius_);
  }

 private:
  RetinaContacts contacts_;
  InstrumentCollisions collisions_;
  RigidBody body_;
  std::string first_, second_, last_holder_;
  std::size_t required_ = 3, handovers_ = 0, drops_ = 0, impacts_ = 0;
  double release_height_ = 5e-4, release_radius_ = 0.0;
};

}  // namespace

std::unique_ptr<Scenario> makeBimanual(const scene::SceneDescription& scene) {
  return std::make_unique<Bimanual>(scene);
}

}  // namespace scenario
}  // namespace vrm_sim
