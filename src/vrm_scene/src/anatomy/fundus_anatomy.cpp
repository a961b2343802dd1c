#include "vrm_scene/anatomy/fundus_anatomy.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace vrm_sim {
namespace anatomy {
namespace {

// A small deterministic generator (xorshift-multiply): the fundus must be the same for a seed on every platform,
// which std::uniform_real_distribution does not promise.
class Random {
 public:
  explicit Random(std::uint32_t seed) : state_(0x9E3779B97F4A7C15ull ^ (static_cast<std::uint64_t>(seed) << 1 | 1)) {}
  std::uint64_t next() {
    state_ ^= state_ >> 12;
    state_ ^= state_ << 25;
    state_ ^= state_ >> 27;
    return state_ * 0x2545F4914F6CDD1Dull;
  }
  float uniform() { return static_cast<float>(next() >> 40) * (1.0f / 16777216.0f); }  // [0, 1)
  float uniform(float lo, float hi) { return lo + (hi - lo) * uniform(); }
  float normal() {  // Irwin-Hall approximation: plenty for jitter
    float s = 0.0f;
    for (int i = 0; i < 4; ++i) s += uniform();
    return (s - 2.0f) * 1.7320508f;
  }

 private:
  std::uint64_t state_;
};

Eigen::Vector2f rotate(const Eigen::Vector2f& v, float angle) {
  const float c = std::cos(angle), s = std::sin(angle);
  return {c * v.x() - s * v.y(), s * v.x() + c * v.y()};
}

// Catmull-Rom through the control points, sampled every `step` metres (approximately).
std::vector<Eigen::Vector2f> spline(const std::vector<Eigen::Vector2f>& p, float step) {
  std::vector<Eigen::Vector2f> out;
  for (std::size_t i = 0; i + 1 < p.size(); ++i) {
    const Eigen::Vector2f p0 = p[i == 0 ? 0 : i - 1], p1 = p[i], p2 = p[i + 1], p3 = p[std::min(i + 2, p.size() - 1)];
    const int n = std::max(1, static_cast<int>((p2 - p1).norm() / step));
    for (int k = 0; k < n; ++k) {
      const float t = static_cast<float>(k) / n, t2 = t * t, t3 = t2 * t;
      out.push_back(0.5f * (2.0f * p1 + (p2 - p0) * t + (2.0f * p0 - 5.0f * p1 + 4.0f * p2 - p3) * t2 +
                            (3.0f * p1 - p0 - 3.0f * p2 + p3) * t3));
    }
  }
  out.push_back(p.back());
  return out;
}

constexpr float kMm = 1e-3f;
constexpr float kStep = 0.1f * kMm;          // centre-line segment length
constexpr float kMinRadius = 0.011f * kMm;   // smaller vessels are not seen at the microscope's resolution
constexpr float kTaperPerMetre = 25.0f;      // 2.5 % calibre loss per mm between bifurcations
constexpr std::size_t kMaxSegments = 40000;  // a bound against runaway growth

struct Grower {
  const FundusParams& params;
  Random& random;
  std::vector<VesselSegment>* out;
  float max_eccentricity;  // along the retina from the fovea

  bool stop(const Eigen::Vector2f& p) const {
    // [Hogan]: the foveal avascular zone, ~0.5 mm across, has no vessels.
    return p.norm() < 0.3f * kMm || p.norm() > max_eccentricity || out->size() >= kMaxSegments;
  }

  void add(const Eigen::Vector2f& a, const Eigen::Vector2f& b, float ra, float rb, bool artery, int arcade, int gen) {
    VesselSegment s;
    s.a = a;
    s.b = b;
    s.radius_a = ra;
    s.radius_b = rb;
    s.artery = artery;
    s.arcade = arcade;
    s.generation = gen;
    out->push_back(s);
  }

  // A daughter vessel's radius at a bifurcation and the parent's remaining one, [Murray]: r^3 = r1^3 + r2^3.
  void bifurcate(float r, float* daughter, float* parent) {
    const float k = random.uniform(0.45f, 0.8f);
    *daughter = k * r;
    *parent = std::cbrt(std::max(0.0f, r * r * r - *daughter * *daughter * *daughter));
  }

  // Free growth: a persistent random walk that bifurcates every 0.8-2 mm (longer for thicker vessels). Issue 33: the
  // heading used to turn by a strongly correlated walk (stationary ~0.1 rad per 0.1 mm step, i.e. ~1 rad/mm of
  // curvature), which curled branches into loops ("tangled vessels"). Now the turning is weakly correlated and
  // smaller, and the heading is pulled back towards the course the branch set out on, so branches wander a little
  // but keep going where they were sent, as healthy retinal vessels do ([Hart]).
  void grow(Eigen::Vector2f p, Eigen::Vector2f dir, float r, bool artery, int arcade, int gen, float length) {
    float next_branch = random.uniform(0.6f, 1.6f) * kMm * std::clamp(r / (0.03f * kMm), 0.6f, 1.6f);
    float travelled = 0.0f;
    float turn = 0.0f;
    Eigen::Vector2f course = dir;
    while (r > kMinRadius && travelled < length && !stop(p)) {
      turn = 0.5f * turn + random.normal() * 0.045f;  // tortuosity: mildly correlated heading changes
      dir = (rotate(dir, turn) + 0.08f * course).normalized();
      const Eigen::Vector2f q = p + kStep * dir;
      if (stop(q)) break;
      const float rq = r * (1.0f - kTaperPerMetre * kStep);
      add(p, q, r, rq, artery, arcade, gen);
      p = q;
      r = rq;
      travelled += kStep;
      if (travelled >= next_branch && gen < 4) {
        float daughter, parent;
        bifurcate(r, &daughter, &parent);
        const float side = random.uniform() < 0.5f ? -1.0f : 1.0f;
        const float angle = random.uniform(0.5f, 1.2f);  // 30-70 deg, the usual retinal branching angles
        grow(p, rotate(dir, side * angle), daughter, artery, arcade, gen + 1, length * random.uniform(0.4f, 0.7f));
        dir = rotate(dir, -side * angle * 0.3f);  // the parent deflects away from its daughter
        course = dir;
        r = parent;
        next_branch = travelled + random.uniform(0.8f, 2.0f) * kMm;
      }
    }
  }

  // The fine waviness of a healthy trunk ([Hart]: a few % longer than its chords): a perpendicular undulation of
  // 70-100 µm over 1.5-2.5 mm wavelengths (+1-2 % of arc over a chord), with its own random phase, fading in over the
  // first mm from the disc centre (the trunks leave the cup straight).
  void undulate(std::vector<Eigen::Vector2f>* line) {
    const std::size_t n = line->size();
    if (n < 3) return;
    const float amplitude = random.uniform(0.07f, 0.10f) * kMm;
    const float wavelength = random.uniform(1.5f, 2.5f) * kMm;
    const float phase = random.uniform(0.0f, 2.0f * static_cast<float>(M_PI));
    std::vector<Eigen::Vector2f> out = *line;
    float s = 0.0f;
    for (std::size_t i = 1; i + 1 < n; ++i) {
      s += ((*line)[i] - (*line)[i - 1]).norm();
      const Eigen::Vector2f t = ((*line)[i + 1] - (*line)[i - 1]).normalized();
      const Eigen::Vector2f normal(-t.y(), t.x());
      const float fade = std::min(1.0f, s / kMm);
      out[i] += fade * amplitude * std::sin(2.0f * static_cast<float>(M_PI) * s / wavelength + phase) * normal;
    }
    *line = std::move(out);
  }

  // A trunk along a jittered arcade path from the disc, branching off the side given by `outward` (a function of
  // where the fovea is: temporal arcades send most branches away from the macula and some small ones into it).
  void trunk(const std::vector<Eigen::Vector2f>& path, float r, bool artery, int arcade, bool temporal) {
    std::vector<Eigen::Vector2f> line = spline(path, kStep);
    undulate(&line);
    float travelled = 0.0f;
    // The first bifurcations lie beyond the disc margin, a disc diameter or more out ([Kanski]), beyond the zone
    // 0.5-1 disc diameter from the margin where [Knudtson] measures the trunks' calibres.
    const float disc_r = 0.5f * params.disc_diameter;
    float next_branch = disc_r + 2.0f * disc_r * 1.05f + random.uniform(0.1f, 0.6f) * kMm;
    for (std::size_t i = 0; i + 1 < line.size() && r > kMinRadius; ++i) {
      const float length = (line[i + 1] - line[i]).norm();
      const float rq = r * (1.0f - kTaperPerMetre * length);
      add(line[i], line[i + 1], r, rq, artery, arcade, 0);
      r = rq;
      travelled += length;
      if (travelled < next_branch) continue;
      const Eigen::Vector2f dir = (line[i + 1] - line[i]).normalized();
      // Which side faces the fovea: the sign of the cross product of the heading and the direction to the fovea.
      const Eigen::Vector2f to_fovea = -line[i + 1];
      const float fovea_side = dir.x() * to_fovea.y() - dir.y() * to_fovea.x() > 0.0f ? 1.0f : -1.0f;
      const bool inward = temporal && random.uniform() < 0.35f;
      const float side = temporal ? (inward ? fovea_side : -fovea_side) : (random.uniform() < 0.5f ? -1.0f : 1.0f);
      float daughter, parent;
      bifurcate(r, &daughter, &parent);
      if (inward) daughter = std::min(daughter, 0.45f * r);  // macular branches are small
      grow(line[i + 1], rotate(dir, side * random.uniform(0.6f, 1.2f)), daughter, artery, arcade, 1,
           random.uniform(3.0f, 7.0f) * kMm);
      r = std::max(parent, 0.8f * r);  // the trunk keeps its identity (a side branch, not a symmetric split)
      next_branch = travelled + random.uniform(1.0f, 2.0f) * kMm;
    }
    // Beyond the drawn arcade the trunk continues into the periphery.
    if (line.size() >= 2) {
      const Eigen::Vector2f dir = (line.back() - line[line.size() - 2]).normalized();
      grow(line.back(), dir, r, artery, arcade, 1, 8.0f * kMm);
    }
  }
};

}  // namespace

FundusAnatomy::FundusAnatomy(const FundusParams& params) : params_(params) {
  if (!(params_.eye_radius > 0.0f) || params_.texture_size < 16 || params_.texture_size > 4096 ||
      !(params_.disc_diameter > 0.0f) || !std::isfinite(params_.disc_fovea_distance)) {
    throw std::invalid_argument("fundus: eye_radius and disc_diameter must be positive, texture_size within 16..4096");
  }
  params_.nasal_sign = params_.nasal_sign < 0.0f ? -1.0f : 1.0f;
  disc_ = Eigen::Vector2f(params_.nasal_sign * params_.disc_fovea_distance, params_.disc_above_fovea);
  growVessels();
}

Eigen::Vector2f FundusAnatomy::cupCentre() const {
  // Slightly temporal of the disc centre ([Jonas]).
  return disc_ - Eigen::Vector2f(params_.nasal_sign * 0.12f * 0.5f * params_.disc_diameter, 0.0f);
}

Eigen::Vector2f FundusAnatomy::toFundus(const Eigen::Vector3f& p) const {
  return fundusCoordinates(p, params_.eye_radius);
}

Eigen::Vector2f fundusCoordinates(const Eigen::Vector3f& p, float eye_radius) {
  const float norm = p.norm();
  if (!(norm > 0.0f)) return Eigen::Vector2f::Zero();
  const float theta = std::acos(std::clamp(-p.z() / norm, -1.0f, 1.0f));
  const Eigen::Vector2f azimuth(p.x(), p.y());
  const float a = azimuth.norm();
  if (a < 1e-12f) return Eigen::Vector2f::Zero();
  return eye_radius * theta * azimuth / a;
}

Eigen::Vector3f FundusAnatomy::toEye(const Eigen::Vector2f& f) const {
  const float s = f.norm();
  const float theta = s / params_.eye_radius;
  const Eigen::Vector2f dir = s > 1e-12f ? Eigen::Vector2f(f / s) : Eigen::Vector2f::UnitX();
  return params_.eye_radius * Eigen::Vector3f(std::sin(theta) * dir.x(), std::sin(theta) * dir.y(), -std::cos(theta));
}

VesselQuery FundusAnatomy::nearestVessel(const Eigen::Vector3f& point_in_eye) const {
  const Eigen::Vector2f p = toFundus(point_in_eye);
  VesselQuery best;
  for (std::size_t i = 0; i < vessels_.size(); ++i) {
    const VesselSegment& s = vessels_[i];
    const Eigen::Vector2f ab = s.b - s.a;
    const float t = std::clamp((p - s.a).dot(ab) / std::max(ab.squaredNorm(), 1e-20f), 0.0f, 1.0f);
    const float d = (p - (s.a + t * ab)).norm();
    if (d < best.distance) {
      best.distance = d;
      best.radius = s.radius_a + (s.radius_b - s.radius_a) * t;
      best.artery = s.artery;
      best.segment = static_cast<int>(i);
    }
  }
  best.inside = best.segment >= 0 && best.distance <= best.radius;
  return best;
}

void FundusAnatomy::growVessels() {
  Random random(params_.seed);
  const float ns = params_.nasal_sign;
  // The retina ends at the equator of the cap; vessels stop a little before.
  Grower grower{params_, random, &vessels_, 0.95f * params_.eye_radius * static_cast<float>(M_PI) * 0.5f};
  auto mm = [&](float x, float y) { return Eigen::Vector2f(ns * x * kMm, y * kMm); };
  auto jittered = [&](std::vector<Eigen::Vector2f> path, float sigma_mm) {
    for (std::size_t i = 1; i < path.size(); ++i)
      path[i] += sigma_mm * kMm * Eigen::Vector2f(random.normal(), random.normal());
    return path;
  };
  const Eigen::Vector2f d = disc_;
  const float disc_r = 0.5f * params_.disc_diameter;
  const Eigen::Vector2f cup = cupCentre();
  const float cup_r = params_.cup_to_disc * disc_r;
  // [Kanski] arcade courses (mm, nasal +, superior +), laid out relative to the disc and the fovea wherever the scene
  // puts the disc (issue 33: the scene's optic_disc may lie 3.1 mm from the fovea, the anatomical default 4.5 mm):
  // the temporal arcades leave the disc vertically, bend temporally and arch over and under the macula ~3 mm from
  // the fovea (at a fraction of the disc's distance on the way), then run on temporally, converging slowly towards the
  // horizontal raphe; the nasal ones run up- and down-nasally, straighter.
  const float dx = std::abs(d.x()) / kMm, dy = d.y() / kMm;
  const std::vector<std::vector<Eigen::Vector2f>> arcades = {
      {d, mm(dx - 0.1f, dy + 1.1f), mm(0.72f * dx, 2.55f), mm(0.3f * dx, 3.05f), mm(-1.0f, 3.2f), mm(-3.5f, 3.0f),
       mm(-6.5f, 2.5f), mm(-9.5f, 2.0f)},
      {d, mm(dx - 0.1f, dy - 1.1f), mm(0.72f * dx, -2.4f), mm(0.3f * dx, -2.85f), mm(-1.0f, -3.0f), mm(-3.5f, -2.8f),
       mm(-6.5f, -2.3f), mm(-9.5f, -1.8f)},
      {d, mm(dx + 0.5f, dy + 1.2f), mm(dx + 1.3f, dy + 2.6f), mm(dx + 2.5f, dy + 4.1f), mm(dx + 4.0f, dy + 5.7f),
       mm(dx + 5.5f, dy + 7.1f)},
      {d, mm(dx + 0.5f, dy - 1.2f), mm(dx + 1.3f, dy - 2.6f), mm(dx + 2.5f, dy - 4.2f), mm(dx + 4.0f, dy - 5.9f),
       mm(dx + 5.5f, dy - 7.4f)},
  };
  // [Jonas] calibres at the disc: veins ~130-150 µm (temporal), nasal vessels thinner; arteries 0.72 of their vein
  // (a [Knudtson] AVR of ~0.62: its formulas combine arteries with 0.88, veins with 0.95; measured in
  // test_fundus_anatomy).
  constexpr float kArteryToVein = 0.74f;
  for (int artery = 0; artery < 2; ++artery) {  // veins first: arteries are drawn over them where they cross
    for (int a = 0; a < 4; ++a) {
      // Control points 1.5-3 mm apart jittered by ~0.1 mm: the trunk's course varies between eyes without kinks.
      std::vector<Eigen::Vector2f> path = jittered(arcades[a], 0.1f);
      // The artery of an arcade runs beside its vein, a few tenths of a mm apart on one side (it crosses the vein
      // at the disc, where both emerge from the cup).
      float side = 0.0f;
      if (artery) {
        side = random.uniform() < 0.5f ? -1.0f : 1.0f;
        for (std::size_t i = 1; i < path.size(); ++i) {
          const Eigen::Vector2f t = (path[std::min(i + 1, path.size() - 1)] - path[i - 1]).normalized();
          // Half the offset at the first control point: the artery bends away from its vein gently at the rim.
          const float offset = random.uniform(0.15f, 0.35f) * (i == 1 ? 0.6f : 1.0f);
          path[i] += side * offset * kMm * Eigen::Vector2f(-t.y(), t.x());
        }
      }
      // Each vessel emerges at the margin of the cup, on the side it heads for (the artery a little beside its
      // vein), not at one central point: the pale cup stays visible between them, as in a healthy disc.
      const Eigen::Vector2f out = (path[1] - cup).normalized();
      path[0] = cup + 0.6f * cup_r * rotate(out, 0.3f * side);
      const bool temporal = a < 2;
      const float vein_radius = (temporal ? 0.07f : 0.055f) * kMm;
      grower.trunk(path, artery ? kArteryToVein * vein_radius : vein_radius, artery != 0, a, temporal);
    }
  }
  // A few small vessels leave the disc margin towards the macula (papillomacular bundle region) and nasally.
  for (int k = 0; k < 4; ++k) {
    const float angle =
        (k < 2 ? (ns > 0 ? static_cast<float>(M_PI) : 0.0f) : (ns > 0 ? 0.0f : static_cast<float>(M_PI))) +
        random.uniform(-0.35f, 0.35f);
    const Eigen::Vector2f dir(std::cos(angle), std::sin(angle));
    grower.grow(d + 0.5f * params_.disc_diameter * dir, dir, 0.022f * kMm, k % 2 == 1, -1, 1,
                random.uniform(1.5f, 3.0f) * kMm);
  }
}

}  // namespace anatomy
}  // namespace vrm_sim
