#include "vrm_tracking/marker_layout.h"

#include <cmath>
#include <string>
#include <vector>

#include "vrm_scene/yaml/strict_reader.h"

namespace vrm_tracking {

namespace {
constexpr double kPi = 3.14159265358979323846;

Eigen::Vector3d spherical(double radius, double polar_from_minus_z_deg, double azimuth_deg) {
  const double p = polar_from_minus_z_deg * kPi / 180.0, a = azimuth_deg * kPi / 180.0;
  return radius * Eigen::Vector3d(std::sin(p) * std::cos(a), std::sin(p) * std::sin(a), -std::cos(p));
}

ColourClass makeClass(int id, const std::string& name, std::array<std::uint8_t, 3> bgr, double h_min, double h_max) {
  ColourClass c;
  c.id = id;
  c.name = name;
  c.bgr = bgr;
  c.h_min = h_min;
  c.h_max = h_max;
  return c;
}

using vrm_sim::yaml::Field;
using vrm_sim::yaml::MapFields;

void readNumber(MapFields& fields, const std::string& key, double& value, const std::string& expectation,
                double minimum, double maximum) {
  if (auto field = fields.optional(key)) value = field->number(expectation, minimum, maximum);
}

ColourClass readClass(const Field& field, int id) {
  ColourClass c;
  c.id = id;
  MapFields fields(field);
  c.name = fields.required("name").text();
  if (auto bgr = fields.optional("bgr")) {
    const std::vector<double> values = bgr->numbers(3, "an integer in [0, 255]", 0.0, 255.0);
    for (int k = 0; k < 3; ++k) {
      if (values[k] != std::floor(values[k])) bgr->fail("expected three integers in [0, 255]");
      c.bgr[k] = static_cast<std::uint8_t>(values[k]);
    }
  }
  readNumber(fields, "h_min", c.h_min, "a hue in [0, 360] degrees", 0.0, 360.0);
  readNumber(fields, "h_max", c.h_max, "a hue in [0, 360] degrees", 0.0, 360.0);
  readNumber(fields, "chroma_min", c.chroma_min, "a chroma in [0, 255]", 0.0, 255.0);
  readNumber(fields, "s_min", c.s_min, "a saturation in [0, 1]", 0.0, 1.0);
  readNumber(fields, "v_min", c.v_min, "a value in [0, 255]", 0.0, 255.0);
  readNumber(fields, "area_min", c.area_min, "a non-negative area in px^2", 0.0, HUGE_VAL);
  readNumber(fields, "area_max", c.area_max, "a positive area in px^2", 0.0, HUGE_VAL);
  readNumber(fields, "roundness_min", c.roundness_min, "a roundness in [0, 1]", 0.0, 1.0);
  fields.finish();
  if (!(c.area_max > c.area_min)) field.fail("area_max must be larger than area_min");
  return c;
}
}  // namespace

const ColourClass* MarkerLayout::findClass(int id) const {
  for (const ColourClass& c : classes) {
    if (c.id == id) return &c;
  }
  return nullptr;
}

const InstrumentMarker* MarkerLayout::findSlot(const std::string& slot) const {
  for (const InstrumentMarker& m : instruments) {
    if (m.slot == slot) return &m;
  }
  return nullptr;
}

MarkerLayout makeDefaultLayout() {
  MarkerLayout layout;
  layout.classes.push_back(makeClass(0, "eye_a", {{40, 40, 230}}, 340.0, 20.0));      // red
  layout.classes.push_back(makeClass(1, "eye_b", {{230, 90, 30}}, 200.0, 250.0));     // blue
  layout.classes.push_back(makeClass(2, "tip_left", {{50, 220, 50}}, 90.0, 150.0));   // green
  layout.classes.push_back(makeClass(3, "tip_right", {{30, 220, 230}}, 40.0, 75.0));  // yellow
  const double r = 0.012;
  layout.eye_markers.push_back({0, spherical(r, 60.0, 0.0)});
  layout.eye_markers.push_back({1, spherical(r, 60.0, 90.0)});
  const double s45 = std::sin(kPi / 4.0) * r, c45 = std::cos(kPi / 4.0) * r;
  layout.instruments.push_back(
      {"left", 2, Eigen::Vector3d(s45 * std::cos(150.0 * kPi / 180.0), s45 * std::sin(150.0 * kPi / 180.0), c45)});
  layout.instruments.push_back(
      {"right", 3, Eigen::Vector3d(s45 * std::cos(30.0 * kPi / 180.0), s45 * std::sin(30.0 * kPi / 180.0), c45)});
  return layout;
}

MarkerLayout layoutFromYamlString(const std::string& text, const std::string& source) {
  MarkerLayout layout = makeDefaultLayout();
  const Field root = vrm_sim::yaml::parseText(text, source);
  MapFields fields(root);
  if (auto classes = fields.optional("classes")) {
    layout.classes.clear();
    for (const Field& entry : classes->items()) {
      ColourClass c = readClass(entry, static_cast<int>(layout.classes.size()));
      for (const ColourClass& other : layout.classes) {
        if (other.name == c.name) entry.fail("a second colour class named '" + c.name + "'");
      }
      layout.classes.push_back(c);
    }
    if (layout.classes.empty()) classes->fail("expected at least one colour class");
  }
  std::vector<std::string> class_names;
  for (const ColourClass& c : layout.classes) class_names.push_back(c.name);
  // A class by name, with a typo hint and file:line:col when the file has no such class.
  auto classId = [&](MapFields& marker) {
    const std::string name = marker.required("class").name(class_names);
    for (const ColourClass& c : layout.classes) {
      if (c.name == name) return c.id;
    }
    return -1;  // not reached: name() accepts only class_names
  };
  if (auto eye = fields.optional("eye_markers")) {
    layout.eye_markers.clear();
    for (const Field& entry : eye->items()) {
      MapFields marker(entry);
      EyeMarker m;
      m.class_id = classId(marker);
      m.position = marker.required("position").vector3();
      marker.finish();
      layout.eye_markers.push_back(m);
    }
    if (layout.eye_markers.size() != 2) eye->fail("exactly two eye markers are needed for the eye's pose");
  }
  if (auto instruments = fields.optional("instruments")) {
    layout.instruments.clear();
    for (const Field& entry : instruments->items()) {
      MapFields marker(entry);
      InstrumentMarker m;
      m.slot = marker.required("slot").text();
      for (const InstrumentMarker& other : layout.instruments) {
        if (other.slot == m.slot) entry.fail("a second marker for slot '" + m.slot + "'");
      }
      m.class_id = classId(marker);
      if (auto trocar = marker.optional("trocar")) {
        m.trocar = trocar->vector3();
      } else {
        m.trocar_from_scene = true;  // the scene's (applySceneTrocars)
      }
      marker.finish();
      layout.instruments.push_back(m);
    }
  }
  if (auto centre = fields.optional("rotation_center")) layout.rotation_center = centre->vector3();
  if (auto radius = fields.optional("eye_marker_radius")) layout.eye_marker_radius = radius->positive();
  if (auto radius = fields.optional("tip_marker_radius")) layout.tip_marker_radius = radius->positive();
  if (auto radius = fields.optional("shaft_radius")) layout.shaft_radius = radius->positive();
  if (auto length = fields.optional("shaft_length")) layout.shaft_length = length->positive();
  fields.finish();
  // Classes replaced without eye markers: the default markers' class ids may name no class any more.
  for (const EyeMarker& m : layout.eye_markers) {
    if (!layout.findClass(m.class_id)) root.fail("the default eye markers' classes are gone: give eye_markers too");
  }
  for (const InstrumentMarker& m : layout.instruments) {
    if (!layout.findClass(m.class_id))
      root.fail("the default instrument markers' classes are gone: give instruments too");
  }
  return layout;
}

MarkerLayout loadLayoutYaml(const std::string& path) {
  return layoutFromYamlString(vrm_sim::yaml::readFile(path, "marker layout"), path);
}

WorldScene worldSceneFromSnapshot(const SurgeonSnapshot& snap, const MarkerLayout& layout) {
  WorldScene scene;
  const Eigen::Quaterniond q = snap.eye_rotation.normalized();
  auto toWorld = [&](const Eigen::Vector3d& p_eye) -> Eigen::Vector3d { return snap.rotation_center + q * p_eye; };
  for (const EyeMarker& m : layout.eye_markers) {
    scene.markers.push_back({m.class_id, toWorld(m.position), Eigen::Vector3d::Zero(), layout.eye_marker_radius});
  }
  for (const InstrumentSample& s : snap.instruments) {
    const InstrumentMarker* slot = layout.findSlot(s.slot);
    if (!slot) continue;
    scene.markers.push_back({slot->class_id, toWorld(s.tip), Eigen::Vector3d::Zero(), layout.tip_marker_radius});
    // The shaft starts behind the tip marker (the marker is the tip) and runs out through the trocar.
    const Eigen::Vector3d axis = (s.tip - s.trocar).normalized();
    scene.shafts.push_back({toWorld(s.tip - axis * 1.5 * layout.tip_marker_radius),
                            toWorld(s.trocar - axis * layout.shaft_length), layout.shaft_radius});
  }
  return scene;
}

void setVelocities(const WorldScene& before, const WorldScene& after, double dt, WorldScene* scene) {
  for (std::size_t i = 0; i < scene->markers.size() && i < before.markers.size() && i < after.markers.size(); ++i) {
    scene->markers[i].velocity = (after.markers[i].position - before.markers[i].position) / dt;
  }
}

}  // namespace vrm_tracking
