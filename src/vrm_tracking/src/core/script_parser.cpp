// YAML reader for SurgeonScript (schema: config/trajectories/README.md). Every error names file, line and field
// path, because scripts are written by hand (instructors, scenario authors) and a silent default is worse than a
// refusal.

#include <yaml-cpp/yaml.h>

#include <cmath>
#include <fstream>
#include <initializer_list>
#include <sstream>

#include "vrm_tracking/surgeon_script.h"

namespace vrm_tracking {

namespace {

constexpr double kDegToRad = 3.14159265358979323846 / 180.0;

class Parser {
 public:
  explicit Parser(std::string source) : source_(std::move(source)) {}

  ScriptDefinition parse(const YAML::Node& root) {
    ScriptDefinition d;
    d.source = source_;
    if (!root.IsMap()) fail(root, "", "top level must be a mapping");
    checkKeys(root, "", {"name", "playback", "eye", "eye_track", "instruments", "pedal_track", "microscope_track"});
    d.name = root["name"] ? readString(root["name"], "name") : std::string("unnamed");
    if (const YAML::Node playback = root["playback"]) {
      const std::string mode = readString(playback, "playback");
      if (mode == "once") {
        d.playback = Playback::kOnce;
      } else if (mode == "loop") {
        d.playback = Playback::kLoop;
      } else {
        fail(playback, "playback", "must be 'once' or 'loop', got '" + mode + "'");
      }
    }
    if (const YAML::Node eye = root["eye"]) {
      parseEye(eye, &d.eye);
    } else {
      d.eye.from_scene = true;  // the scene's (applySceneTrocars)
    }
    if (const YAML::Node track = root["eye_track"]) parseEyeTrack(track, &d.eye_track);
    if (const YAML::Node instruments = root["instruments"]) {
      if (!instruments.IsMap()) fail(instruments, "instruments", "must be a mapping slot -> track");
      for (const auto& entry : instruments) {
        d.instruments.push_back(parseInstrumentTrack(entry.first, entry.second));
      }
    }
    if (const YAML::Node track = root["pedal_track"]) parsePedalTrack(track, &d.pedal_track);
    if (const YAML::Node track = root["microscope_track"]) parseMicroscopeTrack(track, &d.microscope_track);
    return d;
  }

 private:
  static int lineOf(const YAML::Node& node) {
    const YAML::Mark mark = node.Mark();
    return mark.is_null() ? 0 : mark.line + 1;
  }

  [[noreturn]] void fail(const YAML::Node& node, const std::string& field, const std::string& message) const {
    throw ScriptError(source_, lineOf(node), field, message);
  }

  static std::string join(const std::string& base, const std::string& key) {
    return base.empty() ? key : base + "." + key;
  }

  // Unknown keys are errors: a misspelt "jaw_agnle" would otherwise silently keep the previous value.
  void checkKeys(const YAML::Node& map, const std::string& field, std::initializer_list<const char*> allowed) const {
    for (const auto& entry : map) {
      const std::string key = entry.first.Scalar();
      bool known = false;
      for (const char* name : allowed) known = known || key == name;
      if (!known) {
        std::string list;
        for (const char* name : allowed) list += std::string(list.empty() ? "" : ", ") + name;
        fail(entry.first, join(field, key), "unknown key (allowed: " + list + ")");
      }
    }
  }

  double readDouble(const YAML::Node& node, const std::string& field) const {
    if (!node.IsScalar()) fail(node, field, "expected a number");
    double value = 0.0;
    try {
      value = node.as<double>();
    } catch (const YAML::Exception&) {
      fail(node, field, "expected a number, got '" + node.Scalar() + "'");
    }
    if (!std::isfinite(value)) fail(node, field, "must be finite (NaN/inf rejected)");
    return value;
  }

  bool readBool(const YAML::Node& node, const std::string& field) const {
    if (!node.IsScalar()) fail(node, field, "expected true or false");
    try {
      return node.as<bool>();
    } catch (const YAML::Exception&) {
      fail(node, field, "expected true or false, got '" + node.Scalar() + "'");
    }
  }

  std::string readString(const YAML::Node& node, const std::string& field) const {
    if (!node.IsScalar()) fail(node, field, "expected a string");
    return node.Scalar();
  }

  Eigen::Vector3d readVector3(const YAML::Node& node, const std::string& field) const {
    if (!node.IsSequence() || node.size() != 3) fail(node, field, "expected a sequence of 3 numbers [x, y, z]");
    return Eigen::Vector3d(readDouble(node[0], field + "[0]"), readDouble(node[1], field + "[1]"),
                           readDouble(node[2], field + "[2]"));
  }

  void readOptional(const YAML::Node& map, const char* key, const std::string& base, double* value) const {
    if (const YAML::Node node = map[key]) *value = readDouble(node, join(base, key));
  }

  void readOptional(const YAML::Node& map, const char* key, const std::string& base, bool* value) const {
    if (const YAML::Node node = map[key]) *value = readBool(node, join(base, key));
  }

  const YAML::Node requireSequence(const YAML::Node& node, const std::string& field) const {
    if (!node.IsSequence()) fail(node, field, "expected a sequence of keyframes");
    return node;
  }

  // Every keyframe of every track needs its own time; the rest of its fields default to the previous keyframe.
  double readTime(const YAML::Node& keyframe, const std::string& base) const {
    if (!keyframe.IsMap()) fail(keyframe, base, "keyframe must be a mapping with at least 't'");
    const YAML::Node t = keyframe["t"];
    if (!t) fail(keyframe, join(base, "t"), "missing keyframe time");
    return readDouble(t, join(base, "t"));
  }

  void parseEye(const YAML::Node& eye, EyeGeometry* geometry) const {
    if (!eye.IsMap()) fail(eye, "eye", "must be a mapping");
    checkKeys(eye, "eye", {"radius", "margin", "rotation_center"});
    geometry->line = lineOf(eye);
    readOptional(eye, "radius", "eye", &geometry->radius);
    readOptional(eye, "margin", "eye", &geometry->margin);
    if (eye["rotation_center"]) geometry->rotation_center = readVector3(eye["rotation_center"], "eye.rotation_center");
  }

  void parseEyeTrack(const YAML::Node& track, std::vector<EyeKeyframe>* keys) const {
    requireSequence(track, "eye_track");
    for (std::size_t i = 0; i < track.size(); ++i) {
      const YAML::Node k = track[i];
      const std::string base = "eye_track[" + std::to_string(i) + "]";
      EyeKeyframe key = keys->empty() ? EyeKeyframe{} : keys->back();
      key.t = readTime(k, base);
      key.line = lineOf(k);
      checkKeys(k, base, {"t", "rpy", "rpy_deg", "quaternion"});
      const int given = (k["rpy"] ? 1 : 0) + (k["rpy_deg"] ? 1 : 0) + (k["quaternion"] ? 1 : 0);
      if (given > 1) fail(k, base, "give only one of rpy, rpy_deg, quaternion");
      if (k["rpy"] || k["rpy_deg"]) {
        const bool degrees = static_cast<bool>(k["rpy_deg"]);
        const std::string field = join(base, degrees ? "rpy_deg" : "rpy");
        const Eigen::Vector3d rpy = readVector3(k[degrees ? "rpy_deg" : "rpy"], field) * (degrees ? kDegToRad : 1.0);
        // Fixed-axis roll (x), pitch (y), yaw (z): R = Rz(yaw) Ry(pitch) Rx(roll), as in tf2/URDF.
        key.rotation = Eigen::AngleAxisd(rpy.z(), Eigen::Vector3d::UnitZ()) *
                       Eigen::AngleAxisd(rpy.y(), Eigen::Vector3d::UnitY()) *
                       Eigen::AngleAxisd(rpy.x(), Eigen::Vector3d::UnitX());
      } else if (const YAML::Node q = k["quaternion"]) {
        const std::string field = join(base, "quaternion");
        // Named components, so nobody has to guess between [w, x, y, z] and [x, y, z, w].
        if (!q.IsMap()) fail(q, field, "expected a mapping {w, x, y, z}");
        checkKeys(q, field, {"w", "x", "y", "z"});
        for (const char* c : {"w", "x", "y", "z"}) {
          if (!q[c]) fail(q, join(field, c), "missing quaternion component");
        }
        Eigen::Quaterniond rotation(readDouble(q["w"], join(field, "w")), readDouble(q["x"], join(field, "x")),
                                    readDouble(q["y"], join(field, "y")), readDouble(q["z"], join(field, "z")));
        if (rotation.norm() < 1e-9) fail(q, field, "quaternion has zero norm");
        key.rotation = rotation.normalized();
      } else if (keys->empty()) {
        key.rotation = Eigen::Quaterniond::Identity();
      }
      keys->push_back(key);
    }
  }

  InstrumentTrack parseInstrumentTrack(const YAML::Node& name, const YAML::Node& node) const {
    InstrumentTrack track;
    track.slot = readString(name, "instruments");
    track.line = lineOf(name);
    const std::string base = "instruments." + track.slot;
    if (!node.IsMap()) fail(node, base, "must be a mapping with keyframes (and type, trocar)");
    checkKeys(node, base, {"trocar", "type", "keyframes"});
    if (node["trocar"]) {
      track.trocar = readVector3(node["trocar"], join(base, "trocar"));
    } else {
      track.trocar_from_scene = true;  // the scene's (applySceneTrocars)
    }
    bool have_type = false;
    vrm_sim::scene::InstrumentType slot_type = vrm_sim::scene::InstrumentType::kLightPipe;
    if (const YAML::Node type = node["type"]) {
      slot_type = readType(type, join(base, "type"));
      have_type = true;
    }
    const YAML::Node keys = node["keyframes"];
    if (!keys) fail(node, join(base, "keyframes"), "missing");
    requireSequence(keys, join(base, "keyframes"));
    for (std::size_t i = 0; i < keys.size(); ++i) {
      const YAML::Node k = keys[i];
      const std::string kb = join(base, "keyframes[" + std::to_string(i) + "]");
      InstrumentKeyframe key;
      if (track.keyframes.empty()) {
        key.type = slot_type;
      } else {
        key = track.keyframes.back();
      }
      key.t = readTime(k, kb);
      key.line = lineOf(k);
      checkKeys(k, kb,
                {"t", "type", "tip", "on", "height", "roll", "jaw_angle", "suction", "cut_rate", "injection_flow"});
      if (const YAML::Node type = k["type"]) {
        key.type = readType(type, join(kb, "type"));
      } else if (track.keyframes.empty() && !have_type) {
        fail(k, join(kb, "type"), "missing: give the instrument type in the slot or its first keyframe");
      }
      parseTipPosition(k, kb, track.keyframes.empty(), &key);
      readOptional(k, "roll", kb, &key.roll);
      readOptional(k, "jaw_angle", kb, &key.jaw_angle);
      readOptional(k, "suction", kb, &key.suction);
      readOptional(k, "cut_rate", kb, &key.cut_rate);
      readOptional(k, "injection_flow", kb, &key.injection_flow);
      track.keyframes.push_back(key);
    }
    return track;
  }

  // A keyframe that writes `tip` or `on` starts a new position, either plain or on a scene object; nothing of the
  // previous keyframe's surface target carries over then (a plain `tip` after an `on` keyframe is plain again).
  // A keyframe that writes neither keeps the previous position, target included. `height` belongs to `on`: it is
  // measured from that object's surface, so it may not stand alone.
  void parseTipPosition(const YAML::Node& k, const std::string& kb, bool first, InstrumentKeyframe* key) const {
    const YAML::Node tip = k["tip"];
    const YAML::Node on = k["on"];
    const YAML::Node height = k["height"];
    if (height && !on) fail(height, join(kb, "height"), "needs 'on' in the same keyframe (the object it is above)");
    if (tip) {
      key->tip = readVector3(tip, join(kb, "tip"));
    } else if (first) {
      fail(k, join(kb, "tip"), "missing: the first keyframe of a slot needs a tip position");
    }
    if (!tip && !on) return;
    key->target = SurfaceTarget{};
    if (!on) return;
    key->target.object = readString(on, join(kb, "on"));
    if (key->target.object.empty()) fail(on, join(kb, "on"), "must name an object of the scene");
    if (height) key->target.height = readDouble(height, join(kb, "height"));
    key->target.written_tip = key->tip;  // `on` without `tip`: the previous keyframe's written tip
  }

  // vrm_sim's instrument type table (instrumentTypeRegistry), so scripts and scenes spell instruments alike.
  vrm_sim::scene::InstrumentType readType(const YAML::Node& node, const std::string& field) const {
    const std::string name = readString(node, field);
    if (const auto type = vrm_sim::scene::instrumentTypeNamed(name)) return *type;
    std::string expected;
    for (const std::string& known : vrm_sim::scene::instrumentTypeRegistry().names()) {
      expected += (expected.empty() ? "" : "|") + known;
    }
    fail(node, field, "unknown instrument type '" + name + "' (expected " + expected + ")");
  }

  void parsePedalTrack(const YAML::Node& track, std::vector<PedalKeyframe>* keys) const {
    requireSequence(track, "pedal_track");
    for (std::size_t i = 0; i < track.size(); ++i) {
      const YAML::Node k = track[i];
      const std::string base = "pedal_track[" + std::to_string(i) + "]";
      PedalKeyframe key = keys->empty() ? PedalKeyframe{} : keys->back();
      key.t = readTime(k, base);
      key.line = lineOf(k);
      checkKeys(k, base,
                {"t", "travel", "reflux", "instrument_switch", "zoom_in", "zoom_out", "focus_near", "focus_far"});
      readOptional(k, "travel", base, &key.value.travel);
      readOptional(k, "reflux", base, &key.value.reflux);
      readOptional(k, "instrument_switch", base, &key.value.instrument_switch);
      readOptional(k, "zoom_in", base, &key.value.zoom_in);
      readOptional(k, "zoom_out", base, &key.value.zoom_out);
      readOptional(k, "focus_near", base, &key.value.focus_near);
      readOptional(k, "focus_far", base, &key.value.focus_far);
      keys->push_back(key);
    }
  }

  void parseMicroscopeTrack(const YAML::Node& track, std::vector<MicroscopeKeyframe>* keys) const {
    requireSequence(track, "microscope_track");
    for (std::size_t i = 0; i < track.size(); ++i) {
      const YAML::Node k = track[i];
      const std::string base = "microscope_track[" + std::to_string(i) + "]";
      MicroscopeKeyframe key = keys->empty() ? MicroscopeKeyframe{} : keys->back();
      key.t = readTime(k, base);
      key.line = lineOf(k);
      checkKeys(k, base, {"t", "focus_distance", "zoom", "ambient_light", "disparity_scale"});
      readOptional(k, "focus_distance", base, &key.value.focus_distance);
      readOptional(k, "zoom", base, &key.value.zoom);
      readOptional(k, "ambient_light", base, &key.value.ambient_light);
      readOptional(k, "disparity_scale", base, &key.value.disparity_scale);
      keys->push_back(key);
    }
  }

  std::string source_;
};

ScriptDefinition parseDocument(const std::string& text, const std::string& source) {
  YAML::Node root;
  try {
    root = YAML::Load(text);
  } catch (const YAML::ParserException& e) {
    throw ScriptError(source, e.mark.is_null() ? 0 : e.mark.line + 1, "", "YAML syntax error: " + e.msg);
  }
  if (!root || root.IsNull()) throw ScriptError(source, 1, "", "empty script");
  return Parser(source).parse(root);
}

}  // namespace

SurgeonScript SurgeonScript::fromYamlString(const std::string& text, const std::string& source) {
  return SurgeonScript(parseDocument(text, source));
}

ScriptDefinition SurgeonScript::definitionFromFile(const std::string& path) {
  std::ifstream file(path);
  if (!file) throw ScriptError(path, 0, "", "cannot open trajectory file");
  std::stringstream text;
  text << file.rdbuf();
  return parseDocument(text.str(), path);
}

SurgeonScript SurgeonScript::fromFile(const std::string& path) { return SurgeonScript(definitionFromFile(path)); }

}  // namespace vrm_tracking
