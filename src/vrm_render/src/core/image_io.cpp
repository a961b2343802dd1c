#include "vrm_render/image_io.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

namespace vrm_render {
namespace {

double luminance(const std::uint8_t* p) { return 0.299 * p[0] + 0.587 * p[1] + 0.114 * p[2]; }

void checkSameSize(const RgbImage& a, const RgbImage& b) {
  if (a.width != b.width || a.height != b.height || a.data.size() != b.data.size()) {
    throw RenderError("image sizes differ: " + std::to_string(a.width) + "x" + std::to_string(a.height) + " vs " +
                      std::to_string(b.width) + "x" + std::to_string(b.height));
  }
}

}  // namespace

void savePng(const RgbImage& image, const std::string& path) {
  if (image.width <= 0 || image.height <= 0) throw RenderError("savePng: empty image for " + path);
  cv::Mat rgb(image.height, image.width, CV_8UC3, const_cast<std::uint8_t*>(image.data.data()));
  cv::Mat bgr;
  cv::cvtColor(rgb, bgr, cv::COLOR_RGB2BGR);
  bool ok = false;
  try {
    ok = cv::imwrite(path, bgr);
  } catch (const cv::Exception& e) {
    throw RenderError("savePng: cannot write " + path + ": " + e.what());
  }
  if (!ok) throw RenderError("savePng: cannot write " + path);
}

RgbImage loadPng(const std::string& path) {
  cv::Mat bgr = cv::imread(path, cv::IMREAD_COLOR);
  if (bgr.empty()) throw RenderError("loadPng: cannot read " + path);
  cv::Mat rgb;
  cv::cvtColor(bgr, rgb, cv::COLOR_BGR2RGB);
  RgbImage image;
  image.width = rgb.cols;
  image.height = rgb.rows;
  image.data.assign(rgb.data, rgb.data + rgb.total() * 3);
  return image;
}

double psnr(const RgbImage& a, const RgbImage& b) {
  checkSameSize(a, b);
  double sum = 0.0;
  for (std::size_t i = 0; i < a.data.size(); ++i) {
    const double d = static_cast<double>(a.data[i]) - b.data[i];
    sum += d * d;
  }
  if (sum == 0.0) return std::numeric_limits<double>::infinity();
  const double mse = sum / a.data.size();
  return 10.0 * std::log10(255.0 * 255.0 / mse);
}

double fractionDifferent(const RgbImage& a, const RgbImage& b, int threshold) {
  checkSameSize(a, b);
  std::size_t count = 0;
  const std::size_t pixels = static_cast<std::size_t>(a.width) * a.height;
  for (std::size_t i = 0; i < pixels; ++i) {
    int largest = 0;
    for (int c = 0; c < 3; ++c) largest = std::max(largest, std::abs(int(a.data[3 * i + c]) - int(b.data[3 * i + c])));
    if (largest > threshold) ++count;
  }
  return pixels ? static_cast<double>(count) / pixels : 0.0;
}

double meanLuminance(const RgbImage& image, int x0, int y0, int x1, int y1) {
  x0 = std::max(0, x0);
  y0 = std::max(0, y0);
  x1 = std::min(image.width, x1);
  y1 = std::min(image.height, y1);
  double sum = 0.0;
  int count = 0;
  for (int y = y0; y < y1; ++y) {
    for (int x = x0; x < x1; ++x) {
      sum += luminance(image.pixel(x, y));
      ++count;
    }
  }
  return count ? sum / count : 0.0;
}

double laplacianEnergy(const RgbImage& image, int x0, int y0, int x1, int y1) {
  x0 = std::max(1, x0);
  y0 = std::max(1, y0);
  x1 = std::min(image.width - 1, x1);
  y1 = std::min(image.height - 1, y1);
  double sum = 0.0;
  int count = 0;
  for (int y = y0; y < y1; ++y) {
    for (int x = x0; x < x1; ++x) {
      const double l = 4.0 * luminance(image.pixel(x, y)) - luminance(image.pixel(x - 1, y)) -
                       luminance(image.pixel(x + 1, y)) - luminance(image.pixel(x, y - 1)) -
                       luminance(image.pixel(x, y + 1));
      sum += l * l;
      ++count;
    }
  }
  return count ? sum / count : 0.0;
}

}  // namespace vrm_render
