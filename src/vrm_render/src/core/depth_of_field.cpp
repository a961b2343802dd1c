#include "depth_of_field.h"

#include <algorithm>
#include <cmath>
#include <cstring>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

namespace vrm_render {

void dofBlurTaps(int taps, float sigma_px, float weights[4], float offsets[4]) {
  const int half = taps / 2;
  float g[7];
  float sum = 0.0f;
  for (int i = 0; i <= half; ++i) {
    g[i] = std::exp(-0.5f * i * i / (sigma_px * sigma_px));
    sum += i == 0 ? g[i] : 2.0f * g[i];
  }
  weights[0] = g[0] / sum;
  offsets[0] = 0.0f;
  for (int k = 1; k < 4; ++k) weights[k] = offsets[k] = 0.0f;
  for (int k = 1; k <= half / 2; ++k) {
    const float a = g[2 * k - 1], b = g[2 * k];
    weights[k] = (a + b) / sum;
    offsets[k] = (a * (2 * k - 1) + b * 2 * k) / (a + b);
  }
}

void DofBlend::texel(float u, int size, int* i0, int* i1, float* f) {
  const float fl = std::floor(u);
  *f = u - fl;
  *i0 = std::clamp(static_cast<int>(fl), 0, size - 1);
  *i1 = std::clamp(static_cast<int>(fl) + 1, 0, size - 1);
}

void DofBlend::prepareColumns(std::vector<int>* columns, std::vector<float>* weights) {
  columns->resize(2 * static_cast<std::size_t>(width));
  weights->resize(width);
  int* l = columns->data();
  int* r = l + width;
  for (int x = 0; x < width; ++x) {
    texel((x + 0.5f) * blurred_width / width - 0.5f, blurred_width, &l[x], &r[x], &(*weights)[x]);
    l[x] *= 4;
    r[x] *= 4;
  }
  left = l;
  right = r;
  weight = weights->data();
}

// One output row: RGB = sharp + (lerp(b0, b1, g) - sharp) * sharp.a / 255. SSE2 (x86-64 baseline), one pixel per
// vector, the same float operations in the same order as the scalar reference (blendRowScalar, kept for the last
// pixel of a row and for other architectures): bit-identical output.
// Each pixel is stored as 4 bytes at 3 x; the next pixel overwrites the fourth, the row's last pixel is written
// with 3 byte stores so that no byte of another row (maybe another thread's) is touched.
void DofBlend::blendRow(const std::uint8_t* __restrict sharp_row, const float* __restrict b0,
                        const float* __restrict b1, float g, int n, std::uint8_t* __restrict out_row) {
#if defined(__SSE2__)
  const __m128 gv = _mm_set1_ps(g);
  const __m128 half = _mm_set1_ps(0.5f);
  const __m128 inv255 = _mm_set1_ps(1.0f / 255.0f);
  const __m128i zero = _mm_setzero_si128();
  int x = 0;
  for (; x + 1 < n; ++x) {
    std::uint32_t packed;
    std::memcpy(&packed, sharp_row + 4 * x, 4);
    const __m128i s16 = _mm_unpacklo_epi8(_mm_cvtsi32_si128(static_cast<int>(packed)), zero);
    const __m128 v = _mm_cvtepi32_ps(_mm_unpacklo_epi16(s16, zero));
    const __m128 w = _mm_mul_ps(_mm_shuffle_ps(v, v, _MM_SHUFFLE(3, 3, 3, 3)), inv255);
    const __m128 lo = _mm_loadu_ps(b0 + 4 * x);
    const __m128 b = _mm_add_ps(lo, _mm_mul_ps(_mm_sub_ps(_mm_loadu_ps(b1 + 4 * x), lo), gv));
    const __m128 r = _mm_add_ps(_mm_add_ps(v, _mm_mul_ps(_mm_sub_ps(b, v), w)), half);
    const __m128i i32 = _mm_cvttps_epi32(r);
    const __m128i i8 = _mm_packus_epi16(_mm_packs_epi32(i32, zero), zero);
    const std::uint32_t out = static_cast<std::uint32_t>(_mm_cvtsi128_si32(i8));
    std::memcpy(out_row + 3 * x, &out, 4);
  }
  blendRowScalar(sharp_row + 4 * x, b0 + 4 * x, b1 + 4 * x, g, n - x, out_row + 3 * x);
#else
  blendRowScalar(sharp_row, b0, b1, g, n, out_row);
#endif
}

void DofBlend::blendRowScalar(const std::uint8_t* __restrict sharp_row, const float* __restrict b0,
                              const float* __restrict b1, float g, int n, std::uint8_t* __restrict out_row) {
  for (int x = 0; x < n; ++x) {
    const float w = sharp_row[4 * x + 3] * (1.0f / 255.0f);
    for (int c = 0; c < 3; ++c) {
      const float b = b0[4 * x + c] + (b1[4 * x + c] - b0[4 * x + c]) * g;
      const float v = sharp_row[4 * x + c];
      out_row[3 * x + c] = static_cast<std::uint8_t>(v + (b - v) * w + 0.5f);
    }
  }
}

// Blurred row j upsampled to the output width (RGB floats, 4 per pixel; the fourth is not used).
void DofBlend::upsampleRow(int j, float* out) const {
  const std::uint8_t* row = blurred + static_cast<std::size_t>(j) * blurred_width * 4;
#if defined(__SSE2__)
  const __m128i zero = _mm_setzero_si128();
  auto load = [&](const std::uint8_t* p) {
    std::uint32_t packed;
    std::memcpy(&packed, p, 4);
    return _mm_cvtepi32_ps(
        _mm_unpacklo_epi16(_mm_unpacklo_epi8(_mm_cvtsi32_si128(static_cast<int>(packed)), zero), zero));
  };
  for (int x = 0; x < width; ++x) {
    const __m128 a = load(row + left[x]);
    const __m128 b = load(row + right[x]);
    _mm_storeu_ps(out + 4 * x, _mm_add_ps(a, _mm_mul_ps(_mm_sub_ps(b, a), _mm_set1_ps(weight[x]))));
  }
#else
  for (int x = 0; x < width; ++x) {
    const std::uint8_t* a = row + left[x];
    const std::uint8_t* b = row + right[x];
    const float f = weight[x];
    for (int c = 0; c < 3; ++c) out[4 * x + c] = a[c] + (b[c] - a[c]) * f;
  }
#endif
}

// Output rows [y0, y1) (GL order, bottom first); `scratch` is per thread. Each blurred row is upsampled once
// (kept while consecutive output rows share it), so the per-pixel loop reads contiguous memory only.
void DofBlend::rows(int y0, int y1, std::vector<float>* scratch, RgbImage* out) const {
  scratch->resize(8 * static_cast<std::size_t>(width));
  float* upper = scratch->data();
  float* lower = upper + 4 * static_cast<std::size_t>(width);
  int upper_row = -1, lower_row = -1;
  for (int y = y0; y < y1; ++y) {
    int j0, j1;
    float g;
    texel((y + 0.5f) * blurred_height / height - 0.5f, blurred_height, &j0, &j1, &g);
    if (j0 != lower_row) {
      if (j0 == upper_row) {
        std::swap(lower, upper);
        std::swap(lower_row, upper_row);
      } else {
        upsampleRow(j0, lower);
        lower_row = j0;
      }
    }
    if (j1 != upper_row) {
      upsampleRow(j1, upper);
      upper_row = j1;
    }
    blendRow(sharp + static_cast<std::size_t>(y) * width * 4, lower, upper, g, width,
             out->data.data() + static_cast<std::size_t>(height - 1 - y) * width * 3);
  }
}

// RGBA (bottom row first) to RGB (top row first).
void rgbaToRgbFlipped(const std::uint8_t* rgba, int width, int height, RgbImage* out) {
  for (int y = 0; y < height; ++y) {
    const std::uint8_t* s = rgba + static_cast<std::size_t>(y) * width * 4;
    std::uint8_t* o = out->data.data() + static_cast<std::size_t>(height - 1 - y) * width * 3;
    for (int x = 0; x < width; ++x) {
      o[3 * x] = s[4 * x];
      o[3 * x + 1] = s[4 * x + 1];
      o[3 * x + 2] = s[4 * x + 2];
    }
  }
}

}  // namespace vrm_render
