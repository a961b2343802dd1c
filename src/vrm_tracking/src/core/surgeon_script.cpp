#include "vrm_tracking/surgeon_script.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <set>
#include <sstream>

namespace vrm_tracking {

namespace {

constexpr double kPi = 3.14159265358979323846;

std::string formatError(const std::string& source, int line, const std::string& field, const std::string& message) {
  std::ostringstream out;
  out << source << ":" << line << ": ";
  if (!field.empty()) out << field << ": ";
  out << message;
  return out.str();
}

// Keyframe segment containing t: keys[index].t <= t < keys[index + 1].t, alpha in [0, 1). Before the first
// keyframe and after the last one the track holds its end value (alpha = 0).
template <class Key>
std::size_t findSegment(const std::vector<Key>& keys, double t, double* alpha) {
  *alpha = 0.0;
  if (keys.size() < 2 || t <= keys.front().t) return 0;
  if (t >= keys.back().t) return keys.size() - 1;
  const auto next = std::upper_bound(keys.begin(), keys.end(), t, [](double v, const Key& k) { return v < k.t; });
  const std::size_t index = static_cast<std::size_t>(next - keys.begin()) - 1;
  *alpha = (t - keys[index].t) / (keys[index + 1].t - keys[index].t);
  return index;
}

double lerp(double a, double b, double alpha) { return a + alpha * (b - a); }

Eigen::Vector3d lerp(const Eigen::Vector3d& a, const Eigen::Vector3d& b, double alpha) { return a + alpha * (b - a); }

std::string indexed(const std::string& base, std::size_t index) { return base + "[" + std::to_string(index) + "]"; }

}  // namespace

// ---------------------------------------------------------------------------------------------------------------

ScriptError::ScriptError(const std::string& source, int line, const std::string& field, const std::string& message)
    : std::runtime_error(formatError(source, line, field, message)), source_(source), line_(line), field_(field) {}

Eigen::Quaterniond shaftOrientation(const Eigen::Vector3d& trocar, const Eigen::Vector3d& shaft_axis, double roll) {
  const Eigen::Vector3d z = shaft_axis.normalized();
  const Eigen::Vector3d normal = trocar.normalized();
  Eigen::Vector3d tangent = Eigen::Vector3d::UnitZ().cross(normal);
  // A trocar on the eye's optical axis has no circumferential direction; any fixed tangent will do there.
  if (tangent.squaredNorm() < 1e-12) tangent = Eigen::Vector3d::UnitX().cross(normal);
  Eigen::Vector3d x = tangent - tangent.dot(z) * z;
  if (x.squaredNorm() < 1e-12) x = z.unitOrthogonal();  // only for shafts tangent to the sphere (tip outside)
  x.normalize();
  Eigen::Matrix3d basis;
  basis.col(0) = x;
  basis.col(1) = z.cross(x);
  basis.col(2) = z;
  return (Eigen::Quaterniond(basis) * Eigen::AngleAxisd(roll, Eigen::Vector3d::UnitZ())).normalized();
}

std::vector<std::string> surfaceTargetObjects(const ScriptDefinition& definition) {
  std::vector<std::string> objects;
  for (const InstrumentTrack& track : definition.instruments) {
    for (const InstrumentKeyframe& key : track.keyframes) {
      if (key.target.active() && std::find(objects.begin(), objects.end(), key.target.object) == objects.end()) {
        objects.push_back(key.target.object);
      }
    }
  }
  return objects;
}

// ---------------------------------------------------------------------------------------------------------------

Tremor::Tremor(double amplitude, std::uint32_t seed, std::size_t num_slots) : amplitude_(amplitude) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> frequency(8.0, 10.0);  // §1.3: physiological tremor 8–10 Hz
  std::uniform_real_distribution<double> phase(0.0, 2.0 * kPi);
  std::uniform_real_distribution<double> weight(0.2, 1.0);
  components_.reserve(num_slots * 3 * kComponentsPerAxis);
  for (std::size_t i = 0; i < num_slots * 3; ++i) {
    double sum = 0.0;
    const std::size_t first = components_.size();
    for (int k = 0; k < kComponentsPerAxis; ++k) {
      // Draw order is fixed (frequency, phase, weight) so a seed means the same tremor on every platform.
      const double f = frequency(rng);
      const double p = phase(rng);
      const double w = weight(rng);
      components_.push_back({f, p, w});
      sum += w;
    }
    for (std::size_t k = first; k < components_.size(); ++k) components_[k].weight /= sum;
  }
}

Eigen::Vector3d Tremor::offset(std::size_t slot, double t) const {
  Eigen::Vector3d result = Eigen::Vector3d::Zero();
  if (amplitude_ == 0.0) return result;
  const std::size_t base = slot * 3 * kComponentsPerAxis;
  if (base + 3 * kComponentsPerAxis > components_.size()) return result;
  for (int axis = 0; axis < 3; ++axis) {
    double sum = 0.0;
    for (int k = 0; k < kComponentsPerAxis; ++k) {
      const Component& c = components_[base + axis * kComponentsPerAxis + k];
      sum += c.weight * std::sin(2.0 * kPi * c.frequency * t + c.phase);
    }
    result[axis] = amplitude_ * sum;
  }
  return result;
}

// ---------------------------------------------------------------------------------------------------------------

SurgeonScript::SurgeonScript(ScriptDefinition definition) : definition_(std::move(definition)) {
  validate();
  auto extend = [this](double t) { duration_ = std::max(duration_, t); };
  if (!definition_.eye_track.empty()) extend(definition_.eye_track.back().t);
  for (const InstrumentTrack& track : definition_.instruments) {
    if (!track.keyframes.empty()) extend(track.keyframes.back().t);
  }
  if (!definition_.pedal_track.empty()) extend(definition_.pedal_track.back().t);
  if (!definition_.microscope_track.empty()) extend(definition_.microscope_track.back().t);
}

void SurgeonScript::setTremor(double amplitude, std::uint32_t seed) {
  if (!std::isfinite(amplitude) || amplitude < 0.0) {
    throw std::invalid_argument("tremor amplitude must be finite and >= 0");
  }
  tremor_ = std::make_shared<const Tremor>(amplitude, seed, definition_.instruments.size());
}

void SurgeonScript::validate() const {
  const ScriptDefinition& d = definition_;
  const std::string& src = d.source;

  auto finite = [&](double value, int line, const std::string& field) {
    if (!std::isfinite(value)) throw ScriptError(src, line, field, "must be finite (NaN/inf rejected)");
  };
  auto finiteVector = [&](const Eigen::Vector3d& v, int line, const std::string& field) {
    if (!v.allFinite()) throw ScriptError(src, line, field, "must be finite (NaN/inf rejected)");
  };
  auto inRange = [&](double value, double lo, double hi, int line, const std::string& field) {
    finite(value, line, field);
    if (value < lo || value > hi) {
      std::ostringstream msg;
      msg << "value " << value << " outside [" << lo << ", " << hi << "]";
      throw ScriptError(src, line, field, msg.str());
    }
  };
  const double kInf = std::numeric_limits<double>::infinity();
  // Times: a track may start later than 0 (it holds its first value until then) but must increase strictly, or
  // interpolation would divide by zero and the author's intent is ambiguous.
  auto checkTimes = [&](const auto& keys, const std::string& base) {
    for (std::size_t i = 0; i < keys.size(); ++i) {
      const std::string field = indexed(base, i) + ".t";
      inRange(keys[i].t, 0.0, kInf, keys[i].line, field);
      if (i > 0 && !(keys[i].t > keys[i - 1].t)) {
        std::ostringstream msg;
        msg << "keyframe times must increase strictly (" << keys[i].t << " after " << keys[i - 1].t << ")";
        throw ScriptError(src, keys[i].line, field, msg.str());
      }
    }
  };

  inRange(d.eye.radius, 1e-4, 1.0, d.eye.line, "eye.radius");
  inRange(d.eye.margin, 0.0, d.eye.radius, d.eye.line, "eye.margin");
  finiteVector(d.eye.rotation_center, d.eye.line, "eye.rotation_center");

  checkTimes(d.eye_track, "eye_track");
  for (std::size_t i = 0; i < d.eye_track.size(); ++i) {
    const auto& q = d.eye_track[i].rotation;
    if (!q.coeffs().allFinite() || std::abs(q.norm() - 1.0) > 1e-6) {
      throw ScriptError(src, d.eye_track[i].line, indexed("eye_track", i), "rotation must be a finite unit quaternion");
    }
  }

  std::set<std::string> slots;
  for (const InstrumentTrack& track : d.instruments) {
    const std::string base = "instruments." + track.slot;
    if (track.slot.empty()) throw ScriptError(src, track.line, "instruments", "slot name must not be empty");
    if (!slots.insert(track.slot).second) throw ScriptError(src, track.line, base, "duplicate slot");
    if (track.trocar_from_scene) {
      throw ScriptError(src, track.line, base + ".trocar",
                        "not given: the slot's trocar comes from the scene; play the script with one "
                        "(applySceneTrocars; the nodelets use their ~scene or the default scene)");
    }
    finiteVector(track.trocar, track.line, base + ".trocar");
    const double trocar_radius = track.trocar.norm();
    if (trocar_radius < 0.5 * d.eye.radius || trocar_radius > d.eye.radius + d.eye.margin) {
      std::ostringstream msg;
      msg << "trocar at " << trocar_radius * 1e3 << " mm from the centre; it must lie on the eye sphere (radius "
          << d.eye.radius * 1e3 << " mm, margin " << d.eye.margin * 1e3 << " mm)";
      throw ScriptError(src, track.line, base + ".trocar", msg.str());
    }
    if (track.keyframes.empty()) throw ScriptError(src, track.line, base + ".keyframes", "needs at least one keyframe");
    checkTimes(track.keyframes, base + ".keyframes");
    for (std::size_t i = 0; i < track.keyframes.size(); ++i) {
      const InstrumentKeyframe& k = track.keyframes[i];
      const std::string kb = indexed(base + ".keyframes", i);
      finiteVector(k.tip, k.line, kb + ".tip");
      // The ball is convex, so keyframes inside it keep every linearly interpolated tip inside as well.
      if (k.tip.norm() > d.eye.radius + d.eye.margin) {
        std::ostringstream msg;
        msg << "tip is " << k.tip.norm() * 1e3 << " mm from the eye centre, outside the eye sphere (radius "
            << d.eye.radius * 1e3 << " mm + margin " << d.eye.margin * 1e3 << " mm)";
        throw ScriptError(src, k.line, kb + ".tip", msg.str());
      }
      if (k.target.active()) {
        finite(k.target.height, k.line, kb + ".height");
        finiteVector(k.target.written_tip, k.line, kb + ".tip");
      }
      finite(k.roll, k.line, kb + ".roll");
      inRange(k.jaw_angle, 0.0, kPi, k.line, kb + ".jaw_angle");
      inRange(k.suction, 0.0, 1.0, k.line, kb + ".suction");
      inRange(k.cut_rate, 0.0, kInf, k.line, kb + ".cut_rate");
      inRange(k.injection_flow, 0.0, kInf, k.line, kb + ".injection_flow");
    }
  }

  checkTimes(d.pedal_track, "pedal_track");
  for (std::size_t i = 0; i < d.pedal_track.size(); ++i) {
    inRange(d.pedal_track[i].value.travel, 0.0, 1.0, d.pedal_track[i].line, indexed("pedal_track", i) + ".travel");
  }
  checkTimes(d.microscope_track, "microscope_track");
  for (std::size_t i = 0; i < d.microscope_track.size(); ++i) {
    const MicroscopeSample& m = d.microscope_track[i].value;
    const int line = d.microscope_track[i].line;
    const std::string kb = indexed("microscope_track", i);
    inRange(m.focus_distance, 1e-3, kInf, line, kb + ".focus_distance");
    inRange(m.zoom, 1e-3, kInf, line, kb + ".zoom");
    inRange(m.ambient_light, 0.0, 1.0, line, kb + ".ambient_light");
    inRange(m.disparity_scale, 0.0, 1.0, line, kb + ".disparity_scale");
  }
}

SurgeonSnapshot SurgeonScript::sample(double t) const {
  const ScriptDefinition& d = definition_;
  SurgeonSnapshot snap;
  if (!std::isfinite(t) || t < 0.0) t = 0.0;
  if (d.playback == Playback::kLoop) {
    t = duration_ > 0.0 ? std::fmod(t, duration_) : 0.0;
  } else if (t >= duration_) {
    snap.finished = true;
    t = duration_;
  }
  snap.script_time = t;
  snap.rotation_center = d.eye.rotation_center;

  double alpha = 0.0;
  if (!d.eye_track.empty()) {
    const std::size_t i = findSegment(d.eye_track, t, &alpha);
    snap.eye_rotation = alpha > 0.0 ? d.eye_track[i].rotation.slerp(alpha, d.eye_track[i + 1].rotation).normalized()
                                    : d.eye_track[i].rotation;
  }

  snap.instruments.reserve(d.instruments.size());
  for (std::size_t slot = 0; slot < d.instruments.size(); ++slot) {
    const InstrumentTrack& track = d.instruments[slot];
    const std::size_t i = findSegment(track.keyframes, t, &alpha);
    const InstrumentKeyframe& a = track.keyframes[i];
    const InstrumentKeyframe& b = alpha > 0.0 ? track.keyframes[i + 1] : a;
    InstrumentSample s;
    s.slot = track.slot;
    s.type = a.type;  // step: the instrument in hand changes at the keyframe, not halfway
    s.trocar = track.trocar;
    s.tip = lerp(a.tip, b.tip, alpha);
    // Tremor at the wrapped time, so a looped script stays periodic, tremor included.
    if (tremor_) s.tip += tremor_->offset(slot, t);
    s.roll = lerp(a.roll, b.roll, alpha);
    s.jaw_angle = lerp(a.jaw_angle, b.jaw_angle, alpha);
    s.suction = lerp(a.suction, b.suction, alpha);
    s.cut_rate = lerp(a.cut_rate, b.cut_rate, alpha);
    s.injection_flow = lerp(a.injection_flow, b.injection_flow, alpha);
    // Trocar constraint (§7: pose from the tip marker and the fixed insertion hole): the shaft is not scripted,
    // it follows from tip and trocar, so it passes through the trocar by construction.
    const Eigen::Vector3d shaft = s.tip - s.trocar;
    s.insertion_depth = shaft.norm();
    s.shaft_axis = s.insertion_depth > 1e-12 ? Eigen::Vector3d(shaft / s.insertion_depth)
                                             : Eigen::Vector3d(-s.trocar.normalized());
    s.orientation = shaftOrientation(s.trocar, s.shaft_axis, s.roll);
    snap.instruments.push_back(std::move(s));
  }

  if (!d.pedal_track.empty()) {
    const std::size_t i = findSegment(d.pedal_track, t, &alpha);
    snap.pedals = d.pedal_track[i].value;  // booleans step
    if (alpha > 0.0) snap.pedals.travel = lerp(snap.pedals.travel, d.pedal_track[i + 1].value.travel, alpha);
  }

  if (!d.microscope_track.empty()) {
    const std::size_t i = findSegment(d.microscope_track, t, &alpha);
    const MicroscopeSample& a = d.microscope_track[i].value;
    const MicroscopeSample& b = alpha > 0.0 ? d.microscope_track[i + 1].value : a;
    snap.microscope.focus_distance = lerp(a.focus_distance, b.focus_distance, alpha);
    snap.microscope.zoom = lerp(a.zoom, b.zoom, alpha);
    snap.microscope.ambient_light = lerp(a.ambient_light, b.ambient_light, alpha);
    snap.microscope.disparity_scale = lerp(a.disparity_scale, b.disparity_scale, alpha);
  }
  return snap;
}

}  // namespace vrm_tracking
