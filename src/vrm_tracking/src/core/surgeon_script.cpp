#include "vrm_tracking/surgeon_script.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <utility>

namespace vrm_tracking {

namespace scene = vrm_sim::scene;

namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kDegToRad = kPi / 180.0;

// Waypoint segment containing t: keys[index].t <= t < keys[index + 1].t, alpha in [0, 1). Before the first
// waypoint and after the last one the track holds its end value (alpha = 0).
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

// An error at a waypoint: its location with `field` appended to the path the reader gave it.
[[noreturn]] void fail(const vrm_sim::SourceLocation& at, const std::string& source, const std::string& field,
                       const std::string& problem) {
  vrm_sim::SourceLocation where = at;
  if (where.file.empty()) where.file = source;
  where.field += (where.field.empty() || field.empty() ? "" : ".") + field;
  throw ScriptError(where, problem);
}

}  // namespace

SurgeonScript::SurgeonScript(scene::ScriptedSession session, const EyeGeometry& eye, std::vector<ScriptTrack> tracks,
                             std::string source)
    : session_(std::move(session)), eye_(eye), tracks_(std::move(tracks)), source_(std::move(source)) {
  validate();
  duration_ = session_.duration();
}

void SurgeonScript::setTremorAmplitude(double amplitude) {
  if (!std::isfinite(amplitude) || amplitude < 0.0) {
    throw std::invalid_argument("tremor amplitude must be finite and >= 0");
  }
  for (scene::ScriptedInstrument& instrument : session_.instruments) instrument.tremor.amplitude = amplitude;
}

void SurgeonScript::validate() const {
  const scene::ScriptedSession& d = session_;
  auto inRange = [&](double value, double lo, double hi, const vrm_sim::SourceLocation& at, const std::string& field) {
    if (!std::isfinite(value)) fail(at, source_, field, "must be finite (NaN/inf rejected)");
    if (value < lo || value > hi) {
      std::ostringstream message;
      message << "value " << value << " outside [" << lo << ", " << hi << "]";
      fail(at, source_, field, message.str());
    }
  };
  const double kInf = std::numeric_limits<double>::infinity();
  // Times: a track may start later than 0 (it holds its first value until then) but must increase strictly, or
  // interpolation would divide by zero and the author's intent is ambiguous.
  auto checkTimes = [&](const auto& keys) {
    for (std::size_t i = 0; i < keys.size(); ++i) {
      inRange(keys[i].t, 0.0, kInf, keys[i].location, "t");
      if (i > 0 && !(keys[i].t > keys[i - 1].t)) {
        std::ostringstream message;
        message << "waypoint times must increase strictly (" << keys[i].t << " after " << keys[i - 1].t << ")";
        fail(keys[i].location, source_, "t", message.str());
      }
    }
  };
  const vrm_sim::SourceLocation eye_location{source_, 0, 0, "eye"};
  inRange(eye_.radius, 1e-4, 1.0, eye_location, "radius");
  inRange(eye_.margin, 0.0, eye_.radius, eye_location, "margin");
  if (!eye_.rotation_center.allFinite()) fail(eye_location, source_, "rotation_center", "must be finite");

  checkTimes(d.eye);
  for (const scene::EyeWaypoint& waypoint : d.eye) {
    if (!waypoint.rpy_deg.allFinite()) fail(waypoint.location, source_, "rpy_deg", "must be finite");
  }

  if (tracks_.size() != d.instruments.size()) {
    throw std::invalid_argument("SurgeonScript: one ScriptTrack per scripted instrument expected (" +
                                std::to_string(tracks_.size()) + " for " + std::to_string(d.instruments.size()) + ")");
  }
  for (std::size_t slot = 0; slot < d.instruments.size(); ++slot) {
    const scene::ScriptedInstrument& instrument = d.instruments[slot];
    for (std::size_t earlier = 0; earlier < slot; ++earlier) {
      if (d.instruments[earlier].slot == instrument.slot) fail(instrument.location, source_, "slot", "scripted twice");
    }
    const Eigen::Vector3d& trocar = tracks_[slot].trocar;
    const double trocar_radius = trocar.norm();
    if (!trocar.allFinite() || trocar_radius < 0.5 * eye_.radius || trocar_radius > eye_.radius + eye_.margin) {
      std::ostringstream message;
      message << "the " << scene::toString(instrument.slot) << " trocar is " << trocar_radius * 1e3
              << " mm from the centre; it must lie on the eye sphere (radius " << eye_.radius * 1e3 << " mm, margin "
              << eye_.margin * 1e3 << " mm)";
      fail(instrument.location, source_, "slot", message.str());
    }
    if (instrument.path.empty()) fail(instrument.location, source_, "path", "needs at least one waypoint");
    inRange(instrument.tremor.amplitude, 0.0, 1e-3, instrument.location, "tremor.amplitude");
    inRange(instrument.tremor.frequency_hz, 1e-6, 100.0, instrument.location, "tremor.frequency_hz");
    checkTimes(instrument.path);
    for (const scene::InstrumentWaypoint& waypoint : instrument.path) {
      if (!waypoint.on.empty()) {
        fail(waypoint.location, source_, "on",
             "'" + waypoint.on + "' is not resolved: play the script in a scene (playInScene)");
      }
      if (!waypoint.tip_in_eye.allFinite()) fail(waypoint.location, source_, "tip", "must be finite");
      // The ball is convex, so waypoints inside it keep every linearly interpolated tip inside as well.
      if (waypoint.tip_in_eye.norm() > eye_.radius + eye_.margin) {
        std::ostringstream message;
        message << "tip is " << waypoint.tip_in_eye.norm() * 1e3
                << " mm from the eye centre, outside the eye sphere (radius " << eye_.radius * 1e3 << " mm + margin "
                << eye_.margin * 1e3 << " mm)";
        fail(waypoint.location, source_, "tip", message.str());
      }
      inRange(waypoint.roll_deg, -kInf, kInf, waypoint.location, "roll_deg");
      inRange(waypoint.jaw_angle_deg, 0.0, 180.0, waypoint.location, "jaw_angle_deg");
      inRange(waypoint.suction, 0.0, 1.0, waypoint.location, "suction");
      inRange(waypoint.cut_rate_hz, 0.0, kInf, waypoint.location, "cut_rate_hz");
      inRange(waypoint.injection_flow, 0.0, kInf, waypoint.location, "injection_flow");
    }
  }

  checkTimes(d.pedals);
  for (const scene::PedalWaypoint& waypoint : d.pedals) inRange(waypoint.travel, 0.0, 1.0, waypoint.location, "travel");
  checkTimes(d.microscope);
  for (const scene::MicroscopeWaypoint& waypoint : d.microscope) {
    inRange(waypoint.focus_distance, 1e-3, kInf, waypoint.location, "focus_distance");
    inRange(waypoint.zoom, 1e-3, kInf, waypoint.location, "zoom");
    inRange(waypoint.ambient_light, 0.0, 1.0, waypoint.location, "ambient_light");
    inRange(waypoint.disparity_scale, 0.0, 1.0, waypoint.location, "disparity_scale");
  }
}

SurgeonSnapshot SurgeonScript::sample(double t) const {
  const scene::ScriptedSession& d = session_;
  SurgeonSnapshot snap;
  if (!std::isfinite(t) || t < 0.0) t = 0.0;
  if (d.playback == Playback::kLoop) {
    t = duration_ > 0.0 ? std::fmod(t, duration_) : 0.0;
  } else if (t >= duration_) {
    snap.finished = true;
    t = duration_;
  }
  snap.script_time = t;
  snap.rotation_center = eye_.rotation_center;

  double alpha = 0.0;
  if (!d.eye.empty()) {
    const std::size_t i = findSegment(d.eye, t, &alpha);
    const Eigen::Quaterniond a = d.eye[i].rotation();
    snap.eye_rotation = alpha > 0.0 ? a.slerp(alpha, d.eye[i + 1].rotation()).normalized() : a;
  }

  snap.instruments.reserve(d.instruments.size());
  for (std::size_t slot = 0; slot < d.instruments.size(); ++slot) {
    const scene::ScriptedInstrument& instrument = d.instruments[slot];
    // The scene's path sampling (what the offline tools play): linear, the exchange steps at its waypoint.
    const scene::InstrumentWaypoint w = scene::samplePath(instrument.path, t);
    InstrumentSample s;
    s.slot = scene::toString(instrument.slot);
    s.type = w.type.value_or(tracks_[slot].type);
    s.trocar = tracks_[slot].trocar;
    // Tremor at the wrapped time, so a looped script stays periodic, tremor included.
    s.tip = w.tip_in_eye + instrument.tremor.offset(t);
    s.roll = w.roll_deg * kDegToRad;
    s.jaw_angle = w.jaw_angle_deg * kDegToRad;
    s.suction = w.suction;
    s.cut_rate = w.cut_rate_hz;
    s.injection_flow = w.injection_flow;
    // Trocar constraint (§7: pose from the tip marker and the fixed insertion hole): the shaft is not scripted,
    // it follows from tip and trocar, so it passes through the trocar by construction.
    const Eigen::Vector3d shaft = s.tip - s.trocar;
    s.insertion_depth = shaft.norm();
    s.shaft_axis = s.insertion_depth > 1e-12 ? Eigen::Vector3d(shaft / s.insertion_depth)
                                             : Eigen::Vector3d(-s.trocar.normalized());
    s.orientation = shaftOrientation(s.trocar, s.shaft_axis, s.roll);
    snap.instruments.push_back(std::move(s));
  }

  if (!d.pedals.empty()) {
    const std::size_t i = findSegment(d.pedals, t, &alpha);
    const scene::PedalWaypoint& a = d.pedals[i];  // the buttons step
    snap.pedals =
        PedalSample{a.travel, a.reflux, a.instrument_switch, a.zoom_in, a.zoom_out, a.focus_near, a.focus_far};
    if (alpha > 0.0) snap.pedals.travel = lerp(a.travel, d.pedals[i + 1].travel, alpha);
  }

  if (!d.microscope.empty()) {
    const std::size_t i = findSegment(d.microscope, t, &alpha);
    const scene::MicroscopeWaypoint& a = d.microscope[i];
    const scene::MicroscopeWaypoint& b = alpha > 0.0 ? d.microscope[i + 1] : a;
    snap.microscope.focus_distance = lerp(a.focus_distance, b.focus_distance, alpha);
    snap.microscope.zoom = lerp(a.zoom, b.zoom, alpha);
    snap.microscope.ambient_light = lerp(a.ambient_light, b.ambient_light, alpha);
    snap.microscope.disparity_scale = lerp(a.disparity_scale, b.disparity_scale, alpha);
  }
  return snap;
}

}  // namespace vrm_tracking
