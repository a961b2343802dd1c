// The abstract scenarios of thesis §7.4.1: skills without anatomy (navigation, trajectory following, pick and place,
// steady hold). Geometry in the eye frame; the retina is the eye sphere unless the core simulates it.
#include <algorithm>
#include <cmath>

#include "common.h"
#include "scenarios.h"
#include "vrm_sim/scenario/light_cone.h"
#include "vrm_sim/scenario/rigid_body.h"

namespace vrm_sim {
namespace scenario {
namespace {

constexpr double kPi = 3.14159265358979323846;

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

// Follow a path marked on the retina at a given height above it: from its first point to its last.
class Trajectory : public Scenario {
 public:
  explicit Trajectory(const scene::SceneDescription& scene) : contacts_(scene.eye.radius) {
    Params params(scene);
    const std::vector<Eigen::Vector3d> marked = params.points("path");
    if (marked.size() < 2) params.fail("path", "expected at least two points");
    const double height = params.number("height", 5e-4, 0.0, 5e-3);
    for (const Eigen::Vector3d& point : marked) {
      if (!(point.norm() > height)) params.fail("path", "a path point lies at the eye centre");
      path_.push_back(point * (1.0 - height / point.norm()));  // towards the eye centre, i.e. above the retina
    }
    length_ = pathLength(path_);
    tool_ = params.slot("tool", "right");
    tolerance_ = params.number("end_tolerance", 3e-4, 1e-5, 5e-3);
    finish_fraction_ = params.number("finish_fraction", 0.95, 0.1, 1.0);
    params.finish();
  }

  std::vector<Measurement> items() const override { return measurements(0.0); }

  void update(const FrameView& frame, double) override {
    contacts_.update(frame);
    const InstrumentView* tool = frame.instrument(tool_);
    if (tool == nullptr || !tool->valid) return;
    if (!started_) {
      started_ = (tool->tip - path_.front()).norm() < tolerance_;
      last_tip_ = tool->tip;
      if (!started_) return;
    }
    const PolylineProjection projection = projectOnPolyline(path_, tool->tip);
    deviation_.add(projection.distance);
    if (projection.distance < 3.0 * tolerance_) progress_ = std::max(progress_, projection.arc);
    if (frame.dt > 0.0) speed_.add((tool->tip - last_tip_).norm() / frame.dt);
    last_tip_ = tool->tip;
    finished_ = progress_ >= finish_fraction_ * length_ && (tool->tip - path_.back()).norm() < tolerance_;
  }

  bool succeeded() const override { return finished_; }

  std::vector<Measurement> measurements(double) const override {
    return {{"progress", length_ > 0.0 ? progress_ / length_ : 0.0, "1"},
            {"mean_deviation", deviation_.mean(), "m"},
            {"max_deviation", deviation_.max(), "m"},
            {"speed_variability", speed_.coefficientOfVariation(), "1"},
            {"retina_contacts", static_cast<double>(contacts_.count()), "1"}};
  }

  std::string progress() const override {
    if (!started_) return "bring the tip to the start of the path";
    return format("%.0f %% of the path", 100.0 * (length_ > 0.0 ? progress_ / length_ : 0.0));
  }

  void hash(std::uint64_t& state) const override {
    hashValue(state, started_);
    hashValue(state, progress_);
    hashValue(state, deviation_.mean());
    hashValue(state, deviation_.max());
    contacts_.hash(state);
  }

 private:
  std::vector<Eigen::Vector3d> path_;
  double length_ = 0.0, tolerance_ = 3e-4, finish_fraction_ = 0.95;
  std::string tool_;
  bool started_ = false, finished_ = false;
  double progress_ = 0.0;
  Eigen::Vector3d last_tip_ = Eigen::Vector3d::Zero();
  RunningStats deviation_, speed_;
  RetinaContacts contacts_;
};

// Grasp a sphere with the forceps, carry it into a ring and let go there. The sphere is a rigid body (rigid_body.h):
// released outside the ring it falls under gravity with the viscous drag of the eye's fluid filling and comes to rest
// on the retina; every landing is an impact.
class PickAndPlace : public Scenario {
 public:
  explicit PickAndPlace(const scene::SceneDescription& scene)
      : contacts_(scene.eye.radius), ball_("", Eigen::Isometry3d::Identity(), RigidBodyOptions{}) {
    Params params(scene);
    const scene::ObjectDescription& ball = params.object("ball", "ball");
    const Sphere sphere = sphereOf(ball, params, "ball");
    const scene::ObjectDescription& ring = params.object("ring", "ring");
    const auto* torus = ring.mesh.generator ? std::get_if<scene::TorusParams>(&*ring.mesh.generator) : nullptr;
    if (torus == nullptr || ring.frame != scene::ObjectFrame::kEye) {
      params.fail("ring", "object '" + ring.name + "' must be a torus in the eye frame");
    }
    const Eigen::Isometry3d ring_pose = ring.pose.toIsometry();
    ring_centre_ = ring_pose.translation();
    ring_normal_ = ring_pose.linear().col(2);
    ring_radius_ = torus->major_radius;
    tool_ = params.slot("gripper", "right");
    RigidBodyOptions options;
    options.half_extents = Eigen::Vector3d::Constant(sphere.radius);
    options.grasp_reach = sphere.radius + params.number("grasp_tolerance", 2e-4, 0.0, 2e-3);
    options.grasp_angle = params.number("grasp_angle_deg", 8.0, 0.5, 90.0) * kPi / 180.0;
    options.gravity = params.number("gravity", 9.81, 0.0, 100.0);
    options.drag = params.number("drag", 30.0, 0.0, 1e4);
    options.eye_radius = scene.eye.radius;
    params.finish();
    ball_ = RigidBody(ball.name, ball.pose.toIsometry(), options);
  }

  std::vector<Measurement> items() const override { return measurements(0.0); }

  void update(const FrameView& frame, double) override {
    contacts_.update(frame);
    if (placed_) return;  // it stays in the ring
    if (!ball_.update(frame, {tool_}).empty()) {
      if (inRing(ball_.centre())) {
        placed_ = true;
        ball_.place(ball_.pose());
        return;
      }
      ++drops_;
    }
    if (ball_.fall(frame)) ++impacts_;
  }

  bool succeeded() const override { return placed_; }

  std::string penaltySlot(const std::string& item) const override { return item == "drops" ? tool_ : ""; }

  std::vector<Measurement> measurements(double) const override {
    return {{"placed", placed_ ? 1.0 : 0.0, "1"},
            {"drops", static_cast<double>(drops_), "1"},
            {"ball_impacts", static_cast<double>(impacts_), "1"},
            {"retina_contacts", static_cast<double>(contacts_.count()), "1"}};
  }

  std::vector<ObjectPlacement> placements() const override { return {ball_.placement()}; }

  std::string progress() const override {
    if (placed_) return "placed in the ring";
    return ball_.held() ? "carry the sphere into the ring" : "grasp the sphere";
  }

  void hash(std::uint64_t& state) const override {
    ball_.hash(state);
    hashValue(state, placed_);
    hashValue(state, drops_);
    hashValue(state, impacts_);
    contacts_.hash(state);
  }

 private:
  bool inRing(const Eigen::Vector3d& p) const {
    const Eigen::Vector3d d = p - ring_centre_;
    const double along = d.dot(ring_normal_);
    return (d - along * ring_normal_).norm() < ring_radius_ && std::abs(along) < ring_radius_;
  }

  RetinaContacts contacts_;
  RigidBody ball_;
  Eigen::Vector3d ring_centre_, ring_normal_;
  double ring_radius_ = 0.0;
  std::string tool_;
  bool placed_ = false;
  std::size_t drops_ = 0, impacts_ = 0;
};

// Hold the tip inside a small sphere (100 µm) for a while; the tremor (tip RMS, power in the 8-12 Hz band of
// physiological tremor, thesis §1.3) is measured from the tracked tip during the longest hold.
class SteadyHold : public Scenario {
 public:
  explicit SteadyHold(const scene::SceneDescription& scene) : contacts_(scene.eye.radius) {
    Params params(scene);
    const std::vector<Eigen::Vector3d> centre = params.points("centre");
    if (centre.size() != 1) params.fail("centre", "expected one point x, y, z");
    centre_ = centre.front();
    radius_ = params.number("radius", 1e-4, 1e-6, 5e-3);
    hold_time_ = params.number("hold_time", 10.0, 0.1, 600.0);
    band_low_ = params.number("band_low_hz", 8.0, 0.0, 1000.0);
    band_high_ = params.number("band_high_hz", 12.0, band_low_, 1000.0);
    tool_ = params.slot("tool", "right");
    params.finish();
  }

  std::vector<Measurement> items() const override { return measurements(0.0); }

  void update(const FrameView& frame, double elapsed) override {
    contacts_.update(frame);
    const InstrumentView* tool = frame.instrument(tool_);
    const bool inside = tool != nullptr && tool->valid && (tool->tip - centre_).norm() <= radius_;
    if (inside && !inside_) {
      hold_start_ = elapsed;
      samples_.clear();
      times_.clear();
    }
    if (!inside && inside_) {
      ++exits_;
      if (current_is_longest_) analyse();  // the longest hold's figures, however short it was
      current_is_longest_ = false;
    }
    inside_ = inside;
    if (!inside) return;
    samples_.push_back(tool->tip);
    times_.push_back(elapsed);  // running time: independent of where the stamps start
    if (elapsed - hold_start_ >= longest_hold_) {
      longest_hold_ = elapsed - hold_start_;
      current_is_longest_ = true;
    }
    held_ = longest_hold_ >= hold_time_;
    // The band power is a DFT over the hold: refreshed every 0.5 s of samples, and at the end of a hold.
    if (current_is_longest_ && (held_ || samples_.size() % 25 == 1)) analyse();
  }

  bool succeeded() const override { return held_; }

  std::string penaltySlot(const std::string& item) const override { return item == "exits" ? tool_ : ""; }

  std::vector<Measurement> measurements(double) const override {
    return {{"hold", longest_hold_, "s"},
            {"exits", static_cast<double>(exits_), "1"},
            {"tip_rms", rms_, "m"},
            {"tremor_band_power", band_power_, "m^2"},
            {"retina_contacts", static_cast<double>(contacts_.count()), "1"}};
  }

  std::string progress() const override {
    return inside_ ? format("holding %.1f of %.0f s", longest_hold_, hold_time_) : "bring the tip into the sphere";
  }

  void hash(std::uint64_t& state) const override {
    hashValue(state, longest_hold_);
    hashValue(state, exits_);
    hashValue(state, samples_.size());
    contacts_.hash(state);
  }

 private:
  void analyse() {
    rms_ = rmsDistance(samples_, centre_);
    const double span = times_.size() > 1 ? times_.back() - times_.front() : 0.0;
    band_power_ =
        span > 0.0 ? bandPower(samples_, static_cast<double>(times_.size() - 1) / span, band_low_, band_high_) : 0.0;
  }

  Eigen::Vector3d centre_;
  double radius_ = 1e-4, hold_time_ = 10.0, band_low_ = 8.0, band_high_ = 12.0;
  std::string tool_;
  bool inside_ = false, held_ = false, current_is_longest_ = false;
  // Tremor figures of the longest hold; NaN (0 points) until the tip was ever inside.
  double hold_start_ = 0.0, longest_hold_ = 0.0, rms_ = std::nan(""), band_power_ = std::nan("");
  std::size_t exits_ = 0;
  std::vector<Eigen::Vector3d> samples_;
  std::vector<double> times_;
  RetinaContacts contacts_;
};

}  // namespace

std::unique_ptr<Scenario> makeNavigation(const scene::SceneDescription& scene) {
  return std::make_unique<Navigation>(scene);
}
std::unique_ptr<Scenario> makeTrajectory(const scene::SceneDescription& scene) {
  return std::make_unique<Trajectory>(scene);
}
std::unique_ptr<Scenario> makePickAndPlace(const scene::SceneDescription& scene) {
  return std::make_unique<PickAndPlace>(scene);
}
std::unique_ptr<Scenario> makeSteadyHold(const scene::SceneDescription& scene) {
  return std::make_unique<SteadyHold>(scene);
}

}  // namespace scenario
}  // namespace vrm_sim
