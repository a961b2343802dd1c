#include "vrm_tracking/microscope_knobs.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace vrm_tracking {

namespace {

double direction(bool increase, bool decrease) { return (increase ? 1.0 : 0.0) - (decrease ? 1.0 : 0.0); }

// Moves value + offset by rate * dt and clamps the sum to [lo, hi]; the offset is rewritten from the clamped sum so
// holding a button against a limit does not wind up an offset that would have to be unwound later.
double step(double scripted, double* offset, double velocity, double dt, double lo, double hi) {
  const double value = std::clamp(scripted + *offset + velocity * dt, lo, hi);
  *offset = value - scripted;
  return value;
}

}  // namespace

MicroscopeKnobs::MicroscopeKnobs(const MicroscopeLimits& limits) : limits_(limits) {
  const auto& l = limits_;
  const bool ok = std::isfinite(l.zoom_min) && std::isfinite(l.zoom_max) && std::isfinite(l.focus_min) &&
                  std::isfinite(l.focus_max) && l.zoom_min > 0.0 && l.zoom_min <= l.zoom_max && l.focus_min > 0.0 &&
                  l.focus_min <= l.focus_max && l.zoom_rate >= 0.0 && l.focus_rate >= 0.0 &&
                  std::isfinite(l.zoom_rate) && std::isfinite(l.focus_rate);
  if (!ok) throw std::invalid_argument("microscope limits: need 0 < min <= max and finite rates >= 0");
}

MicroscopeSample MicroscopeKnobs::update(const MicroscopeSample& scripted, const PedalSample& buttons, double dt) {
  if (!(dt > 0.0)) dt = 0.0;
  MicroscopeSample out = scripted;
  out.zoom = step(scripted.zoom, &zoom_offset_, limits_.zoom_rate * direction(buttons.zoom_in, buttons.zoom_out), dt,
                  limits_.zoom_min, limits_.zoom_max);
  out.focus_distance = step(scripted.focus_distance, &focus_offset_,
                            limits_.focus_rate * direction(buttons.focus_far, buttons.focus_near), dt,
                            limits_.focus_min, limits_.focus_max);
  out.ambient_light = std::clamp(scripted.ambient_light, 0.0, 1.0);
  out.disparity_scale = std::clamp(scripted.disparity_scale, 0.0, 1.0);
  return out;
}

}  // namespace vrm_tracking
