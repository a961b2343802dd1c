#include "vrm_render/frame_check.h"

#include <algorithm>
#include <cmath>
#include <opencv2/imgproc.hpp>

#include "vrm_sim/scenario/light_cone.h"

namespace vrm_render {
namespace {

cv::Mat greyMat(const RgbImage& image) {
  if (image.width <= 0 || image.height <= 0 ||
      image.data.size() != static_cast<std::size_t>(image.width) * image.height * 3) {
    throw RenderError("frame_check: empty or inconsistent image");
  }
  cv::Mat out(image.height, image.width, CV_64F);
  for (int y = 0; y < image.height; ++y) {
    double* row = out.ptr<double>(y);
    for (int x = 0; x < image.width; ++x) row[x] = grey(image.pixel(x, y));
  }
  return out;
}

}  // namespace

double grey(const std::uint8_t* rgb) { return 0.299 * rgb[0] + 0.587 * rgb[1] + 0.114 * rgb[2]; }

ShadowResult findShadow(const RgbImage& with_shadows, const RgbImage& without_shadows, const Eigen::Vector2f& tip_px,
                        const ShadowCriteria& criteria) {
  if (with_shadows.width != without_shadows.width || with_shadows.height != without_shadows.height) {
    throw RenderError("findShadow: images of different sizes");
  }
  const cv::Mat with = greyMat(with_shadows), without = greyMat(without_shadows);
  cv::Mat darker(with.rows, with.cols, CV_8U);
  for (int y = 0; y < with.rows; ++y) {
    for (int x = 0; x < with.cols; ++x) {
      const double off = without.at<double>(y, x);
      darker.at<std::uint8_t>(y, x) =
          off >= criteria.min_grey && with.at<double>(y, x) <= (1.0 - criteria.min_darkening) * off ? 1 : 0;
    }
  }
  cv::Mat labels, stats, centroids;
  const int count = cv::connectedComponentsWithStats(darker, labels, stats, centroids, 8, CV_32S);
  std::vector<double> nearest(count, 1e18), sum_with(count, 0.0), sum_without(count, 0.0);
  for (int y = 0; y < labels.rows; ++y) {
    for (int x = 0; x < labels.cols; ++x) {
      const int label = labels.at<int>(y, x);
      if (label == 0) continue;
      const double dx = x + 0.5 - tip_px.x(), dy = y + 0.5 - tip_px.y();
      nearest[label] = std::min(nearest[label], std::sqrt(dx * dx + dy * dy));
      sum_with[label] += with.at<double>(y, x);
      sum_without[label] += without.at<double>(y, x);
    }
  }
  ShadowResult result;
  int best = 0;
  for (int label = 1; label < count; ++label) {
    if (stats.at<int>(label, cv::CC_STAT_AREA) < criteria.min_region_px) continue;
    ++result.regions;
    if (best == 0 || nearest[label] < nearest[best]) best = label;
  }
  if (best == 0) return result;
  result.region_px = stats.at<int>(best, cv::CC_STAT_AREA);
  result.darkening = 1.0 - sum_with[best] / std::max(1e-9, sum_without[best]);
  result.distance_px = nearest[best];
  result.pass = result.distance_px <= criteria.max_tip_distance_px;
  return result;
}

Window workingArea(const Eigen::Vector2f& tip_px, int width, int height, int side) {
  Window w;
  const int cx = static_cast<int>(std::floor(tip_px.x())), cy = static_cast<int>(std::floor(tip_px.y()));
  w.x0 = std::clamp(cx - side / 2, 0, width);
  w.y0 = std::clamp(cy - side / 2, 0, height);
  w.x1 = std::clamp(cx + side / 2, 0, width);
  w.y1 = std::clamp(cy + side / 2, 0, height);
  return w;
}

double laplacianVariance(const RgbImage& image, const Window& window, const std::vector<PixelClass>* classes) {
  if (window.pixels() < 9) throw RenderError("laplacianVariance: window outside the image or too small");
  if (classes && classes->size() != static_cast<std::size_t>(image.width) * image.height) {
    throw RenderError("laplacianVariance: pixel classes of the wrong size");
  }
  const cv::Mat g = greyMat(image);
  const cv::Rect rect(window.x0, window.y0, window.x1 - window.x0, window.y1 - window.y0);
  cv::Mat lap;
  cv::Laplacian(g(rect), lap, CV_64F, 1, 1.0, 0.0, cv::BORDER_REPLICATE);
  cv::Mat mask = cv::Mat::ones(lap.size(), CV_8U);
  if (classes) {
    cv::Mat fundus(image.height, image.width, CV_8U);
    for (int y = 0; y < image.height; ++y) {
      for (int x = 0; x < image.width; ++x) {
        fundus.at<std::uint8_t>(y, x) = (*classes)[static_cast<std::size_t>(y) * image.width + x] != PixelClass::kOther;
      }
    }
    cv::erode(fundus, fundus, cv::Mat::ones(3, 3, CV_8U));  // the whole 3x3 stencil on the fundus
    mask = fundus(rect).clone();
    if (cv::countNonZero(mask) < 9) throw RenderError("laplacianVariance: no fundus in the working area");
  }
  cv::Scalar mean, stddev;
  cv::meanStdDev(lap, mean, stddev, mask);
  return stddev[0] * stddev[0];
}

std::vector<PixelClass> classifyFundus(const std::vector<float>& depth, const CameraView& camera,
                                       const Eigen::Vector3f& eye_centre, float eye_radius, bool light_on,
                                       const Eigen::Vector3f& light_tip, const Eigen::Vector3f& light_axis,
                                       double cone_half_angle_deg, float tolerance) {
  const int w = camera.width, h = camera.height;
  if (depth.size() != static_cast<std::size_t>(w) * h) throw RenderError("classifyFundus: depth of the wrong size");
  const Eigen::Matrix4f inverse = camera.viewProjection().inverse();
  const double cone_cos = vrm_sim::scenario::lightConeCos(cone_half_angle_deg);
  std::vector<PixelClass> classes(depth.size(), PixelClass::kOther);
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      const float d = depth[static_cast<std::size_t>(y) * w + x];
      if (!(d < 1.0f)) continue;  // background
      const Eigen::Vector4f ndc((x + 0.5f) / w * 2.0f - 1.0f, 1.0f - (y + 0.5f) / h * 2.0f, d * 2.0f - 1.0f, 1.0f);
      const Eigen::Vector4f world = inverse * ndc;
      const Eigen::Vector3f p = world.head<3>() / world.w();
      if (std::abs((p - eye_centre).norm() - eye_radius) > tolerance) continue;
      const bool inside =
          light_on && vrm_sim::scenario::litByLightPipe(
                          light_tip.cast<double>(), light_axis.normalized().cast<double>(), p.cast<double>(), cone_cos);
      classes[static_cast<std::size_t>(y) * w + x] = inside ? PixelClass::kFundusInside : PixelClass::kFundusOutside;
    }
  }
  return classes;
}

ConeResult coneLighting(const RgbImage& image, const std::vector<PixelClass>& classes, const ConeCriteria& criteria) {
  if (classes.size() != static_cast<std::size_t>(image.width) * image.height) {
    throw RenderError("coneLighting: pixel classes of the wrong size");
  }
  ConeResult result;
  double inside = 0.0, outside = 0.0;
  for (std::size_t i = 0; i < classes.size(); ++i) {
    const std::uint8_t* p = image.data.data() + 3 * i;
    if (classes[i] == PixelClass::kFundusInside) {
      inside += grey(p);
      ++result.inside_px;
      if (std::max({p[0], p[1], p[2]}) == 255) ++result.saturated_px;
    } else if (classes[i] == PixelClass::kFundusOutside) {
      outside += grey(p);
      ++result.outside_px;
    }
  }
  if (result.inside_px) result.inside_grey = inside / result.inside_px;
  if (result.outside_px) result.outside_grey = outside / result.outside_px;
  if (result.inside_px && result.outside_px) result.ratio = result.inside_grey / std::max(1e-9, result.outside_grey);
  // No fundus outside the cone (all lit): the ratio condition holds trivially.
  const bool ratio_ok = result.outside_px == 0 ? result.inside_px > 0 : result.ratio >= criteria.min_ratio;
  result.pass =
      result.inside_px >= criteria.min_inside_px && result.inside_grey >= criteria.min_inside_grey && ratio_ok;
  return result;
}

}  // namespace vrm_render
