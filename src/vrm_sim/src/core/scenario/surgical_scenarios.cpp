// The surgical scenarios (thesis §7): membrane peeling, ILM peeling and a vitrectomy step, scored from what the
// simulation core reports about the tissue (adhesion points, tearing, cutting) and the retina (contacts, bleeding).
#include <algorithm>
#include <cmath>

#include "common.h"
#include "scenarios.h"

namespace vrm_sim {
namespace scenario {
namespace {

constexpr double kPi = 3.14159265358979323846;

const scene::ObjectDescription& deformableObject(Params& params, const std::string& parameter,
                                                 const std::string& fallback) {
  const scene::ObjectDescription& object = params.object(parameter, fallback);
  if (!object.isDeformable()) params.fail(parameter, "object '" + object.name + "' is not deformable (tissue model)");
  return object;
}

// What a peel is scored on (membrane and ILM alike). `tool` (default right) is the working instrument whose work
// outside the light pipe's cone is measured (unlit_work, see UnlitWork).
class Peel : public Scenario {
 public:
  Peel(const scene::SceneDescription& scene, Params& params, const std::string& fallback)
      : contacts_(scene.eye.radius), unlit_(scene, params, params.slot("tool", "right")) {
    object_ = deformableObject(params, "tissue", fallback).name;
  }

  void update(const FrameView& frame, double) override {
    contacts_.update(frame);
    unlit_.update(frame);
    bleeding_area_ = frame.retina.injured_area;
    const TissueView* tissue = frame.tissue(object_);
    if (tissue == nullptr) return;
    if (!initial_adhesions_) initial_adhesions_ = tissue->adhesion_points + tissue->released_adhesions;
    remaining_ = tissue->adhesion_points;
    released_ = tissue->released_adhesions;
    torn_ = tissue->torn_springs;
    max_force_ = tissue->max_adhesion_force;
    lifted_fraction_ = tissue->lifted_fraction;
    updateShape(*tissue);
  }

  // Detached from every adhesion point: each one peeled off, or the rest cut free with the vitrector — a tear that
  // isolates an adhesion point also removes it, but that is a torn membrane, not a detached one.
  bool succeeded() const override {
    if (!initial_adhesions_ || *initial_adhesions_ == 0) return false;
    return released_ >= *initial_adhesions_ || (remaining_ == 0 && torn_ == 0);
  }

  std::vector<Measurement> items() const override { return measurements(0.0); }

  std::string penaltySlot(const std::string& item) const override { return item == "unlit_work" ? unlit_.tool() : ""; }

  std::vector<Measurement> measurements(double) const override {
    const double initial = initial_adhesions_ ? static_cast<double>(*initial_adhesions_) : 0.0;
    const double detached = torn_ > 0 ? static_cast<double>(released_) : initial - static_cast<double>(remaining_);
    return {{"detached_fraction", initial > 0.0 ? std::clamp(detached / initial, 0.0, 1.0) : 0.0, "1"},
            {"torn_springs", static_cast<double>(torn_), "1"},
            {"max_adhesion_force", max_force_, "N"},
            {"lifted_fraction", lifted_fraction_, "1"},
            {"retina_contacts", static_cast<double>(contacts_.count()), "1"},
            {"bleeding_area", bleeding_area_, "m^2"},
            {"unlit_work", unlit_.seconds(), "s"}};
  }

  std::string progress() const override {
    const std::size_t initial = initial_adhesions_ ? *initial_adhesions_ : 0;
    return format("%zu of %zu adhesion points detached%s", initial - std::min(initial, remaining_), initial,
                  torn_ > 0 ? " (torn)" : "");
  }

  void hash(std::uint64_t& state) const override {
    hashValue(state, remaining_);
    hashValue(state, torn_);
    hashValue(state, max_force_);
    hashValue(state, bleeding_area_);
    contacts_.hash(state);
    unlit_.hash(state);
  }

 protected:
  virtual void updateShape(const TissueView&) {}

  std::string object_;
  std::optional<std::size_t> initial_adhesions_;
  std::size_t remaining_ = 0;
  std::uint64_t released_ = 0, torn_ = 0;
  double max_force_ = 0.0, lifted_fraction_ = 0.0, bleeding_area_ = 0.0;
  RetinaContacts contacts_;
  UnlitWork unlit_;
};

// Membrane peeling: success once the membrane let go of every adhesion point, peeled with the forceps or cut free with
// the vitrector.
class MembranePeeling : public Peel {
 public:
  MembranePeeling(const scene::SceneDescription& scene, Params&& params) : Peel(scene, params, "membrane") {
    params.finish();
  }
};

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

 private:
  std::string object_, tool_;
  double eye_radius_, warning_distance_ = 5e-4, facing_cos_ = 0.5, required_removed_ = 0.8;
  double removed_ = 0.0, damage_ = 0.0, damaged_area_ = 0.0;
  ContactCounter warnings_;
  RetinaContacts contacts_;
  UnlitWork unlit_;
};

}  // namespace

std::unique_ptr<Scenario> makeMembranePeeling(const scene::SceneDescription& scene) {
  return std::make_unique<MembranePeeling>(scene, Params(scene));
}
std::unique_ptr<Scenario> makeIlmPeeling(const scene::SceneDescription& scene) {
  return std::make_unique<IlmPeeling>(scene, Params(scene));
}
std::unique_ptr<Scenario> makeVitrectomy(const scene::SceneDescription& scene) {
  return std::make_unique<Vitrectomy>(scene, Params(scene));
}

}  // namespace scenario
}  // namespace vrm_sim
