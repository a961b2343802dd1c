// The VR part's simulation nodelet: a thin adapter around the ROS-free simulation core vrm_sim::world::World
// (world/world.h — frame assembly by input stamps, collision, tissue, grasping, cutting, tearing, bleeding). It
// converts the input messages (vrm_sim/conversions.h), hands them to the core and publishes what a frame produced.
// The offline tools (tissue_offline, session replays) drive the very same core, so the same inputs give the same
// state here and there (test/graph/core_equivalence).
//
// Subscribes: eye_state, instrument_state, pedals, scenario_command.
// Publishes (zero copy, stamps = the frame's input stamp):
//   tissue/<object>     vrm_msgs/TissueMesh of each deformable object, when it changed; of the retina (positions
//                       static, `injury` per vertex) when its bleeding changed
//   simulation_state    vrm_msgs/SimulationState after every frame (state hash, per-tissue grasp/strain/peel outcome,
//                       retina contacts)
//   tissue_timing       vrm_msgs/StageTiming (collision_<object>, tissue_<object>, bleeding_<object>; wall clock)
//   collision_report, collision_markers   only while subscribed (rigid objects without bleeding are only tested then)
// Parameters (private): scene (name or path), collision_detector (override for every object), max_frame_time (s,
// default 0.05), collision_max_pixel_size (m), wall_clock_budget (default false: deterministic frames; true: each
// tissue stops at its scene time_budget_ms of wall time, as EyeSi did), eye_frame / world_frame names.
#include <nodelet/nodelet.h>
#include <ros/ros.h>
#include <visualization_msgs/MarkerArray.h>

#include <boost/make_shared.hpp>
#include <fstream>
#include <map>
#include <memory>
#include <mutex>
#include <pluginlib/class_list_macros.hpp>

#include "vrm_msgs/CollisionReport.h"
#include "vrm_msgs/SimulationState.h"
#include "vrm_msgs/StageTiming.h"
#include "vrm_msgs/TissueMesh.h"
#include "vrm_msgs/publish.h"
#include "vrm_sim/conversions.h"
#include "vrm_sim/mge/membrane.h"
#include "vrm_sim/scene/scene_loader.h"
#include "vrm_sim/world/world.h"

namespace vrm_sim {

class TissueSim : public nodelet::Nodelet {
 public:
  void onInit() override {
    ros::NodeHandle& nh = getNodeHandle();
    ros::NodeHandle& private_nh = getPrivateNodeHandle();
    const std::string scene_parameter = private_nh.param<std::string>("scene", "membrane_peeling");
    world::WorldOptions options;
    options.detector_override = private_nh.param<std::string>("collision_detector", "");
    options.max_frame_time = private_nh.param("max_frame_time", 0.05);
    options.collision_max_pixel_size = private_nh.param("collision_max_pixel_size", 0.0);
    options.wall_clock_budget = private_nh.param("wall_clock_budget", false);
    options.clock = [] { return ros::WallTime::now().toSec(); };
    options.log = [this](world::Severity severity, const std::string& message) {
      if (severity == world::Severity::kWarning) {
        NODELET_WARN("%s", message.c_str());
      } else {
        NODELET_INFO("%s", message.c_str());
      }
    };
    eye_frame_ = private_nh.param<std::string>("eye_frame", "eye");
    world_frame_ = private_nh.param<std::string>("world_frame", "world");
    const std::string scene_path =
        std::ifstream(scene_parameter).good() ? scene_parameter : scene::shippedScenePath(scene_parameter);
    try {
      world_ = std::make_unique<world::World>(scene::loadScene(scene_path), options);
    } catch (const std::exception& error) {
      NODELET_FATAL("tissue_sim: cannot set up scene '%s': %s", scene_parameter.c_str(), error.what());
      ros::requestShutdown();
      return;
    }
    if (!world_->simulatesAnything()) {
      NODELET_INFO("scene '%s' simulates neither tissue nor collision: tissue_sim idle", world_->scene().name.c_str());
      return;
    }
    for (const std::string& name : world_->tissueNames()) {
      mesh_publishers_[name] = nh.advertise<vrm_msgs::TissueMesh>("tissue/" + name, 2);
    }
    for (const world::InjuryReport& injury : world_->injuries()) {
      mesh_publishers_[injury.object] = nh.advertise<vrm_msgs::TissueMesh>("tissue/" + injury.object, 2, true);
    }
    state_publisher_ = nh.advertise<vrm_msgs::SimulationState>("simulation_state", 50);
    timing_publisher_ = nh.advertise<vrm_msgs::StageTiming>("tissue_timing", 5);
    report_publisher_ = nh.advertise<vrm_msgs::CollisionReport>("collision_report", 20);
    marker_publisher_ = nh.advertise<visualization_msgs::MarkerArray>("collision_markers", 2);
    world_->setFrameObserver([this](const world::FrameResult& frame) { publish(frame); });
    eye_subscriber_ = nh.subscribe("eye_state", 10, &TissueSim::onEyeState, this);
    instrument_subscriber_ = nh.subscribe("instrument_state", 20, &TissueSim::onInstrumentState, this);
    pedal_subscriber_ = nh.subscribe("pedals", 20, &TissueSim::onPedals, this);
    command_subscriber_ = nh.subscribe("scenario_command", 10, &TissueSim::onScenarioCommand, this);
    NODELET_INFO("tissue_sim: scene '%s', %zu deformable objects, %zu bleeding surfaces, deterministic frames: %s",
                 world_->scene().name.c_str(), world_->tissueNames().size(), world_->injuries().size(),
                 options.wall_clock_budget ? "no (wall-clock budget)" : "yes");
  }

 private:
  // The manager runs callbacks on several threads; the core is one state machine.
  void onEyeState(const vrm_msgs::EyeState::ConstPtr& eye) {
    std::lock_guard<std::mutex> lock(mutex_);
    prepareReports();
    world_->handle(toWorld(*eye));
  }
  void onInstrumentState(const vrm_msgs::InstrumentState::ConstPtr& instrument) {
    std::lock_guard<std::mutex> lock(mutex_);
    prepareReports();
    world_->handle(toWorld(*instrument));
  }
  void onPedals(const vrm_msgs::PedalState::ConstPtr& pedals) {
    std::lock_guard<std::mutex> lock(mutex_);
    world_->handle(toWorld(*pedals));
  }
  void onScenarioCommand(const vrm_msgs::ScenarioCommand::ConstPtr& command) {
    std::lock_guard<std::mutex> lock(mutex_);
    const auto converted = toWorld(*command);
    if (!converted) {
      NODELET_WARN("scenario_command with unknown command %u ignored", static_cast<unsigned>(command->command));
      return;
    }
    world_->handle(*converted);
  }

  void prepareReports() {
    reports_wanted_ = report_publisher_.getNumSubscribers() > 0;
    markers_wanted_ = marker_publisher_.getNumSubscribers() > 0;
    world_->setRigidReports(reports_wanted_ || markers_wanted_);
  }

  static ros::Time wallStamp(double seconds) { return ros::Time(std::max(seconds, 0.0)); }

  void publish(const world::FrameResult& frame) {
    const ros::Time stamp = toRosTime(frame.stamp);
    for (const world::TissueReport& tissue : frame.tissues) {
      if (!tissue.changed) continue;
      auto mesh = boost::make_shared<vrm_msgs::TissueMesh>();
      mge::Membrane& membrane = *world_->membrane(tissue.object);
      fillTissueMesh(membrane.positions(), membrane.nodeCount(), membrane.triangleNodeSlots(), membrane.triangleCount(),
                     *mesh);
      mesh->header.stamp = stamp;
      mesh->header.frame_id = frameName(tissue.frame_id);
      mesh->tissue_id = tissue.object;
      mesh->version = tissue.version;
      mesh->topology_version = tissue.topology_version;
      vrm_msgs::publishShared(mesh_publishers_[tissue.object], mesh);
      ++meshes_published_;
    }
    for (const world::InjuryReport& injury : frame.injuries) {
      if (!injury.changed) continue;
      auto mesh = boost::make_shared<vrm_msgs::TissueMesh>();
      fillTissueMesh(*injury.mesh, *mesh);
      mesh->injury = *injury.injury;
      mesh->header.stamp = stamp;
      mesh->header.frame_id = frameName(injury.frame_id);
      mesh->tissue_id = injury.object;
      mesh->version = injury.version;
      mesh->topology_version = 1;
      vrm_msgs::publishShared(mesh_publishers_[injury.object], mesh);
    }
    boost::shared_ptr<visualization_msgs::MarkerArray> markers;
    if (markers_wanted_) markers = boost::make_shared<visualization_msgs::MarkerArray>();
    for (const world::CollisionRecord& record : frame.collisions) {
      if (reports_wanted_) {
        auto report = boost::make_shared<vrm_msgs::CollisionReport>();
        report->header.stamp = stamp;
        report->header.frame_id = frameName(record.frame_id);
        report->detector = record.detector;
        report->object_a = "instrument_" + record.instrument;
        report->object_b = record.object;
        fillCollisionReport(record.result, *report);
        vrm_msgs::publishShared(report_publisher_, report);
      }
      if (markers) {
        visualization_msgs::Marker marker;
        marker.header.stamp = stamp;
        marker.header.frame_id = frameName(record.frame_id);
        marker.ns = record.object + "/" + record.instrument;
        if (record.result.triangles.empty()) {
          marker.action = visualization_msgs::Marker::DELETE;
        } else {
          fillTriangleListMarker(record.surface.positions, record.surface.triangles, record.result.triangles,
                                 {1.0f, 0.1f, 0.1f, 0.8f}, marker);
        }
        markers->markers.push_back(std::move(marker));
      }
    }
    if (markers) vrm_msgs::publishShared(marker_publisher_, markers);

    auto timing = boost::make_shared<vrm_msgs::StageTiming>();
    timing->header.stamp = stamp;
    timing->frame = frame.frame;
    for (const world::StageTime& stage : frame.stages) {
      vrm_msgs::StageStamp entry;
      entry.stage = stage.stage;
      entry.start = wallStamp(stage.start);
      entry.end = wallStamp(stage.end);
      timing->stages.push_back(entry);
    }
    vrm_msgs::publishShared(timing_publisher_, timing);

    auto state = boost::make_shared<vrm_msgs::SimulationState>();
    fillSimulationState(frame, world_->statistics().late_inputs, *state);
    vrm_msgs::publishShared(state_publisher_, state);
    logProgress(frame);
  }

  // A status line every ~5 s of frames: what the simulation is doing, for the console and the launch log.
  void logProgress(const world::FrameResult& frame) {
    if (frame.frame % 250 != 0) return;
    const world::WorldStatistics& statistics = world_->statistics();
    std::string tissues;
    for (const world::TissueReport& tissue : frame.tissues) {
      char line[200];
      std::snprintf(line, sizeof(line), " %s: v%lu grasped %zu strain %.2f lift %.2f mm %s;", tissue.object.c_str(),
                    static_cast<unsigned long>(tissue.version), tissue.grasped_nodes, tissue.max_strain,
                    1e3 * tissue.max_lift, world::toString(tissue.outcome));
      tissues += line;
    }
    NODELET_INFO(
        "tissue_sim: frame %lu, %lu tissue meshes published,%s retina contacts %zu; frame %.2f ms mean, "
        "%.2f ms max",
        static_cast<unsigned long>(frame.frame), static_cast<unsigned long>(meshes_published_), tissues.c_str(),
        frame.injuries.empty() ? 0 : frame.injuries.front().contacts,
        1e3 * statistics.total_frame_wall_time / std::max<std::uint64_t>(statistics.frames, 1),
        1e3 * statistics.max_frame_wall_time);
  }

  const std::string& frameName(const std::string& core_frame) const {
    return core_frame == "world" ? world_frame_ : eye_frame_;
  }

  std::unique_ptr<world::World> world_;
  std::mutex mutex_;
  std::string eye_frame_, world_frame_;
  bool reports_wanted_ = false, markers_wanted_ = false;
  std::uint64_t meshes_published_ = 0;
  std::map<std::string, ros::Publisher> mesh_publishers_;
  ros::Publisher state_publisher_, timing_publisher_, report_publisher_, marker_publisher_;
  ros::Subscriber eye_subscriber_, instrument_subscriber_, pedal_subscriber_, command_subscriber_;
};

}  // namespace vrm_sim

PLUGINLIB_EXPORT_CLASS(vrm_sim::TissueSim, nodelet::Nodelet)
