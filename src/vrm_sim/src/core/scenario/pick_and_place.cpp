// An abstract scenario of thesis §7.4.1 (a skill without anatomy). Geometry in the eye frame; the retina is the eye
// sphere unless the core simulates it.
#include <cmath>
#include <string>
#include <variant>

#include "common.h"
#include "scenarios.h"
#include "vrm_sim/scenario/rigid_body.h"

namespace vrm_sim {
namespace scenario {
namespace {

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

  void transferState(StateArchive& archive) override {
    archive.section("pick_and_place");
    archive(ball_)(placed_)(drops_)(impacts_)(contacts_);
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

}  // namespace

std::unique_ptr<Scenario> makePickAndPlace(const scene::SceneDescription& scene) {
  return std::make_unique<PickAndPlace>(scene);
}

}  // namespace scenario
}  // namespace vrm_sim
