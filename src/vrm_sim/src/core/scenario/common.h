#pragma once
// Shared pieces of the scenario types (not installed): strict parameter reading and the retina contact counter.

#include <optional>
#include <set>
#include <string>
#include <vector>

#include "vrm_scene/scene_loader.h"
#include "vrm_sim/scenario/light_cone.h"
#include "vrm_sim/scenario/metrics.h"
#include "vrm_sim/scenario/scenario.h"

namespace vrm_sim {
namespace scenario {

constexpr double kPi = 3.14159265358979323846;

// Reads the scenario's `params`; every parameter a type does not ask for is an error on finish(), like the loader's
// unknown keys, so a misspelt parameter never silently leaves a default in place.
class Params {
 public:
  explicit Params(const scene::SceneDescription& scene) : scene_(scene), scenario_(*scene.scenario) {}

  double number(const std::string& name, double fallback, double minimum, double maximum);
  std::string name(const std::string& name, const std::string& fallback);
  std::vector<std::string> names(const std::string& name);
  std::vector<Eigen::Vector3d> points(const std::string& name);  // a flat list x1, y1, z1, x2, ...
  // A scene object the scenario refers to, by the name in parameter `name` (default `fallback`).
  const scene::ObjectDescription& object(const std::string& name, const std::string& fallback);
  // The instrument slot named by parameter `name` ("left" | "right"); the scene must have an instrument there.
  std::string slot(const std::string& name, const std::string& fallback);
  void finish() const;
  [[noreturn]] void fail(const std::string& name, const std::string& problem) const;

 private:
  const scene::ScenarioParam* get(const std::string& name);
  const scene::SceneDescription& scene_;
  const scene::ScenarioDescription& scenario_;
  std::set<std::string> asked_;
};

// The centre (in the object's frame) and radius of a sphere object (generator sphere).
struct Sphere {
  std::string name;
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  double radius = 0.0;
};
Sphere sphereOf(const scene::ObjectDescription& object, Params& params, const std::string& parameter);

// A scene object the scenario works on as tissue: it must have a tissue model.
const scene::ObjectDescription& deformableObject(Params& params, const std::string& parameter,
                                                 const std::string& fallback);

// Retina contacts of every instrument: the simulation core's contact events where the retina is simulated
// (bleeding), else the instrument tips' distance to the eye sphere (enter below 50 µm, leave above 100 µm).
class RetinaContacts {
 public:
  explicit RetinaContacts(double eye_radius) : eye_radius_(eye_radius) {}
  void update(const FrameView& frame);
  std::size_t count() const;
  void hash(std::uint64_t& state) const;
  // The baseline of the core's event count too: rebuilt from the next frame, it would forget the contacts so far.
  void transferState(StateArchive& archive) { archive(first_events_)(events_)(tips_); }

 private:
  double eye_radius_;
  std::optional<std::size_t> first_events_;
  std::size_t events_ = 0;
  std::vector<std::pair<std::string, ContactCounter>> tips_;
};

// Work outside the light pipe's cone (issue 33; vitreoretinal surgery is bimanual: the light pipe lights what the other
// hand works on). The working instrument is "working" while it is tracked, its tip in the posterior half of the eye
// (eye frame z < 0: the fundus, not the trocars' pars plana) and within `work_distance` (parameter, default 1.5 mm)
// of the retina (the eye sphere) — where it grasps, peels or cuts. unlit() counts the seconds (the frames' dt) it
// works while its tip is not lit by the light pipe (litByLightPipe with `light_cone_deg`, default
// kLightConeHalfAngleDeg); a light pipe that is not tracked lights nothing. Parameters read: light (slot, default
// left; the scene must have an instrument there), light_cone_deg, work_distance.
class UnlitWork {
 public:
  UnlitWork(const scene::SceneDescription& scene, Params& params, const std::string& tool);
  void update(const FrameView& frame);
  double seconds() const { return seconds_; }
  bool working() const { return working_; }
  bool lit() const { return lit_; }
  const std::string& tool() const { return tool_; }
  void hash(std::uint64_t& state) const;
  // working_ and lit_ are redone by the next update, but saved so the accessors agree right after a load.
  void transferState(StateArchive& archive) { archive(seconds_)(working_)(lit_); }

 private:
  double eye_radius_;
  std::string tool_, light_;
  double cone_cos_ = 0.9, work_distance_ = 1.5e-3;
  double seconds_ = 0.0;
  bool working_ = false, lit_ = true;
};

std::string format(const char* format, ...);

}  // namespace scenario
}  // namespace vrm_sim
