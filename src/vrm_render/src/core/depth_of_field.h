#pragma once
// Depth of field on the CPU (pass 3b of the renderer, thesis §7.4.2): the Gaussian taps of the reduced-resolution
// blur the GPU runs, and the blend of the sharp image with the blurred one, fused with the readback. Private to
// vrm_render_core (no GL here: it works on glReadPixels' buffers).

#include <cstdint>
#include <vector>

#include "vrm_render/render_types.h"

namespace vrm_render {

// The separable Gaussian blur's weights and offsets for `taps` (9 or 13) taps of sigma `sigma_px`: tap 0 alone,
// then pairs (1,2), (3,4)[, (5,6)] merged into one bilinear fetch each. Fills taps / 4 + 1 entries of each array.
void dofBlurTaps(int taps, float sigma_px, float weights[4], float offsets[4]);

// out (RGB, top row first) = mix(sharp, blurred, sharp.a / 255), the blurred image sampled bilinearly at each pixel
// centre like texture() with GL_LINEAR and CLAMP_TO_EDGE. sharp (width x height) and blurred are RGBA8 as
// glReadPixels returns them, bottom row first. On llvmpipe a full-resolution composite pass costs several times
// this loop (generic texture sampling for every pixel).
struct DofBlend {
  const std::uint8_t* sharp = nullptr;
  int width = 0;
  int height = 0;
  const std::uint8_t* blurred = nullptr;
  int blurred_width = 0;
  int blurred_height = 0;
  const int* left = nullptr;  // per output column: offsets of the two blurred texels in an RGBA row
  const int* right = nullptr;
  const float* weight = nullptr;  // of the right texel

  // Fills left / right / weight, kept in the caller's buffers (reused between frames).
  void prepareColumns(std::vector<int>* columns, std::vector<float>* weights);
  // Output rows [y0, y1) (GL order, bottom first); `scratch` is per thread. out->data must hold width x height RGB.
  void rows(int y0, int y1, std::vector<float>* scratch, RgbImage* out) const;

  // One output row: RGB = sharp + (lerp(b0, b1, g) - sharp) * sharp.a / 255 (public for tests).
  static void blendRow(const std::uint8_t* sharp_row, const float* b0, const float* b1, float g, int n,
                       std::uint8_t* out_row);
  static void blendRowScalar(const std::uint8_t* sharp_row, const float* b0, const float* b1, float g, int n,
                             std::uint8_t* out_row);

 private:
  static void texel(float u, int size, int* i0, int* i1, float* f);
  void upsampleRow(int j, float* out) const;
};

// RGBA (bottom row first) to RGB (top row first): the readback without depth of field.
void rgbaToRgbFlipped(const std::uint8_t* rgba, int width, int height, RgbImage* out);

}  // namespace vrm_render
