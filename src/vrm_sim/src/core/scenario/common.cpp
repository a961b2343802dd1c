#include "common.h"

#include <algorithm>
#include <cmath>
#include <cstdarg>
#include <cstdio>
#include <variant>

namespace vrm_sim {
namespace scenario {

const scene::ScenarioParam* Params::get(const std::string& name) {
  asked_.insert(name);
  return scenario_.param(name);
}

void Params::fail(const std::string& name, const std::string& problem) const {
  const scene::ScenarioParam* param = scenario_.param(name);
  scene::SourceLocation where = param != nullptr ? param->location : scenario_.location;
  where.field = param != nullptr ? "scenario.params." + name : "scenario.params";
  throw scene::SceneError(where, problem);
}

double Params::number(const std::string& name, double fallback, double minimum, double maximum) {
  const scene::ScenarioParam* param = get(name);
  if (param == nullptr) return fallback;
  char range[96];
  std::snprintf(range, sizeof(range), "a number in [%g, %g]", minimum, maximum);
  if (param->numbers.size() != 1 || !param->names.empty()) fail(name, std::string("expected ") + range);
  const double value = param->numbers.front();
  if (!(value >= minimum && value <= maximum)) fail(name, format("expected %s, got %g", range, value));
  return value;
}

std::string Params::name(const std::string& name, const std::string& fallback) {
  const scene::ScenarioParam* param = get(name);
  if (param == nullptr) return fallback;
  if (param->names.size() != 1 || !param->numbers.empty()) fail(name, "expected one name");
  return param->names.front();
}

std::vector<std::string> Params::names(const std::string& name) {
  const scene::ScenarioParam* param = get(name);
  if (param == nullptr) fail(name, "missing required parameter '" + name + "'");
  if (param->names.empty() || !param->numbers.empty()) fail(name, "expected a list of names");
  return param->names;
}

std::vector<Eigen::Vector3d> Params::points(const std::string& name) {
  const scene::ScenarioParam* param = get(name);
  if (param == nullptr) fail(name, "missing required parameter '" + name + "'");
  if (param->numbers.empty() || param->numbers.size() % 3 != 0 || !param->names.empty()) {
    fail(name, "expected a flat list of x, y, z coordinates (a multiple of 3 numbers)");
  }
  std::vector<Eigen::Vector3d> points;
  for (std::size_t i = 0; i < param->numbers.size(); i += 3) {
    points.emplace_back(param->numbers[i], param->numbers[i + 1], param->numbers[i + 2]);
  }
  return points;
}

const scene::ObjectDescription& Params::object(const std::string& name, const std::string& fallback) {
  const std::string object_name = this->name(name, fallback);
  const scene::ObjectDescription* object = scene_.findObject(object_name);
  if (object == nullptr) {
    std::string known;
    for (const auto& candidate : scene_.objects) known += (known.empty() ? "" : ", ") + candidate.name;
    fail(name, "the scene has no object '" + object_name + "' (objects: " + known + ")");
  }
  return *object;
}

std::string Params::slot(const std::string& name, const std::string& fallback) {
  const std::string slot = this->name(name, fallback);
  if (slot != "left" && slot != "right") fail(name, "expected left or right, got '" + slot + "'");
  const scene::InstrumentSlot which = slot == "left" ? scene::InstrumentSlot::kLeft : scene::InstrumentSlot::kRight;
  if (scene_.findInstrument(which) == nullptr) fail(name, "the scene has no instrument in slot '" + slot + "'");
  return slot;
}

void Params::finish() const {
  for (const auto& [name, param] : scenario_.params) {
    if (asked_.count(name) > 0) continue;
    std::string known;
    for (const auto& asked : asked_) known += (known.empty() ? "" : ", ") + asked;
    fail(name, "unknown parameter for scenario type '" + scenario_.type + "'; its parameters: " + known);
  }
}

Sphere sphereOf(const scene::ObjectDescription& object, Params& params, const std::string& parameter) {
  const auto* sphere = object.mesh.generator ? std::get_if<scene::SphereParams>(&*object.mesh.generator) : nullptr;
  if (sphere == nullptr) params.fail(parameter, "object '" + object.name + "' must be a sphere (generator sphere)");
  if (object.frame != scene::ObjectFrame::kEye)
    params.fail(parameter, "object '" + object.name + "' must be in the eye frame");
  return {object.name, object.pose.xyz, sphere->radius};
}

const scene::ObjectDescription& deformableObject(Params& params, const std::string& parameter,
                                                 const std::string& fallback) {
  const scene::ObjectDescription& object = params.object(parameter, fallback);
  if (!object.isDeformable()) params.fail(parameter, "object '" + object.name + "' is not deformable (tissue model)");
  return object;
}

void RetinaContacts::update(const FrameView& frame) {
  if (frame.retina.simulated) {
    if (!first_events_) first_events_ = frame.retina.contact_events - (frame.retina.in_contact ? 1 : 0);
    events_ = frame.retina.contact_events - *first_events_;
    return;
  }
  for (const InstrumentView& instrument : frame.instruments) {
    auto counter =
        std::find_if(tips_.begin(), tips_.end(), [&](const auto& entry) { return entry.first == instrument.slot; });
    if (counter == tips_.end()) {
      tips_.emplace_back(instrument.slot, ContactCounter{});
      counter = tips_.end() - 1;
    }
    const double clearance = instrument.valid ? eye_radius_ - instrument.tip.norm() : 1.0;
    counter->second.update(clearance, 5e-5, 1e-4);
  }
}

std::size_t RetinaContacts::count() const {
  std::size_t count = events_;
  for (const auto& entry : tips_) count += entry.second.count();
  return count;
}

void RetinaContacts::hash(std::uint64_t& state) const { hashValue(state, count()); }

UnlitWork::UnlitWork(const scene::SceneDescription& scene, Params& params, const std::string& tool)
    : eye_radius_(scene.eye.radius), tool_(tool) {
  light_ = params.slot("light", "left");
  if (light_ == tool_)
    params.fail("light", "the light pipe and the working instrument are the same slot '" + tool_ + "'");
  cone_cos_ = lightConeCos(params.number("light_cone_deg", kLightConeHalfAngleDeg, 1.0, 90.0));
  work_distance_ = params.number("work_distance", 1.5e-3, 0.0, scene.eye.radius);
}

void UnlitWork::update(const FrameView& frame) {
  working_ = false;
  lit_ = true;
  const InstrumentView* tool = frame.instrument(tool_);
  if (tool == nullptr || !tool->valid || !tool->tip.allFinite()) return;
  working_ = tool->tip.z() < 0.0 && eye_radius_ - tool->tip.norm() <= work_distance_;
  if (!working_) return;
  const InstrumentView* light = frame.instrument(light_);
  lit_ = light != nullptr && light->valid && litByLightPipe(light->tip, light->axis, tool->tip, cone_cos_);
  if (!lit_ && frame.dt > 0.0) seconds_ += frame.dt;
}

void UnlitWork::hash(std::uint64_t& state) const { hashValue(state, seconds_); }

std::string format(const char* format, ...) {
  char text[512];
  va_list arguments;
  va_start(arguments, format);
  std::vsnprintf(text, sizeof(text), format, arguments);
  va_end(arguments);
  return text;
}

}  // namespace scenario
}  // namespace vrm_sim
