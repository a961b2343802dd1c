#pragma once
// Knob twin of the EyeSi microscope (thesis §7: focus, zoom and ambient light knobs; zoom/focus also on the foot
// pedals). The scripted microscope track is the baseline; pedal buttons add a persistent offset while held, the
// way a motorised zoom keeps moving while its button is pressed, and the result is held within the limits.

#include "vrm_tracking/surgeon_script.h"

namespace vrm_tracking {

struct MicroscopeLimits {
  double zoom_min = 1.0;
  double zoom_max = 4.0;
  double zoom_rate = 0.5;     // magnification per second while a zoom button is held
  double focus_min = 0.15;    // m
  double focus_max = 0.25;    // m
  double focus_rate = 0.005;  // m/s while a focus button is held
};

class MicroscopeKnobs {
 public:
  // Throws std::invalid_argument for empty ranges or negative rates.
  explicit MicroscopeKnobs(const MicroscopeLimits& limits);

  // dt: seconds since the previous update (the caller's clock; <= 0 moves nothing). Buttons pressed in both
  // directions cancel. focus_near shortens the focus distance.
  MicroscopeSample update(const MicroscopeSample& scripted, const PedalSample& buttons, double dt);

  void reset() { zoom_offset_ = focus_offset_ = 0.0; }
  const MicroscopeLimits& limits() const { return limits_; }

 private:
  MicroscopeLimits limits_;
  double zoom_offset_ = 0.0;
  double focus_offset_ = 0.0;
};

}  // namespace vrm_tracking
