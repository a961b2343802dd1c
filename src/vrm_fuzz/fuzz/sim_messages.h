#pragma once
// Every message handler of vrm_sim's nodelets with arbitrary field values, through the same conversions and core
// calls as the nodelets:
//   scenario_manager  EyeState, InstrumentState, PedalState, ScenarioCommand -> conversions.h toWorld ->
//                     world::Session::handle; each closed frame is published as the nodelet does (fillTissueMesh,
//                     fillCollisionReport, fillTriangleListMarker, fillSimulationState, fillScenarioStatus/Score)
//   scene_manager     EyeState, InstrumentState (pose -> toEigen -> toTransformMsg), MicroscopeSettings, SessionInfo
//   stereo_renderer   MicroscopeSettings -> the microscope cameras (vrm_render microscope_camera.h; the mesh upload
//                     itself needs a GL context, see README), TissueMesh -> fillTriangleListMarker (RViz path)
// The first byte picks the shipped scene (as the nodelet's ~scene parameter); its bit 7 turns on rigid reports.
// A persistent World per scene (issue 39 §3): building one costs 10-200 ms under ASan (the membrane most), so the
// Session lives on across inputs as it does in a running node, and each input is the next stretch of its session: its
// stamps are moved to start 20 ms after the previous input's last frame (their differences, backwards ones included,
// are kept). The World is built again every kRebuildEvery inputs, and whenever a fuzzed LOAD switched it to another
// scene. A crash that needs the inputs before it may not replay alone: the regression replay builds a fresh World for
// every file (vrm_fuzz::resetPersistentState). Frames step at most kMaxFrameTime (the nodelet's max_frame_time,
// smaller): with 64 messages per input that bounds the physics an input costs. sim_conversions.cpp runs the same
// messages through the same handlers without a World, at full speed.
#include <vrm_msgs/MicroscopeSettings.h>
#include <vrm_msgs/SessionInfo.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <memory>
#include <optional>

#include "ros_messages.h"
#include "vrm_render/microscope_camera.h"
#include "vrm_scene/scene_loader.h"
#include "vrm_sim/conversions.h"
#include "vrm_sim/mge/membrane.h"
#include "vrm_sim/world/session.h"

namespace vrm_fuzz_sim {
namespace {  // a copy per entry point: both are linked into the replay test

using namespace vrm_sim;

// Every shipped scene; the seeds' first byte picks from the first seven.
const std::vector<std::string>& shippedSceneNames() {
  static const std::vector<std::string> names = {
      "navigation",     "membrane_peeling", "vitrectomy",        "steady_hold",       "ilm_peeling",
      "pick_and_place", "trajectory",       "laser_coagulation", "retina_relocation", "posterior_hyaloid",
      "bimanual",       "object_manipulation"};
  return names;
}

const scene::SceneDescription& shippedScene(std::uint8_t selector) {
  const std::vector<std::string>& names = shippedSceneNames();
  static std::map<std::string, scene::SceneDescription> cache;
  const std::string& name = names[selector % names.size()];
  auto found = cache.find(name);
  if (found == cache.end()) found = cache.emplace(name, scene::loadScene(scene::shippedScenePath(name))).first;
  return found->second;
}

bool finite(const geometry_msgs::Pose& pose) {
  return std::isfinite(pose.position.x) && std::isfinite(pose.position.y) && std::isfinite(pose.position.z) &&
         std::isfinite(pose.orientation.x) && std::isfinite(pose.orientation.y) && std::isfinite(pose.orientation.z) &&
         std::isfinite(pose.orientation.w);
}

// What scenario_manager publishes per frame.
void publishFrame(world::Session& session, const world::FrameResult& frame) {
  for (const world::TissueReport& tissue : frame.tissues) {
    if (!tissue.changed) continue;
    vrm_msgs::TissueMesh mesh;
    mge::Membrane& membrane = *session.world().membrane(tissue.object);
    fillTissueMesh(membrane.positions(), membrane.nodeCount(), membrane.triangleNodeSlots(), membrane.triangleCount(),
                   mesh);
  }
  for (const world::InjuryReport& injury : frame.injuries) {
    if (!injury.changed) continue;
    vrm_msgs::TissueMesh mesh;
    fillTissueMesh(*injury.mesh, mesh);
    mesh.injury = *injury.injury;
  }
  for (const world::CollisionRecord& record : frame.collisions) {
    vrm_msgs::CollisionReport report;
    fillCollisionReport(record.result, report);
    if (!record.result.triangles.empty()) {
      visualization_msgs::Marker marker;
      fillTriangleListMarker(record.surface.positions, record.surface.triangles, record.result.triangles,
                             {1.0f, 0.1f, 0.1f, 0.8f}, marker);
    }
  }
  vrm_msgs::SimulationState state;
  fillSimulationState(frame, session.world().statistics(), state);
  if (const scenario::Status* status = session.world().scenarioStatus()) {
    vrm_msgs::ScenarioStatus message;
    fillScenarioStatus(*status, message);
    vrm_msgs::Score score;
    fillScore(status->score, score);
  }
}

void sceneManagerPose(const geometry_msgs::Pose& pose) {
  if (!finite(pose)) return;  // scene_manager's guard
  toTransformMsg(toEigen(pose));
}

void rendererMicroscope(const vrm_msgs::MicroscopeSettings& settings) {
  vrm_render::MicroscopeState knobs;
  knobs.focus_distance = settings.focus_distance;
  knobs.zoom = settings.zoom;
  knobs.ambient_light = settings.ambient_light;
  knobs.disparity_scale = settings.disparity_scale;
  try {
    for (vrm_render::Eye eye : {vrm_render::Eye::kLeft, vrm_render::Eye::kRight}) {
      const vrm_render::CameraView view = vrm_render::microscopeCamera({}, knobs, 64, 48, eye, true);
      Eigen::Vector2f pixel;
      vrm_render::projectToPixel(view, Eigen::Vector3f(0.0f, 0.0f, -0.01f), &pixel);
    }
  } catch (const vrm_render::RenderError&) {
  }
}

constexpr int kRebuildEvery = 256;
constexpr double kMaxFrameTime = 0.005;  // s

struct PersistentSession {
  std::unique_ptr<world::Session> session;
  std::string scene;  // the shipped scene it was built for
  int inputs = 0;
  world::Stamp next_base = 1'000'000'000;  // where the next input's stamps start (ns)
};

std::map<std::uint8_t, PersistentSession>& persistentSessions() {
  static std::map<std::uint8_t, PersistentSession> sessions;
  return sessions;
}

void dropPersistentSessions() { persistentSessions().clear(); }

// The session of scene `selector`, built (again) when needed; nullptr if it cannot be built.
PersistentSession* sessionFor(std::uint8_t selector) {
  static const bool reset_registered = (vrm_fuzz::registerReset(&dropPersistentSessions), true);
  (void)reset_registered;
  PersistentSession& entry = persistentSessions()[static_cast<std::uint8_t>(selector % shippedSceneNames().size())];
  const scene::SceneDescription& description = shippedScene(selector);
  if (entry.session && entry.inputs < kRebuildEvery && entry.session->world().scene().name == description.name) {
    ++entry.inputs;
    return &entry;
  }
  world::WorldOptions options;
  options.clock = [] { return 0.0; };  // measurement only; a constant keeps runs reproducible
  options.log = [](world::Severity, const std::string&) {};
  options.max_frame_time = kMaxFrameTime;
  entry = PersistentSession{};
  try {
    entry.session = std::make_unique<world::Session>(description, options);
  } catch (const std::exception&) {
    return nullptr;  // cannot happen for a shipped scene (the World tests say so); not the fuzzed part
  }
  world::Session* current = entry.session.get();
  entry.session->setFrameObserver([current](const world::FrameResult& frame) { publishFrame(*current, frame); });
  entry.scene = description.name;
  entry.inputs = 1;
  return &entry;
}

// Moves an input's stamps behind the session's last frame, keeping their differences. A shifted stamp stays what a
// ros::Time header can carry (0 to 2^32 s), as every stamp the nodelet converts does: one outside made toRosTime
// throw in the harness, a case the node cannot meet.
class StampShift {
 public:
  explicit StampShift(world::Stamp base) : base_(base) {}
  world::Stamp operator()(world::Stamp stamp) {
    if (!first_) first_ = stamp;
    const __int128 shifted = static_cast<__int128>(base_) + stamp - *first_;
    const __int128 latest = static_cast<__int128>(std::numeric_limits<std::uint32_t>::max()) * 1'000'000'000 + 999'999'999;
    return static_cast<world::Stamp>(shifted > latest ? latest : shifted < 0 ? 0 : shifted);
  }

 private:
  world::Stamp base_;
  std::optional<world::Stamp> first_;
};

// with_world = false: the conversions only (sim_conversions).
inline int runSimMessages(const std::uint8_t* data, std::size_t size, bool with_world) {
  vrm_fuzz::Bytes in(data, size);
  if (in.empty()) return 0;
  const std::uint8_t selector = in.take<std::uint8_t>();  // the scene; bit 7: rigid reports
  PersistentSession* persistent = nullptr;
  world::Session* session = nullptr;
  if (with_world) {
    persistent = sessionFor(selector);
    if (persistent == nullptr) return 0;
    session = persistent->session.get();
    session->world().setRigidReports((selector & 0x80) != 0);
  }
  StampShift shift(persistent ? persistent->next_base : 0);

  vrm_fuzz::Frame frame;
  int messages = 0;
  while (messages++ < 64 && vrm_fuzz::nextFrame(in, &frame)) {
    switch (frame.kind % 7) {
      case 0: {
        vrm_msgs::EyeState eye;
        if (!vrm_fuzz::deserialize(frame, &eye)) break;
        world::EyeState converted = toWorld(eye);
        converted.stamp = shift(converted.stamp);
        if (session) session->handle(converted);
        geometry_msgs::Pose pose;
        pose.position = eye.rotation_center;
        pose.orientation = eye.rotation;
        if (eye.valid) sceneManagerPose(pose);
        worldFromEye(eye);
        break;
      }
      case 1: {
        vrm_msgs::InstrumentState instrument;
        if (!vrm_fuzz::deserialize(frame, &instrument)) break;
        world::InstrumentState converted = toWorld(instrument);
        converted.stamp = shift(converted.stamp);
        if (session) session->handle(converted);
        if (instrument.valid) sceneManagerPose(instrument.tip_pose);
        break;
      }
      case 2: {
        vrm_msgs::PedalState pedals;
        if (!vrm_fuzz::deserialize(frame, &pedals)) break;
        world::PedalState converted = toWorld(pedals);
        converted.stamp = shift(converted.stamp);
        if (session) session->handle(converted);
        break;
      }
      case 3: {
        vrm_msgs::ScenarioCommand command;
        if (!vrm_fuzz::deserialize(frame, &command)) break;
        auto converted = toWorld(command);
        if (!session) break;
        if (converted) {
          converted->stamp = shift(converted->stamp);
          session->handle(*converted);
        } else {
          session->world().note("unknown command " + std::to_string(command.command) + " ignored");
        }
        break;
      }
      case 4: {
        vrm_msgs::MicroscopeSettings settings;
        if (vrm_fuzz::deserialize(frame, &settings)) rendererMicroscope(settings);
        break;
      }
      case 5: {
        vrm_msgs::SessionInfo info;
        if (vrm_fuzz::deserialize(frame, &info) && session) (void)(info.scene == session->world().scene().name);
        break;
      }
      case 6: {
        vrm_msgs::TissueMesh mesh;
        if (!vrm_fuzz::deserialize(frame, &mesh)) break;
        visualization_msgs::Marker marker;
        fillTriangleListMarker(mesh, {1.0f, 1.0f, 1.0f, 1.0f}, marker);
        break;
      }
    }
  }
  if (session) {
    session->flush();
    session->world().stateHash();
    // A LOAD replaced the World; the next input's stamps follow this one's last frame.
    if (session->world().scene().name != persistent->scene) persistent->inputs = kRebuildEvery;
    if (const auto last = session->world().lastFrameStamp()) {
      persistent->next_base = std::max(persistent->next_base, *last + 20'000'000);
    }
  }
  return 0;
}

}  // namespace
}  // namespace vrm_fuzz_sim
