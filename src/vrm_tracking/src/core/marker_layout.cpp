#include "vrm_tracking/marker_layout.h"

#include <yaml-cpp/yaml.h>

#include <cmath>
#include <fstream>
#include <map>
#include <sstream>
#include <stdexcept>

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

Eigen::Vector3d readVector(const YAML::Node& node, const std::string& source, const std::string& field) {
  if (!node || !node.IsSequence() || node.size() != 3)
    throw std::runtime_error(source + ": " + field + ": expected [x, y, z]");
  Eigen::Vector3d v(node[0].as<double>(), node[1].as<double>(), node[2].as<double>());
  if (!v.allFinite()) throw std::runtime_error(source + ": " + field + ": not finite");
  return v;
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
  YAML::Node root;
  try {
    root = YAML::Load(text);
    if (!root || !root.IsMap()) throw std::runtime_error(source + ": expected a map");
    std::map<std::string, int> ids;
    if (const YAML::Node classes = root["classes"]) {
      layout.classes.clear();
      for (std::size_t i = 0; i < classes.size(); ++i) {
        const YAML::Node n = classes[i];
        const std::string field = "classes[" + std::to_string(i) + "]";
        ColourClass c;
        c.id = static_cast<int>(i);
        if (!n["name"]) throw std::runtime_error(source + ": " + field + ".name: missing");
        c.name = n["name"].as<std::string>();
        if (n["bgr"]) {
          for (int k = 0; k < 3; ++k) c.bgr[k] = static_cast<std::uint8_t>(n["bgr"][k].as<int>());
        }
        c.h_min = n["h_min"].as<double>(c.h_min);
        c.h_max = n["h_max"].as<double>(c.h_max);
        c.chroma_min = n["chroma_min"].as<double>(c.chroma_min);
        c.s_min = n["s_min"].as<double>(c.s_min);
        c.v_min = n["v_min"].as<double>(c.v_min);
        c.area_min = n["area_min"].as<double>(c.area_min);
        c.area_max = n["area_max"].as<double>(c.area_max);
        c.roundness_min = n["roundness_min"].as<double>(c.roundness_min);
        if (!(c.area_min >= 0 && c.area_max > c.area_min)) {
          throw std::runtime_error(source + ": " + field + ": area_min/area_max inconsistent");
        }
        ids[c.name] = c.id;
        layout.classes.push_back(c);
      }
    } else {
      for (const ColourClass& c : layout.classes) ids[c.name] = c.id;
    }
    auto classId = [&](const YAML::Node& n, const std::string& field) {
      if (!n) throw std::runtime_error(source + ": " + field + ": missing");
      const auto it = ids.find(n.as<std::string>());
      if (it == ids.end())
        throw std::runtime_error(source + ": " + field + ": unknown class '" + n.as<std::string>() + "'");
      return it->second;
    };
    if (const YAML::Node eye = root["eye_markers"]) {
      layout.eye_markers.clear();
      for (std::size_t i = 0; i < eye.size(); ++i) {
        const std::string field = "eye_markers[" + std::to_string(i) + "]";
        layout.eye_markers.push_back(
            {classId(eye[i]["class"], field + ".class"), readVector(eye[i]["position"], source, field + ".position")});
      }
    }
    if (const YAML::Node inst = root["instruments"]) {
      layout.instruments.clear();
      for (std::size_t i = 0; i < inst.size(); ++i) {
        const std::string field = "instruments[" + std::to_string(i) + "]";
        if (!inst[i]["slot"]) throw std::runtime_error(source + ": " + field + ".slot: missing");
        InstrumentMarker marker;
        marker.slot = inst[i]["slot"].as<std::string>();
        marker.class_id = classId(inst[i]["class"], field + ".class");
        if (inst[i]["trocar"]) {
          marker.trocar = readVector(inst[i]["trocar"], source, field + ".trocar");
        } else {
          marker.trocar_from_scene = true;  // the scene's (applySceneTrocars)
        }
        layout.instruments.push_back(marker);
      }
    }
    if (root["rotation_center"])
      layout.rotation_center = readVector(root["rotation_center"], source, "rotation_center");
    layout.eye_marker_radius = root["eye_marker_radius"].as<double>(layout.eye_marker_radius);
    layout.tip_marker_radius = root["tip_marker_radius"].as<double>(layout.tip_marker_radius);
  } catch (const YAML::Exception& e) {
    throw std::runtime_error(source + ": " + e.what());
  }
  if (layout.eye_markers.size() != 2) throw std::runtime_error(source + ": eye_markers: exactly two are needed");
  return layout;
}

MarkerLayout loadLayoutYaml(const std::string& path) {
  std::ifstream file(path);
  if (!file) throw std::runtime_error(path + ": cannot open marker layout");
  std::stringstream buffer;
  buffer << file.rdbuf();
  return layoutFromYamlString(buffer.str(), path);
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
