#include "vrm_tracking/rig_renderer.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <opencv2/imgproc.hpp>
#include <random>

namespace vrm_tracking {

namespace {

// One drawable: a marker sphere (projected as a disc, smeared over the exposure) or a piece of a shaft, ordered
// back to front (painter's algorithm) so a shaft in front of a marker hides it.
struct Drawable {
  double depth = 0.0;
  bool is_marker = true;
  std::size_t index = 0;
  Eigen::Vector2d a = Eigen::Vector2d::Zero(), b = Eigen::Vector2d::Zero();  // shaft piece endpoints (px)
  double radius_px = 0.0;
  std::vector<Eigen::Vector2d> centres;  // marker: sub-frame centres over the exposure
  std::vector<double> radii;
  cv::Rect box;  // pixels it may change (clipped to the image)
};

std::uint64_t mix(std::uint64_t a, std::uint64_t b) {
  std::uint64_t x = a * 0x9E3779B97F4A7C15ULL ^ (b + 0x7F4A7C159E3779B9ULL + (a << 6) + (a >> 2));
  x ^= x >> 31;
  x *= 0xBF58476D1CE4E5B9ULL;
  x ^= x >> 27;
  return x;
}

// Coverage of a disc of radius r blurred by a Gaussian of σ at distance d from its centre (edge profile of a
// defocused/PSF-blurred disc, exact for a straight edge): symmetric about the centre, so it moves no centroid.
// Beyond ±3.5 (erfc(3.5) = 7e-7) the value is taken as 0 or 1 without the libm call: most pixels of a box are.
inline double discCoverage(double d, double r, double sigma) {
  const double z = (d - r) / (M_SQRT2 * sigma);
  if (z >= 3.5) return 0.0;
  if (z <= -3.5) return 1.0;
  return 0.5 * std::erfc(z);
}

double segmentDistance(const Eigen::Vector2d& p, const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
  const Eigen::Vector2d ab = b - a;
  const double len2 = ab.squaredNorm();
  const double t = len2 > 0.0 ? std::clamp((p - a).dot(ab) / len2, 0.0, 1.0) : 0.0;
  return (p - (a + t * ab)).norm();
}

constexpr std::size_t kNormalTableSize = 1 << 16;

const std::vector<float>& normalTable() {
  static const std::vector<float> table = [] {
    std::vector<float> t(kNormalTableSize);
    std::mt19937 rng(12345);
    std::normal_distribution<float> normal(0.f, 1.f);
    for (float& v : t) v = normal(rng);
    return t;
  }();
  return table;
}

// --- The span path (issue 30 item 4) ---

// Pixels a drawable may change: x0..x1 (inclusive) of row y.
struct Span {
  int y, x0, x1;
};

// 0.5·erfc(z) on [-3.5, 3.5] in steps of 1/512 for linear interpolation (error < 1e-6 against discCoverage's libm
// call, far below one DN), and exactly discCoverage's 0 and 1 outside.
constexpr double kErfcRange = 3.5;
constexpr int kErfcSteps = 512;

const std::vector<double>& halfErfcTable() {
  static const std::vector<double> table = [] {
    std::vector<double> t(static_cast<std::size_t>(2 * kErfcRange * kErfcSteps) + 2);
    for (std::size_t i = 0; i < t.size(); ++i) t[i] = 0.5 * std::erfc(static_cast<double>(i) / kErfcSteps - kErfcRange);
    return t;
  }();
  return table;
}

// discCoverage(d, r, σ) with z = (d − r)·inv_sqrt2_sigma, from the table.
inline double tabulatedCoverage(double z, const double* table) {
  if (z >= kErfcRange) return 0.0;
  if (z <= -kErfcRange) return 1.0;
  const double u = (z + kErfcRange) * kErfcSteps;
  const int i = static_cast<int>(u);
  return table[i] + (u - i) * (table[i + 1] - table[i]);
}

// Standard normal draws in Q12 (z · 4096, |z| < 8), 2 MiB: the untouched pixels read a row's worth from a random
// offset per row and frame. Per pixel the draws are independent (adjacent bank entries), and two frames share a
// pixel's draw only if a row lands on the same offset (p = 1e-6): no fixed pattern between consecutive frames.
constexpr std::size_t kNormalBankSize = std::size_t(1) << 20;

const std::vector<std::int16_t>& normalBankQ12() {
  static const std::vector<std::int16_t> bank = [] {
    std::vector<std::int16_t> b(kNormalBankSize);
    std::mt19937 rng(20261127);
    std::normal_distribution<double> normal(0.0, 1.0);
    for (std::int16_t& v : b) v = static_cast<std::int16_t>(std::lround(std::clamp(normal(rng), -7.99, 7.99) * 4096.0));
    return b;
  }();
  return bank;
}

// The x interval of row y within distance R of the segment a–b (a capsule: convex, so one interval). False if empty.
bool capsuleRowSpan(const Eigen::Vector2d& a, const Eigen::Vector2d& b, double R, double y, double* xl, double* xr) {
  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  for (const Eigen::Vector2d* p : {&a, &b}) {
    const double dy = y - p->y();
    if (std::abs(dy) <= R) {
      const double h = std::sqrt(R * R - dy * dy);
      lo = std::min(lo, p->x() - h);
      hi = std::max(hi, p->x() + h);
    }
  }
  const Eigen::Vector2d d = b - a;
  const double len2 = d.squaredNorm();
  if (len2 > 1e-18) {
    constexpr double kEps = 1e-9;
    const double ry = y - a.y(), len = std::sqrt(len2);
    // Side band: the projection parameter t = ((x−ax)·dx + ry·dy)/len² in [0, 1] and |perpendicular| ≤ R.
    double t_lo = -std::numeric_limits<double>::infinity(), t_hi = -t_lo;  // as x bounds
    if (std::abs(d.x()) > kEps) {
      const double x0 = a.x() - ry * d.y() / d.x(), x1 = a.x() + (len2 - ry * d.y()) / d.x();
      t_lo = std::min(x0, x1);
      t_hi = std::max(x0, x1);
    } else if (ry * d.y() < 0.0 || ry * d.y() > len2) {
      t_hi = t_lo;  // empty
    }
    double p_lo = -std::numeric_limits<double>::infinity(), p_hi = -p_lo;
    if (std::abs(d.y()) > kEps) {  // (x−ax)·dy − ry·dx in [−R·len, R·len]
      const double x0 = a.x() + (ry * d.x() - R * len) / d.y(), x1 = a.x() + (ry * d.x() + R * len) / d.y();
      p_lo = std::min(x0, x1);
      p_hi = std::max(x0, x1);
    } else if (std::abs(ry) > R) {
      p_hi = p_lo;  // empty
    }
    const double s_lo = std::max(t_lo, p_lo), s_hi = std::min(t_hi, p_hi);
    if (s_lo <= s_hi) {
      lo = std::min(lo, s_lo);
      hi = std::max(hi, s_hi);
    }
  }
  *xl = lo;
  *xr = hi;
  return lo <= hi;
}

// Pixels (integer centres) of row y in [xl, xr], clipped to the image; false if none.
bool pixelRange(double xl, double xr, int width, int* x0, int* x1) {
  if (!(xl <= xr) || xr < 0.0 || xl > width - 1.0) return false;
  *x0 = static_cast<int>(std::ceil(std::max(xl, 0.0)));
  *x1 = static_cast<int>(std::floor(std::min(xr, width - 1.0)));
  return *x0 <= *x1;
}

// Sorted by row and start, overlapping or adjacent spans joined: every touched pixel once.
void mergeSpans(std::vector<Span>* spans) {
  std::sort(spans->begin(), spans->end(),
            [](const Span& p, const Span& q) { return p.y != q.y ? p.y < q.y : p.x0 < q.x0; });
  std::size_t n = 0;
  for (const Span& sp : *spans) {
    if (n > 0 && (*spans)[n - 1].y == sp.y && sp.x0 <= (*spans)[n - 1].x1 + 1) {
      (*spans)[n - 1].x1 = std::max((*spans)[n - 1].x1, sp.x1);
    } else {
      (*spans)[n++] = sp;
    }
  }
  spans->resize(n);
}

}  // namespace

RigRenderer::RigRenderer(CameraRig rig, MarkerLayout layout, RenderConfig config)
    : rig_(std::move(rig)), layout_(std::move(layout)), config_(config) {
  buildBackgrounds();
}

void RigRenderer::buildBackgrounds() {
  backgrounds_.clear();
  for (std::size_t c = 0; c < rig_.size(); ++c) {
    const CameraModel& cam = rig_.cameras[c];
    std::mt19937 rng(static_cast<std::uint32_t>(mix(config_.seed, 1000 + c)));
    cv::Mat bg(cam.height, cam.width, CV_32FC3);
    // A vertical gradient (the inside of the mask housing is unevenly lit) plus grey clutter (cables, mechanics).
    for (int y = 0; y < cam.height; ++y) {
      const float level = static_cast<float>(config_.background * (0.7 + 0.6 * y / std::max(1, cam.height - 1)));
      bg.row(y).setTo(cv::Scalar(level, level, level));
    }
    std::uniform_real_distribution<double> ux(0, cam.width), uy(0, cam.height), size(5, 60), grey(10, 110), tint(-6, 6),
        angle(0, 180);
    for (int i = 0; i < config_.clutter; ++i) {
      const double g = grey(rng);
      // Slightly tinted grey: low chroma, below every class's chroma_min, as real mechanics would be.
      const cv::Scalar colour(g + tint(rng), g + tint(rng), g + tint(rng));
      const cv::Point centre(static_cast<int>(ux(rng)), static_cast<int>(uy(rng)));
      if (i % 2 == 0) {
        cv::ellipse(bg, centre, cv::Size(static_cast<int>(size(rng)), static_cast<int>(size(rng) / 2)), angle(rng), 0,
                    360, colour, cv::FILLED, cv::LINE_AA);
      } else {
        cv::rectangle(bg, cv::Rect(centre.x, centre.y, static_cast<int>(size(rng)), static_cast<int>(size(rng))),
                      colour, cv::FILLED);
      }
    }
    cv::GaussianBlur(bg, bg, cv::Size(0, 0), 1.5);
    backgrounds_.push_back(bg);
    // The exposed background level per pixel and channel, for the untouched pixels' table lookup.
    std::vector<std::uint8_t> levels(static_cast<std::size_t>(cam.width) * cam.height * 3);
    for (int y = 0; y < cam.height; ++y) {
      const float* in = bg.ptr<float>(y);
      for (int i = 0; i < 3 * cam.width; ++i) {
        levels[static_cast<std::size_t>(y) * 3 * cam.width + i] =
            static_cast<std::uint8_t>(std::clamp(static_cast<int>(std::lround(in[i] * config_.exposure)), 0, 255));
      }
    }
    background_levels_.push_back(std::move(levels));
  }
  // noise_lut_[level·256 + k]: level + σ(level)·z_k, rounded and saturated; 256 normal draws per level (the 64 Ki
  // normal table, so the levels' draws are independent).
  const std::vector<float>& table = normalTable();
  noise_lut_.resize(256 * 256);
  for (int lvl = 0; lvl < 256; ++lvl) {
    const float sd = sensorSigma(lvl);
    for (int k = 0; k < 256; ++k) {
      const float v = lvl + sd * table[static_cast<std::size_t>(lvl) * 256 + k];
      noise_lut_[static_cast<std::size_t>(lvl) * 256 + k] =
          static_cast<std::uint8_t>(std::clamp(static_cast<int>(v + 256.5f) - 256, 0, 255));
    }
  }
  // The span path's tables, built here rather than inside the first frame (a 1 Mi-draw bank costs ~20 ms).
  normalBankQ12();
  halfErfcTable();
  // The span path's untouched pixels: σ(level) per pixel and channel in Q11, if every σ < 16 DN fits an int16.
  background_sigma_q11_.clear();
  if (sensorSigma(255) < 15.99f) {
    for (const std::vector<std::uint8_t>& levels : background_levels_) {
      std::vector<std::int16_t> q(levels.size());
      for (std::size_t i = 0; i < levels.size(); ++i) {
        q[i] = static_cast<std::int16_t>(std::lround(sensorSigma(levels[i]) * 2048.f));
      }
      background_sigma_q11_.push_back(std::move(q));
    }
  }
}

float RigRenderer::sensorSigma(int level) const {
  return static_cast<float>(
      std::sqrt(config_.read_noise * config_.read_noise + std::max(0.0, config_.shot_gain) * level));
}

std::vector<ProjectedMarker> RigRenderer::project(std::size_t camera, const WorldScene& scene) const {
  const CameraModel& cam = rig_.cameras.at(camera);
  std::vector<ProjectedMarker> out;
  for (const WorldMarker& m : scene.markers) {
    ProjectedMarker p;
    p.class_id = m.class_id;
    if (cam.project(m.position, &p.pixel)) {
      const double depth = (cam.world_to_camera * m.position).z();
      p.radius_px = cam.K(0, 0) * m.radius / depth;
      p.visible = cam.inImage(p.pixel, p.radius_px);
    }
    out.push_back(p);
  }
  return out;
}

void RigRenderer::render(std::size_t camera, const WorldScene& scene, std::uint64_t frame_index, cv::Mat* image,
                         std::vector<ProjectedMarker>* truth) const {
  if (config_.reference_path) {
    renderReference(camera, scene, frame_index, image, truth);
  } else {
    renderSpans(camera, scene, frame_index, image, truth);
  }
}

void RigRenderer::renderReference(std::size_t camera, const WorldScene& scene, std::uint64_t frame_index,
                                  cv::Mat* image, std::vector<ProjectedMarker>* truth) const {
  const CameraModel& cam = rig_.cameras.at(camera);
  std::mt19937_64 rng(mix(mix(config_.seed, camera), frame_index));
  std::vector<ProjectedMarker> projected = project(camera, scene);
  std::vector<Drawable> drawables;
  for (std::size_t i = 0; i < scene.markers.size(); ++i) {
    if (!projected[i].visible && projected[i].radius_px <= 0.0) continue;
    Drawable d;
    d.depth = (cam.world_to_camera * scene.markers[i].position).z();
    d.index = i;
    drawables.push_back(d);
  }
  if (config_.shafts) {
    for (const WorldSegment& s : scene.shafts) {
      constexpr int kPieces = 24;  // short pieces so depth ordering against markers holds piecewise
      for (int k = 0; k < kPieces; ++k) {
        const Eigen::Vector3d a = s.a + (s.b - s.a) * (static_cast<double>(k) / kPieces);
        const Eigen::Vector3d b = s.a + (s.b - s.a) * (static_cast<double>(k + 1) / kPieces);
        Drawable d;
        d.is_marker = false;
        if (!cam.project(a, &d.a) || !cam.project(b, &d.b)) continue;
        d.depth = (cam.world_to_camera * (0.5 * (a + b))).z();
        d.radius_px = cam.K(0, 0) * s.radius / d.depth;
        drawables.push_back(d);
      }
    }
  }
  std::sort(drawables.begin(), drawables.end(), [](const Drawable& x, const Drawable& y) { return x.depth > y.depth; });

  // Distractors lie in the background (behind the eye): markers and shafts are drawn over them.
  const double sigma = std::max(0.3, config_.blur_px);
  const int samples = std::max(1, config_.motion_samples);
  const cv::Rect frame(0, 0, cam.width, cam.height);
  auto box = [&frame](double x0, double y0, double x1, double y1) {
    const int ix0 = static_cast<int>(std::floor(x0)), iy0 = static_cast<int>(std::floor(y0));
    return cv::Rect(ix0, iy0, static_cast<int>(std::ceil(x1)) - ix0 + 1, static_cast<int>(std::ceil(y1)) - iy0 + 1) &
           frame;
  };
  // Where anything is drawn: only these boxes get the float radiance and the exact sensor model; the rest of the
  // frame is the static background through a per-level noise table (see below).
  std::vector<cv::Rect> touched;
  for (Drawable& d : drawables) {
    if (d.is_marker) {
      const WorldMarker& m = scene.markers[d.index];
      // Sub-frame positions over [-T/2, T/2] around the stamp: the blob's centroid stays the mid-exposure point.
      for (int s = 0; s < samples; ++s) {
        const double dt = samples > 1 ? config_.exposure_time * ((s + 0.5) / samples - 0.5) : 0.0;
        Eigen::Vector2d px;
        const Eigen::Vector3d p = m.position + m.velocity * dt;
        if (!cam.project(p, &px)) continue;
        d.centres.push_back(px);
        d.radii.push_back(cam.K(0, 0) * m.radius / (cam.world_to_camera * p).z());
      }
      double x0 = 1e9, x1 = -1e9, y0 = 1e9, y1 = -1e9;
      for (std::size_t s = 0; s < d.centres.size(); ++s) {
        const double ext = d.radii[s] + 4.0 * sigma + 1.0;
        x0 = std::min(x0, d.centres[s].x() - ext);
        x1 = std::max(x1, d.centres[s].x() + ext);
        y0 = std::min(y0, d.centres[s].y() - ext);
        y1 = std::max(y1, d.centres[s].y() + ext);
      }
      if (!d.centres.empty()) d.box = box(x0, y0, x1, y1);
    } else {
      const double ext = d.radius_px + 3.0 * sigma + 1.0;
      d.box = box(std::min(d.a.x(), d.b.x()) - ext, std::min(d.a.y(), d.b.y()) - ext, std::max(d.a.x(), d.b.x()) + ext,
                  std::max(d.a.y(), d.b.y()) + ext);
    }
    if (d.box.area() > 0) touched.push_back(d.box);
  }
  struct Distractor {
    cv::Point centre;
    int kind;
    double angle;
    cv::Scalar colour;
  };
  std::vector<Distractor> distractors;
  if (config_.distractors > 0) {
    std::uniform_real_distribution<double> ux(0, cam.width), uy(0, cam.height), angle(0, 180), u01(0, 1);
    for (int i = 0; i < config_.distractors; ++i) {
      Distractor dd;
      dd.centre = cv::Point(static_cast<int>(ux(rng)), static_cast<int>(uy(rng)));
      dd.kind = i % 3;
      dd.colour = cv::Scalar(220, 40, 220);  // magenta: no class
      if (dd.kind != 2 && !layout_.classes.empty()) {
        const ColourClass& c =
            layout_.classes[static_cast<std::size_t>(u01(rng) * layout_.classes.size()) % layout_.classes.size()];
        dd.colour = cv::Scalar(c.bgr[0], c.bgr[1], c.bgr[2]);
      }
      dd.angle = dd.kind == 0 ? angle(rng) : 0.0;
      const int reach = (dd.kind == 0 ? 14 : dd.kind == 1 ? 40 : 4) + 2;  // + anti-aliasing
      const cv::Rect r = box(dd.centre.x - reach, dd.centre.y - reach, dd.centre.x + reach, dd.centre.y + reach);
      if (r.area() > 0) touched.push_back(r);
      distractors.push_back(dd);
    }
  }
  // Reused per thread: a fresh 3.7 MB float image per frame costs page faults, not just a copy.
  thread_local cv::Mat radiance_buffer;
  radiance_buffer.create(cam.height, cam.width, CV_32FC3);
  cv::Mat& radiance = radiance_buffer;
  const cv::Mat& background = backgrounds_.at(camera);
  for (const cv::Rect& r : touched) background(r).copyTo(radiance(r));

  for (const Distractor& dd : distractors) {
    if (dd.kind == 0) {  // a reflection streak: elongated, class-coloured
      cv::ellipse(radiance, dd.centre, cv::Size(14, 2), dd.angle, 0, 360, dd.colour, cv::FILLED, cv::LINE_AA);
    } else if (dd.kind == 1) {  // a large coloured patch (a glove, a label)
      cv::circle(radiance, dd.centre, 40, dd.colour, cv::FILLED, cv::LINE_AA);
    } else {
      cv::circle(radiance, dd.centre, 4, dd.colour, cv::FILLED, cv::LINE_AA);
    }
  }

  // Radiance of a marker: its colour at full exposure sits at ~240 DN so exposure > 1.06 saturates.
  for (const Drawable& d : drawables) {
    if (d.box.area() <= 0) continue;
    const int ix0 = d.box.x, ix1 = d.box.br().x - 1, iy0 = d.box.y, iy1 = d.box.br().y - 1;
    if (d.is_marker) {
      const WorldMarker& m = scene.markers[d.index];
      const ColourClass* cls = layout_.findClass(m.class_id);
      if (!cls) continue;
      const cv::Vec3f colour(cls->bgr[0], cls->bgr[1], cls->bgr[2]);
      for (int y = iy0; y <= iy1; ++y) {
        cv::Vec3f* row = radiance.ptr<cv::Vec3f>(y);
        for (int x = ix0; x <= ix1; ++x) {
          double a = 0.0;
          for (std::size_t s = 0; s < d.centres.size(); ++s) {
            a += discCoverage(std::hypot(x - d.centres[s].x(), y - d.centres[s].y()), d.radii[s], sigma);
          }
          a /= static_cast<double>(d.centres.size());
          if (a < 1e-4) continue;
          row[x] = row[x] * static_cast<float>(1.0 - a) + colour * static_cast<float>(a);
        }
      }
    } else {
      const cv::Vec3f steel(70.f, 72.f, 75.f);
      for (int y = iy0; y <= iy1; ++y) {
        cv::Vec3f* row = radiance.ptr<cv::Vec3f>(y);
        for (int x = ix0; x <= ix1; ++x) {
          const double a = discCoverage(segmentDistance(Eigen::Vector2d(x, y), d.a, d.b), d.radius_px, sigma);
          if (a < 1e-4) continue;
          row[x] = row[x] * static_cast<float>(1.0 - a) + steel * static_cast<float>(a);
        }
      }
    }
  }

  // Sensor: exposure, shot noise (variance ∝ signal), read noise, 8-bit quantisation with saturation.
  image->create(cam.height, cam.width, CV_8UC3);
  std::uint64_t state = rng() | 1ULL;
  auto next = [&state] {
    state ^= state << 13;
    state ^= state >> 7;
    state ^= state << 17;
    return state;
  };
  // Untouched pixels: the background's exposed level (static) through noise_lut_ — one table load per channel,
  // eight 8-bit random indices per 64-bit draw. Quantising the background level first costs nothing measurable
  // (no centroid is taken there).
  const std::uint8_t* level = background_levels_.at(camera).data();
  const std::uint8_t* lut = noise_lut_.data();
  for (int y = 0; y < cam.height; ++y) {
    std::uint8_t* out = image->ptr<std::uint8_t>(y);
    const std::uint8_t* lv = level + static_cast<std::size_t>(y) * 3 * cam.width;
    int i = 0;
    for (; i + 8 <= 3 * cam.width; i += 8) {
      std::uint64_t r = next();
      for (int j = 0; j < 8; ++j, r >>= 8) out[i + j] = lut[(lv[i + j] << 8) | (r & 255)];
    }
    for (std::uint64_t r = next(); i < 3 * cam.width; ++i, r >>= 8) out[i] = lut[(lv[i] << 8) | (r & 255)];
  }
  // Touched pixels: the exact model from the float radiance. Per-pixel normal draws from a fixed table indexed by
  // the xorshift stream: ~10× faster than std::normal_distribution. Overlapping boxes are simply redone.
  const std::vector<float>& table = normalTable();
  const float exposure = static_cast<float>(config_.exposure);
  // Noise σ per signal level from a table (read noise and shot noise, variance ∝ signal): no sqrt per pixel.
  std::array<float, 257> sigma_of_level;
  for (int lvl = 0; lvl <= 256; ++lvl) sigma_of_level[lvl] = sensorSigma(lvl);
  for (const cv::Rect& r : touched) {
    for (int y = r.y; y < r.br().y; ++y) {
      const float* in = radiance.ptr<float>(y) + 3 * r.x;
      std::uint8_t* out = image->ptr<std::uint8_t>(y) + 3 * r.x;
      for (int i = 0; i < 3 * r.width; ++i) {
        float v = in[i] * exposure;
        const float sd = sigma_of_level[std::clamp(static_cast<int>(v), 0, 256)];
        v += sd * table[next() & (kNormalTableSize - 1)];
        // Round half up without a libm call (v > -256 always: noise is a few σ of at most ~16 DN).
        out[i] = static_cast<std::uint8_t>(std::clamp(static_cast<int>(v + 256.5f) - 256, 0, 255));
      }
    }
  }

  if (truth) {
    // A marker counts as visible when its centre is not covered by a shaft piece nearer to the camera.
    for (std::size_t i = 0; i < projected.size(); ++i) {
      if (!projected[i].visible || !config_.shafts) continue;
      const double depth = (cam.world_to_camera * scene.markers[i].position).z();
      for (const Drawable& d : drawables) {
        if (!d.is_marker && d.depth < depth &&
            segmentDistance(projected[i].pixel, d.a, d.b) < d.radius_px + 0.5 * projected[i].radius_px) {
          projected[i].visible = false;
          break;
        }
      }
    }
    *truth = std::move(projected);
  }
}

void RigRenderer::exposeBackground(std::size_t camera, std::uint64_t frame_key, cv::Mat* image) const {
  const CameraModel& cam = rig_.cameras.at(camera);
  const std::size_t row_len = static_cast<std::size_t>(3) * cam.width;
  const std::uint8_t* level = background_levels_.at(camera).data();
  if (background_sigma_q11_.empty() || row_len >= kNormalBankSize) {
    // σ beyond the fixed-point range: the reference's per-byte noise table.
    std::uint64_t state = frame_key | 1ULL;
    const std::uint8_t* lut = noise_lut_.data();
    for (int y = 0; y < cam.height; ++y) {
      std::uint8_t* out = image->ptr<std::uint8_t>(y);
      const std::uint8_t* lv = level + static_cast<std::size_t>(y) * row_len;
      for (std::size_t i = 0; i < row_len; ++i) {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        out[i] = lut[(lv[i] << 8) | (state & 255)];
      }
    }
    return;
  }
  // level + round(σ·z) in fixed point: z in Q12 times σ in Q11, high 16 bits (σz in Q7), rounded half up — the
  // reference's rounding. One multiply per byte, no table lookup: the compiler vectorises it (pmulhw).
  const std::int16_t* bank = normalBankQ12().data();
  const std::int16_t* sigma = background_sigma_q11_.at(camera).data();
  const std::size_t offsets = kNormalBankSize - row_len;
  for (int y = 0; y < cam.height; ++y) {
    const std::int16_t* z = bank + mix(frame_key, static_cast<std::uint64_t>(y) + 1) % offsets;
    const std::uint8_t* lv = level + static_cast<std::size_t>(y) * row_len;
    const std::int16_t* sq = sigma + static_cast<std::size_t>(y) * row_len;
    std::uint8_t* out = image->ptr<std::uint8_t>(y);
    for (std::size_t i = 0; i < row_len; ++i) {
      const int noise_q7 = (static_cast<int>(z[i]) * sq[i]) >> 16;
      const int v = lv[i] + ((noise_q7 + 64) >> 7);
      out[i] = static_cast<std::uint8_t>(v < 0 ? 0 : v > 255 ? 255 : v);
    }
  }
}

// The same scene, drawables, painter's order, coverage model, distractor draws and sensor model as
// renderReference, restricted to the pixels that can change: each marker's rows of pixels within reach of a disc at
// one of its sub-frame positions, each shaft piece's rows within reach of its capsule, each distractor's box. The rest
// of the frame is exposeBackground. Cost follows the markers' and shafts' pixel count, not the frame's.
void RigRenderer::renderSpans(std::size_t camera, const WorldScene& scene, std::uint64_t frame_index, cv::Mat* image,
                              std::vector<ProjectedMarker>* truth) const {
  const CameraModel& cam = rig_.cameras.at(camera);
  std::mt19937_64 rng(mix(mix(config_.seed, camera), frame_index));
  std::vector<ProjectedMarker> projected = project(camera, scene);
  const double sigma = std::max(0.3, config_.blur_px);
  const double inv_sqrt2_sigma = 1.0 / (M_SQRT2 * sigma);
  // Beyond this distance outside a disc or capsule the coverage is exactly 0 (discCoverage's z >= 3.5).
  const double reach = kErfcRange * M_SQRT2 * sigma;
  const int samples = std::max(1, config_.motion_samples);
  const double* erfc_table = halfErfcTable().data();

  struct Drawable {
    double depth = 0.0;
    bool is_marker = true;
    std::size_t index = 0;                                                     // marker index, or shaft index
    Eigen::Vector2d a = Eigen::Vector2d::Zero(), b = Eigen::Vector2d::Zero();  // shaft piece ends (px)
    double radius_px = 0.0;
    double t_lo = 0.0, t_hi = 0.0;  // shaft piece: its share of the shaft's projection parameter
    std::vector<Eigen::Vector2d> centres;
    std::vector<double> radii;
    std::vector<Span> spans;  // marker
  };
  std::vector<Drawable> drawables;
  std::vector<Span> touched;
  for (std::size_t i = 0; i < scene.markers.size(); ++i) {
    if (!projected[i].visible && projected[i].radius_px <= 0.0) continue;
    const WorldMarker& m = scene.markers[i];
    Drawable d;
    d.depth = (cam.world_to_camera * m.position).z();
    d.index = i;
    for (int s = 0; s < samples; ++s) {
      const double dt = samples > 1 ? config_.exposure_time * ((s + 0.5) / samples - 0.5) : 0.0;
      Eigen::Vector2d px;
      const Eigen::Vector3d p = m.position + m.velocity * dt;
      if (!cam.project(p, &px)) continue;
      d.centres.push_back(px);
      d.radii.push_back(cam.K(0, 0) * m.radius / (cam.world_to_camera * p).z());
    }
    if (d.centres.empty()) continue;
    double y_lo = std::numeric_limits<double>::infinity(), y_hi = -y_lo;
    for (std::size_t s = 0; s < d.centres.size(); ++s) {
      y_lo = std::min(y_lo, d.centres[s].y() - d.radii[s] - reach);
      y_hi = std::max(y_hi, d.centres[s].y() + d.radii[s] + reach);
    }
    const int row0 = static_cast<int>(std::ceil(std::max(y_lo, 0.0)));
    const int row1 = static_cast<int>(std::floor(std::min(y_hi, cam.height - 1.0)));
    for (int y = row0; y <= row1; ++y) {
      double xl = std::numeric_limits<double>::infinity(), xr = -xl;
      for (std::size_t s = 0; s < d.centres.size(); ++s) {
        const double rr = d.radii[s] + reach, dy = y - d.centres[s].y();
        if (std::abs(dy) > rr) continue;
        const double h = std::sqrt(rr * rr - dy * dy);
        xl = std::min(xl, d.centres[s].x() - h);
        xr = std::max(xr, d.centres[s].x() + h);
      }
      int x0, x1;
      if (pixelRange(xl, xr, cam.width, &x0, &x1)) d.spans.push_back({y, x0, x1});
    }
    touched.insert(touched.end(), d.spans.begin(), d.spans.end());
    drawables.push_back(std::move(d));
  }
  if (config_.shafts) {
    for (const WorldSegment& seg : scene.shafts) {
      constexpr int kPieces = 24;  // the reference's pieces: the same depth order against the markers
      for (int k = 0; k < kPieces; ++k) {
        const Eigen::Vector3d pa = seg.a + (seg.b - seg.a) * (static_cast<double>(k) / kPieces);
        const Eigen::Vector3d pb = seg.a + (seg.b - seg.a) * (static_cast<double>(k + 1) / kPieces);
        Drawable d;
        d.is_marker = false;
        if (!cam.project(pa, &d.a) || !cam.project(pb, &d.b)) continue;
        d.depth = (cam.world_to_camera * (0.5 * (pa + pb))).z();
        d.radius_px = cam.K(0, 0) * seg.radius / d.depth;
        // Each piece is its own capsule, as in the reference (where two pieces overlap at a joint both blend).
        const double rr = d.radius_px + reach;
        const int row0 = static_cast<int>(std::ceil(std::max(std::min(d.a.y(), d.b.y()) - rr, 0.0)));
        const int row1 = static_cast<int>(std::floor(std::min(std::max(d.a.y(), d.b.y()) + rr, cam.height - 1.0)));
        for (int y = row0; y <= row1; ++y) {
          double xl, xr;
          int x0, x1;
          if (capsuleRowSpan(d.a, d.b, rr, y, &xl, &xr) && pixelRange(xl, xr, cam.width, &x0, &x1)) {
            d.spans.push_back({y, x0, x1});
          }
        }
        touched.insert(touched.end(), d.spans.begin(), d.spans.end());
        drawables.push_back(std::move(d));
      }
    }
  }
  std::sort(drawables.begin(), drawables.end(), [](const Drawable& x, const Drawable& y) { return x.depth > y.depth; });

  // Distractors: the reference's draws from the same stream, so both paths put them at the same places.
  const cv::Rect frame(0, 0, cam.width, cam.height);
  struct Distractor {
    cv::Point centre;
    int kind;
    double angle;
    cv::Scalar colour;
  };
  std::vector<Distractor> distractors;
  if (config_.distractors > 0) {
    std::uniform_real_distribution<double> ux(0, cam.width), uy(0, cam.height), angle(0, 180), u01(0, 1);
    for (int i = 0; i < config_.distractors; ++i) {
      Distractor dd;
      dd.centre = cv::Point(static_cast<int>(ux(rng)), static_cast<int>(uy(rng)));
      dd.kind = i % 3;
      dd.colour = cv::Scalar(220, 40, 220);  // magenta: no class
      if (dd.kind != 2 && !layout_.classes.empty()) {
        const ColourClass& c =
            layout_.classes[static_cast<std::size_t>(u01(rng) * layout_.classes.size()) % layout_.classes.size()];
        dd.colour = cv::Scalar(c.bgr[0], c.bgr[1], c.bgr[2]);
      }
      dd.angle = dd.kind == 0 ? angle(rng) : 0.0;
      const int reach_px = (dd.kind == 0 ? 14 : dd.kind == 1 ? 40 : 4) + 2;  // + anti-aliasing
      const cv::Rect r =
          cv::Rect(dd.centre.x - reach_px, dd.centre.y - reach_px, 2 * reach_px + 1, 2 * reach_px + 1) & frame;
      for (int y = r.y; y < r.br().y; ++y) touched.push_back({y, r.x, r.br().x - 1});
      distractors.push_back(dd);
    }
  }
  mergeSpans(&touched);

  thread_local cv::Mat radiance_buffer;
  radiance_buffer.create(cam.height, cam.width, CV_32FC3);
  cv::Mat& radiance = radiance_buffer;
  const cv::Mat& background = backgrounds_.at(camera);
  for (const Span& sp : touched) {
    std::copy_n(background.ptr<float>(sp.y) + 3 * sp.x0, 3 * (sp.x1 - sp.x0 + 1),
                radiance.ptr<float>(sp.y) + 3 * sp.x0);
  }
  for (const Distractor& dd : distractors) {
    if (dd.kind == 0) {
      cv::ellipse(radiance, dd.centre, cv::Size(14, 2), dd.angle, 0, 360, dd.colour, cv::FILLED, cv::LINE_AA);
    } else if (dd.kind == 1) {
      cv::circle(radiance, dd.centre, 40, dd.colour, cv::FILLED, cv::LINE_AA);
    } else {
      cv::circle(radiance, dd.centre, 4, dd.colour, cv::FILLED, cv::LINE_AA);
    }
  }

  const cv::Vec3f steel(70.f, 72.f, 75.f);
  for (const Drawable& d : drawables) {
    if (d.is_marker) {
      const ColourClass* cls = layout_.findClass(scene.markers[d.index].class_id);
      if (!cls) continue;
      const cv::Vec3f colour(cls->bgr[0], cls->bgr[1], cls->bgr[2]);
      const double inv_n = 1.0 / static_cast<double>(d.centres.size());
      for (const Span& sp : d.spans) {
        cv::Vec3f* row = radiance.ptr<cv::Vec3f>(sp.y);
        for (int x = sp.x0; x <= sp.x1; ++x) {
          double a = 0.0;
          for (std::size_t s = 0; s < d.centres.size(); ++s) {
            const double dx = x - d.centres[s].x(), dy = sp.y - d.centres[s].y();
            a += tabulatedCoverage((std::sqrt(dx * dx + dy * dy) - d.radii[s]) * inv_sqrt2_sigma, erfc_table);
          }
          a *= inv_n;
          if (a < 1e-4) continue;
          row[x] = row[x] * static_cast<float>(1.0 - a) + colour * static_cast<float>(a);
        }
      }
      continue;
    }
    // A shaft piece: coverage by the distance to its own segment, on its capsule's rows.
    const Eigen::Vector2d ab = d.b - d.a;
    const double len2 = ab.squaredNorm();
    for (const Span& sp : d.spans) {
      cv::Vec3f* row = radiance.ptr<cv::Vec3f>(sp.y);
      const double ry = sp.y - d.a.y();
      for (int x = sp.x0; x <= sp.x1; ++x) {
        const double rx = x - d.a.x();
        const double t = len2 > 0.0 ? std::clamp((rx * ab.x() + ry * ab.y()) / len2, 0.0, 1.0) : 0.0;
        const double ex = rx - t * ab.x(), ey = ry - t * ab.y();
        const double a = tabulatedCoverage((std::sqrt(ex * ex + ey * ey) - d.radius_px) * inv_sqrt2_sigma, erfc_table);
        if (a < 1e-4) continue;
        row[x] = row[x] * static_cast<float>(1.0 - a) + steel * static_cast<float>(a);
      }
    }
  }

  // Sensor: the untouched pixels from the noise bank, then the touched ones exactly as renderReference does.
  image->create(cam.height, cam.width, CV_8UC3);
  exposeBackground(camera, mix(mix(config_.seed, camera) ^ 0x5EEDBA4CULL, frame_index), image);
  std::uint64_t state = rng() | 1ULL;
  const std::vector<float>& table = normalTable();
  const float exposure = static_cast<float>(config_.exposure);
  std::array<float, 257> sigma_of_level;
  for (int lvl = 0; lvl <= 256; ++lvl) sigma_of_level[lvl] = sensorSigma(lvl);
  for (const Span& sp : touched) {
    const float* in = radiance.ptr<float>(sp.y) + 3 * sp.x0;
    std::uint8_t* out = image->ptr<std::uint8_t>(sp.y) + 3 * sp.x0;
    for (int i = 0; i < 3 * (sp.x1 - sp.x0 + 1); ++i) {
      state ^= state << 13;
      state ^= state >> 7;
      state ^= state << 17;
      float v = in[i] * exposure;
      const float sd = sigma_of_level[std::clamp(static_cast<int>(v), 0, 256)];
      v += sd * table[state & (kNormalTableSize - 1)];
      out[i] = static_cast<std::uint8_t>(std::clamp(static_cast<int>(v + 256.5f) - 256, 0, 255));
    }
  }

  if (truth) {
    // As renderReference: a marker's centre covered by a nearer shaft piece is hidden.
    for (std::size_t i = 0; i < projected.size(); ++i) {
      if (!projected[i].visible || !config_.shafts) continue;
      const double depth = (cam.world_to_camera * scene.markers[i].position).z();
      for (const Drawable& d : drawables) {
        if (!d.is_marker && d.depth < depth &&
            segmentDistance(projected[i].pixel, d.a, d.b) < d.radius_px + 0.5 * projected[i].radius_px) {
          projected[i].visible = false;
          break;
        }
      }
    }
    *truth = std::move(projected);
  }
}

}  // namespace vrm_tracking
