#pragma once
// PNG snapshots and image comparison metrics (golden-image tests, snapshot service). OpenCV-based, ROS-free.

#include <string>

#include "vrm_render/render_types.h"

namespace vrm_render {

// Throws RenderError when the file cannot be written / read.
void savePng(const RgbImage& image, const std::string& path);
RgbImage loadPng(const std::string& path);

// Peak signal-to-noise ratio over all channels (dB; +inf for identical images). Throws for size mismatch.
double psnr(const RgbImage& a, const RgbImage& b);
// Fraction of pixels whose largest channel difference exceeds `threshold`.
double fractionDifferent(const RgbImage& a, const RgbImage& b, int threshold);
// Mean luminance (0..255) of the rectangle [x0, x1) x [y0, y1), clipped to the image.
double meanLuminance(const RgbImage& image, int x0, int y0, int x1, int y1);
// Mean squared Laplacian of the luminance over a rectangle: a focus (sharpness) measure.
double laplacianEnergy(const RgbImage& image, int x0, int y0, int x1, int y1);

}  // namespace vrm_render
