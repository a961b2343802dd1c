#include "vrm_tracking/motion_metrics.h"

#include <algorithm>
#include <cmath>
#include <complex>

namespace vrm_tracking {

MotionMetrics motionMetrics(const std::vector<double>& t, const std::vector<Eigen::Vector3d>& p, double band_lo,
                            double band_hi) {
  MotionMetrics m;
  const std::size_t n_in = std::min(t.size(), p.size());
  if (n_in < 8) return m;
  m.duration = t[n_in - 1] - t[0];
  for (std::size_t i = 1; i < n_in; ++i) {
    const double d = (p[i] - p[i - 1]).norm(), dt = t[i] - t[i - 1];
    m.path_length += d;
    if (dt > 0.0) m.max_speed = std::max(m.max_speed, d / dt);
  }
  m.mean_speed = m.duration > 0.0 ? m.path_length / m.duration : 0.0;

  // Resample uniformly at the median interval (the tracker's rate) so the spectrum is well defined.
  std::vector<double> dts;
  for (std::size_t i = 1; i < n_in; ++i) dts.push_back(t[i] - t[i - 1]);
  std::nth_element(dts.begin(), dts.begin() + dts.size() / 2, dts.end());
  const double dt = dts[dts.size() / 2];
  if (!(dt > 0.0)) return m;
  const std::size_t n = static_cast<std::size_t>(std::floor(m.duration / dt)) + 1;
  std::vector<Eigen::Vector3d> x(n);
  std::size_t j = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const double ti = t[0] + i * dt;
    while (j + 2 < n_in && t[j + 1] < ti) ++j;
    const double a = std::clamp((ti - t[j]) / std::max(1e-12, t[j + 1] - t[j]), 0.0, 1.0);
    x[i] = (1.0 - a) * p[j] + a * p[j + 1];
  }
  // Remove the linear trend (the deliberate motion's lowest frequencies would leak into the band), then a Hann
  // window against leakage, compensated by its mean square (3/8) so the band power is unbiased for a sinusoid.
  const double tm = (n - 1) / 2.0;
  double stt = 0.0;
  Eigen::Vector3d mean = Eigen::Vector3d::Zero(), slope = Eigen::Vector3d::Zero();
  for (std::size_t i = 0; i < n; ++i) mean += x[i];
  mean /= static_cast<double>(n);
  for (std::size_t i = 0; i < n; ++i) {
    stt += (i - tm) * (i - tm);
    slope += (i - tm) * (x[i] - mean);
  }
  slope /= stt;
  double window_ms = 0.0;
  std::vector<Eigen::Vector3d> y(n);
  for (std::size_t i = 0; i < n; ++i) {
    const double w = 0.5 - 0.5 * std::cos(2.0 * M_PI * i / (n - 1));
    window_ms += w * w;
    y[i] = w * (x[i] - mean - (i - tm) * slope);
  }
  window_ms /= static_cast<double>(n);
  // One-sided band power by direct DFT of the band's bins only (a few dozen bins: cheaper than a full FFT).
  const double fs = 1.0 / dt;
  const std::size_t k0 = static_cast<std::size_t>(std::ceil(band_lo * n / fs));
  const std::size_t k1 = std::min(static_cast<std::size_t>(std::floor(band_hi * n / fs)), (n - 1) / 2);
  double power = 0.0;
  for (std::size_t k = std::max<std::size_t>(k0, 1); k <= k1; ++k) {
    for (int axis = 0; axis < 3; ++axis) {
      std::complex<double> X = 0.0;
      for (std::size_t i = 0; i < n; ++i) X += y[i](axis) * std::polar(1.0, -2.0 * M_PI * k * i / n);
      power += 2.0 * std::norm(X) / (static_cast<double>(n) * n);
    }
  }
  m.tremor_rms = std::sqrt(power / window_ms);
  return m;
}

}  // namespace vrm_tracking
