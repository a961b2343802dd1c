#include "vrm_render/fundus.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "vrm_render/render_types.h"

namespace vrm_render {
namespace {

// Value noise on an integer lattice hashed with the seed, smoothly interpolated: the choroidal pattern.
float hashLattice(int x, int y, std::uint32_t seed) {
  std::uint32_t h = static_cast<std::uint32_t>(x) * 374761393u + static_cast<std::uint32_t>(y) * 668265263u + seed;
  h = (h ^ (h >> 13)) * 1274126177u;
  h ^= h >> 16;
  return static_cast<float>(h & 0xFFFFFF) * (1.0f / 16777216.0f);
}

float valueNoise(float x, float y, std::uint32_t seed) {
  const float fx = std::floor(x), fy = std::floor(y);
  const int ix = static_cast<int>(fx), iy = static_cast<int>(fy);
  float tx = x - fx, ty = y - fy;
  tx = tx * tx * (3.0f - 2.0f * tx);
  ty = ty * ty * (3.0f - 2.0f * ty);
  const float a = hashLattice(ix, iy, seed), b = hashLattice(ix + 1, iy, seed);
  const float c = hashLattice(ix, iy + 1, seed), d = hashLattice(ix + 1, iy + 1, seed);
  return (a + (b - a) * tx) + ((c + (d - c) * tx) - (a + (b - a) * tx)) * ty;
}

constexpr float kMm = 1e-3f;

float smoothstep(float e0, float e1, float x) {
  const float t = std::clamp((x - e0) / (e1 - e0), 0.0f, 1.0f);
  return t * t * (3.0f - 2.0f * t);
}

}  // namespace

FundusMap::FundusMap(const FundusParams& params)
    : anatomy_([&] {
        try {
          return vrm_sim::anatomy::FundusAnatomy(params);
        } catch (const std::invalid_argument& error) {
          throw RenderError(error.what());
        }
      }()) {
  bake();
}

void FundusMap::bake() {
  const FundusParams& params = anatomy_.params();
  const Eigen::Vector2f disc = anatomy_.discCentre();
  const std::vector<VesselSegment>& vessels = anatomy_.vessels();
  const int n = params.texture_size;
  const float radius = params.eye_radius;
  const float texel = 2.0f * radius / n;
  std::vector<float> rgb(static_cast<std::size_t>(n) * n * 3);
  const std::uint32_t seed = params.seed * 2654435761u;
  const float disc_r = 0.5f * params.disc_diameter;
  const Eigen::Vector2f cup = cupCentre();

  for (int j = 0; j < n; ++j) {
    for (int i = 0; i < n; ++i) {
      const float x = -radius + (i + 0.5f) * texel, y = -radius + (j + 0.5f) * texel;
      const float rr = std::min(x * x + y * y, radius * radius * 0.9999f);
      const Eigen::Vector2f f = toFundus(Eigen::Vector3f(x, y, -std::sqrt(radius * radius - rr)));
      // Choroid: orange-red RPE/choroid background; the choroidal vessels show as a lighter network with darker
      // pigmented interstices (a mildly "tigroid" fundus), on a ~0.7 mm scale, plus slow variation.
      const float u = f.x() / (0.45f * kMm), v = f.y() / (0.45f * kMm);
      const float ridge = 1.0f - std::abs(2.0f * valueNoise(u, v, seed) - 1.0f);
      const float ridge2 = 1.0f - std::abs(2.0f * valueNoise(2.1f * u + 5.3f, 2.1f * v - 1.7f, seed + 7u) - 1.0f);
      const float slow = valueNoise(f.x() / (3.0f * kMm), f.y() / (3.0f * kMm), seed + 13u);
      const float choroid = 0.55f * std::pow(ridge, 3.0f) + 0.25f * std::pow(ridge2, 3.0f);
      float r = 0.80f * (0.86f + 0.14f * slow) * (0.91f + 0.12f * choroid);
      float g = 0.33f * (0.86f + 0.14f * slow) * (0.88f + 0.16f * choroid);
      float b = 0.17f * (0.86f + 0.14f * slow) * (0.88f + 0.14f * choroid);
      // Macula ([Hogan]): xanthophyll and denser RPE pigment darken it towards the fovea; the foveola darker still,
      // with its small light reflex in the centre.
      const float e2 = f.squaredNorm();
      const float macula = std::exp(-e2 / (params.macula_radius * params.macula_radius));
      const float fovea = std::exp(-e2 / (params.fovea_radius * params.fovea_radius));
      r *= 1.0f - 0.30f * macula - 0.15f * fovea;
      g *= 1.0f - 0.42f * macula - 0.20f * fovea;
      b *= 1.0f - 0.50f * macula - 0.20f * fovea;
      const float reflex = std::exp(-e2 / (0.04f * kMm * 0.04f * kMm));
      r += 0.25f * reflex;
      g += 0.22f * reflex;
      b += 0.15f * reflex;
      // Optic disc ([Hogan]: vertically oval, 1.5 x 1.75 mm): pinkish-yellow neuroretinal rim, a pale cup, a thin
      // darker peripapillary ring.
      const Eigen::Vector2f dd = f - disc;
      const float de = std::sqrt(dd.x() * dd.x() / (0.93f * 0.93f) + dd.y() * dd.y() / (1.07f * 1.07f)) / disc_r;
      const float ring = std::exp(-(de - 1.08f) * (de - 1.08f) / 0.004f);
      r *= 1.0f - 0.25f * ring;
      g *= 1.0f - 0.30f * ring;
      b *= 1.0f - 0.30f * ring;
      // Issue 33: yellow-white (the rim was salmon-pink, 0.98/0.70/0.52, and read as a dim disc).
      const float rim = 1.0f - smoothstep(0.9f, 1.02f, de);
      r += (0.98f - r) * rim;
      g += (0.80f - g) * rim;
      b += (0.58f - b) * rim;
      const Eigen::Vector2f dc = f - cup;
      const float cup_e = dc.norm() / (params.cup_to_disc * disc_r);
      const float pale = 1.0f - smoothstep(0.6f, 1.15f, cup_e);
      r += (1.0f - r) * pale;
      g += (0.96f - g) * pale;
      b += (0.86f - b) * pale;
      float* out = rgb.data() + (static_cast<std::size_t>(j) * n + i) * 3;
      out[0] = r;
      out[1] = g;
      out[2] = b;
    }
  }

  // Vessels: each segment as a capsule of its radius in texel space (the orthographic map is within a few % of
  // the fundus map near the posterior pole). Cross-section: blood absorbs more along the longer central path, a
  // central light reflex, brighter on arteries ([Kanski]); anti-aliased over one texel. Per texel the most opaque
  // vessel wins (no darkening where a vessel's own segments overlap), an artery over a vein where they cross.
  std::vector<float> opacity(static_cast<std::size_t>(n) * n, 0.0f);
  std::vector<std::uint8_t> is_artery(static_cast<std::size_t>(n) * n, 0);
  std::vector<float> profile(static_cast<std::size_t>(n) * n, 0.0f);
  auto toTexel = [&](const Eigen::Vector2f& f) {
    const Eigen::Vector3f p = toEye(f);
    return Eigen::Vector2f((p.x() + radius) / texel - 0.5f, (p.y() + radius) / texel - 0.5f);
  };
  for (const VesselSegment& s : vessels) {
    const Eigen::Vector2f a = toTexel(s.a), b = toTexel(s.b);
    const float ra = s.radius_a / texel, rb = s.radius_b / texel;
    const float reach = std::max(ra, rb) + 1.0f;
    const int x0 = std::max(0, static_cast<int>(std::floor(std::min(a.x(), b.x()) - reach)));
    const int x1 = std::min(n - 1, static_cast<int>(std::ceil(std::max(a.x(), b.x()) + reach)));
    const int y0 = std::max(0, static_cast<int>(std::floor(std::min(a.y(), b.y()) - reach)));
    const int y1 = std::min(n - 1, static_cast<int>(std::ceil(std::max(a.y(), b.y()) + reach)));
    const Eigen::Vector2f ab = b - a;
    const float len2 = std::max(ab.squaredNorm(), 1e-12f);
    for (int y = y0; y <= y1; ++y) {
      for (int x = x0; x <= x1; ++x) {
        const Eigen::Vector2f p(static_cast<float>(x), static_cast<float>(y));
        const float t = std::clamp((p - a).dot(ab) / len2, 0.0f, 1.0f);
        const float d = (p - (a + t * ab)).norm();
        const float r = ra + (rb - ra) * t;
        // Sub-texel vessels are drawn 0.8 texel wide and fainter, not as a dotted line.
        const float re = std::max(r, 0.8f);
        const float cover = std::clamp(re + 0.5f - d, 0.0f, 1.0f) * std::min(1.0f, 0.4f + 0.6f * r / re);
        if (cover <= 0.0f) continue;
        const float across = std::min(1.0f, d / re);
        const float op = cover * (0.55f + 0.45f * std::sqrt(1.0f - across * across));
        const std::size_t k = static_cast<std::size_t>(y) * n + x;
        const bool over = s.artery ? (op > 0.5f * opacity[k] || is_artery[k]) && op > (is_artery[k] ? opacity[k] : 0.0f)
                                   : !is_artery[k] && op > opacity[k];
        if (!over) continue;
        opacity[k] = op;
        is_artery[k] = s.artery ? 1 : 0;
        profile[k] = across;
      }
    }
  }

  texture_.resize(static_cast<std::size_t>(n) * n * 4);
  for (std::size_t k = 0; k < opacity.size(); ++k) {
    float* c = rgb.data() + 3 * k;
    if (opacity[k] > 0.0f) {
      const bool artery = is_artery[k] != 0;
      const float vr = artery ? 0.62f : 0.38f, vg = artery ? 0.12f : 0.06f, vb = artery ? 0.08f : 0.06f;
      // Issue 33: the arteries' reflex at 0.16 lifted their centre above half the vessel's depth in the red-free
      // (green) view, so that an artery read as two thin lines; a narrow reflex that leaves it one dark vessel.
      const float reflex = (artery ? 0.08f : 0.04f) * std::exp(-profile[k] * profile[k] / 0.04f);
      const float o = std::min(1.0f, opacity[k]);
      c[0] += (vr + reflex - c[0]) * o;
      c[1] += (vg + reflex * 0.8f - c[1]) * o;
      c[2] += (vb + reflex * 0.7f - c[2]) * o;
    }
    for (int ch = 0; ch < 3; ++ch) {
      texture_[4 * k + ch] = static_cast<std::uint8_t>(std::clamp(c[ch], 0.0f, 1.0f) * 255.0f + 0.5f);
    }
    texture_[4 * k + 3] = 255;
  }
}

TexelRect paintBurn(std::vector<std::uint8_t>* texture, int size, float eye_radius, const FundusBurn& burn) {
  TexelRect rect;
  if (!burn.position.allFinite() || !(burn.diameter > 0.0f) || !std::isfinite(burn.whiteness) || !(eye_radius > 0.0f) ||
      texture->size() != static_cast<std::size_t>(size) * size * 4) {
    return rect;
  }
  const float radius = 0.5f * burn.diameter;
  const float texel = 2.0f * eye_radius / size;
  // Clamped before the cast: a finite but huge burn (a corrupt LaserBurn) lies far off the texture, and a float beyond
  // int's range cast to int is undefined (found by the mesh_upload fuzz target).
  const auto toTexel = [&](float v) {
    return static_cast<int>(std::clamp(std::floor((v + eye_radius) / texel), -1.0f, static_cast<float>(size)));
  };
  const int x0 = std::max(0, toTexel(burn.position.x() - radius)),
            x1 = std::min(size - 1, toTexel(burn.position.x() + radius));
  const int y0 = std::max(0, toTexel(burn.position.y() - radius)),
            y1 = std::min(size - 1, toTexel(burn.position.y() + radius));
  if (x0 > x1 || y0 > y1) return rect;
  // Denatured retina scatters: a grey-white lesion, whitest at its centre (a strong burn's white core, a grey halo).
  const Eigen::Vector3f white(0.93f, 0.91f, 0.84f);
  const float strength = std::clamp(burn.whiteness, 0.0f, 1.0f);
  for (int j = y0; j <= y1; ++j) {
    for (int i = x0; i <= x1; ++i) {
      const float x = -eye_radius + (i + 0.5f) * texel, y = -eye_radius + (j + 0.5f) * texel;
      const float rr = std::min(x * x + y * y, eye_radius * eye_radius * 0.9999f);
      const Eigen::Vector3f on_retina(x, y, -std::sqrt(eye_radius * eye_radius - rr));
      const float r = (on_retina - burn.position).norm() / radius;
      if (r >= 1.0f) continue;
      const float cover = strength * smoothstep(1.0f, 0.6f, r) * (0.8f + 0.2f * (1.0f - r));
      std::uint8_t* rgba = texture->data() + (static_cast<std::size_t>(j) * size + i) * 4;
      for (int c = 0; c < 3; ++c) {
        const float value = rgba[c] / 255.0f + cover * (white[c] - rgba[c] / 255.0f);
        rgba[c] = static_cast<std::uint8_t>(std::lround(std::clamp(value, 0.0f, 1.0f) * 255.0f));
      }
    }
  }
  rect.x = x0;
  rect.y = y0;
  rect.width = x1 - x0 + 1;
  rect.height = y1 - y0 + 1;
  return rect;
}

}  // namespace vrm_render
