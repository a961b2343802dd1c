// Tissue simulation nodelet (thesis §5) with collision detection (thesis §4): builds its own MGE membranes for the
// scene's deformable objects and steps them on every instrument_state within each object's time budget (stamps
// from the input). Before each step it tests every active instrument against every membrane with the collision
// detector the scene names for that object (objects[].collision.detector, or ~collision_detector for all):
//
//   zcoll, zcoll_f, zcoll[_f]_cpu, zcoll[_f]_gl   image space: the detector's per-node deformation vectors (Eq. 4.2,
//       along the instrument axis, thesis §4.2.2) are the tissue's collision response (TissueSimulator::
//       addDeformations); the simulator's own capsule test is switched off for that membrane.
//   geometric, myszkowski_cpu, fcl*               the response stays the simulator's exact capsule test (per step,
//       ε-shell); the detector only reports (these give no, or no image-space, deformation vectors).
//   none                                          the object does not collide at all.
//
// Forceps never push tissue (their jaws grasp it); their contacts are reported only. Instrument poses arrive in
// their header.frame_id ("eye" normally, or "world"); each object lives in the eye or world frame, so poses are
// transformed with the latest eye_state (world <- eye; the scene's rest pose until the first one).
//
// Publishes each membrane as vrm_msgs/TissueMesh on tissue/<object> (only when it changed; version++),
// vrm_msgs/StageTiming on tissue_timing (stages collision_<object>, tissue_<object>), and, while subscribed,
// vrm_msgs/CollisionReport on collision_report (one per instrument and object per input, stamp = input stamp,
// vectors in the object's frame) and visualization_msgs/MarkerArray on collision_markers (the colliding triangles).
// Rigid objects with a detector are tested only while somebody subscribes to those topics. Idle when the scene
// simulates neither tissue nor collision.
#include <nodelet/nodelet.h>
#include <ros/ros.h>
#include <visualization_msgs/MarkerArray.h>

#include <algorithm>
#include <boost/make_shared.hpp>
#include <cmath>
#include <fstream>
#include <map>
#include <memory>
#include <optional>
#include <pluginlib/class_list_macros.hpp>
#include <variant>

#include "vrm_msgs/CollisionReport.h"
#include "vrm_msgs/EyeState.h"
#include "vrm_msgs/InstrumentState.h"
#include "vrm_msgs/StageTiming.h"
#include "vrm_msgs/TissueMesh.h"
#include "vrm_msgs/publish.h"
#include "vrm_sim/collision/collision_detector.h"
#include "vrm_sim/conversions.h"
#include "vrm_sim/mge/membrane.h"
#include "vrm_sim/scene/scene_loader.h"
#include "vrm_sim/tissue/offline_run.h"
#include "vrm_sim/tissue/tissue_simulator.h"

namespace vrm_sim {

namespace {

constexpr double kRadToDeg = 180.0 / M_PI;

// The detectors whose deformation vectors drive the tissue response (see the top of the file).
bool deformsTissue(const std::string& detector) {
  return detector.rfind("zcoll", 0) == 0;  // zcoll, zcoll_f, zcoll[_f]_cpu, zcoll[_f]_gl
}

}  // namespace

class TissueSim : public nodelet::Nodelet {
 public:
  void onInit() override {
    ros::NodeHandle& nh = getNodeHandle();
    ros::NodeHandle& private_nh = getPrivateNodeHandle();
    const std::string scene_parameter = private_nh.param<std::string>("scene", "membrane_peeling");
    max_frame_time_ = private_nh.param("max_frame_time", 0.05);
    detector_override_ = private_nh.param<std::string>("collision_detector", "");
    eye_frame_ = private_nh.param<std::string>("eye_frame", "eye");
    world_frame_ = private_nh.param<std::string>("world_frame", "world");
    const std::string scene_path =
        std::ifstream(scene_parameter).good() ? scene_parameter : scene::shippedScenePath(scene_parameter);
    try {
      scene_ = scene::loadScene(scene_path);
      if (!scene_.simulates(scene::Simulation::kTissue) && !scene_.simulates(scene::Simulation::kCollision)) {
        NODELET_INFO("scene '%s' simulates neither tissue nor collision: tissue_sim idle", scene_.name.c_str());
        return;
      }
      buildInstruments();
      buildTissues();
      buildRigidColliders();
    } catch (const std::exception& error) {
      NODELET_FATAL("tissue_sim: cannot set up scene '%s': %s", scene_parameter.c_str(), error.what());
      ros::requestShutdown();
      return;
    }
    world_from_eye_ = scene::Pose{scene_.eye.centre_in_world, scene_.eye.rest_rpy_deg}.toIsometry();
    for (auto& [name, tissue] : tissues_) {
      tissue.publisher = nh.advertise<vrm_msgs::TissueMesh>("tissue/" + name, 2);
    }
    timing_publisher_ = nh.advertise<vrm_msgs::StageTiming>("tissue_timing", 5);
    report_publisher_ = nh.advertise<vrm_msgs::CollisionReport>("collision_report", 20);
    marker_publisher_ = nh.advertise<visualization_msgs::MarkerArray>("collision_markers", 2);
    eye_subscriber_ = nh.subscribe("eye_state", 10, &TissueSim::onEyeState, this);
    instrument_subscriber_ = nh.subscribe("instrument_state", 20, &TissueSim::onInstrumentState, this);
    NODELET_INFO("tissue_sim: scene '%s', %zu deformable objects, %zu rigid colliders", scene_.name.c_str(),
                 tissues_.size(), rigid_.size());
  }

 private:
  struct Instrument {
    const scene::InstrumentDescription* description = nullptr;  // as the scene declares the slot
    scene::InstrumentDescription current;                    // the type in use (the scene's or one of its alternatives)
    bool cutting = false;                                    // vitrector with suction and cutter running
    tissue::InstrumentInput shape;                           // capsule and grasping parameters; pose filled per object
    Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();  // in `frame_id`
    std::string frame_id;
    bool active = false;
    double jaw_angle = 1.0;  // rad
    collision::InstrumentModel model;
    int model_jaw_deg = -1000;  // jaw angle the model was built for (forceps), whole degrees
    std::uint64_t model_version = 0;
  };

  // One object the instruments are tested against, with a detector per instrument (detectors cache the
  // instrument's depth image / BVH, thesis Alg. 4.2 line 4).
  struct Collider {
    std::string object;
    std::string frame_id;
    std::string detector_name;
    collision::CollisionOptions options;
    struct PerInstrument {
      std::unique_ptr<collision::CollisionDetector> detector;
      std::uint64_t model_version = 0;
      std::optional<Eigen::Vector3d> last_tip;  // in frame_id, for the instrument velocity of eq. 5.12
    };
    std::map<std::string, PerInstrument> instruments;
  };

  struct Tissue {
    std::unique_ptr<mge::Membrane> membrane;
    std::unique_ptr<tissue::TissueSimulator> simulator;
    std::string frame_id;
    std::uint64_t version = 1;
    std::uint64_t topology_version = 1;
    std::vector<float> last_positions;
    ros::Publisher publisher;
    std::optional<Collider> collider;  // none if the detector is "none"
    bool detector_response = false;    // true: deformation vectors from the detector, capsule test off
  };

  struct RigidObject {
    TriangleMesh mesh;
    Collider collider;
  };

  std::string frameOf(scene::ObjectFrame frame) const {
    return frame == scene::ObjectFrame::kEye ? eye_frame_ : world_frame_;
  }

  std::optional<Collider> makeCollider(const scene::ObjectDescription& object) {
    const std::string name = detector_override_.empty() ? object.collision.detector : detector_override_;
    if (name == "none") return std::nullopt;
    Collider collider;
    collider.object = object.name;
    collider.frame_id = frameOf(object.frame);
    collider.detector_name = name;
    collider.options.resolution = object.collision.resolution;
    collider.options.max_pixel_size = getPrivateNodeHandle().param("collision_max_pixel_size", 0.0);
    collision::makeCollisionDetector(name);  // throws for an unknown name (the loader checks scene names already)
    return collider;
  }

  void buildInstruments() {
    for (const auto& description : scene_.instruments) {
      Instrument instrument;
      instrument.description = &description;
      setInstrumentType(instrument, description.type);
      instruments_[scene::toString(description.slot)] = std::move(instrument);
    }
  }

  // The slot's shape for `type`: the scene's parameters for its declared type, the generator defaults for an
  // alternative. The collision model is rebuilt on the next query.
  void setInstrumentType(Instrument& instrument, scene::InstrumentType type) {
    instrument.current = *instrument.description;
    if (type != instrument.description->type) {
      instrument.current.type = type;
      instrument.current.params = scene::defaultInstrumentParams(type);
    }
    instrument.shape = tissue::instrumentInputFor(instrument.current);
    // The geometric detector's exact shape: the simulator's capsule (distal end at the tip).
    const double r = instrument.shape.radius;
    instrument.model.primitives = {collision::Primitive::capsule(
        Eigen::Vector3d(0, 0, -r), Eigen::Vector3d(0, 0, -std::max(instrument.shape.length, r)), r)};
    instrument.model_version = 0;
  }

  // Instrument switching (thesis §7: the trainee changes instruments in a trocar): the scene lists which types a
  // slot may take; any other type in the input keeps the current one.
  void switchInstrumentIfNeeded(Instrument& instrument, std::uint8_t message_type, const std::string& slot) {
    static_assert(static_cast<int>(scene::InstrumentType::kLightPipe) == vrm_msgs::InstrumentState::LIGHT_PIPE &&
                      static_cast<int>(scene::InstrumentType::kForceps) == vrm_msgs::InstrumentState::FORCEPS &&
                      static_cast<int>(scene::InstrumentType::kVitrector) == vrm_msgs::InstrumentState::VITRECTOR &&
                      static_cast<int>(scene::InstrumentType::kNeedle) == vrm_msgs::InstrumentState::NEEDLE &&
                      static_cast<int>(scene::InstrumentType::kHook) == vrm_msgs::InstrumentState::HOOK,
                  "scene::InstrumentType must follow the InstrumentState type constants");
    if (message_type > vrm_msgs::InstrumentState::HOOK) return;
    const auto type = static_cast<scene::InstrumentType>(message_type);
    if (type == instrument.current.type) return;
    const auto& allowed = instrument.description->alternatives;
    if (type != instrument.description->type && std::find(allowed.begin(), allowed.end(), type) == allowed.end()) {
      NODELET_WARN_THROTTLE(10.0, "instrument_state '%s': type %s is not allowed in this slot by the scene; keeping %s",
                            slot.c_str(), scene::toString(type), scene::toString(instrument.current.type));
      return;
    }
    NODELET_INFO("instrument '%s' switched to %s", slot.c_str(), scene::toString(type));
    setInstrumentType(instrument, type);
  }

  void buildTissues() {
    if (!scene_.simulates(scene::Simulation::kTissue)) return;
    for (const auto& object : scene_.objects) {
      if (!object.isDeformable()) continue;
      const TriangleMesh mesh = scene::buildMesh(object, scene::MeshFrame::kParent);
      Tissue tissue;
      tissue.membrane = mge::buildMembrane(mesh, tissue::membraneOptionsFor(object.tissue, mesh.vertexCount()));
      tissue.simulator = std::make_unique<tissue::TissueSimulator>(
          *tissue.membrane, tissue::tissueConfigFor(object.tissue, object.collision));
      tissue.frame_id = frameOf(object.frame);
      if (scene_.simulates(scene::Simulation::kCollision)) tissue.collider = makeCollider(object);
      tissue.detector_response = tissue.collider && deformsTissue(tissue.collider->detector_name);
      NODELET_INFO("tissue_sim: '%s' collides with detector '%s'; response from %s", object.name.c_str(),
                   tissue.collider ? tissue.collider->detector_name.c_str() : "none",
                   tissue.detector_response ? "its deformation vectors"
                   : tissue.collider        ? "the exact capsule test"
                                            : "nothing (no collision)");
      tissues_.emplace(object.name, std::move(tissue));
    }
  }

  void buildRigidColliders() {
    if (!scene_.simulates(scene::Simulation::kCollision)) return;
    for (const auto& object : scene_.objects) {
      if (object.isDeformable()) continue;
      std::optional<Collider> collider = makeCollider(object);
      if (!collider) continue;
      rigid_.push_back({scene::buildMesh(object, scene::MeshFrame::kParent), std::move(*collider)});
    }
  }

  // target <- source for the frames this nodelet knows (eye, world); nullopt for any other.
  std::optional<Eigen::Isometry3d> transform(const std::string& target, const std::string& source) const {
    const std::string& from = source.empty() ? eye_frame_ : source;
    if (from == target) return Eigen::Isometry3d::Identity();
    if (target == eye_frame_ && from == world_frame_) return world_from_eye_.inverse();
    if (target == world_frame_ && from == eye_frame_) return world_from_eye_;
    return std::nullopt;
  }

  void onEyeState(const vrm_msgs::EyeState::ConstPtr& eye) {
    if (!eye->valid) return;
    const Eigen::Isometry3d pose = worldFromEye(*eye);
    if (!pose.matrix().allFinite()) {
      NODELET_WARN_THROTTLE(1.0, "eye_state with a non-finite pose ignored");
      return;
    }
    world_from_eye_ = pose;
  }

  void onInstrumentState(const vrm_msgs::InstrumentState::ConstPtr& state) {
    auto slot = instruments_.find(state->instrument_id);
    if (slot == instruments_.end()) return;
    const geometry_msgs::Pose& pose = state->tip_pose;
    const double values[] = {pose.position.x,    pose.position.y,    pose.position.z,    pose.orientation.x,
                             pose.orientation.y, pose.orientation.z, pose.orientation.w, state->jaw_angle};
    for (double value : values) {
      if (!std::isfinite(value)) {
        NODELET_WARN_THROTTLE(1.0, "instrument_state '%s' with non-finite values ignored",
                              state->instrument_id.c_str());
        return;
      }
    }
    if (!transform(eye_frame_, state->header.frame_id)) {
      NODELET_WARN_THROTTLE(1.0, "instrument_state '%s' in unknown frame '%s' ignored (eye or world expected)",
                            state->instrument_id.c_str(), state->header.frame_id.c_str());
      return;
    }
    Instrument& instrument = slot->second;
    // Invalid tracking: the instrument keeps its last pose but stops interacting (no phantom grasps).
    instrument.pose = toEigen(pose);
    instrument.frame_id = state->header.frame_id;
    instrument.jaw_angle = state->valid ? state->jaw_angle : 1.0;
    instrument.active = state->valid;
    switchInstrumentIfNeeded(instrument, state->type, state->instrument_id);
    instrument.cutting = state->valid && instrument.current.type == scene::InstrumentType::kVitrector &&
                         state->suction > 0.0 && state->cut_rate > 0.0;

    // Simulated time comes from the input stamps: a replayed session steps exactly as the live one did.
    const ros::Time stamp = state->header.stamp;
    double frame_time = last_stamp_.isZero() ? 0.0 : (stamp - last_stamp_).toSec();
    if (frame_time < 0.0) return;  // out-of-order input
    frame_time = std::min(frame_time, max_frame_time_);
    last_stamp_ = stamp;

    const bool reports_wanted = report_publisher_.getNumSubscribers() > 0;
    const bool markers_wanted = marker_publisher_.getNumSubscribers() > 0;
    boost::shared_ptr<visualization_msgs::MarkerArray> markers;
    if (markers_wanted) markers = boost::make_shared<visualization_msgs::MarkerArray>();

    auto timing = boost::make_shared<vrm_msgs::StageTiming>();
    timing->header.stamp = stamp;
    timing->frame = ++frame_count_;
    const tissue::Clock clock = [] { return ros::WallTime::now().toSec(); };
    for (auto& [name, tissue] : tissues_) {
      std::vector<tissue::InstrumentInput> inputs;
      for (const auto& [slot_name, source] : instruments_) {
        tissue::InstrumentInput input = source.shape;
        input.pose = *transform(tissue.frame_id, source.frame_id) * source.pose;
        input.jaw_angle = source.jaw_angle;
        // The capsule test is the response unless the detector's deformation vectors are (or nothing collides).
        input.collides = source.active && source.shape.collides && tissue.collider && !tissue.detector_response;
        input.can_grasp = source.active && source.shape.can_grasp;
        input.cuts = source.active && source.cutting && scene_.simulates(scene::Simulation::kCutting);
        inputs.push_back(input);
      }
      if (tissue.collider) {
        vrm_msgs::StageStamp stage;
        stage.stage = "collision_" + name;
        stage.start = ros::Time::now();
        const collision::SurfaceView surface = collision::SurfaceView::of(*tissue.membrane);
        std::vector<tissue::NodeDeformation> deformations;
        std::size_t index = 0;
        for (auto& [slot_name, source] : instruments_) {
          const Eigen::Isometry3d& pose = inputs[index++].pose;
          if (!source.active) continue;
          const collision::CollisionResult result = collide(*tissue.collider, slot_name, source, pose, surface);
          if (tissue.detector_response && source.shape.collides) {
            appendDeformations(result, velocity(*tissue.collider, slot_name, pose, frame_time), deformations);
          }
          publishResult(*tissue.collider, slot_name, result, surface, stamp, reports_wanted, markers.get());
        }
        if (!deformations.empty()) tissue.simulator->addDeformations(deformations);
        stage.end = ros::Time::now();
        timing->stages.push_back(stage);
      }

      vrm_msgs::StageStamp stage;
      stage.stage = "tissue_" + name;
      stage.start = ros::Time::now();
      tissue.simulator->setInstruments(inputs);
      const tissue::FrameReport report = tissue.simulator->advance(frame_time, clock);
      if (report.fallbacks > 0) {
        NODELET_WARN_THROTTLE(1.0, "tissue '%s': watchdog rolled back %d steps (total %lu)", name.c_str(),
                              report.fallbacks, static_cast<unsigned long>(tissue.simulator->statistics().fallbacks));
      }
      stage.end = ros::Time::now();
      timing->stages.push_back(stage);
      if (report.steps > 0) publishIfChanged(tissue, name, stamp);
    }
    if ((reports_wanted || markers_wanted) && !rigid_.empty()) {
      vrm_msgs::StageStamp stage;
      stage.stage = "collision_rigid";
      stage.start = ros::Time::now();
      for (RigidObject& object : rigid_) {
        const collision::SurfaceView surface = collision::SurfaceView::of(object.mesh);
        for (auto& [slot_name, source] : instruments_) {
          if (!source.active) continue;
          const Eigen::Isometry3d pose = *transform(object.collider.frame_id, source.frame_id) * source.pose;
          const collision::CollisionResult result = collide(object.collider, slot_name, source, pose, surface);
          publishResult(object.collider, slot_name, result, surface, stamp, reports_wanted, markers.get());
        }
      }
      stage.end = ros::Time::now();
      timing->stages.push_back(stage);
    }
    if (markers) vrm_msgs::publishShared(marker_publisher_, markers);
    vrm_msgs::publishShared(timing_publisher_, timing);
  }

  // The instrument's collision mesh follows its shape: the forceps' jaws open and close (whole degrees, so a
  // noisy jaw angle does not invalidate the detectors' cached depth images every frame).
  void updateModel(Instrument& instrument) {
    int jaw_deg = 0;
    scene::InstrumentDescription description = instrument.current;
    if (auto* forceps = std::get_if<scene::ForcepsParams>(&description.params)) {
      jaw_deg = static_cast<int>(std::lround(std::clamp(instrument.jaw_angle, 0.0, 1.5) * kRadToDeg));
      forceps->jaw_angle_deg = jaw_deg;
    }
    if (instrument.model_version > 0 && jaw_deg == instrument.model_jaw_deg) return;
    instrument.model.mesh = scene::buildInstrumentMesh(description);
    instrument.model_jaw_deg = jaw_deg;
    ++instrument.model_version;
  }

  collision::CollisionResult collide(Collider& collider, const std::string& slot, Instrument& instrument,
                                     const Eigen::Isometry3d& pose, const collision::SurfaceView& surface) {
    updateModel(instrument);
    Collider::PerInstrument& entry = collider.instruments[slot];
    if (!entry.detector) entry.detector = collision::makeCollisionDetector(collider.detector_name, collider.options);
    if (entry.model_version != instrument.model_version) {
      entry.detector->setInstrument(instrument.model);
      entry.model_version = instrument.model_version;
    }
    collision::CollisionResult result = entry.detector->collide(pose, surface);
    if (result.status == collision::CollisionStatus::kBackendUnavailable ||
        result.status == collision::CollisionStatus::kInvalidInput) {
      NODELET_WARN_THROTTLE(5.0, "collision '%s' vs '%s' (%s): %s", slot.c_str(), collider.object.c_str(),
                            collider.detector_name.c_str(), collision::toString(result.status));
    }
    return result;
  }

  // Instrument tip velocity in the collider's frame (v_P of eq. 5.12) from the last query.
  Eigen::Vector3d velocity(Collider& collider, const std::string& slot, const Eigen::Isometry3d& pose,
                           double frame_time) {
    std::optional<Eigen::Vector3d>& last = collider.instruments[slot].last_tip;
    Eigen::Vector3d v = Eigen::Vector3d::Zero();
    if (last && frame_time > 0.0) v = (pose.translation() - *last) / frame_time;
    last = pose.translation();
    return v;
  }

  static void appendDeformations(const collision::CollisionResult& result, const Eigen::Vector3d& instrument_velocity,
                                 std::vector<tissue::NodeDeformation>& deformations) {
    for (std::size_t i = 0; i < result.nodes.size(); ++i) {
      tissue::NodeDeformation d;
      d.node = result.nodes[i];
      d.deformation = result.deformations[i];
      // Image space: every vector of a query is parallel to the projection direction (Eq. 4.2).
      const double length = d.deformation.norm();
      if (length > 0.0) d.normal = d.deformation / length;
      d.instrument_velocity = instrument_velocity;
      deformations.push_back(d);
    }
  }

  void publishResult(const Collider& collider, const std::string& slot, const collision::CollisionResult& result,
                     const collision::SurfaceView& surface, const ros::Time& stamp, bool report_wanted,
                     visualization_msgs::MarkerArray* markers) {
    if (report_wanted) {
      auto report = boost::make_shared<vrm_msgs::CollisionReport>();
      report->header.stamp = stamp;
      report->header.frame_id = collider.frame_id;
      report->detector = collider.detector_name;
      report->object_a = "instrument_" + slot;
      report->object_b = collider.object;
      fillCollisionReport(result, *report);
      vrm_msgs::publishShared(report_publisher_, report);
    }
    if (markers) {
      visualization_msgs::Marker marker;
      marker.header.stamp = stamp;
      marker.header.frame_id = collider.frame_id;
      marker.ns = collider.object + "/" + slot;
      marker.id = 0;
      if (result.triangles.empty()) {
        marker.action = visualization_msgs::Marker::DELETE;
      } else {
        fillTriangleListMarker(surface.positions, surface.triangles, result.triangles, {1.0f, 0.1f, 0.1f, 0.8f},
                               marker);
      }
      markers->markers.push_back(std::move(marker));
    }
  }

  void publishIfChanged(Tissue& tissue, const std::string& name, const ros::Time& stamp) {
    auto mesh = boost::make_shared<vrm_msgs::TissueMesh>();
    mge::Membrane& membrane = *tissue.membrane;
    fillTissueMesh(membrane.positions(), membrane.nodeCount(), membrane.triangleNodeSlots(), membrane.triangleCount(),
                   *mesh);
    // A cut or tear may leave the positions as they were and only drop triangles: publish on either change.
    const std::uint64_t topology_version = 1 + tissue.simulator->topologyChanges();
    if (mesh->positions == tissue.last_positions && topology_version == tissue.topology_version) return;
    tissue.last_positions = mesh->positions;
    tissue.topology_version = topology_version;
    mesh->header.stamp = stamp;
    mesh->header.frame_id = tissue.frame_id;
    mesh->tissue_id = name;
    mesh->version = ++tissue.version;
    mesh->topology_version = topology_version;
    vrm_msgs::publishShared(tissue.publisher, mesh);
  }

  scene::SceneDescription scene_;
  std::map<std::string, Tissue> tissues_;
  std::vector<RigidObject> rigid_;
  std::map<std::string, Instrument> instruments_;
  std::string detector_override_;
  std::string eye_frame_, world_frame_;
  Eigen::Isometry3d world_from_eye_ = Eigen::Isometry3d::Identity();
  double max_frame_time_ = 0.05;
  ros::Time last_stamp_;
  std::uint64_t frame_count_ = 0;
  ros::Publisher timing_publisher_, report_publisher_, marker_publisher_;
  ros::Subscriber eye_subscriber_, instrument_subscriber_;
};

}  // namespace vrm_sim

PLUGINLIB_EXPORT_CLASS(vrm_sim::TissueSim, nodelet::Nodelet)
