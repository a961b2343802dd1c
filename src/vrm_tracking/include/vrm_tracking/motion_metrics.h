#pragma once
// Skill metrics of a tracked instrument tip (beyond the thesis, which §7 scores only trajectory following by speed
// and accuracy): physiological tremor as the RMS of the motion in the 8–12 Hz band (§1.3: tremor at 8–10 Hz),
// path length and speed. Inputs are uniformly sampled positions (the tracking rate); irregular samples are
// resampled linearly first.

#include <Eigen/Core>
#include <vector>

namespace vrm_tracking {

struct MotionMetrics {
  double duration = 0.0;     // s
  double path_length = 0.0;  // m (includes measurement noise: compare at equal noise)
  double mean_speed = 0.0;   // m/s
  double max_speed = 0.0;    // m/s (between consecutive samples)
  double tremor_rms = 0.0;   // m, 3D RMS of the band-limited motion
};

// t: seconds, strictly increasing; p: positions (m). band in Hz. Fewer than 8 samples: all zero.
MotionMetrics motionMetrics(const std::vector<double>& t, const std::vector<Eigen::Vector3d>& p, double band_lo = 8.0,
                            double band_hi = 12.0);

}  // namespace vrm_tracking
