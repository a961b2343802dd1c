#pragma once
// Every message handler of vrm_sim's nodelets with arbitrary field values, through the same conversions and core
// calls as the nodelets:
//   scenario_manager  EyeState, InstrumentState, PedalState, ScenarioCommand -> conversions.h toWorld ->
//                     world::Session::handle; each closed frame is published as the nodelet does (fillTissueMesh,
//                     fillCollisionReport, fillTriangleListMarker, fillSimulationState, fillScenarioStatus/Score)
//   scene_manager     EyeState, InstrumentState (pose -> toEigen -> toTransformMsg), MicroscopeSettings, SessionInfo
//   stereo_renderer   MicroscopeSettings -> the microscope cameras (vrm_render microscope_camera.h; the mesh upload
//                     itself needs a GL context, see README), TissueMesh -> fillTriangleListMarker (RViz path)
// The first byte picks the shipped scene the session starts with (as the nodelet's ~scene parameter). Building a
// World costs 0.1-1 s under ASan (tissue scenes most), so this target runs slowly; sim_conversions.cpp runs the same
// messages through the same handlers without a World, at full speed.
#include <vrm_msgs/MicroscopeSettings.h>
#include <vrm_msgs/SessionInfo.h>

#include <cmath>
#include <map>
#include <memory>

#include "ros_messages.h"
#include "vrm_render/microscope_camera.h"
#include "vrm_sim/conversions.h"
#include "vrm_sim/mge/membrane.h"
#include "vrm_sim/scene/scene_loader.h"
#include "vrm_sim/world/session.h"

namespace vrm_fuzz_sim {
namespace {  // a copy per entry point: both are linked into the replay test

using namespace vrm_sim;

const scene::SceneDescription& shippedScene(std::uint8_t selector) {
  static const std::vector<std::string> names = {"navigation",  "membrane_peeling", "vitrectomy", "steady_hold",
                                                 "ilm_peeling", "pick_and_place",   "trajectory"};
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

// with_world = false: the conversions only (sim_conversions).
inline int runSimMessages(const std::uint8_t* data, std::size_t size, bool with_world) {
  vrm_fuzz::Bytes in(data, size);
  if (in.empty()) return 0;
  if (!with_world) in.take<std::uint8_t>();
  world::WorldOptions options;
  options.clock = [] { return 0.0; };  // measurement only; a constant keeps runs reproducible
  options.log = [](world::Severity, const std::string&) {};
  std::unique_ptr<world::Session> session;
  if (with_world) {
    try {
      session = std::make_unique<world::Session>(shippedScene(in.take<std::uint8_t>()), options);
    } catch (const std::exception&) {
      return 0;  // cannot happen for a shipped scene (the World tests say so); not the fuzzed part
    }
    world::Session* current = session.get();
    session->setFrameObserver([current](const world::FrameResult& frame) { publishFrame(*current, frame); });
    session->world().setRigidReports((data[0] & 0x80) != 0);
  }

  vrm_fuzz::Frame frame;
  int messages = 0;
  while (messages++ < 64 && vrm_fuzz::nextFrame(in, &frame)) {
    switch (frame.kind % 7) {
      case 0: {
        vrm_msgs::EyeState eye;
        if (!vrm_fuzz::deserialize(frame, &eye)) break;
        const world::EyeState converted = toWorld(eye);
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
        const world::InstrumentState converted = toWorld(instrument);
        if (session) session->handle(converted);
        if (instrument.valid) sceneManagerPose(instrument.tip_pose);
        break;
      }
      case 2: {
        vrm_msgs::PedalState pedals;
        if (!vrm_fuzz::deserialize(frame, &pedals)) break;
        const world::PedalState converted = toWorld(pedals);
        if (session) session->handle(converted);
        break;
      }
      case 3: {
        vrm_msgs::ScenarioCommand command;
        if (!vrm_fuzz::deserialize(frame, &command)) break;
        const auto converted = toWorld(command);
        if (!session) break;
        if (converted) {
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
  }
  return 0;
}

}  // namespace
}  // namespace vrm_fuzz_sim
