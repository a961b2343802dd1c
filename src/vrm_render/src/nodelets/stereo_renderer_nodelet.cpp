// Thin ROS wrapper of vrm_render::StereoRenderer (thesis §6, §7.4.2): collects the latest scene meshes, eye and
// instrument poses and microscope knobs, renders when an input changed (at most `rate` Hz) and publishes left/right
// rgb8 images with CameraInfo. Stamps are the newest input stamp the frame reflects; nothing reads a clock for them.
//
// Subscribes (node handle namespace): meshes/<object> (vrm_msgs/TissueMesh, latched, one per scene object; for
// deformable objects also tissue/<object> from tissue_sim),
//   eye_state, instrument_state, microscope.
// Publishes: stereo/left/image_raw + camera_info, stereo/right/image_raw + camera_info (image_transport),
//   render_timing (vrm_msgs/StageTiming).
// Service: ~save_snapshot (std_srvs/Trigger): writes the last frame as PNGs into ~snapshot_dir.

#include <cv_bridge/cv_bridge.h>
#include <image_transport/image_transport.h>
#include <nodelet/nodelet.h>
#include <ros/ros.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>
#include <std_srvs/Trigger.h>
#include <vrm_msgs/EyeState.h>
#include <vrm_msgs/InstrumentState.h>
#include <vrm_msgs/MicroscopeSettings.h>
#include <vrm_msgs/StageTiming.h>
#include <vrm_msgs/TissueMesh.h>
#include <vrm_msgs/publish.h>

#include <boost/make_shared.hpp>
#include <cstdio>
#include <fstream>
#include <map>
#include <mutex>
#include <pluginlib/class_list_macros.hpp>

#include "vrm_render/image_io.h"
#include "vrm_render/scene_setup.h"
#include "vrm_render/stereo_renderer.h"
#include "vrm_sim/scene/scene_loader.h"

namespace vrm_render {

namespace {

Eigen::Isometry3f toIsometry(const geometry_msgs::Pose& pose) {
  Eigen::Isometry3f t = Eigen::Isometry3f::Identity();
  t.translation() = Eigen::Vector3f(pose.position.x, pose.position.y, pose.position.z);
  Eigen::Quaternionf q(pose.orientation.w, pose.orientation.x, pose.orientation.y, pose.orientation.z);
  if (q.norm() < 1e-6f) q = Eigen::Quaternionf::Identity();
  t.linear() = q.normalized().toRotationMatrix();
  return t;
}

MeshView toMeshView(const vrm_msgs::TissueMesh& msg) {
  MeshView view;
  view.positions = msg.positions.data();
  view.vertex_count = msg.positions.size() / 3;
  view.normals = msg.normals.size() == msg.positions.size() ? msg.normals.data() : nullptr;
  view.colors = msg.colors.size() == view.vertex_count * 4 && view.vertex_count ? msg.colors.data() : nullptr;
  view.injury = msg.injury.size() == view.vertex_count && view.vertex_count ? msg.injury.data() : nullptr;
  view.triangles = msg.triangles.data();
  view.triangle_count = msg.triangles.size() / 3;
  return view;
}

}  // namespace

class StereoRendererNodelet : public nodelet::Nodelet {
 public:
  void onInit() override {
    ros::NodeHandle& nh = getNodeHandle();
    ros::NodeHandle& pnh = getPrivateNodeHandle();
    RenderOptions options;
    pnh.param("width", options.width, options.width);
    pnh.param("height", options.height, options.height);
    pnh.param("stereo", options.stereo, options.stereo);
    pnh.param("shadows", options.shadow_pass, options.shadow_pass);
    pnh.param("lighting", options.lighting, options.lighting);
    pnh.param("bump_mapping", options.bump_mapping, options.bump_mapping);
    pnh.param("depth_of_field", options.dof_pass, options.dof_pass);
    pnh.param("shadow_map_size", options.shadow_map_size, options.shadow_map_size);
    pnh.param("dof_downsample", options.dof_downsample, options.dof_downsample);
    pnh.param("ghost_instruments", ghost_instruments_, false);
    // glFinish between passes: exact per-pass StageTiming, at the cost of some llvmpipe overlap (bench_render).
    pnh.param("time_passes", options.time_passes, options.time_passes);
    pnh.param("rate", rate_, 30.0);
    pnh.param("snapshot_dir", snapshot_dir_, std::string());
    pnh.param("snapshot_count", snapshot_count_, 0);
    pnh.param("snapshot_every", snapshot_every_, 10);
    pnh.param("world_frame", world_frame_, std::string("world"));
    pnh.param("eye_frame", eye_frame_, std::string("eye"));
    const std::string scene_parameter = pnh.param<std::string>("scene", "membrane_peeling");

    try {
      const std::string path =
          std::ifstream(scene_parameter).good() ? scene_parameter : vrm_sim::scene::shippedScenePath(scene_parameter);
      scene_ = vrm_sim::scene::loadScene(path);
      renderer_ = std::make_unique<StereoRenderer>(options);
    } catch (const std::exception& error) {
      NODELET_FATAL("stereo_renderer cannot start: %s", error.what());
      throw;
    }
    for (const auto& object : scene_.objects) {
      renderer_->setStyle(object.name, objectStyle(object));
      mesh_subscribers_.push_back(nh.subscribe<vrm_msgs::TissueMesh>(
          "meshes/" + object.name, 2,
          boost::bind(&StereoRendererNodelet::onMesh, this, object.name, boost::placeholders::_1)));
      // Deformable objects: the scene manager's latched rest shape first, then tissue_sim's deformed versions.
      if (object.isDeformable() && scene_.simulates(vrm_sim::scene::Simulation::kTissue)) {
        mesh_subscribers_.push_back(nh.subscribe<vrm_msgs::TissueMesh>(
            "tissue/" + object.name, 2,
            boost::bind(&StereoRendererNodelet::onMesh, this, object.name, boost::placeholders::_1)));
      }
    }
    for (const auto& instrument : scene_.instruments) {
      const std::string id = instrumentObjectId(instrument);
      const MeshData mesh = toMeshData(vrm_sim::scene::buildInstrumentMesh(instrument));
      renderer_->setStyle(id, instrumentStyle(instrument, ghost_instruments_));
      renderer_->updateMesh(id, mesh.view(), 1);
      renderer_->setVisible(id, false);  // until tracked
      slots_[vrm_sim::scene::toString(instrument.slot)] = {id, instrument.type, {}};
    }
    eye_sub_ = nh.subscribe("eye_state", 5, &StereoRendererNodelet::onEyeState, this);
    instrument_sub_ = nh.subscribe("instrument_state", 10, &StereoRendererNodelet::onInstrumentState, this);
    microscope_sub_ = nh.subscribe("microscope", 5, &StereoRendererNodelet::onMicroscope, this);

    image_transport::ImageTransport it(nh);
    left_pub_ = it.advertiseCamera("stereo/left/image_raw", 1);
    if (options.stereo) right_pub_ = it.advertiseCamera("stereo/right/image_raw", 1);
    timing_pub_ = nh.advertise<vrm_msgs::StageTiming>("render_timing", 5);
    snapshot_srv_ = pnh.advertiseService("save_snapshot", &StereoRendererNodelet::onSaveSnapshot, this);
    timer_ = nh.createTimer(ros::Duration(1.0 / std::max(1.0, rate_)), &StereoRendererNodelet::onTimer, this);
    NODELET_INFO("stereo_renderer: scene '%s', %dx%d %s, passes shadow=%d dof=%d, up to %.1f Hz", scene_.name.c_str(),
                 options.width, options.height, options.stereo ? "stereo" : "mono", options.shadow_pass,
                 options.dof_pass, rate_);
  }

 private:
  struct Slot {
    std::string object_id;
    vrm_sim::scene::InstrumentType type;
    vrm_msgs::InstrumentState::ConstPtr state;
  };

  void noteStamp(const ros::Time& stamp) {
    if (stamp > newest_stamp_) newest_stamp_ = stamp;
    dirty_ = true;
  }

  void onMesh(const std::string& name, const vrm_msgs::TissueMesh::ConstPtr& mesh) {
    std::lock_guard<std::mutex> lock(mutex_);
    // A late latched rest shape must not replace a newer deformed version of the same object.
    auto newest = newest_mesh_version_.find(name);
    if (newest != newest_mesh_version_.end() && mesh->version < newest->second) return;
    newest_mesh_version_[name] = mesh->version;
    pending_meshes_[name] = mesh;
    noteStamp(mesh->header.stamp);
  }
  void onEyeState(const vrm_msgs::EyeState::ConstPtr& eye) {
    if (!eye->valid) return;
    std::lock_guard<std::mutex> lock(mutex_);
    eye_ = eye;
    noteStamp(eye->header.stamp);
  }
  void onInstrumentState(const vrm_msgs::InstrumentState::ConstPtr& state) {
    std::lock_guard<std::mutex> lock(mutex_);
    auto slot = slots_.find(state->instrument_id);
    if (slot == slots_.end()) return;
    slot->second.state = state;
    noteStamp(state->header.stamp);
  }
  void onMicroscope(const vrm_msgs::MicroscopeSettings::ConstPtr& settings) {
    std::lock_guard<std::mutex> lock(mutex_);
    microscope_ = settings;
    noteStamp(settings->header.stamp);
  }

  bool onSaveSnapshot(std_srvs::Trigger::Request&, std_srvs::Trigger::Response& response) {
    std::lock_guard<std::mutex> lock(render_mutex_);
    if (last_frame_.images[0].data.empty()) {
      response.message = "no frame rendered yet";
      return true;
    }
    try {
      response.message = saveSnapshot(last_frame_, last_stamp_);
      response.success = true;
    } catch (const std::exception& error) {
      response.message = error.what();
    }
    return true;
  }

  std::string saveSnapshot(const StereoFrame& frame, const ros::Time& stamp) {
    const std::string dir = snapshot_dir_.empty() ? std::string("/tmp") : snapshot_dir_;
    char name[64];
    std::snprintf(name, sizeof(name), "/render_%06llu_%u.%09u", static_cast<unsigned long long>(frame_count_),
                  stamp.sec, stamp.nsec);
    savePng(frame.images[0], dir + name + "_left.png");
    if (!frame.images[1].data.empty()) savePng(frame.images[1], dir + name + "_right.png");
    return dir + name;
  }

  // Collects the inputs that arrived since the last frame; false when there is nothing new to show.
  bool takeInputs(std::map<std::string, vrm_msgs::TissueMesh::ConstPtr>* meshes, ros::Time* stamp) {
    std::lock_guard<std::mutex> lock(mutex_);
    if (!dirty_ || newest_stamp_ <= last_stamp_) return false;
    dirty_ = false;
    meshes->swap(pending_meshes_);
    *stamp = newest_stamp_;
    eye_in_use_ = eye_;
    microscope_in_use_ = microscope_;
    slot_states_.clear();
    for (const auto& entry : slots_) slot_states_[entry.first] = entry.second.state;
    return true;
  }

  void onTimer(const ros::TimerEvent&) {
    std::lock_guard<std::mutex> render_lock(render_mutex_);
    // Render only what somebody sees: with no image or timing subscriber and no snapshot due, the frame is skipped
    // (a headless session keeps its cores for tracking and simulation). Inputs stay queued as the latest state.
    const bool snapshot_due = snapshot_count_ > 0 && !snapshot_dir_.empty() && snapshots_saved_ < snapshot_count_;
    const bool watched =
        left_pub_.getNumSubscribers() > 0 || right_pub_.getNumSubscribers() > 0 || timing_pub_.getNumSubscribers() > 0;
    if (!snapshot_due && !watched) return;
    std::map<std::string, vrm_msgs::TissueMesh::ConstPtr> meshes;
    ros::Time stamp;
    if (!takeInputs(&meshes, &stamp)) return;
    const ros::Time start = ros::Time::now();
    for (const auto& entry : meshes) {
      try {
        renderer_->updateMesh(entry.first, toMeshView(*entry.second), entry.second->version);
        mesh_frames_[entry.first] = entry.second->header.frame_id;
      } catch (const RenderError& error) {
        NODELET_ERROR_THROTTLE(1.0, "mesh '%s' rejected: %s", entry.first.c_str(), error.what());
      }
    }
    Eigen::Isometry3f world_from_eye = Eigen::Isometry3f::Identity();
    if (eye_in_use_) {
      geometry_msgs::Pose pose;
      pose.position = eye_in_use_->rotation_center;
      pose.orientation = eye_in_use_->rotation;
      world_from_eye = toIsometry(pose);
    }
    auto frameToWorld = [&](const std::string& frame) {
      return frame == world_frame_ ? Eigen::Isometry3f::Identity() : world_from_eye;
    };
    try {
      for (const auto& entry : mesh_frames_) renderer_->setPose(entry.first, frameToWorld(entry.second));
      LightPipe light;
      for (const auto& entry : slot_states_) {
        const Slot& slot = slots_.at(entry.first);
        const auto& state = entry.second;
        const bool valid = state && state->valid;
        renderer_->setVisible(slot.object_id, valid);
        if (!valid) continue;
        const Eigen::Isometry3f pose =
            frameToWorld(state->header.frame_id.empty() ? eye_frame_ : state->header.frame_id) *
            toIsometry(state->tip_pose);
        renderer_->setPose(slot.object_id, pose);
        if (slot.type == vrm_sim::scene::InstrumentType::kLightPipe) light = lightPipeAt(pose);
      }
      renderer_->setLightPipe(light);
      if (microscope_in_use_) {
        MicroscopeState knobs;
        knobs.focus_distance = microscope_in_use_->focus_distance;
        knobs.zoom = microscope_in_use_->zoom;
        knobs.ambient_light = microscope_in_use_->ambient_light;
        knobs.disparity_scale = microscope_in_use_->disparity_scale;
        renderer_->setMicroscope(knobs);
      }
    } catch (const RenderError& error) {
      NODELET_WARN_THROTTLE(1.0, "input ignored: %s", error.what());
    }
    try {
      renderer_->render(&last_frame_);
    } catch (const RenderError& error) {
      NODELET_ERROR_THROTTLE(1.0, "render failed: %s", error.what());
      return;
    }
    const ros::Time end = ros::Time::now();
    ++frame_count_;
    last_stamp_ = stamp;
    if (snapshot_count_ > 0 && !snapshot_dir_.empty() && snapshots_saved_ < snapshot_count_ &&
        frame_count_ % std::max(1, snapshot_every_) == 0) {
      try {
        saveSnapshot(last_frame_, stamp);
        ++snapshots_saved_;
      } catch (const std::exception& error) {
        NODELET_WARN_THROTTLE(5.0, "snapshot failed: %s", error.what());
      }
    }
    publishEye(0, left_pub_, stamp);
    if (renderer_->options().stereo) publishEye(1, right_pub_, stamp);
    publishTiming(stamp, start, end);
  }

  void publishEye(int eye, const image_transport::CameraPublisher& publisher, const ros::Time& stamp) {
    if (publisher.getNumSubscribers() == 0) return;
    const CameraView camera = renderer_->camera(eye == 0 ? Eye::kLeft : Eye::kRight);
    const RgbImage& rgb = last_frame_.images[eye];
    auto image = boost::make_shared<sensor_msgs::Image>();
    image->header.stamp = stamp;
    image->header.frame_id = eye == 0 ? "microscope_left_optical" : "microscope_right_optical";
    image->width = rgb.width;
    image->height = rgb.height;
    image->encoding = "rgb8";
    image->step = rgb.width * 3;
    image->data = rgb.data;  // the snapshot service keeps last_frame_, so this is the one copy
    auto info = boost::make_shared<sensor_msgs::CameraInfo>();
    info->header = image->header;
    info->width = rgb.width;
    info->height = rgb.height;
    info->distortion_model = "plumb_bob";
    info->D.assign(5, 0.0);
    const Eigen::Matrix4f& p = camera.projection;
    const double fx = p(0, 0) * rgb.width / 2.0, fy = p(1, 1) * rgb.height / 2.0;
    const double cx = (1.0 - p(0, 2)) * rgb.width / 2.0, cy = (1.0 + p(1, 2)) * rgb.height / 2.0;
    info->K = {fx, 0, cx, 0, fy, cy, 0, 0, 1};
    info->R = {1, 0, 0, 0, 1, 0, 0, 0, 1};
    // Tx = -fx * (offset of this eye from the left eye): the stereo convention of sensor_msgs/CameraInfo.
    const CameraView left = renderer_->camera(Eye::kLeft);
    const double tx = -fx * (camera.position - left.position).norm();
    info->P = {fx, 0, cx, tx, 0, fy, cy, 0, 0, 0, 1, 0};
    publisher.publish(image, info);
  }

  void publishTiming(const ros::Time& stamp, const ros::Time& start, const ros::Time& end) {
    auto timing = boost::make_shared<vrm_msgs::StageTiming>();
    timing->header.stamp = stamp;
    timing->frame = frame_count_;
    const PassTimings& t = last_frame_.timings;
    ros::Time cursor = start;
    for (const auto& stage :
         {std::make_pair("render_upload", t.ms_upload), std::make_pair("render_shadow", t.ms_shadow),
          std::make_pair("render_scene", t.ms_scene), std::make_pair("render_dof", t.ms_dof),
          std::make_pair("render_readback", t.ms_readback)}) {
      vrm_msgs::StageStamp s;
      s.stage = stage.first;
      s.start = cursor;
      cursor += ros::Duration(stage.second * 1e-3);
      s.end = cursor;
      timing->stages.push_back(s);
    }
    vrm_msgs::StageStamp total;
    total.stage = "render";
    total.start = start;
    total.end = end;
    timing->stages.push_back(total);
    vrm_msgs::publishShared(timing_pub_, timing);
  }

  vrm_sim::scene::SceneDescription scene_;
  std::unique_ptr<StereoRenderer> renderer_;
  bool ghost_instruments_ = false;
  double rate_ = 30.0;
  std::string snapshot_dir_;
  int snapshot_count_ = 0;
  int snapshot_every_ = 10;
  int snapshots_saved_ = 0;
  std::string world_frame_;
  std::string eye_frame_;

  std::mutex mutex_;  // inputs
  std::map<std::string, vrm_msgs::TissueMesh::ConstPtr> pending_meshes_;
  std::map<std::string, Slot> slots_;
  vrm_msgs::EyeState::ConstPtr eye_;
  vrm_msgs::MicroscopeSettings::ConstPtr microscope_;
  ros::Time newest_stamp_;
  bool dirty_ = false;

  std::mutex render_mutex_;  // renderer and last frame
  std::map<std::string, std::string> mesh_frames_;
  std::map<std::string, vrm_msgs::InstrumentState::ConstPtr> slot_states_;
  vrm_msgs::EyeState::ConstPtr eye_in_use_;
  vrm_msgs::MicroscopeSettings::ConstPtr microscope_in_use_;
  StereoFrame last_frame_;
  ros::Time last_stamp_;
  std::uint64_t frame_count_ = 0;

  std::vector<ros::Subscriber> mesh_subscribers_;
  std::map<std::string, std::uint64_t> newest_mesh_version_;
  ros::Subscriber eye_sub_, instrument_sub_, microscope_sub_;
  image_transport::CameraPublisher left_pub_, right_pub_;
  ros::Publisher timing_pub_;
  ros::ServiceServer snapshot_srv_;
  ros::Timer timer_;
};

}  // namespace vrm_render

PLUGINLIB_EXPORT_CLASS(vrm_render::StereoRendererNodelet, nodelet::Nodelet)
