#include "vrm_scene/scene_loader.h"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <mutex>
#include <sstream>

#include "vrm_scene/hash.h"
#include "vrm_scene/meshes/mesh_io.h"
#include "vrm_scene/meshes/mesh_utils.h"
#include "vrm_scene/registry.h"
#include "vrm_scene/yaml/strict_reader.h"

namespace vrm_sim {
namespace scene {
namespace {

namespace fs = std::filesystem;
constexpr double kPi = 3.14159265358979323846;
constexpr double kDegToRad = kPi / 180.0;

using yaml::Field;
using yaml::joinNames;
using yaml::MapFields;

// ---- typed readers: each fills a struct whose members already hold the defaults -------------------------------

void readPositive(MapFields& fields, const std::string& key, double& value) {
  if (auto field = fields.optional(key)) value = field->positive();
}
void readNonNegative(MapFields& fields, const std::string& key, double& value) {
  if (auto field = fields.optional(key)) value = field->nonNegative();
}
void readFinite(MapFields& fields, const std::string& key, double& value) {
  if (auto field = fields.optional(key)) value = field->finite();
}
void readInteger(MapFields& fields, const std::string& key, int& value, int minimum, int maximum) {
  if (auto field = fields.optional(key)) value = field->integer(minimum, maximum);
}
void readAngle(MapFields& fields, const std::string& key, double& value, double minimum, double maximum,
               bool minimum_inclusive = true, bool maximum_inclusive = true) {
  if (auto field = fields.optional(key)) {
    std::ostringstream expectation;
    expectation << "an angle in " << (minimum_inclusive ? "[" : "(") << minimum << ", " << maximum
                << (maximum_inclusive ? "]" : ")") << " degrees";
    value = field->number(expectation.str(), minimum, maximum, minimum_inclusive, maximum_inclusive);
  }
}
void readFraction(MapFields& fields, const std::string& key, double& value) {
  if (auto field = fields.optional(key)) value = field->number("a number in [0, 1]", 0.0, 1.0);
}

constexpr int kMaxResolution = 100000;

void readShaft(MapFields& fields, ShaftParams& shaft) {
  auto field = fields.optional("shaft");
  if (!field) return;
  MapFields shaft_fields(*field);
  readPositive(shaft_fields, "diameter", shaft.diameter);
  readPositive(shaft_fields, "length", shaft.length);
  readInteger(shaft_fields, "segments", shaft.segments, 3, 1024);
  shaft_fields.finish();
}

void readParams(MapFields& f, RetinaParams& p) {
  readPositive(f, "radius", p.radius);
  readAngle(f, "coverage_deg", p.coverage_deg, 0.0, 180.0, false, false);
  readInteger(f, "ring_count", p.ring_count, 1, 2000);
}
void readParams(MapFields& f, MembraneParams& p) {
  readPositive(f, "retina_radius", p.retina_radius);
  readNonNegative(f, "height_above_retina", p.height_above_retina);
  readPositive(f, "diameter", p.diameter);
  readInteger(f, "ring_count", p.ring_count, 1, 2000);
  readAngle(f, "centre_offset_deg", p.centre_offset_deg, 0.0, 180.0);
  readFinite(f, "centre_azimuth_deg", p.centre_azimuth_deg);
  readInteger(f, "adhesion_point_count", p.adhesion_point_count, 0, kMaxResolution);
  readFraction(f, "adhesion_ring_fraction", p.adhesion_ring_fraction);
  if (auto everywhere = f.optional("adhere_everywhere")) p.adhere_everywhere = everywhere->boolean();
  readNonNegative(f, "adhesion_disc_radius", p.adhesion_disc_radius);
  readAngle(f, "adhesion_disc_offset_deg", p.adhesion_disc_offset_deg, 0.0, 180.0);
  readFinite(f, "adhesion_disc_azimuth_deg", p.adhesion_disc_azimuth_deg);
}
void readParams(MapFields& f, SphereParams& p) {
  readPositive(f, "radius", p.radius);
  readInteger(f, "ring_count", p.ring_count, 2, 2000);
}
void readParams(MapFields& f, BoxParams& p) {
  if (auto field = f.optional("size")) {
    const auto size = field->numbers(3, "a positive number", 0.0, HUGE_VAL);
    for (int axis = 0; axis < 3; ++axis) {
      if (!(size[axis] > 0.0)) field->fail("expected three positive edge lengths");
      p.size[axis] = size[axis];
    }
  }
}
void readParams(MapFields& f, CylinderParams& p) {
  readPositive(f, "radius", p.radius);
  readPositive(f, "length", p.length);
  readInteger(f, "segments", p.segments, 3, 4096);
}
void readParams(MapFields& f, CapsuleParams& p) {
  readPositive(f, "radius", p.radius);
  readNonNegative(f, "length", p.length);
  readInteger(f, "segments", p.segments, 3, 4096);
  readInteger(f, "cap_rings", p.cap_rings, 1, 1000);
}
void readParams(MapFields& f, ConeParams& p) {
  readPositive(f, "radius", p.radius);
  readPositive(f, "height", p.height);
  readInteger(f, "segments", p.segments, 3, 4096);
}
void readParams(MapFields& f, TorusParams& p) {
  readPositive(f, "major_radius", p.major_radius);
  readPositive(f, "minor_radius", p.minor_radius);
  readInteger(f, "major_segments", p.major_segments, 3, 4096);
  readInteger(f, "minor_segments", p.minor_segments, 3, 4096);
}
void readParams(MapFields& f, DiscParams& p) {
  readPositive(f, "radius", p.radius);
  readInteger(f, "ring_count", p.ring_count, 1, 2000);
}
void readParams(MapFields& f, PlaneParams& p) {
  readPositive(f, "size_x", p.size_x);
  readPositive(f, "size_y", p.size_y);
  readInteger(f, "subdivisions", p.subdivisions, 1, 4096);
}
void readParams(MapFields& f, LightPipeParams& p) {
  readShaft(f, p.shaft);
  readPositive(f, "tip_length", p.tip_length);
  readInteger(f, "tip_rings", p.tip_rings, 1, 1000);
}
void readParams(MapFields& f, ForcepsParams& p) {
  readShaft(f, p.shaft);
  readPositive(f, "jaw_length", p.jaw_length);
  readPositive(f, "jaw_base_width", p.jaw_base_width);
  readPositive(f, "jaw_tip_width", p.jaw_tip_width);
  readPositive(f, "jaw_thickness", p.jaw_thickness);
  readAngle(f, "jaw_angle_deg", p.jaw_angle_deg, 0.0, 180.0);
}
void readParams(MapFields& f, VitrectorParams& p) {
  readShaft(f, p.shaft);
  readPositive(f, "port_distance_from_tip", p.port_distance_from_tip);
  readPositive(f, "port_length", p.port_length);
  readAngle(f, "port_width_deg", p.port_width_deg, 0.0, 180.0, false, false);
  readPositive(f, "port_depth", p.port_depth);
}
void readParams(MapFields& f, NeedleParams& p) {
  readShaft(f, p.shaft);
  readAngle(f, "bevel_angle_deg", p.bevel_angle_deg, 0.0, 90.0, false, true);
}
void readParams(MapFields& f, LaserProbeParams& p) {
  readShaft(f, p.shaft);
  readPositive(f, "fibre_diameter", p.fibre_diameter);
  if (auto field = f.optional("numerical_aperture")) {
    p.numerical_aperture = field->number("a numerical aperture in (0, 1)", 0.0, 1.0, false, false);
  }
  if (auto field = f.optional("power_mw")) p.power_mw = field->number("a power in (0, 3000] mW", 0.0, 3000.0, false);
  if (auto field = f.optional("duration_ms")) {
    p.duration_ms = field->number("an exposure in (0, 5000] ms", 0.0, 5000.0, false);
  }
  if (auto field = f.optional("interval_ms")) p.interval_ms = field->number("an interval in [0, 5000] ms", 0.0, 5000.0);
}
void readParams(MapFields& f, HookParams& p) {
  readShaft(f, p.shaft);
  readPositive(f, "hook_diameter", p.hook_diameter);
  readPositive(f, "bend_radius", p.bend_radius);
  readAngle(f, "bend_angle_deg", p.bend_angle_deg, 0.0, 180.0, false, true);
  readPositive(f, "hook_length", p.hook_length);
  readPositive(f, "neck_length", p.neck_length);
  readInteger(f, "path_samples_per_bend", p.path_samples_per_bend, 1, 1000);
}

// Parses `params` (may be absent) for the generator `params` already holds, then dry-runs the generator so that
// combinations no single field check catches (e.g. a torus tube wider than its ring) fail here, with a position.
void readGeneratorParams(const std::optional<Field>& params_field, const Field& anchor, GeneratorParams& params) {
  if (params_field) {
    MapFields fields(*params_field);
    std::visit([&fields](auto& typed) { readParams(fields, typed); }, params);
    fields.finish();
  }
  try {
    generateMesh(params);
  } catch (const std::invalid_argument& error) {
    (params_field ? *params_field : anchor).fail(error.what());
  }
}

Material readMaterial(const Field& field) {
  Material material;
  MapFields fields(field);
  if (auto diffuse = fields.optional("diffuse")) {
    const auto values = diffuse->numbers(4, "a colour component in [0, 1]", 0.0, 1.0);
    std::copy(values.begin(), values.end(), material.diffuse_rgba.begin());
  }
  if (auto specular = fields.optional("specular")) {
    const auto values = specular->numbers(3, "a colour component in [0, 1]", 0.0, 1.0);
    std::copy(values.begin(), values.end(), material.specular_rgb.begin());
  }
  readNonNegative(fields, "shininess", material.shininess);
  fields.finish();
  return material;
}

Pose readPose(const Field& field) {
  Pose pose;
  MapFields fields(field);
  if (auto xyz = fields.optional("xyz")) pose.xyz = xyz->vector3();
  if (auto rpy = fields.optional("rpy_deg")) pose.rpy_deg = rpy->vector3();
  fields.finish();
  return pose;
}

TissueParameters readTissue(const Field& field) {
  TissueParameters tissue;
  MapFields fields(field);
  // Model and integrator names are checked against their registries where the World is built (the tissue layer
  // owns them; this floor links no physics): the locations kept here give that check file:line:col.
  const Field model = fields.required("model");
  tissue.model = model.text();
  tissue.model_location = model.location();
  if (auto integrator = fields.optional("integrator")) {
    tissue.integrator = integrator->text();
    tissue.integrator_location = integrator->location();
  }
  readPositive(fields, "stiffness", tissue.stiffness);
  readNonNegative(fields, "damping", tissue.damping);
  readPositive(fields, "node_mass", tissue.node_mass);
  if (auto strain_limit = fields.optional("strain_limit")) {
    tissue.strain_limit =
        strain_limit->number("a number >= 1 (a multiple of the rest length)", 1.0, HUGE_VAL, true, false);
  }
  readNonNegative(fields, "bending_stiffness", tissue.bending_stiffness);
  readNonNegative(fields, "adhesion_stiffness", tissue.adhesion_stiffness);
  readNonNegative(fields, "adhesion_break_force", tissue.adhesion_break_force);
  if (auto f = fields.optional("adhesion_release_time")) {
    tissue.adhesion_release_time = f->number("a time in [0, 10] s", 0.0, 10.0);
  }
  if (auto f = fields.optional("adhesion_tear_force")) {
    tissue.adhesion_tear_force = f->nonNegative();
    if (tissue.adhesion_tear_force > 0.0 && !(tissue.adhesion_tear_force > tissue.adhesion_break_force)) {
      f->fail("adhesion_tear_force must exceed adhesion_break_force (else every release tears), got " + f->shown());
    }
  }
  if (auto f = fields.optional("fluid_modulus"))
    tissue.fluid_modulus = f->number("a pressure in [0, 1e7] Pa", 0.0, 1e7);
  if (auto f = fields.optional("fluid_leak_time")) {
    tissue.fluid_leak_time = f->number("a time in (0, 1000] s", 0.0, 1000.0, false);
  }
  if (auto f = fields.optional("needle_pierce_radius")) {
    tissue.needle_pierce_radius = f->number("a distance in [0, 2e-3] m", 0.0, 2e-3);
  }
  if (auto f = fields.optional("needle_slack")) tissue.needle_slack = f->number("a distance in [0, 2e-3] m", 0.0, 2e-3);
  if (auto f = fields.optional("suction_hold_radius")) {
    tissue.suction_hold_radius = f->number("a distance in [0, 2e-3] m", 0.0, 2e-3);
  }
  if (auto f = fields.optional("suction_hold_level")) {
    tissue.suction_hold_level = f->number("a suction level in (0, 1]", 0.0, 1.0, false);
  }
  readPositive(fields, "time_budget_ms", tissue.time_budget_ms);
  readPositive(fields, "dt", tissue.dt);
  if (auto plastic = fields.optional("plastic")) tissue.plastic = plastic->boolean();
  readNonNegative(fields, "early_stop_force", tissue.early_stop_force);
  if (auto tear = fields.optional("tear_strain")) {
    tissue.tear_strain =
        tear->number("0 (no tearing) or a number > 1 (a multiple of the rest length)", 0.0, HUGE_VAL, true, false);
    if (tissue.tear_strain > 0.0 && !(tissue.tear_strain > 1.0)) {
      tear->fail("expected 0 (no tearing) or a number > 1 (a multiple of the rest length), got " + tear->shown());
    }
  }
  if (auto chainmail = fields.optional("chainmail")) {
    if (tissue.model != "chainmail") chainmail->fail("chainmail limits need model: chainmail");
    MapFields limits(*chainmail);
    ChainMailParameters& c = tissue.chainmail;
    if (auto f = limits.optional("min_stretch")) c.min_stretch = f->number("a number in (0, 1]", 0.0, 1.0, false);
    if (auto f = limits.optional("max_stretch")) c.max_stretch = f->number("a number >= 1", 1.0, HUGE_VAL, true, false);
    if (auto f = limits.optional("max_shear")) c.max_shear = f->number("a number >= 0", 0.0, HUGE_VAL, true, false);
    if (auto f = limits.optional("relaxation")) c.relaxation = f->number("a number in [0, 1]", 0.0, 1.0);
    readInteger(limits, "relaxation_iterations", c.relaxation_iterations, 0, 100);
    limits.finish();
  }
  if (auto refinement = fields.optional("refinement")) {
    MapFields settings(*refinement);
    RefinementParameters& r = tissue.refinement;
    readInteger(settings, "levels", r.levels, 0, 4);
    readPositive(settings, "radius", r.radius);
    readInteger(settings, "element_budget", r.element_budget, 1, 10000000);
    if (auto f = settings.optional("chain_stiffness_scaling")) r.chain_stiffness_scaling = f->boolean();
    settings.finish();
    if (r.levels > 0) {
      if (tissue.model != "mass_spring") refinement->fail("refinement needs model: mass_spring");
      if (tissue.bending_stiffness > 0.0) refinement->fail("refinement does not support bending springs");
      if (tissue.adhesion_stiffness > 0.0) refinement->fail("refinement does not support adhesion_stiffness");
    }
  }
  fields.finish();
  return tissue;
}

CollisionParameters readCollision(const Field& field) {
  CollisionParameters collision;
  MapFields fields(field);
  if (auto detector = fields.optional("detector")) {  // checked against the detector registry with the World
    collision.detector = detector->text();
    collision.detector_location = detector->location();
  }
  readInteger(fields, "resolution", collision.resolution, 1, 16384);
  if (auto scale = fields.optional("epsilon_shell_scale")) {
    collision.epsilon_shell_scale = scale->number("a scale factor in [1, 2]", 1.0, 2.0);
  }
  fields.finish();
  return collision;
}

EyeDescription readEye(const Field& field) {
  EyeDescription eye;
  MapFields fields(field);
  readPositive(fields, "radius", eye.radius);
  if (auto centre = fields.optional("centre")) eye.centre_in_world = centre->vector3();
  if (auto rpy = fields.optional("rest_rpy_deg")) eye.rest_rpy_deg = rpy->vector3();
  if (auto trocars = fields.optional("trocars")) {
    for (const Field& item : trocars->items()) {
      MapFields trocar_fields(item);
      Trocar trocar;
      const Field name = trocar_fields.required("name");
      trocar.name = name.text();
      for (const auto& existing : eye.trocars) {
        if (existing.name == trocar.name) name.fail("duplicate trocar name '" + trocar.name + "'");
      }
      auto position = trocar_fields.optional("position");
      auto angle = trocar_fields.optional("angle_from_optical_axis_deg");
      auto azimuth = trocar_fields.optional("azimuth_deg");
      if (position && (angle || azimuth)) {
        item.fail("give either 'position' or 'angle_from_optical_axis_deg' + 'azimuth_deg', not both");
      }
      if (position) {
        trocar.position_in_eye = position->vector3();
      } else if (angle && azimuth) {
        const double polar = angle->number("an angle in [0, 180] degrees", 0.0, 180.0) * kDegToRad;
        const double around = azimuth->finite() * kDegToRad;
        trocar.position_in_eye = eye.radius * Eigen::Vector3d(std::sin(polar) * std::cos(around),
                                                              std::sin(polar) * std::sin(around), std::cos(polar));
      } else {
        item.fail("a trocar needs 'position' or both 'angle_from_optical_axis_deg' and 'azimuth_deg'");
      }
      trocar_fields.finish();
      eye.trocars.push_back(trocar);
    }
  } else {
    eye.trocars = defaultTrocars(eye.radius);
  }
  fields.finish();
  return eye;
}

// Relative to the scene file first (scene-specific assets), then to the package (shared assets).
std::string resolveMeshPath(const Field& field, const std::string& scene_file) {
  const fs::path written = field.text();
  std::vector<fs::path> candidates;
  if (written.is_absolute()) {
    candidates.push_back(written);
  } else {
    candidates.push_back(fs::absolute(scene_file).parent_path() / written);
    const std::string package = packageDirectory();
    if (!package.empty()) candidates.push_back(fs::path(package) / written);
  }
  std::string looked_in;
  for (const auto& candidate : candidates) {
    std::error_code error;
    if (fs::is_regular_file(candidate, error)) return fs::weakly_canonical(candidate).string();
    looked_in += (looked_in.empty() ? "" : ", ") + candidate.lexically_normal().string();
  }
  field.fail("mesh file '" + written.string() + "' not found (looked for " + looked_in + ")");
}

MeshSource readMeshSource(const Field& field, const EyeDescription& eye, const std::string& scene_file) {
  MeshSource source;
  MapFields fields(field);
  auto generator = fields.optional("generator");
  auto params = fields.optional("params");
  auto file = fields.optional("file");
  auto scale = fields.optional("scale");
  if (generator && file) field.fail("give either 'generator' or 'file', not both");
  if (!generator && !file) field.fail("missing 'generator' or 'file'");
  if (generator) {
    if (scale) scale->fail("'scale' applies to mesh files only; generators take their sizes in 'params'");
    const std::string name = generator->name(generatorNames());
    GeneratorParams typed = *defaultGeneratorParams(name);
    // Eye assets default to the eye's radius, so changing eye.radius keeps retina and membrane consistent.
    if (auto* retina = std::get_if<RetinaParams>(&typed)) retina->radius = eye.radius;
    if (auto* membrane = std::get_if<MembraneParams>(&typed)) membrane->retina_radius = eye.radius;
    readGeneratorParams(params, *generator, typed);
    source.generator = typed;
  } else {
    if (params) params->fail("'params' applies to generators only");
    source.file = resolveMeshPath(*file, scene_file);
    if (scale) source.scale = scale->positive();
  }
  fields.finish();
  return source;
}

ObjectDescription readObject(const Field& field, const EyeDescription& eye, const std::string& scene_file) {
  ObjectDescription object;
  object.location = field.location();
  MapFields fields(field);
  object.name = fields.required("name").text();
  object.role = fields.required("role").choice<ObjectRole>({{"retina", ObjectRole::kRetina},
                                                            {"membrane", ObjectRole::kMembrane},
                                                            {"ilm", ObjectRole::kIlm},
                                                            {"rigid", ObjectRole::kRigid},
                                                            {"abstract_target", ObjectRole::kAbstractTarget},
                                                            {"decoration", ObjectRole::kDecoration}});
  object.mesh = readMeshSource(fields.required("mesh"), eye, scene_file);
  if (auto frame = fields.optional("frame")) {
    object.frame = frame->choice<ObjectFrame>({{"eye", ObjectFrame::kEye}, {"world", ObjectFrame::kWorld}});
  }
  if (auto pose = fields.optional("pose")) object.pose = readPose(*pose);
  if (auto material = fields.optional("material")) object.material = readMaterial(*material);
  if (auto tissue = fields.optional("tissue")) {
    object.tissue = readTissue(*tissue);
    const bool rigid_role = object.role == ObjectRole::kRigid || object.role == ObjectRole::kAbstractTarget ||
                            object.role == ObjectRole::kDecoration;
    if (rigid_role && object.tissue.isDeformable()) {
      tissue->child(tissue->node()["model"], "model")
          .fail(std::string("an object with role '") + toString(object.role) + "' cannot be deformable");
    }
  }
  if (auto collision = fields.optional("collision")) object.collision = readCollision(*collision);
  fields.finish();
  return object;
}

const std::vector<std::pair<std::string, InstrumentType>>& instrumentTypeNames() {
  static const std::vector<std::pair<std::string, InstrumentType>> names = [] {
    std::vector<std::pair<std::string, InstrumentType>> result;
    for (const auto& entry : instrumentTypeRegistry().entries()) result.emplace_back(entry.name, entry.make);
    return result;
  }();
  return names;
}

// The time of a waypoint of any track: >= 0, strictly after the previous one's.
double readWaypointTime(MapFields& fields, const double* previous) {
  const Field t = fields.required("t");
  const double time = t.nonNegative();
  if (previous != nullptr && !(time > *previous)) {
    t.fail("waypoint times must increase, got " + t.shown() + " after " + std::to_string(*previous));
  }
  return time;
}

std::vector<InstrumentWaypoint> readInstrumentPath(const Field& field) {
  std::vector<InstrumentWaypoint> path;
  for (const Field& item : field.items()) {
    MapFields fields(item);
    InstrumentWaypoint waypoint;
    waypoint.location = item.location();
    waypoint.t = readWaypointTime(fields, path.empty() ? nullptr : &path.back().t);
    waypoint.tip_in_eye = fields.required("tip").vector3();
    if (auto jaw = fields.optional("jaw_angle_deg")) {
      waypoint.jaw_angle_deg = jaw->number("an angle in [0, 180] degrees", 0.0, 180.0);
    }
    readFraction(fields, "suction", waypoint.suction);
    readNonNegative(fields, "cut_rate_hz", waypoint.cut_rate_hz);
    readFinite(fields, "roll_deg", waypoint.roll_deg);
    readNonNegative(fields, "injection_flow", waypoint.injection_flow);
    if (auto type = fields.optional("type")) waypoint.type = type->choice(instrumentTypeNames());
    if (auto on = fields.optional("on")) waypoint.on = on->text();
    if (auto height = fields.optional("height")) {
      if (waypoint.on.empty()) height->fail("a height is measured above a scene object: write `on: OBJECT` with it");
      waypoint.height = height->number("a height in [-0.005, 0.005] m", -0.005, 0.005);
    }
    fields.finish();
    path.push_back(waypoint);
  }
  if (path.empty()) field.fail("expected at least one waypoint");
  return path;
}

std::vector<EyeWaypoint> readEyeTrack(const Field& field) {
  std::vector<EyeWaypoint> track;
  for (const Field& item : field.items()) {
    MapFields fields(item);
    EyeWaypoint waypoint;
    waypoint.location = item.location();
    waypoint.t = readWaypointTime(fields, track.empty() ? nullptr : &track.back().t);
    const Field rpy = fields.required("rpy_deg");
    waypoint.rpy_deg = rpy.vector3();
    // A mechanical eye turns a few degrees in its socket; more is a unit mistake (radians written as degrees).
    if (waypoint.rpy_deg.cwiseAbs().maxCoeff() > 45.0)
      rpy.fail("expected angles within +-45 degrees, got " + rpy.shown());
    fields.finish();
    track.push_back(waypoint);
  }
  if (track.empty()) field.fail("expected at least one waypoint");
  return track;
}

// Omitted keys carry over from the previous waypoint (a button pressed at one waypoint stays pressed until released).
std::vector<PedalWaypoint> readPedalTrack(const Field& field) {
  std::vector<PedalWaypoint> track;
  for (const Field& item : field.items()) {
    MapFields fields(item);
    PedalWaypoint waypoint = track.empty() ? PedalWaypoint{} : track.back();
    waypoint.location = item.location();
    waypoint.t = readWaypointTime(fields, track.empty() ? nullptr : &track.back().t);
    readFraction(fields, "travel", waypoint.travel);
    const std::pair<const char*, bool*> buttons[] = {
        {"reflux", &waypoint.reflux},         {"instrument_switch", &waypoint.instrument_switch},
        {"zoom_in", &waypoint.zoom_in},       {"zoom_out", &waypoint.zoom_out},
        {"focus_near", &waypoint.focus_near}, {"focus_far", &waypoint.focus_far}};
    for (const auto& [key, value] : buttons) {
      if (auto button = fields.optional(key)) *value = button->boolean();
    }
    fields.finish();
    track.push_back(waypoint);
  }
  if (track.empty()) field.fail("expected at least one waypoint");
  return track;
}

std::vector<MicroscopeWaypoint> readMicroscopeTrack(const Field& field) {
  std::vector<MicroscopeWaypoint> track;
  for (const Field& item : field.items()) {
    MapFields fields(item);
    MicroscopeWaypoint waypoint = track.empty() ? MicroscopeWaypoint{} : track.back();
    waypoint.location = item.location();
    waypoint.t = readWaypointTime(fields, track.empty() ? nullptr : &track.back().t);
    readPositive(fields, "focus_distance", waypoint.focus_distance);
    readPositive(fields, "zoom", waypoint.zoom);
    readFraction(fields, "ambient_light", waypoint.ambient_light);
    readFraction(fields, "disparity_scale", waypoint.disparity_scale);
    fields.finish();
    track.push_back(waypoint);
  }
  if (track.empty()) field.fail("expected at least one waypoint");
  return track;
}

PathTremor readTremor(const Field& field) {
  PathTremor tremor;
  MapFields fields(field);
  if (auto amplitude = fields.optional("amplitude")) {
    tremor.amplitude = amplitude->number("an amplitude in [0, 0.001] m", 0.0, 1e-3);
  }
  if (auto frequency = fields.optional("frequency_hz")) {
    tremor.frequency_hz = frequency->number("a frequency in (0, 100] Hz", 0.0, 100.0, false, true);
  }
  fields.finish();
  return tremor;
}

InstrumentDescription readInstrument(const Field& field, const EyeDescription& eye) {
  InstrumentDescription instrument;
  instrument.location = field.location();
  MapFields fields(field);
  instrument.slot = fields.required("slot").choice<InstrumentSlot>(
      {{"left", InstrumentSlot::kLeft}, {"right", InstrumentSlot::kRight}});
  const Field type = fields.required("type");
  instrument.type = type.choice(instrumentTypeNames());
  instrument.params = defaultInstrumentParams(instrument.type);
  readGeneratorParams(fields.optional("params"), type, instrument.params);
  const std::optional<Field> trocar = fields.optional("trocar");
  instrument.trocar = trocar ? trocar->text() : toString(instrument.slot);
  const bool trocar_exists = std::any_of(eye.trocars.begin(), eye.trocars.end(), [&instrument](const Trocar& known) {
    return known.name == instrument.trocar;
  });
  if (!trocar_exists) {
    std::vector<std::string> names;
    for (const auto& known : eye.trocars) names.push_back(known.name);
    (trocar ? *trocar : field)
        .fail("unknown trocar '" + instrument.trocar + "'" + typoSuggestion(instrument.trocar, names) +
              "; the eye has: " + joinNames(names));
  }
  if (auto alternatives = fields.optional("alternatives")) {
    for (const Field& item : alternatives->items()) {
      const InstrumentType alternative = item.choice(instrumentTypeNames());
      if (alternative == instrument.type || std::find(instrument.alternatives.begin(), instrument.alternatives.end(),
                                                      alternative) != instrument.alternatives.end()) {
        item.fail(std::string("duplicate instrument type '") + toString(alternative) + "'");
      }
      instrument.alternatives.push_back(alternative);
    }
  }
  if (auto material = fields.optional("material")) instrument.material = readMaterial(*material);
  if (auto path = fields.optional("path")) {
    instrument.path = readInstrumentPath(*path);
    // tissue_offline plays this path as written: exchanges and tips on objects are the scripted sessions' (issue 34).
    const std::vector<Field> items = path->items();
    for (std::size_t i = 0; i < instrument.path.size(); ++i) {
      if (instrument.path[i].type || !instrument.path[i].on.empty()) {
        items[i].fail("an instrument's own path takes neither `type` nor `on`: script them in scenario.scripts");
      }
    }
  }
  if (auto tremor = fields.optional("tremor")) instrument.tremor = readTremor(*tremor);
  fields.finish();
  return instrument;
}

// ---- the scenario section ----

ScenarioParam readScenarioParam(const Field& field) {
  ScenarioParam param;
  param.location = field.location();
  auto read_one = [&param](const Field& item) {
    double value = 0.0;
    if (!item.node().IsScalar() || item.node().Scalar().empty()) {
      item.fail("expected a number or a name, got " + item.shown());
    }
    const std::string& scalar = item.node().Scalar();
    char* end = nullptr;
    value = std::strtod(scalar.c_str(), &end);
    if (end == scalar.c_str() + scalar.size()) {
      if (!std::isfinite(value)) item.fail("expected a finite number, got " + item.shown());
      param.numbers.push_back(value);
    } else {
      param.names.push_back(scalar);
    }
  };
  if (field.node().IsSequence()) {
    for (const Field& item : field.items()) read_one(item);
    if (!param.numbers.empty() && !param.names.empty()) field.fail("expected numbers or names, not a mix");
  } else {
    read_one(field);
  }
  return param;
}

std::vector<ScriptedInstrument> readScriptedInstruments(const Field& field) {
  std::vector<ScriptedInstrument> script;
  for (const Field& item : field.items()) {
    MapFields fields(item);
    ScriptedInstrument part;
    part.location = item.location();
    const Field slot = fields.required("slot");
    part.slot = slot.choice<InstrumentSlot>({{"left", InstrumentSlot::kLeft}, {"right", InstrumentSlot::kRight}});
    if (auto type = fields.optional("type")) part.type = type->choice(instrumentTypeNames());
    part.path = readInstrumentPath(fields.required("path"));
    if (auto tremor = fields.optional("tremor")) part.tremor = readTremor(*tremor);
    fields.finish();
    for (const ScriptedInstrument& earlier : script) {
      if (earlier.slot == part.slot) slot.fail(std::string("slot '") + toString(part.slot) + "' is scripted twice");
    }
    script.push_back(std::move(part));
  }
  if (script.empty()) field.fail("expected at least one scripted instrument");
  return script;
}

// A scripted session: the short form (the list of instruments) or the full form (a map). A script file is the full
// form at the top level, where `name` may name it.
ScriptedSession readScript(const Field& field, const std::string& name, bool file) {
  ScriptedSession session;
  session.name = name;
  session.location = field.location();
  if (field.node().IsSequence()) {
    session.instruments = readScriptedInstruments(field);
    return session;
  }
  MapFields fields(field);
  if (file) {
    if (auto format = fields.optional("format_version")) format->integer(1, 1);
    if (auto written = fields.optional("name")) session.name = written->text();
  }
  if (auto playback = fields.optional("playback")) {
    session.playback = playback->choice<Playback>({{"once", Playback::kOnce}, {"loop", Playback::kLoop}});
  }
  if (auto missing = fields.optional("missing_objects")) {
    session.keep_tip_on_missing_object = missing->choice<bool>({{"error", false}, {"keep_tip", true}});
  }
  if (auto instruments = fields.optional("instruments")) session.instruments = readScriptedInstruments(*instruments);
  if (auto eye = fields.optional("eye")) session.eye = readEyeTrack(*eye);
  if (auto pedals = fields.optional("pedals")) session.pedals = readPedalTrack(*pedals);
  if (auto microscope = fields.optional("microscope")) session.microscope = readMicroscopeTrack(*microscope);
  fields.finish();
  if (session.instruments.empty() && session.eye.empty() && session.pedals.empty() && session.microscope.empty()) {
    field.fail("expected at least one track (instruments, eye, pedals or microscope)");
  }
  return session;
}

// Only checks the shape (levels are maps of dotted paths); applyDifficulty() resolved the paths before parsing.
void readDifficulty(const Field& field, ScenarioDescription& scenario) {
  MapFields fields(field);
  const Field levels = fields.required("levels");
  if (!levels.node().IsMap() || levels.node().size() == 0) levels.fail("expected a map of named levels");
  for (const auto& entry : levels.node()) scenario.difficulty_levels.push_back(entry.first.Scalar());
  const Field default_level = fields.required("default");
  default_level.name(scenario.difficulty_levels);
  fields.finish();
}

ScenarioDescription readScenario(const Field& field, const std::string& difficulty) {
  ScenarioDescription scenario;
  scenario.location = field.location();
  MapFields fields(field);
  // The scenario layer sits above the scene and checks the type against its registry (makeScenario, with this
  // field's location).
  const Field type = fields.required("type");
  scenario.type = type.text();
  scenario.type_location = type.location();
  if (auto description = fields.optional("description")) scenario.description = description->text();
  readNonNegative(fields, "time_limit", scenario.time_limit);
  if (auto params = fields.optional("params")) {
    MapFields param_fields(*params);
    for (const auto& entry : params->node()) {
      const std::string key = entry.first.Scalar();
      scenario.params[key] = readScenarioParam(*param_fields.optional(key));
    }
    param_fields.finish();
  }
  if (auto fail_if = fields.optional("fail_if")) {
    MapFields fail_fields(*fail_if);
    for (const auto& entry : fail_if->node()) {
      const std::string key = entry.first.Scalar();
      const Field value = *fail_fields.optional(key);
      scenario.fail_if.push_back({key, value.finite(), value.location()});
    }
    fail_fields.finish();
  }
  if (auto scoring = fields.optional("scoring")) {
    MapFields item_fields(*scoring);
    for (const auto& entry : scoring->node()) {
      const std::string key = entry.first.Scalar();
      const Field item = *item_fields.optional(key);
      ScoringRule rule;
      rule.item = key;
      rule.location = item.location();
      MapFields rule_fields(item);
      readNonNegative(rule_fields, "weight", rule.weight);
      rule.best = rule_fields.required("best").finite();
      rule.worst = rule_fields.required("worst").finite();
      rule_fields.finish();
      if (rule.best == rule.worst) item.fail("best and worst must differ");
      scenario.scoring.push_back(rule);
    }
    item_fields.finish();
    double total_weight = 0.0;
    for (const ScoringRule& rule : scenario.scoring) total_weight += rule.weight;
    if (!(total_weight > 0.0)) scoring->fail("expected at least one item with a positive weight");
  }
  if (auto levels = fields.optional("difficulty")) {
    readDifficulty(*levels, scenario);
    scenario.difficulty = difficulty;
  } else if (!difficulty.empty()) {
    field.fail("difficulty '" + difficulty + "' requested, but the scenario has no difficulty levels");
  }
  if (auto scripts = fields.optional("scripts")) {
    MapFields script_fields(*scripts);
    for (const auto& entry : scripts->node()) {
      const std::string key = entry.first.Scalar();
      scenario.scripts[key] = readScript(*script_fields.optional(key), key, false);
    }
    script_fields.finish();
  }
  fields.finish();
  return scenario;
}

// Difficulty levels override scene values by dotted path ("objects.membrane.tissue.adhesion_stiffness"; list items
// are addressed by their `name` or `slot`). The override is written into the YAML tree before it is parsed, so the
// overridden value passes the same checks as a written one and an error points at the override's line.
YAML::Node resolveOverride(YAML::Node root, const Field& key_field, const std::string& path, bool create_leaf) {
  std::vector<std::string> parts;
  std::stringstream stream(path);
  for (std::string part; std::getline(stream, part, '.');) parts.push_back(part);
  if (parts.size() < 2 || std::any_of(parts.begin(), parts.end(), [](const std::string& p) { return p.empty(); })) {
    key_field.fail("expected a dotted path such as objects.membrane.tissue.stiffness");
  }
  // Node::operator= on a valid node overwrites the node it refers to (yaml-cpp); walking uses reset() instead.
  YAML::Node node;
  node.reset(root);
  std::string walked;
  for (std::size_t i = 0; i < parts.size(); ++i) {
    const std::string& part = parts[i];
    const bool leaf = i + 1 == parts.size();
    if (node.IsSequence()) {
      std::optional<std::size_t> match;
      const YAML::Node& list = node;
      for (std::size_t j = 0; j < list.size(); ++j) {
        const YAML::Node item = list[j];
        if (!item.IsMap()) continue;
        for (const char* id_key : {"name", "slot"}) {
          if (item[id_key] && item[id_key].IsScalar() && item[id_key].Scalar() == part) match = j;
        }
      }
      if (!match) key_field.fail("'" + walked + "' has no item named '" + part + "'");
      if (leaf) key_field.fail("'" + path + "' names a whole list item; name one of its values");
      YAML::Node item = node[*match];
      node.reset(item);
    } else if (node.IsMap()) {
      const YAML::Node& lookup = node;  // const: a lookup must not insert the key
      if (!lookup[part]) {
        if (leaf && create_leaf) return node;  // the caller adds the key (the parser then checks it is allowed)
        if (leaf) return node;
        key_field.fail("'" + (walked.empty() ? part : walked + "." + part) + "' is not in the scene");
      }
      if (leaf) return node;
      YAML::Node child = node[part];
      node.reset(child);
    } else {
      key_field.fail("'" + walked + "' is a value, not a map or list");
    }
    walked += (walked.empty() ? "" : ".") + part;
  }
  return node;
}

std::string applyDifficulty(YAML::Node root, const std::string& file, const std::string& requested) {
  const YAML::Node& const_root = root;
  const YAML::Node scenario = root.IsMap() ? const_root["scenario"] : YAML::Node();
  if (!scenario || !scenario.IsMap() || !scenario["difficulty"]) return requested;
  const YAML::Node difficulty = scenario["difficulty"];
  const Field difficulty_field(difficulty, "scenario.difficulty", file);
  if (!difficulty.IsMap() || !difficulty["levels"] || !difficulty["levels"].IsMap())
    return requested;  // reported later
  const YAML::Node levels = difficulty["levels"];
  std::vector<std::string> names;
  for (const auto& entry : levels) names.push_back(entry.first.Scalar());
  std::string level = requested;
  if (level.empty()) {
    if (!difficulty["default"] || !difficulty["default"].IsScalar()) return requested;  // reported later
    level = difficulty["default"].Scalar();
  }
  if (std::find(names.begin(), names.end(), level) == names.end()) {
    difficulty_field.fail("unknown difficulty level '" + level + "'" + typoSuggestion(level, names) +
                          "; levels: " + joinNames(names));
  }
  // Every level's paths must resolve (a typo in "hard" fails even while "easy" is loaded); only `level` is applied.
  // Snapshot the overrides first: applying one changes the tree the others are resolved in.
  struct Override {
    std::string path;
    YAML::Node value;
    Field key;
  };
  std::vector<Override> chosen;
  for (const auto& entry : levels) {
    const std::string name = entry.first.Scalar();
    const Field level_field(entry.second, "scenario.difficulty.levels." + name, file);
    if (entry.second.IsNull()) continue;
    if (!entry.second.IsMap()) level_field.fail("expected a map of dotted paths to values, got " + level_field.shown());
    for (const auto& override_entry : entry.second) {
      const std::string path = override_entry.first.Scalar();
      const Field key_field(override_entry.first, level_field.path() + "." + path, file);
      if (path.rfind("scenario.difficulty", 0) == 0) key_field.fail("a level cannot change the levels");
      resolveOverride(root, key_field, path, true);
      if (name == level) chosen.push_back({path, override_entry.second, key_field});  // not a Clone: keeps its mark
    }
  }
  for (const Override& override_value : chosen) {
    YAML::Node parent = resolveOverride(root, override_value.key, override_value.path, true);
    const std::string leaf = override_value.path.substr(override_value.path.rfind('.') + 1);
    if (!parent.IsMap()) override_value.key.fail("'" + override_value.path + "' does not name a map entry");
    parent[leaf] = override_value.value;
  }
  return level;
}

SceneDescription readScene(const YAML::Node& root, const std::string& file, const std::string& difficulty) {
  const Field root_field(root, "", file);
  if (!root.IsMap())
    root_field.fail("a scene file must be a map with the keys scene, eye, objects, ...; got " + root_field.shown());
  SceneDescription scene;
  scene.source_file = file;
  MapFields fields(root_field);
  if (auto version = fields.optional("format_version")) version->integer(1, 1);

  MapFields header(fields.required("scene"));
  scene.name = header.required("name").text();
  if (auto description = header.optional("description")) scene.description = description->text();
  scene.kind = header.required("kind").choice<SceneKind>(
      {{"abstract", SceneKind::kAbstract}, {"surgical", SceneKind::kSurgical}});
  header.finish();

  if (auto eye = fields.optional("eye")) {
    scene.eye = readEye(*eye);
  } else {
    scene.eye.trocars = defaultTrocars(scene.eye.radius);
  }

  const Field objects = fields.required("objects");
  const std::vector<Field> object_items = objects.items();
  if (object_items.empty()) objects.fail("a scene needs at least one object");
  std::vector<Field> tissue_model_fields;
  for (const Field& item : object_items) {
    ObjectDescription object = readObject(item, scene.eye, file);
    if (scene.findObject(object.name) != nullptr) {
      item.child(item.node()["name"], "name").fail("duplicate object name '" + object.name + "'");
    }
    if (object.isDeformable()) {
      tissue_model_fields.push_back(
          item.child(item.node()["tissue"], "tissue").child(item.node()["tissue"]["model"], "model"));
    }
    scene.objects.push_back(std::move(object));
  }

  if (auto instruments = fields.optional("instruments")) {
    for (const Field& item : instruments->items()) {
      InstrumentDescription instrument = readInstrument(item, scene.eye);
      if (scene.findInstrument(instrument.slot) != nullptr) {
        item.fail(std::string("slot '") + toString(instrument.slot) + "' already has an instrument");
      }
      scene.instruments.push_back(std::move(instrument));
    }
  }

  const Field simulations = fields.required("simulations");
  std::vector<std::pair<std::string, Simulation>> simulation_names;
  for (Simulation simulation : {Simulation::kTissue, Simulation::kCollision, Simulation::kGrasping,
                                Simulation::kCutting, Simulation::kBleeding}) {
    simulation_names.emplace_back(toString(simulation), simulation);
  }
  for (const Field& item : simulations.items()) {
    if (!scene.simulations.insert(item.choice(simulation_names)).second) item.fail("listed twice");
  }
  if (auto scenario = fields.optional("scenario")) {
    scene.scenario = readScenario(*scenario, difficulty);
  } else if (!difficulty.empty()) {
    root_field.fail("difficulty '" + difficulty + "' requested, but the scene has no scenario section");
  }
  fields.finish();

  // The simulation skips the mass-spring model entirely when no object is deformable, so both statements must agree.
  if (scene.hasDeformableObjects() && !scene.simulates(Simulation::kTissue)) {
    tissue_model_fields.front().fail("the object is deformable but 'simulations' does not list 'tissue'");
  }
  if (!scene.hasDeformableObjects() && scene.simulates(Simulation::kTissue)) {
    simulations.fail("'tissue' is listed but no object has a tissue model other than 'none'");
  }
  if (scene.kind == SceneKind::kAbstract && scene.hasDeformableObjects()) {
    tissue_model_fields.front().fail("abstract scenes have no deformable objects (thesis §7); use kind: surgical");
  }
  return scene;
}

SceneDescription parseScene(const std::string& text, const std::string& file, const std::string& difficulty) {
  const YAML::Node root = yaml::parseText(text, file).node();
  try {
    const std::string level = applyDifficulty(root, file, difficulty);
    return readScene(root, file, level);
  } catch (const YAML::Exception& error) {  // not expected: every access above checks the node type first
    SourceLocation location;
    location.file = file;
    throw SceneError(location, std::string("unexpected YAML error: ") + error.what());
  }
}

}  // namespace

const char* const kDefaultSceneName = "membrane_peeling";

std::uint64_t sceneContentHash(const std::string& file, const std::string& difficulty) {
  std::ifstream in(file, std::ios::binary);
  if (!in) return 0;
  std::uint64_t hash = kHashSeed;
  char buffer[4096];
  while (in.read(buffer, sizeof(buffer)) || in.gcount() > 0) {
    hash = hashBytes(hash, buffer, static_cast<std::size_t>(in.gcount()));
  }
  const char separator = 0;  // between the file and the level: "a" + "bc" is not "ab" + "c"
  hash = hashBytes(hash, &separator, 1);
  return hashBytes(hash, difficulty.data(), difficulty.size());
}

SceneDescription loadScene(const std::string& name_or_path, const std::string& difficulty) {
  const std::string path = resolveScenePath(name_or_path);
  SourceLocation location;
  location.file = path;
  std::error_code error;
  if (!fs::exists(path, error)) {
    if (path == name_or_path) throw SceneError(location, "scene file not found");
    std::string shipped;
    for (const std::string& name : shippedScenes()) shipped += (shipped.empty() ? "" : ", ") + name;
    location.file = name_or_path;
    throw SceneError(location, "neither a scene file nor a shipped scene (shipped: " + shipped + ")");
  }
  return parseScene(yaml::readFile(path, "scene file"), path, difficulty);
}

SceneDescription loadSceneFromString(const std::string& yaml_text, const std::string& virtual_path,
                                     const std::string& difficulty) {
  return parseScene(yaml_text, virtual_path, difficulty);
}

ScriptedSession loadScript(const std::string& name_or_path) {
  const std::string path = resolveScriptPath(name_or_path);
  SourceLocation location;
  location.file = path;
  std::error_code error;
  if (!fs::is_regular_file(path, error)) {
    if (path == name_or_path) throw SceneError(location, "script file not found");
    std::string shipped;
    for (const std::string& name : shippedScripts()) shipped += (shipped.empty() ? "" : ", ") + name;
    location.file = name_or_path;
    throw SceneError(location, "neither a script file nor a shipped script (shipped: " + shipped + ")");
  }
  return loadScriptFromString(yaml::readFile(path, "script file"), path);
}

std::string resolveScriptPath(const std::string& name_or_path) {
  std::error_code error;
  if (fs::is_regular_file(name_or_path, error)) return name_or_path;
  if (name_or_path.find('/') != std::string::npos || name_or_path.find('.') != std::string::npos) return name_or_path;
  const std::string package = packageDirectory();
  if (package.empty()) return name_or_path;
  return (fs::path(package) / "config" / "scripts" / (name_or_path + ".yaml")).string();
}

std::vector<std::string> shippedScripts() {
  std::vector<std::string> names;
  const std::string package = packageDirectory();
  if (package.empty()) return names;
  std::error_code error;
  for (const auto& entry : fs::directory_iterator(fs::path(package) / "config" / "scripts", error)) {
    if (entry.path().extension() == ".yaml") names.push_back(entry.path().stem().string());
  }
  std::sort(names.begin(), names.end());
  return names;
}

ScriptedSession loadScriptFromString(const std::string& yaml_text, const std::string& virtual_path) {
  const Field root = yaml::parseText(yaml_text, virtual_path);
  if (!root.node().IsMap()) root.fail("expected a scripted session (a map: instruments, eye, pedals, microscope)");
  return readScript(root, fs::path(virtual_path).stem().string(), true);
}

std::string resolveScenePath(const std::string& name_or_path) {
  std::error_code error;
  if (fs::is_regular_file(name_or_path, error)) return name_or_path;
  // A path or a file name that does not exist stays itself, so loadScene reports it missing under its own name.
  if (name_or_path.find('/') != std::string::npos || name_or_path.find('.') != std::string::npos) return name_or_path;
  return shippedScenePath(name_or_path);
}

namespace {
// Set once per process by whoever knows where the package is (the ROS layer, a tool, a test); a mutex because
// nodelets of one manager set and read it from their own threads.
std::mutex package_directory_mutex;
std::string package_directory;
}  // namespace

void setPackageDirectory(const std::string& directory) {
  std::lock_guard<std::mutex> lock(package_directory_mutex);
  package_directory = directory;
}

std::string packageDirectory() {
  std::lock_guard<std::mutex> lock(package_directory_mutex);
  return package_directory;
}

std::vector<std::string> shippedScenes() {
  std::vector<std::string> names;
  const std::string package = packageDirectory();
  if (package.empty()) return names;
  std::error_code error;
  for (const auto& entry : fs::directory_iterator(fs::path(package) / "config" / "scenes", error)) {
    if (entry.path().extension() == ".yaml") names.push_back(entry.path().stem().string());
  }
  std::sort(names.begin(), names.end());
  return names;
}

std::string shippedScenePath(const std::string& scene_name) {
  const std::string package = packageDirectory();
  if (package.empty()) {
    SourceLocation location;
    location.file = scene_name;
    throw SceneError(location,
                     "not a scene file, and no shipped scenes: the vrm_sim package directory is unknown "
                     "(ROS nodes and tools: vrm_sim must be on ROS_PACKAGE_PATH, source setup.bash; "
                     "ROS-free code: scene::setPackageDirectory)");
  }
  return (fs::path(package) / "config" / "scenes" / (scene_name + ".yaml")).string();
}

TriangleMesh buildMesh(const ObjectDescription& object, MeshFrame frame) {
  TriangleMesh mesh;
  SourceLocation location = object.location;
  location.field += location.field.empty() ? "mesh" : ".mesh";
  if (object.mesh.generator) {
    try {
      mesh = generateMesh(*object.mesh.generator);
    } catch (const std::invalid_argument& error) {
      throw SceneError(location, error.what());
    }
  } else {
    MeshImportOptions options;
    options.scale = object.mesh.scale;
    try {
      mesh = importMesh(object.mesh.file, options);
    } catch (const MeshIoError& error) {
      throw SceneError(location, error.what());
    }
  }
  mesh.name = object.name;
  if (frame == MeshFrame::kParent) transformMesh(mesh, object.pose.toIsometry());
  return mesh;
}

std::vector<TriangleMesh> resolveMeshes(const SceneDescription& scene) {
  std::vector<TriangleMesh> meshes;
  meshes.reserve(scene.objects.size());
  for (const auto& object : scene.objects) meshes.push_back(buildMesh(object, MeshFrame::kParent));
  return meshes;
}

TriangleMesh buildInstrumentMesh(const InstrumentDescription& instrument) {
  try {
    TriangleMesh mesh = generateMesh(instrument.params);
    mesh.name = std::string(toString(instrument.slot)) + "_" + toString(instrument.type);
    return mesh;
  } catch (const std::invalid_argument& error) {
    throw SceneError(instrument.location, error.what());
  }
}

}  // namespace scene
}  // namespace vrm_sim
