// The object manipulation modules of thesis §7.4.1 beyond the sphere (boxes, rings, key-and-lock). Rigid objects only
// (no tissue simulation): the bodies are rigid_body.h's, their placements go to the World (collision) and the renderer
// (SimulationState.objects). Geometry in the eye frame.
#include <algorithm>
#include <cmath>
#include <set>
#include <string>
#include <vector>

#include "common.h"
#include "rigid_object_params.h"
#include "scenarios.h"
#include "vrm_sim/scenario/rigid_body.h"

namespace vrm_sim {
namespace scenario {
namespace {

// Angle (rad) between two directions, folded for a symmetric shape: `period` = pi for a box seen along one axis (a
// half-turn gives the same footprint), 2 pi for no symmetry.
double foldedAngle(double angle, double period) {
  angle = std::fmod(std::abs(angle), period);
  return std::min(angle, period - angle);
}

// The angle of `direction` about `normal` from `reference` (both projected into the plane normal to `normal`).
double angleAbout(const Eigen::Vector3d& direction, const Eigen::Vector3d& reference, const Eigen::Vector3d& normal) {
  const Eigen::Vector3d d = direction - direction.dot(normal) * normal;
  const Eigen::Vector3d r = reference - reference.dot(normal) * normal;
  return std::atan2(r.cross(d).dot(normal), r.dot(d));
}

// Grasp and place a box on its target pad (position and yaw within tolerance), thread a ring over a post, and insert
// a key into a lock (position, direction and twist within tolerance, the contact force on the lock limited), in the
// order of `tasks`. Released anywhere else an object falls onto the retina (a drop) and can be grasped again.
class ObjectManipulation : public Scenario {
 public:
  explicit ObjectManipulation(const scene::SceneDescription& scene)
      : eye_radius_(scene.eye.radius), contacts_(scene.eye.radius) {
    Params params(scene);
    tool_ = params.slot("gripper", "right");
    const RigidBodyOptions options = bodyOptions(scene, params);
    release_height_ = params.number("release_height", 5e-4, 0.0, 0.01);
    std::vector<std::string> tasks = params.names("tasks");
    if (tasks.empty()) tasks = {"box", "ring", "key"};
    for (const std::string& task : tasks) {
      if (task == "box") {
        const scene::ObjectDescription& box = params.object("box", "box");
        const auto& size = generatorOf<scene::BoxParams>(box, params, "box", "box").size;
        RigidBodyOptions box_options = options;
        box_options.half_extents = 0.5 * size;
        const scene::ObjectDescription& pad = params.object("box_target", "box_target");
        generatorOf<scene::DiscParams>(pad, params, "box_target", "disc");
        pad_ = pad.pose.toIsometry();
        place_tolerance_ = params.number("place_tolerance", 3e-4, 1e-5, 5e-3);
        yaw_tolerance_ = params.number("yaw_tolerance_deg", 15.0, 0.5, 90.0) * kDegree;
        box_ = bodies_.size();
        bodies_.emplace_back(box.name, box.pose.toIsometry(), box_options);
      } else if (task == "ring") {
        const scene::ObjectDescription& ring = params.object("ring", "ring");
        const auto& torus = generatorOf<scene::TorusParams>(ring, params, "ring", "torus");
        RigidBodyOptions ring_options = options;
        ring_options.half_extents = {torus.major_radius + torus.minor_radius, torus.major_radius + torus.minor_radius,
                                     torus.minor_radius};
        ring_options.resting_axes = {2};
        // The jaws hold the ring by its tube: the tip is near the ring's rim, not its centre.
        ring_options.grasp_reach = torus.major_radius + options.grasp_reach;
        ring_major_ = torus.major_radius;
        ring_minor_ = torus.minor_radius;
        const scene::ObjectDescription& post = params.object("post", "post");
        const auto& cylinder = generatorOf<scene::CylinderParams>(post, params, "post", "cylinder");
        const Eigen::Isometry3d post_pose = post.pose.toIsometry();
        post_axis_ = post_pose.linear().col(2);
        post_base_ = post_pose.translation() - 0.5 * cylinder.length * post_axis_;
        post_length_ = cylinder.length;
        post_radius_ = cylinder.radius;
        if (ring_major_ - ring_minor_ <= post_radius_) {
          params.fail("ring", "the ring's hole (major - minor radius) must be wider than the post's radius");
        }
        ring_tilt_tolerance_ = params.number("ring_tilt_tolerance_deg", 20.0, 0.5, 90.0) * kDegree;
        ring_ = bodies_.size();
        bodies_.emplace_back(ring.name, ring.pose.toIsometry(), ring_options);
      } else if (task == "key") {
        const scene::ObjectDescription& key = params.object("key", "key");
        const auto& size = generatorOf<scene::BoxParams>(key, params, "key", "box").size;
        RigidBodyOptions key_options = options;
        key_options.half_extents = 0.5 * size;
        key_length_ = size.z();
        key_width_ = size.x();
        const scene::ObjectDescription& lock = params.object("lock", "lock");
        const auto& lock_size = generatorOf<scene::BoxParams>(lock, params, "lock", "box").size;
        lock_ = lock.pose.toIsometry();
        lock_opening_ = lock_ * Eigen::Vector3d(0.0, 0.0, 0.5 * lock_size.z());
        lock_half_width_ = 0.5 * std::min(lock_size.x(), lock_size.y());
        key_clearance_ = params.number("key_clearance", 1e-4, 0.0, 2e-3);
        key_tilt_tolerance_ = params.number("key_tilt_tolerance_deg", 8.0, 0.1, 45.0) * kDegree;
        key_twist_tolerance_ = params.number("key_twist_tolerance_deg", 10.0, 0.1, 90.0) * kDegree;
        insert_depth_ = params.number("insert_depth", 4e-4, 1e-5, 0.01);
        contact_stiffness_ = params.number("contact_stiffness", 50.0, 0.0, 1e6);
        key_ = bodies_.size();
        bodies_.emplace_back(key.name, key.pose.toIsometry(), key_options);
      } else {
        params.fail("tasks", "unknown task '" + task + "' (box, ring, key)");
      }
    }
    params.finish();
    tasks_ = tasks;
  }

  std::vector<Measurement> items() const override { return measurements(0.0); }

  // Only the current task's object moves (the tasks are done in order; a done one stays where it was placed).
  void update(const FrameView& frame, double) override {
    contacts_.update(frame);
    const std::size_t i = current();
    if (i == kNone) return;
    RigidBody& body = bodies_[i];
    if (!body.update(frame, {tool_}).empty()) {
      release_height_above_retina_ = heightAboveRetina(body.centre());
      if (i == ring_ && threaded()) {
        Eigen::Isometry3d seated = Eigen::Isometry3d::Identity();
        const Eigen::Vector3d normal = body.pose().linear().col(2);
        seated.linear() =
            Eigen::Quaterniond::FromTwoVectors(normal.dot(post_axis_) >= 0.0 ? normal : -normal, post_axis_)
                .toRotationMatrix() *
            body.pose().linear();
        seated.translation() = post_base_ + ring_minor_ * post_axis_;
        body.place(seated);
        done_.insert(i);
        return;
      }
    }
    if (body.fall(frame)) landed(i);
    if (i == ring_ && body.held()) postCollision();
    if (i == key_ && body.held()) keyInLock();
  }

  bool succeeded() const override { return done_.size() == bodies_.size(); }

  std::string penaltySlot(const std::string& item) const override {
    return item == "object_drops" || item == "post_collisions" || item == "max_key_force" ? tool_ : "";
  }

  std::vector<Measurement> measurements(double) const override {
    return {{"tasks_done", static_cast<double>(done_.size()), "1"},
            {"orientation_error", yaw_error_ / kDegree, "deg"},
            {"object_drops", static_cast<double>(drops_), "1"},
            {"object_impacts", static_cast<double>(impacts_), "1"},
            {"post_collisions", static_cast<double>(post_collisions_.count()), "1"},
            {"max_key_force", max_key_force_, "N"},
            {"retina_contacts", static_cast<double>(contacts_.count()), "1"}};
  }

  std::vector<ObjectPlacement> placements() const override {
    std::vector<ObjectPlacement> placements;
    for (const RigidBody& body : bodies_) placements.push_back(body.placement());
    return placements;
  }

  std::string progress() const override {
    const std::size_t i = current();
    if (i == kNone) return "all tasks done";
    const std::string step = format("task %zu of %zu: ", done_.size() + 1, bodies_.size());
    const bool held = bodies_[i].held();
    if (i == box_) return step + (held ? "set the box down on the pad, turned like it" : "grasp the box");
    if (i == ring_) return step + (held ? "thread the ring over the post" : "grasp the ring");
    return step + (held ? format("insert the key (force %.1f mN)", 1e3 * key_force_) : "grasp the key");
  }

  void hash(std::uint64_t& state) const override {
    for (const RigidBody& body : bodies_) body.hash(state);
    for (std::size_t i : done_) hashValue(state, i);
    hashValue(state, drops_);
    hashValue(state, impacts_);
    hashValue(state, max_key_force_);
    hashValue(state, yaw_error_);
    contacts_.hash(state);
  }

  // The bodies in place: they are built from the scene (their names and options), only their motion is state.
  void transferState(StateArchive& archive) override {
    archive.section("object_manipulation").expect(bodies_.size(), "the number of objects");
    for (RigidBody& body : bodies_) archive(body);
    archive(done_)(release_height_above_retina_)(yaw_error_)(post_collisions_)(key_force_)(max_key_force_);
    archive(drops_)(impacts_)(contacts_);
  }

 private:
  static constexpr std::size_t kNone = static_cast<std::size_t>(-1);

  std::size_t current() const {
    for (std::size_t i = 0; i < bodies_.size(); ++i) {
      if (!done_.count(i)) return i;
    }
    return kNone;
  }
  double heightAboveRetina(const Eigen::Vector3d& point) const { return eye_radius_ - point.norm(); }

  // A released body reached the retina: on the pad, set down and turned like it, the box is placed; anything else is
  // a drop, and a fall from higher than release_height an impact on the retina.
  void landed(std::size_t index) {
    RigidBody& body = bodies_[index];
    if (release_height_above_retina_ > release_height_) ++impacts_;
    if (index == box_) {
      const Eigen::Vector3d normal = pad_.linear().col(2);
      const Eigen::Vector3d offset = body.centre() - pad_.translation();
      const double distance = (offset - offset.dot(normal) * normal).norm();
      const double yaw = foldedAngle(angleAbout(body.pose().linear().col(0), pad_.linear().col(0), normal), kPi);
      if (distance <= place_tolerance_ && yaw <= yaw_tolerance_) {
        yaw_error_ = yaw;
        done_.insert(index);
        return;
      }
    }
    ++drops_;
  }

  // The ring is threaded when its centre is below the post's top and over its base, the post passes through the
  // hole without touching the tube, and the ring lies within ring_tilt_tolerance of flat on the post.
  bool threaded() const {
    const RigidBody& ring = bodies_[ring_];
    const Eigen::Vector3d offset = ring.centre() - post_base_;
    const double along = offset.dot(post_axis_);
    const double radial = (offset - along * post_axis_).norm();
    const double tilt = std::acos(std::min(1.0, std::abs(ring.pose().linear().col(2).dot(post_axis_))));
    return along >= 0.0 && along <= post_length_ && radial + post_radius_ <= ring_major_ - ring_minor_ &&
           tilt <= ring_tilt_tolerance_;
  }

  // The held ring's tube against the post (the ring's plane cuts the post where the tube is): a collision event.
  void postCollision() {
    const RigidBody& ring = bodies_[ring_];
    const Eigen::Vector3d offset = ring.centre() - post_base_;
    const double along = offset.dot(post_axis_);
    const double radial = (offset - along * post_axis_).norm();
    const double gap = std::abs(radial - ring_major_) - (ring_minor_ + post_radius_);
    const bool beside_post = along >= -ring_minor_ && along <= post_length_ + ring_minor_;
    post_collisions_.update(beside_post ? gap : 1.0, 0.0, 2e-5);
  }

  // The key's leading end (the end deeper along the lock's axis) in the slot: the force on the lock is the contact
  // stiffness times how far the key is off the slot (lateral offset beyond the clearance, the tilt and twist beyond
  // their tolerances, as penetrations of the key's end and edge into the slot's walls). Inserted to insert_depth
  // with no force, the key turns the lock: the task is done and the key stays in the lock.
  void keyInLock() {
    RigidBody& key = bodies_[key_];
    const Eigen::Vector3d slot_axis = lock_.linear().col(2);
    const Eigen::Vector3d key_axis = key.pose().linear().col(2);
    const double direction = key_axis.dot(slot_axis) >= 0.0 ? 1.0 : -1.0;
    const Eigen::Vector3d lead = key.centre() - direction * 0.5 * key_length_ * key_axis;
    const double depth = (lock_opening_ - lead).dot(slot_axis);
    const Eigen::Vector3d lateral = (lead - lock_opening_) - (lead - lock_opening_).dot(slot_axis) * slot_axis;
    key_force_ = 0.0;
    if (depth <= 0.0 || lateral.norm() > lock_half_width_) return;
    const double tilt = std::acos(std::min(1.0, std::abs(key_axis.dot(slot_axis))));
    const double twist = foldedAngle(angleAbout(key.pose().linear().col(0), lock_.linear().col(0), slot_axis), kPi);
    const double inside = std::min(depth, key_length_);
    const double penetration = std::max(0.0, lateral.norm() - key_clearance_) +
                               inside * std::sin(std::max(0.0, tilt - key_tilt_tolerance_)) +
                               0.5 * key_width_ * std::sin(std::max(0.0, twist - key_twist_tolerance_));
    key_force_ = contact_stiffness_ * penetration;
    max_key_force_ = std::max(max_key_force_, key_force_);
    if (depth >= insert_depth_ && penetration == 0.0) {
      key.place(key.pose());
      done_.insert(key_);
    }
  }

  std::string tool_;
  std::vector<std::string> tasks_;
  std::vector<RigidBody> bodies_;
  std::set<std::size_t> done_;
  std::size_t box_ = kNone, ring_ = kNone, key_ = kNone;
  double eye_radius_ = 0.012;
  double release_height_ = 5e-4, release_height_above_retina_ = 0.0;
  // box
  Eigen::Isometry3d pad_ = Eigen::Isometry3d::Identity();
  double place_tolerance_ = 3e-4, yaw_tolerance_ = 0.26, yaw_error_ = 0.0;
  // ring and post
  double ring_major_ = 0.0, ring_minor_ = 0.0, ring_tilt_tolerance_ = 0.35;
  Eigen::Vector3d post_axis_ = Eigen::Vector3d::UnitZ(), post_base_ = Eigen::Vector3d::Zero();
  double post_length_ = 0.0, post_radius_ = 0.0;
  ContactCounter post_collisions_;
  // key and lock
  Eigen::Isometry3d lock_ = Eigen::Isometry3d::Identity();
  Eigen::Vector3d lock_opening_ = Eigen::Vector3d::Zero();
  double lock_half_width_ = 0.0, key_length_ = 0.0, key_width_ = 0.0, key_clearance_ = 1e-4;
  double key_tilt_tolerance_ = 0.14, key_twist_tolerance_ = 0.17, insert_depth_ = 4e-4, contact_stiffness_ = 50.0;
  double key_force_ = 0.0, max_key_force_ = 0.0;
  std::size_t drops_ = 0, impacts_ = 0;
  RetinaContacts contacts_;
};

}  // namespace

std::unique_ptr<Scenario> makeObjectManipulation(const scene::SceneDescription& scene) {
  return std::make_unique<ObjectManipulation>(scene);
}

}  // namespace scenario
}  // namespace vrm_sim
