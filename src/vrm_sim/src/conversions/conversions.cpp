#include "vrm_sim/conversions.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>

#include "vrm_msgs/InstrumentTypes.h"

namespace vrm_sim {

Eigen::Isometry3d toEigen(const geometry_msgs::Pose& pose) {
  Eigen::Isometry3d result = Eigen::Isometry3d::Identity();
  result.translation() = Eigen::Vector3d(pose.position.x, pose.position.y, pose.position.z);
  Eigen::Quaterniond rotation(pose.orientation.w, pose.orientation.x, pose.orientation.y, pose.orientation.z);
  // An all-zero quaternion (a default-constructed message) means "no rotation", not a singular matrix.
  if (rotation.squaredNorm() < 1e-12) rotation = Eigen::Quaterniond::Identity();
  result.linear() = rotation.normalized().toRotationMatrix();
  return result;
}

geometry_msgs::Pose toPoseMsg(const Eigen::Isometry3d& pose) {
  geometry_msgs::Pose result;
  result.position.x = pose.translation().x();
  result.position.y = pose.translation().y();
  result.position.z = pose.translation().z();
  const Eigen::Quaterniond rotation(pose.rotation());
  result.orientation.w = rotation.w();
  result.orientation.x = rotation.x();
  result.orientation.y = rotation.y();
  result.orientation.z = rotation.z();
  return result;
}

geometry_msgs::Transform toTransformMsg(const Eigen::Isometry3d& transform) {
  const geometry_msgs::Pose pose = toPoseMsg(transform);
  geometry_msgs::Transform result;
  result.translation.x = pose.position.x;
  result.translation.y = pose.position.y;
  result.translation.z = pose.position.z;
  result.rotation = pose.orientation;
  return result;
}

void fillTissueMesh(const Eigen::Vector3d* positions, std::size_t vertex_count,
                    const std::array<std::uint32_t, 3>* triangles, std::size_t triangle_count,
                    vrm_msgs::TissueMesh& message) {
  message.positions.resize(3 * vertex_count);
  for (std::size_t i = 0; i < vertex_count; ++i) {
    for (int axis = 0; axis < 3; ++axis) message.positions[3 * i + axis] = static_cast<float>(positions[i][axis]);
  }
  message.triangles.resize(3 * triangle_count);
  std::vector<Eigen::Vector3d> normals(vertex_count, Eigen::Vector3d::Zero());
  for (std::size_t t = 0; t < triangle_count; ++t) {
    const auto& triangle = triangles[t];
    for (int corner = 0; corner < 3; ++corner) message.triangles[3 * t + corner] = triangle[corner];
    // The cross product's length is twice the area: larger triangles weigh more.
    const Eigen::Vector3d area_normal =
        (positions[triangle[1]] - positions[triangle[0]]).cross(positions[triangle[2]] - positions[triangle[0]]);
    for (int corner = 0; corner < 3; ++corner) normals[triangle[corner]] += area_normal;
  }
  message.normals.resize(3 * vertex_count);
  for (std::size_t i = 0; i < vertex_count; ++i) {
    const double length = normals[i].norm();
    const Eigen::Vector3d unit = length > 0 ? Eigen::Vector3d(normals[i] / length) : Eigen::Vector3d::Zero();
    for (int axis = 0; axis < 3; ++axis) message.normals[3 * i + axis] = static_cast<float>(unit[axis]);
  }
}

void fillTissueMesh(const TriangleMesh& mesh, vrm_msgs::TissueMesh& message) {
  fillTissueMesh(mesh.vertices.data(), mesh.vertices.size(), mesh.triangles.data(), mesh.triangles.size(), message);
}

void fillTriangleListMarker(const vrm_msgs::TissueMesh& mesh, const std::array<float, 4>& rgba,
                            visualization_msgs::Marker& marker) {
  marker.header = mesh.header;
  marker.ns = mesh.tissue_id;
  marker.type = visualization_msgs::Marker::TRIANGLE_LIST;
  marker.action = visualization_msgs::Marker::ADD;
  marker.pose.orientation.w = 1.0;
  marker.scale.x = marker.scale.y = marker.scale.z = 1.0;
  marker.color.r = rgba[0];
  marker.color.g = rgba[1];
  marker.color.b = rgba[2];
  marker.color.a = rgba[3];
  // The mesh may come off the wire: a triangle with an index beyond the positions (or a trailing partial one) is
  // left out instead of read out of bounds (found by fuzzing, src/vrm_fuzz/regressions/sim_messages).
  const std::size_t vertex_count = mesh.positions.size() / 3;
  marker.points.clear();
  marker.points.reserve(mesh.triangles.size() - mesh.triangles.size() % 3);
  for (std::size_t t = 0; t + 3 <= mesh.triangles.size(); t += 3) {
    if (mesh.triangles[t] >= vertex_count || mesh.triangles[t + 1] >= vertex_count ||
        mesh.triangles[t + 2] >= vertex_count) {
      continue;
    }
    for (std::size_t corner = 0; corner < 3; ++corner) {
      const std::size_t vertex = mesh.triangles[t + corner];
      geometry_msgs::Point point;
      point.x = mesh.positions[3 * vertex];
      point.y = mesh.positions[3 * vertex + 1];
      point.z = mesh.positions[3 * vertex + 2];
      marker.points.push_back(point);
    }
  }
}

void fillTriangleListMarker(const Eigen::Vector3d* positions, const std::array<std::uint32_t, 3>* triangles,
                            const std::vector<std::uint32_t>& selected, const std::array<float, 4>& rgba,
                            visualization_msgs::Marker& marker) {
  marker.type = visualization_msgs::Marker::TRIANGLE_LIST;
  marker.action = visualization_msgs::Marker::ADD;
  marker.pose.orientation.w = 1.0;
  marker.scale.x = marker.scale.y = marker.scale.z = 1.0;
  marker.color.r = rgba[0];
  marker.color.g = rgba[1];
  marker.color.b = rgba[2];
  marker.color.a = rgba[3];
  marker.points.resize(3 * selected.size());
  for (std::size_t i = 0; i < selected.size(); ++i) {
    for (int corner = 0; corner < 3; ++corner) {
      const Eigen::Vector3d& p = positions[triangles[selected[i]][corner]];
      geometry_msgs::Point& point = marker.points[3 * i + corner];
      point.x = p.x();
      point.y = p.y();
      point.z = p.z();
    }
  }
}

Eigen::Isometry3d worldFromEye(const vrm_msgs::EyeState& eye) {
  geometry_msgs::Pose pose;
  pose.position = eye.rotation_center;
  pose.orientation = eye.rotation;
  return toEigen(pose);
}

void fillCollisionReport(const collision::CollisionResult& result, vrm_msgs::CollisionReport& report) {
  auto toVector3 = [](const Eigen::Vector3d& v) {
    geometry_msgs::Vector3 msg;
    msg.x = v.x();
    msg.y = v.y();
    msg.z = v.z();
    return msg;
  };
  report.colliding = result.colliding;
  report.triangles = result.triangles;
  report.nodes = result.nodes;
  report.deformations.clear();
  report.deformations.reserve(result.deformations.size());
  for (const Eigen::Vector3d& d : result.deformations) report.deformations.push_back(toVector3(d));
  report.contact_points.clear();
  report.contact_points.reserve(result.contact_points.size());
  for (const Eigen::Vector3d& p : result.contact_points) {
    geometry_msgs::Point point;
    point.x = p.x();
    point.y = p.y();
    point.z = p.z();
    report.contact_points.push_back(point);
  }
  report.contact_normals.clear();
  report.contact_normals.reserve(result.contact_normals.size());
  for (const Eigen::Vector3d& n : result.contact_normals) report.contact_normals.push_back(toVector3(n));
  report.pixel_size = result.pixel_size;
  report.ms_raster = result.timing.ms_raster;
  report.ms_readback = result.timing.ms_readback;
  report.ms_analysis = result.timing.ms_analysis;
  report.ms_total = result.timing.ms_total;
}

world::Stamp toStamp(const ros::Time& stamp) {
  return static_cast<world::Stamp>(stamp.sec) * 1000000000LL + static_cast<world::Stamp>(stamp.nsec);
}

ros::Time toRosTime(world::Stamp stamp) {
  ros::Time time;
  time.fromNSec(static_cast<std::uint64_t>(std::max<world::Stamp>(stamp, 0)));
  return time;
}

world::EyeState toWorld(const vrm_msgs::EyeState& eye) {
  world::EyeState state;
  state.stamp = toStamp(eye.header.stamp);
  state.rotation = Eigen::Quaterniond(eye.rotation.w, eye.rotation.x, eye.rotation.y, eye.rotation.z);
  state.rotation_center = Eigen::Vector3d(eye.rotation_center.x, eye.rotation_center.y, eye.rotation_center.z);
  state.valid = eye.valid;
  return state;
}

namespace {

struct InstrumentTypeConstant {
  scene::InstrumentType type;
  std::uint8_t constant;
};
constexpr InstrumentTypeConstant kInstrumentTypeConstants[] = {
    {scene::InstrumentType::kLightPipe, vrm_msgs::InstrumentTypes::LIGHT_PIPE},
    {scene::InstrumentType::kForceps, vrm_msgs::InstrumentTypes::FORCEPS},
    {scene::InstrumentType::kVitrector, vrm_msgs::InstrumentTypes::VITRECTOR},
    {scene::InstrumentType::kNeedle, vrm_msgs::InstrumentTypes::NEEDLE},
    {scene::InstrumentType::kHook, vrm_msgs::InstrumentTypes::HOOK},
    {scene::InstrumentType::kLaserProbe, vrm_msgs::InstrumentTypes::LASER_PROBE}};
constexpr std::uint8_t kNoInstrumentType = 255;

}  // namespace

std::optional<scene::InstrumentType> instrumentTypeFromMsg(std::uint8_t msg_type) {
  for (const InstrumentTypeConstant& entry : kInstrumentTypeConstants) {
    if (entry.constant == msg_type) return entry.type;
  }
  return std::nullopt;
}

std::uint8_t toMsgType(std::optional<scene::InstrumentType> type) {
  if (!type) return kNoInstrumentType;
  for (const InstrumentTypeConstant& entry : kInstrumentTypeConstants) {
    if (entry.type == *type) return entry.constant;
  }
  return kNoInstrumentType;
}

world::InstrumentState toWorld(const vrm_msgs::InstrumentState& instrument) {
  world::InstrumentState state;
  state.stamp = toStamp(instrument.header.stamp);
  state.slot = instrument.instrument_id;
  state.type = instrumentTypeFromMsg(instrument.type);
  // Copied number for number (the core rejects non-finite or zero quaternions).
  const geometry_msgs::Pose& pose = instrument.tip_pose;
  state.tip_position = Eigen::Vector3d(pose.position.x, pose.position.y, pose.position.z);
  state.tip_orientation =
      Eigen::Quaterniond(pose.orientation.w, pose.orientation.x, pose.orientation.y, pose.orientation.z);
  state.frame_id = instrument.header.frame_id;
  state.jaw_angle = instrument.jaw_angle;
  state.suction = instrument.suction;
  state.cut_rate = instrument.cut_rate;
  state.injection_flow = instrument.injection_flow;
  state.valid = instrument.valid;
  return state;
}

vrm_msgs::InstrumentState toMsg(const world::InstrumentState& instrument) {
  vrm_msgs::InstrumentState message;
  message.header.stamp = toRosTime(instrument.stamp);
  message.header.frame_id = instrument.frame_id;
  message.instrument_id = instrument.slot;
  message.type = toMsgType(instrument.type);
  message.tip_pose.position.x = instrument.tip_position.x();
  message.tip_pose.position.y = instrument.tip_position.y();
  message.tip_pose.position.z = instrument.tip_position.z();
  message.tip_pose.orientation.w = instrument.tip_orientation.w();
  message.tip_pose.orientation.x = instrument.tip_orientation.x();
  message.tip_pose.orientation.y = instrument.tip_orientation.y();
  message.tip_pose.orientation.z = instrument.tip_orientation.z();
  message.jaw_angle = instrument.jaw_angle;
  message.suction = instrument.suction;
  message.cut_rate = instrument.cut_rate;
  message.injection_flow = instrument.injection_flow;
  message.tracking_quality = instrument.valid ? 1.0f : 0.0f;
  message.valid = instrument.valid;
  return message;
}

world::PedalState toWorld(const vrm_msgs::PedalState& pedals) {
  world::PedalState state;
  state.stamp = toStamp(pedals.header.stamp);
  state.travel = pedals.travel;
  state.reflux = pedals.reflux;
  state.instrument_switch = pedals.instrument_switch;
  state.zoom_in = pedals.zoom_in;
  state.zoom_out = pedals.zoom_out;
  state.focus_near = pedals.focus_near;
  state.focus_far = pedals.focus_far;
  return state;
}

namespace {

// The one table between ScenarioCommand's constants and the core's command types (both directions use it).
struct CommandConstant {
  world::ScenarioCommand::Type type;
  std::uint8_t constant;
};
constexpr CommandConstant kCommandConstants[] = {
    {world::ScenarioCommand::Type::kLoad, vrm_msgs::ScenarioCommand::LOAD},
    {world::ScenarioCommand::Type::kStart, vrm_msgs::ScenarioCommand::START},
    {world::ScenarioCommand::Type::kPause, vrm_msgs::ScenarioCommand::PAUSE},
    {world::ScenarioCommand::Type::kResume, vrm_msgs::ScenarioCommand::RESUME},
    {world::ScenarioCommand::Type::kStop, vrm_msgs::ScenarioCommand::STOP},
    {world::ScenarioCommand::Type::kReset, vrm_msgs::ScenarioCommand::RESET},
    {world::ScenarioCommand::Type::kSelectInstrument, vrm_msgs::ScenarioCommand::SELECT_INSTRUMENT}};

}  // namespace

std::optional<world::ScenarioCommand> toWorld(const vrm_msgs::ScenarioCommand& command) {
  const auto type = std::find_if(std::begin(kCommandConstants), std::end(kCommandConstants),
                                 [&](const CommandConstant& entry) { return entry.constant == command.command; });
  if (type == std::end(kCommandConstants)) return std::nullopt;
  world::ScenarioCommand result;
  result.stamp = toStamp(command.header.stamp);
  result.command = type->type;
  result.scenario = command.scenario;
  result.argument = command.argument;
  result.seed = command.seed;
  return result;
}

vrm_msgs::EyeState toMsg(const world::EyeState& eye) {
  vrm_msgs::EyeState message;
  message.header.stamp = toRosTime(eye.stamp);
  message.header.frame_id = "world";
  message.rotation.w = eye.rotation.w();
  message.rotation.x = eye.rotation.x();
  message.rotation.y = eye.rotation.y();
  message.rotation.z = eye.rotation.z();
  message.rotation_center.x = eye.rotation_center.x();
  message.rotation_center.y = eye.rotation_center.y();
  message.rotation_center.z = eye.rotation_center.z();
  message.tracking_quality = eye.valid ? 1.0f : 0.0f;
  message.valid = eye.valid;
  return message;
}

vrm_msgs::PedalState toMsg(const world::PedalState& pedals) {
  vrm_msgs::PedalState message;
  message.header.stamp = toRosTime(pedals.stamp);
  message.travel = pedals.travel;
  message.reflux = pedals.reflux;
  message.instrument_switch = pedals.instrument_switch;
  message.zoom_in = pedals.zoom_in;
  message.zoom_out = pedals.zoom_out;
  message.focus_near = pedals.focus_near;
  message.focus_far = pedals.focus_far;
  return message;
}

vrm_msgs::ScenarioCommand toMsg(const world::ScenarioCommand& command) {
  const auto value = std::find_if(std::begin(kCommandConstants), std::end(kCommandConstants),
                                  [&](const CommandConstant& entry) { return entry.type == command.command; });
  vrm_msgs::ScenarioCommand message;
  message.header.stamp = toRosTime(command.stamp);
  message.command = value->constant;  // every Type has its constant (kCommandConstants)
  message.scenario = command.scenario;
  message.argument = command.argument;
  message.seed = command.seed;
  return message;
}

void fillInputFrame(const world::InputFrame& frame, const std::string& world_frame, const std::string& eye_frame,
                    vrm_msgs::InputFrame& message) {
  using Kind = world::InputFrame::Kind;
  message.header.stamp = toRosTime(frame.stamp);
  message.header.frame_id = world_frame;
  message.sequence = frame.sequence;
  message.kind = frame.kind == Kind::kFrame   ? vrm_msgs::InputFrame::KIND_FRAME
                 : frame.kind == Kind::kState ? vrm_msgs::InputFrame::KIND_STATE
                                              : vrm_msgs::InputFrame::KIND_LOAD;
  message.eye_inputs.clear();
  for (const world::EyeState& eye : frame.eye_inputs) message.eye_inputs.push_back(toMsg(eye));
  message.instrument_inputs.clear();
  for (const world::InstrumentState& state : frame.instrument_inputs) message.instrument_inputs.push_back(toMsg(state));
  message.pedals.clear();
  for (const world::PedalState& pedals : frame.pedals) message.pedals.push_back(toMsg(pedals));
  message.commands.clear();
  for (const world::ScenarioCommand& command : frame.commands) message.commands.push_back(toMsg(command));
  message.missing = frame.missing;
  message.late = frame.late;
  message.silenced = frame.silenced;
  message.held_back = frame.held_back;
  message.inputs = frame.inputs;
  message.late_inputs = frame.late_inputs;
  message.rejected_inputs = frame.rejected_inputs;
  message.eye_pose = toPoseMsg(frame.world_from_eye);
  message.eye_valid = frame.eye_valid;
  message.instruments.clear();
  for (const world::AppliedInstrument& applied : frame.instruments) {
    vrm_msgs::AppliedInstrument instrument;
    instrument.slot = applied.slot;
    instrument.type = scene::toString(applied.type);
    instrument.header.stamp = message.header.stamp;
    instrument.header.frame_id = applied.frame_id == "world" ? world_frame : eye_frame;
    instrument.pose = toPoseMsg(applied.pose);
    instrument.jaw_angle = applied.jaw_angle;
    instrument.suction = applied.suction;
    instrument.cut_rate = applied.cut_rate;
    instrument.cutting = applied.cutting;
    instrument.valid = applied.valid;
    instrument.delivered = applied.delivered;
    message.instruments.push_back(std::move(instrument));
  }
}

world::InputFrame toWorld(const vrm_msgs::InputFrame& message) {
  using Kind = world::InputFrame::Kind;
  world::InputFrame frame;
  frame.stamp = toStamp(message.header.stamp);
  frame.sequence = message.sequence;
  frame.kind = message.kind == vrm_msgs::InputFrame::KIND_STATE  ? Kind::kState
               : message.kind == vrm_msgs::InputFrame::KIND_LOAD ? Kind::kLoad
                                                                 : Kind::kFrame;
  for (const vrm_msgs::EyeState& eye : message.eye_inputs) frame.eye_inputs.push_back(toWorld(eye));
  for (const vrm_msgs::InstrumentState& state : message.instrument_inputs) {
    frame.instrument_inputs.push_back(toWorld(state));
  }
  for (const vrm_msgs::PedalState& pedals : message.pedals) frame.pedals.push_back(toWorld(pedals));
  for (const vrm_msgs::ScenarioCommand& command : message.commands) {
    if (auto converted = toWorld(command)) frame.commands.push_back(*converted);
  }
  frame.missing = message.missing;
  frame.late = message.late;
  frame.silenced = message.silenced;
  frame.held_back = message.held_back;
  frame.inputs = message.inputs;
  frame.late_inputs = message.late_inputs;
  frame.rejected_inputs = message.rejected_inputs;
  frame.world_from_eye = toEigen(message.eye_pose);
  frame.eye_valid = message.eye_valid;
  return frame;  // the applied instruments are the World's to fill when it applies the frame
}

static_assert(static_cast<int>(world::PeelOutcome::kUntouched) == vrm_msgs::TissueState::UNTOUCHED &&
                  static_cast<int>(world::PeelOutcome::kGrasped) == vrm_msgs::TissueState::GRASPED &&
                  static_cast<int>(world::PeelOutcome::kLifted) == vrm_msgs::TissueState::LIFTED &&
                  static_cast<int>(world::PeelOutcome::kTorn) == vrm_msgs::TissueState::TORN,
              "world::PeelOutcome must follow the TissueState outcome constants");

void fillSimulationState(const world::FrameResult& frame, const world::WorldStatistics& statistics,
                         vrm_msgs::SimulationState& message) {
  message.header.stamp = toRosTime(frame.stamp);
  message.frame = frame.frame;
  message.state_hash = frame.state_hash;
  message.frame_time = frame.frame_time;
  message.wall_time = frame.wall_time;
  message.paused = frame.paused;
  message.late_inputs = statistics.late_inputs;
  message.frames_without_source = statistics.frames_without_source;
  message.input_sequence = statistics.input_sequence;
  message.tissues.clear();
  for (const world::TissueReport& report : frame.tissues) {
    vrm_msgs::TissueState tissue;
    tissue.tissue_id = report.object;
    tissue.version = report.version;
    tissue.topology_version = report.topology_version;
    tissue.steps = static_cast<std::uint32_t>(report.steps);
    tissue.fallbacks = static_cast<std::uint32_t>(report.fallbacks);
    tissue.grasped_nodes = static_cast<std::uint32_t>(report.grasped_nodes);
    tissue.max_strain = report.max_strain;
    tissue.max_lift = report.max_lift;
    tissue.lifted_fraction = report.lifted_fraction;
    tissue.torn_springs = report.torn_springs;
    tissue.cut_nodes = report.cut_nodes;
    tissue.released_adhesions = report.released_adhesions;
    tissue.outcome = static_cast<std::uint8_t>(report.outcome);
    message.tissues.push_back(tissue);
  }
  message.objects.clear();
  if (frame.scenario != nullptr) {
    for (const scenario::ObjectPlacement& placement : frame.scenario->placements) {
      vrm_msgs::ObjectPose object;
      object.header.stamp = message.header.stamp;
      object.header.frame_id = placement.frame_id;
      object.name = placement.name;
      object.pose = toPoseMsg(placement.pose);
      message.objects.push_back(object);
    }
  }
  message.burns.clear();
  if (frame.scenario != nullptr) {
    message.burns.reserve(frame.scenario->burns.size());
    for (const scenario::LaserBurn& burn : frame.scenario->burns) {
      vrm_msgs::LaserBurn entry;
      entry.position.x = burn.position.x();
      entry.position.y = burn.position.y();
      entry.position.z = burn.position.z();
      entry.diameter = burn.diameter;
      entry.grade = burn.grade;
      entry.whiteness = burn.whiteness;
      entry.power = burn.power;
      entry.duration = burn.duration;
      entry.time = burn.time;
      message.burns.push_back(entry);
    }
  }
  message.retina_contacts = 0;
  message.max_injury = 0.0f;
  for (const world::InjuryReport& injury : frame.injuries) {
    message.retina_contacts += static_cast<std::uint32_t>(injury.contacts);
    message.max_injury = std::max(message.max_injury, static_cast<float>(injury.max_injury));
  }
}

void fillScore(const scenario::Score& score, vrm_msgs::Score& message) {
  message.total = score.total;
  message.items.clear();
  for (const scenario::ScoreItem& item : score.items) {
    vrm_msgs::ScoreItem entry;
    entry.name = item.name;
    entry.value = item.value;
    entry.unit = item.unit;
    entry.weight = item.weight;
    message.items.push_back(entry);
  }
}

void fillScenarioStatus(const scenario::Status& status, vrm_msgs::ScenarioStatus& message) {
  message.scenario = status.scenario;
  message.difficulty = status.difficulty;
  switch (status.state) {
    case scenario::State::kIdle:
      message.state = vrm_msgs::ScenarioStatus::IDLE;
      break;
    case scenario::State::kRunning:
      message.state = vrm_msgs::ScenarioStatus::RUNNING;
      break;
    case scenario::State::kPaused:
      message.state = vrm_msgs::ScenarioStatus::PAUSED;
      break;
    case scenario::State::kFinished:
      message.state = vrm_msgs::ScenarioStatus::FINISHED;
      break;
    case scenario::State::kFailed:
      message.state = vrm_msgs::ScenarioStatus::FAILED;
      break;
  }
  message.elapsed = status.elapsed;
  message.message = status.progress.empty() || status.message.find("refused") != std::string::npos ||
                            status.state == scenario::State::kFinished || status.state == scenario::State::kFailed
                        ? status.message
                        : status.progress;
  fillScore(status.score, message.score);
}

}  // namespace vrm_sim
