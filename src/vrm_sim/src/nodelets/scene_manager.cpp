// The VR part's entry point (thesis §2.4: object manager + scenario manager). Loads the scene, builds only what
// it needs (MGE membranes for deformable objects only), keeps the frame tree on tf2 (world -> eye -> trocar_* ->
// instrument_*) and publishes the scene's surfaces for rendering, collision and RViz.
// The pose tf follows the simulation's decisions, not the raw device topics (issue 31): scenario_manager publishes
// every input frame it closed (vrm_msgs/InputFrame, topic input_frame) with the poses the World applied, and this
// node broadcasts exactly those, stamped with the frame's stamp — a source the mediator left out, an input the World
// rejected or a refused type switch look the same on tf as in the simulation, and a replay produces the same tf.
// Only KIND_FRAME frames carry poses (KIND_STATE / KIND_LOAD frames apply pedals and commands only).
// The scene follows its one owner (issue 32): scenario_manager announces the running scene on the latched
// running_scene (vrm_msgs/RunningScene) at start-up and after every LOAD it accepted; this node loads the announced
// file and level unless it already runs that content, and then rebuilds its objects, re-broadcasts the trocar frames,
// re-publishes the surfaces and scene markers (DELETEALL first, so RViz drops the old scene) and, in a live session,
// a new latched session_info for the new scene (a bag begun after the LOAD replays it). ~scene is the start-up scene
// only; a scene that cannot be loaded here keeps the old one and says why.
#include <geometry_msgs/TransformStamped.h>
#include <nodelet/nodelet.h>
#include <ros/ros.h>
#include <tf2_ros/static_transform_broadcaster.h>
#include <tf2_ros/transform_broadcaster.h>
#include <visualization_msgs/MarkerArray.h>

#include <boost/make_shared.hpp>
#include <chrono>
#include <cmath>
#include <map>
#include <memory>
#include <mutex>
#include <pluginlib/class_list_macros.hpp>
#include <set>

#include "vrm_msgs/InputFrame.h"
#include "vrm_msgs/MicroscopeSettings.h"
#include "vrm_msgs/PedalState.h"
#include "vrm_msgs/RunningScene.h"
#include "vrm_msgs/ScenarioCommand.h"
#include "vrm_msgs/SessionInfo.h"
#include "vrm_msgs/TissueMesh.h"
#include "vrm_msgs/publish.h"
#include "vrm_scene/package_data.h"
#include "vrm_scene/scene_loader.h"
#include "vrm_sim/conversions.h"
#include "vrm_sim/graph_failure.h"
#include "vrm_sim/mge/membrane.h"
#include "vrm_sim/world/tissue_setup.h"

namespace vrm_sim {

namespace {

bool isFinite(const geometry_msgs::Pose& pose) {
  const double values[] = {pose.position.x,    pose.position.y,    pose.position.z,   pose.orientation.x,
                           pose.orientation.y, pose.orientation.z, pose.orientation.w};
  for (double value : values) {
    if (!std::isfinite(value)) return false;
  }
  return true;
}

std::array<float, 4> toRgba(const std::array<double, 4>& rgba) {
  return {static_cast<float>(rgba[0]), static_cast<float>(rgba[1]), static_cast<float>(rgba[2]),
          static_cast<float>(rgba[3])};
}

}  // namespace

class SceneManager : public nodelet::Nodelet {
 public:
  void onInit() override {
    ros::NodeHandle& nh = getNodeHandle();
    ros::NodeHandle& private_nh = getPrivateNodeHandle();
    world_frame_ = private_nh.param<std::string>("world_frame", "world");
    eye_frame_ = private_nh.param<std::string>("eye_frame", "eye");
    // false when another node owns world -> eye -> trocar_* -> instrument_* (the optical tracker, tracking mode):
    // one publisher per transform.
    publish_pose_tf_ = private_nh.param("publish_pose_tf", true);
    const std::string scene_parameter = private_nh.param<std::string>("scene", scene::kDefaultSceneName);

    usePackageData();  // shipped scenes by name: the devel space's source package or the installed share directory
    const std::string difficulty = private_nh.param<std::string>("difficulty", "");
    try {
      scene_ = scene::loadScene(scene_parameter, difficulty);
      world::checkSimulationNames(scene_);  // as the World does: a typo fails here too, not only in the simulation
      content_hash_ = scene::sceneContentHash(scene_.source_file, loadedDifficulty(scene_));
      buildObjects();
    } catch (const std::exception& error) {
      // A broken scene ends the session with the reason, instead of a simulator running on half a scene.
      NODELET_FATAL("cannot load scene '%s': %s", scene_parameter.c_str(), error.what());
      failGraph("scene_manager: cannot load scene '" + scene_parameter + "': " + error.what());
      return;
    }
    NODELET_INFO("scene '%s' (%s): %zu objects, %zu deformable, %zu instruments", scene_.name.c_str(),
                 scene_.source_file.c_str(), scene_.objects.size(), membranes_.size(), scene_.instruments.size());

    if (publish_pose_tf_) publishStaticFrames();
    publishSurfaces();

    if (publish_pose_tf_) frame_subscriber_ = nh.subscribe("input_frame", 10, &SceneManager::onInputFrame, this);
    pedal_subscriber_ = nh.subscribe("pedals", 10, &SceneManager::onPedals, this);
    microscope_subscriber_ = nh.subscribe("microscope", 10, &SceneManager::onMicroscope, this);
    command_subscriber_ = nh.subscribe("scenario_command", 10, &SceneManager::onScenarioCommand, this);

    session_publisher_ = nh.advertise<vrm_msgs::SessionInfo>("session_info", 1, /*latch=*/true);
    publish_session_info_ = private_nh.param("publish_session_info", true);
    if (publish_session_info_) {
      session_template_.difficulty = difficulty;
      session_template_.collision_detector = private_nh.param<std::string>("collision_detector", "");
      session_template_.auto_start = private_nh.param("auto_start", true);
      session_template_.duration = private_nh.param("duration", 0.0);
      session_template_.simulated_hardware = private_nh.param("simulated_hardware", true);
      session_template_.seed = static_cast<std::uint32_t>(private_nh.param("seed", 1));
      session_template_.software_version = VRM_SIM_VERSION;
      publishSessionInfo();
    } else {
      // Replay: the recorded session_info arrives from the bag.
      session_subscriber_ = nh.subscribe("session_info", 1, &SceneManager::onSessionInfo, this);
    }
    scene_subscriber_ = nh.subscribe("running_scene", 1, &SceneManager::onRunningScene, this);
  }

 private:
  static std::string loadedDifficulty(const scene::SceneDescription& scene) {
    return scene.scenario ? scene.scenario->difficulty : "";
  }

  void publishSessionInfo() {
    auto info = boost::make_shared<vrm_msgs::SessionInfo>(session_template_);
    info->header.stamp = ros::Time::now();  // the session's start: a source stamp, recorded with the inputs
    info->scene = scene_.name;
    info->scene_file = scene_.source_file;
    vrm_msgs::publishShared(session_publisher_, info);
  }

  // The announced scene, unless this node already runs that content (the start-up announcement, normally).
  void onRunningScene(const vrm_msgs::RunningScene::ConstPtr& announced) {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      if (announced->file == scene_.source_file && announced->content_hash == content_hash_) return;
    }
    const auto start = std::chrono::steady_clock::now();
    scene::SceneDescription next;
    try {
      next = scene::loadScene(announced->file, announced->difficulty);
      world::checkSimulationNames(next);
    } catch (const std::exception& error) {
      NODELET_ERROR("scene_manager: cannot follow the running scene '%s' (%s): %s; still on '%s'",
                    announced->name.c_str(), announced->file.c_str(), error.what(), scene_.name.c_str());
      return;
    }
    std::lock_guard<std::mutex> lock(mutex_);
    const std::string previous = scene_.name;
    scene_ = std::move(next);
    content_hash_ = announced->content_hash;
    membranes_.clear();  // they live in graph_
    meshes_.clear();
    graph_ = std::make_unique<mge::Graph>();
    buildObjects();
    if (publish_pose_tf_) publishStaticFrames();
    publishSurfaces();
    if (publish_session_info_) {
      session_template_.difficulty = announced->difficulty;
      session_template_.seed = announced->seed;
      publishSessionInfo();
    }
    NODELET_INFO("scene_manager: scene '%s' -> '%s' (LOAD %u, %s): %zu objects, %zu deformable, in %.0f ms",
                 previous.c_str(), scene_.name.c_str(), announced->load, scene_.source_file.c_str(),
                 scene_.objects.size(), membranes_.size(),
                 std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count());
  }

  void buildObjects() {
    for (const auto& object : scene_.objects) {
      TriangleMesh mesh = scene::buildMesh(object, scene::MeshFrame::kParent);
      // Model only what the scene needs: mass-spring state exists for deformable objects only.
      if (object.isDeformable() && scene_.simulates(scene::Simulation::kTissue)) {
        membranes_[object.name] =
            mge::buildMembrane(*graph_, mesh, world::membraneOptionsFor(object.tissue, mesh.vertexCount()));
      }
      meshes_.emplace(object.name, std::move(mesh));
    }
  }

  std::string parentFrame(const scene::ObjectDescription& object) const {
    return object.frame == scene::ObjectFrame::kEye ? eye_frame_ : world_frame_;
  }

  void publishStaticFrames() {
    std::vector<geometry_msgs::TransformStamped> frames;
    for (const auto& trocar : scene_.eye.trocars) {
      geometry_msgs::TransformStamped frame;
      frame.header.frame_id = eye_frame_;
      frame.child_frame_id = "trocar_" + trocar.name;
      Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
      pose.translation() = trocar.position_in_eye;
      frame.transform = toTransformMsg(pose);
      frames.push_back(frame);
    }
    static_broadcaster_.sendTransform(frames);
  }

  // One latched TissueMesh topic per object (meshes/<name>), plus one latched marker array for RViz. Deformable
  // objects are published from their MGE arrays, which is where the tissue simulation will update them.
  void publishSurfaces() {
    ros::NodeHandle& nh = getNodeHandle();
    auto markers = boost::make_shared<visualization_msgs::MarkerArray>();
    visualization_msgs::Marker clear;  // RViz drops the previous scene's markers
    clear.action = visualization_msgs::Marker::DELETEALL;
    markers->markers.push_back(clear);
    int marker_id = 0;
    std::map<std::string, ros::Publisher> kept;
    for (const auto& object : scene_.objects) {
      auto mesh = boost::make_shared<vrm_msgs::TissueMesh>();
      mesh->header.frame_id = parentFrame(object);
      mesh->tissue_id = object.name;
      mesh->version = 1;
      mesh->topology_version = 1;
      auto membrane = membranes_.find(object.name);
      if (membrane != membranes_.end()) {
        mge::Membrane& tissue = *membrane->second;
        fillTissueMesh(tissue.positions(), tissue.nodeCount(), tissue.triangleNodeSlots(), tissue.triangleCount(),
                       *mesh);
      } else {
        fillTissueMesh(meshes_.at(object.name), *mesh);
      }
      visualization_msgs::Marker marker;
      fillTriangleListMarker(*mesh, toRgba(object.material.diffuse_rgba), marker);
      marker.id = marker_id++;
      markers->markers.push_back(marker);

      auto existing = mesh_publishers_.find(object.name);
      ros::Publisher publisher = existing != mesh_publishers_.end()
                                     ? existing->second
                                     : nh.advertise<vrm_msgs::TissueMesh>("meshes/" + object.name, 1, /*latch=*/true);
      vrm_msgs::publishShared(publisher, mesh);
      kept[object.name] = publisher;
    }
    // An object of the previous scene is gone: its latched mesh topic goes with it.
    for (auto& [name, publisher] : mesh_publishers_) {
      if (kept.count(name) == 0) publisher.shutdown();
    }
    mesh_publishers_ = std::move(kept);
    for (const auto& instrument : scene_.instruments) {
      const std::string slot = scene::toString(instrument.slot);
      vrm_msgs::TissueMesh mesh;
      fillTissueMesh(scene::buildInstrumentMesh(instrument), mesh);
      mesh.header.frame_id = "instrument_" + slot;
      mesh.tissue_id = "instrument_" + slot;
      visualization_msgs::Marker marker;
      fillTriangleListMarker(mesh, toRgba(instrument.material.diffuse_rgba), marker);
      marker.frame_locked = true;  // follows the tracked instrument frame
      marker.id = marker_id++;
      markers->markers.push_back(marker);
    }
    if (!marker_publisher_) {
      marker_publisher_ = nh.advertise<visualization_msgs::MarkerArray>("scene_markers", 1, /*latch=*/true);
    }
    vrm_msgs::publishShared(marker_publisher_, markers);
  }

  // tf from the poses the World applied in this frame. An instrument that is not valid (lost by the tracker, its
  // input rejected, its source silent) is not broadcast: tf keeps its last applied pose, and so do the scene markers,
  // which are frame-locked to instrument_<slot> (drawn where it was last applied, not hidden).
  void onInputFrame(const vrm_msgs::InputFrame::ConstPtr& frame) {
    if (frame->kind != vrm_msgs::InputFrame::KIND_FRAME) return;
    std::lock_guard<std::mutex> lock(mutex_);  // the trocars are the running scene's
    std::vector<geometry_msgs::TransformStamped> transforms;
    if (frame->eye_valid) {
      if (isFinite(frame->eye_pose)) {
        geometry_msgs::TransformStamped transform;
        transform.header.stamp = frame->header.stamp;
        transform.header.frame_id = world_frame_;
        transform.child_frame_id = eye_frame_;
        transform.transform = toTransformMsg(toEigen(frame->eye_pose));
        transforms.push_back(transform);
      } else {
        NODELET_WARN_THROTTLE(1.0, "input frame %lu with a non-finite eye pose: eye not on tf",
                              static_cast<unsigned long>(frame->sequence));
      }
    }
    for (const vrm_msgs::AppliedInstrument& instrument : frame->instruments) {
      if (!instrument.valid) continue;
      if (!isFinite(instrument.pose) || instrument.slot.empty()) {
        NODELET_WARN_THROTTLE(1.0, "input frame %lu: instrument '%s' with a non-finite pose or no slot ignored",
                              static_cast<unsigned long>(frame->sequence), instrument.slot.c_str());
        continue;
      }
      geometry_msgs::TransformStamped transform;
      transform.header.stamp = frame->header.stamp;
      transform.header.frame_id = instrument.header.frame_id.empty() ? eye_frame_ : instrument.header.frame_id;
      transform.child_frame_id = "instrument_" + instrument.slot;
      Eigen::Isometry3d tip = toEigen(instrument.pose);
      // world -> eye -> trocar_* -> instrument_*: the instrument hangs below its trocar (an eye-frame translation).
      const scene::Trocar* trocar = scene_.findTrocar(instrument.slot);
      if (trocar && transform.header.frame_id == eye_frame_) {
        transform.header.frame_id = "trocar_" + trocar->name;
        tip.translation() -= trocar->position_in_eye;
      }
      transform.transform = toTransformMsg(tip);
      transforms.push_back(transform);
    }
    if (!transforms.empty()) broadcaster_.sendTransform(transforms);
  }

  // Pedals, knobs and scenario commands are consumed by the simulation, rendering and scenario layers as they
  // arrive; the scene manager takes them so a replay's player has a subscriber for every recorded input.
  void onPedals(const vrm_msgs::PedalState::ConstPtr& pedals) { last_pedals_ = pedals; }
  void onMicroscope(const vrm_msgs::MicroscopeSettings::ConstPtr& settings) {
    if (!std::isfinite(settings->focus_distance) || !std::isfinite(settings->zoom)) {
      NODELET_WARN_THROTTLE(1.0, "microscope settings with non-finite values ignored");
      return;
    }
    last_microscope_ = settings;
  }
  void onScenarioCommand(const vrm_msgs::ScenarioCommand::ConstPtr& command) {
    NODELET_INFO("scenario command %u '%s' '%s' (seed %u)", command->command, command->scenario.c_str(),
                 command->argument.c_str(), command->seed);
  }
  void onSessionInfo(const vrm_msgs::SessionInfo::ConstPtr& info) {
    std::lock_guard<std::mutex> lock(mutex_);
    if (info->scene != scene_.name) {
      NODELET_WARN("replaying a session of scene '%s' with scene '%s' loaded", info->scene.c_str(),
                   scene_.name.c_str());
    }
  }

  std::string world_frame_;
  std::string eye_frame_;
  bool publish_pose_tf_ = true;
  std::mutex mutex_;  // the running scene and what is built from it; callbacks come on several threads
  scene::SceneDescription scene_;
  std::uint64_t content_hash_ = 0;
  std::unique_ptr<mge::Graph> graph_ = std::make_unique<mge::Graph>();
  std::map<std::string, TriangleMesh> meshes_;
  std::map<std::string, std::unique_ptr<mge::Membrane>> membranes_;

  tf2_ros::TransformBroadcaster broadcaster_;
  tf2_ros::StaticTransformBroadcaster static_broadcaster_;
  std::map<std::string, ros::Publisher> mesh_publishers_;  // by object name
  ros::Publisher marker_publisher_;
  ros::Publisher session_publisher_;
  bool publish_session_info_ = true;
  vrm_msgs::SessionInfo session_template_;  // what a new scene's session_info repeats
  ros::Subscriber frame_subscriber_, pedal_subscriber_, microscope_subscriber_, command_subscriber_,
      session_subscriber_, scene_subscriber_;
  vrm_msgs::PedalState::ConstPtr last_pedals_;
  vrm_msgs::MicroscopeSettings::ConstPtr last_microscope_;
};

}  // namespace vrm_sim

PLUGINLIB_EXPORT_CLASS(vrm_sim::SceneManager, nodelet::Nodelet)
