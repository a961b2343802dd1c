// Tissue simulation nodelet (thesis §5): builds its own MGE membranes for the scene's deformable objects, steps them
// on every instrument_state within each object's time budget (stamps from the input), collides the instruments
// (capsule / sphere by instrument type) with the membranes, grasps with the forceps, and publishes each membrane as
// vrm_msgs/TissueMesh on tissue/<object> (not latched; only when it changed; version++) and vrm_msgs/StageTiming
// on tissue_timing. Idle when the scene does not simulate tissue.
#include <nodelet/nodelet.h>
#include <ros/ros.h>

#include <boost/make_shared.hpp>
#include <cmath>
#include <fstream>
#include <map>
#include <memory>
#include <pluginlib/class_list_macros.hpp>
#include <variant>

#include "vrm_msgs/InstrumentState.h"
#include "vrm_msgs/StageTiming.h"
#include "vrm_msgs/TissueMesh.h"
#include "vrm_msgs/publish.h"
#include "vrm_sim/conversions.h"
#include "vrm_sim/mge/membrane.h"
#include "vrm_sim/scene/scene_loader.h"
#include "vrm_sim/tissue/tissue_simulator.h"

namespace vrm_sim {

namespace {

tissue::TissueConfig toTissueConfig(const scene::TissueParameters& parameters,
                                    const scene::CollisionParameters& collision) {
  tissue::TissueConfig config;
  config.integrator = parameters.integrator;
  config.dt = parameters.dt;
  config.time_budget_ms = parameters.time_budget_ms;
  config.forces.damping = parameters.damping;
  config.strain_limit = parameters.strain_limit;
  config.plastic = parameters.plastic;
  config.adhesion_stiffness = parameters.adhesion_stiffness;
  config.shell_scale = collision.epsilon_shell_scale;
  config.integrator_options.cg_max_iterations = 10;
  config.integrator_options.cg_tolerance = 1e-6;
  return config;
}

// The instrument's collision shape: a capsule along the shaft (radius from the shaft diameter), grasping for the
// forceps. Instrument frame: origin at the tip, +z from the handle to the tip.
tissue::InstrumentInput instrumentShape(const scene::InstrumentDescription& description) {
  tissue::InstrumentInput instrument;
  const scene::ShaftParams* shaft = nullptr;
  std::visit(
      [&](const auto& params) {
        using T = std::decay_t<decltype(params)>;
        if constexpr (std::is_same_v<T, scene::LightPipeParams> || std::is_same_v<T, scene::ForcepsParams> ||
                      std::is_same_v<T, scene::VitrectorParams> || std::is_same_v<T, scene::NeedleParams> ||
                      std::is_same_v<T, scene::HookParams>) {
          shaft = &params.shaft;
        }
        if constexpr (std::is_same_v<T, scene::ForcepsParams>) instrument.jaw_length = params.jaw_length;
      },
      description.params);
  instrument.radius = shaft ? 0.5 * shaft->diameter : 3e-4;
  instrument.length = shaft ? shaft->length : 0.0;
  instrument.can_grasp = description.type == scene::InstrumentType::kForceps;
  // Forceps: the jaws grasp; the shaft stays behind them and above the tissue while grasping.
  instrument.collides = !instrument.can_grasp;
  return instrument;
}

}  // namespace

class TissueSim : public nodelet::Nodelet {
 public:
  void onInit() override {
    ros::NodeHandle& nh = getNodeHandle();
    ros::NodeHandle& private_nh = getPrivateNodeHandle();
    const std::string scene_parameter = private_nh.param<std::string>("scene", "membrane_peeling");
    max_frame_time_ = private_nh.param("max_frame_time", 0.05);
    const std::string scene_path =
        std::ifstream(scene_parameter).good() ? scene_parameter : scene::shippedScenePath(scene_parameter);
    try {
      scene_ = scene::loadScene(scene_path);
      if (!scene_.simulates(scene::Simulation::kTissue)) {
        NODELET_INFO("scene '%s' simulates no tissue: tissue_sim idle", scene_.name.c_str());
        return;
      }
      buildTissues();
    } catch (const std::exception& error) {
      NODELET_FATAL("tissue_sim: cannot set up scene '%s': %s", scene_parameter.c_str(), error.what());
      ros::requestShutdown();
      return;
    }
    for (auto& [name, tissue] : tissues_) {
      tissue.publisher = nh.advertise<vrm_msgs::TissueMesh>("tissue/" + name, 2);
    }
    timing_publisher_ = nh.advertise<vrm_msgs::StageTiming>("tissue_timing", 5);
    instrument_subscriber_ = nh.subscribe("instrument_state", 20, &TissueSim::onInstrumentState, this);
    NODELET_INFO("tissue_sim: scene '%s', %zu deformable objects", scene_.name.c_str(), tissues_.size());
  }

 private:
  struct Tissue {
    std::unique_ptr<mge::Membrane> membrane;
    std::unique_ptr<tissue::TissueSimulator> simulator;
    std::vector<std::array<std::uint32_t, 3>> triangles;
    std::string frame_id;
    std::uint64_t version = 1;
    std::vector<float> last_positions;
    ros::Publisher publisher;
  };

  void buildTissues() {
    for (const auto& object : scene_.objects) {
      if (!object.isDeformable()) continue;
      const TriangleMesh mesh = scene::buildMesh(object, scene::MeshFrame::kParent);
      mge::MembraneOptions options;
      options.total_mass = object.tissue.node_mass * static_cast<double>(mesh.vertexCount());
      options.stretch_stiffness = object.tissue.stiffness;
      options.bending_springs = object.tissue.bending_stiffness > 0.0;
      options.bending_stiffness = object.tissue.bending_stiffness;
      Tissue tissue;
      tissue.membrane = mge::buildMembrane(mesh, options);
      tissue.simulator =
          std::make_unique<tissue::TissueSimulator>(*tissue.membrane, toTissueConfig(object.tissue, object.collision));
      tissue.frame_id = object.frame == scene::ObjectFrame::kEye ? "eye" : "world";
      tissues_.emplace(object.name, std::move(tissue));
    }
    for (const auto& instrument : scene_.instruments) {
      instruments_[scene::toString(instrument.slot)] = instrumentShape(instrument);
    }
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
    tissue::InstrumentInput& instrument = slot->second;
    // Invalid tracking: the instrument keeps its last pose but stops interacting (no phantom grasps).
    instrument.pose = toEigen(pose);
    instrument.jaw_angle = state->valid ? state->jaw_angle : 1.0;
    active_[state->instrument_id] = state->valid;

    // Simulated time comes from the input stamps: a replayed session steps exactly as the live one did.
    const ros::Time stamp = state->header.stamp;
    double frame_time = last_stamp_.isZero() ? 0.0 : (stamp - last_stamp_).toSec();
    if (frame_time < 0.0) return;  // out-of-order input
    frame_time = std::min(frame_time, max_frame_time_);
    last_stamp_ = stamp;

    std::vector<tissue::InstrumentInput> inputs;
    for (const auto& [name, input] : instruments_) {
      tissue::InstrumentInput active = input;
      if (!active_[name]) {
        active.collides = false;
        active.can_grasp = false;
      }
      inputs.push_back(active);
    }
    auto timing = boost::make_shared<vrm_msgs::StageTiming>();
    timing->header.stamp = stamp;
    timing->frame = ++frame_count_;
    const tissue::Clock clock = [] { return ros::WallTime::now().toSec(); };
    for (auto& [name, tissue] : tissues_) {
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
    vrm_msgs::publishShared(timing_publisher_, timing);
  }

  void publishIfChanged(Tissue& tissue, const std::string& name, const ros::Time& stamp) {
    auto mesh = boost::make_shared<vrm_msgs::TissueMesh>();
    mge::Membrane& membrane = *tissue.membrane;
    fillTissueMesh(membrane.positions(), membrane.nodeCount(), membrane.triangleNodeSlots(), membrane.triangleCount(),
                   *mesh);
    if (mesh->positions == tissue.last_positions) return;
    tissue.last_positions = mesh->positions;
    mesh->header.stamp = stamp;
    mesh->header.frame_id = tissue.frame_id;
    mesh->tissue_id = name;
    mesh->version = ++tissue.version;
    mesh->topology_version = 1;
    vrm_msgs::publishShared(tissue.publisher, mesh);
  }

  scene::SceneDescription scene_;
  std::map<std::string, Tissue> tissues_;
  std::map<std::string, tissue::InstrumentInput> instruments_;
  std::map<std::string, bool> active_;
  double max_frame_time_ = 0.05;
  ros::Time last_stamp_;
  std::uint64_t frame_count_ = 0;
  ros::Publisher timing_publisher_;
  ros::Subscriber instrument_subscriber_;
};

}  // namespace vrm_sim

PLUGINLIB_EXPORT_CLASS(vrm_sim::TissueSim, nodelet::Nodelet)
