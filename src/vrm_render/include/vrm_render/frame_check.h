#pragma once
// Checks of a rendered frame against re-renderings of the same state with one pass switched off (issue 33 items
// 3-5): the working instrument's shadow, focus on the working area, the light pipe's cone lighting the fundus.
// ROS-free; the frame_check tool (tools/frame_check.cpp) applies them to run.sh's saved snapshots.
//
// "Grey" is the luma of the sRGB pixel (0.299 R + 0.587 G + 0.114 B, 0..255), as image_io's meanLuminance.

#include <Eigen/Core>
#include <algorithm>
#include <cstdint>
#include <string>
#include <vector>

#include "vrm_render/microscope_camera.h"
#include "vrm_render/render_types.h"

namespace vrm_render {

// Item 3: a region of >= min_region_px pixels, each darker by >= min_darkening (grey_with <= (1 - d) grey_without)
// than with shadows off, whose nearest pixel lies within max_tip_distance_px of the projected working tip.
struct ShadowCriteria {
  double min_darkening = 0.25;
  int min_region_px = 200;
  double max_tip_distance_px = 15.0;
  double min_grey = 6.0;  // pixels darker than this without shadows (background) are never a shadow
};
struct ShadowResult {
  int region_px = 0;          // of the chosen region (the qualifying one nearest the tip; 0: none)
  double darkening = 0.0;     // 1 - mean grey with / mean grey without, over the region
  double distance_px = -1.0;  // region's nearest pixel to the tip (-1: no region)
  int regions = 0;            // connected darker regions of >= min_region_px
  bool pass = false;
};
ShadowResult findShadow(const RgbImage& with_shadows, const RgbImage& without_shadows, const Eigen::Vector2f& tip_px,
                        const ShadowCriteria& criteria = {});

// Item 4: variance of the grey Laplacian (3x3 kernel) over a window; the working area is a square of `side` pixels
// centred on the projected working tip, clipped to the image. With `classes` (classifyFundus), only pixels whose 3x3
// neighbourhood is all fundus count: the working plane (the retina and the tissue on it) must be in focus; the
// instruments' shafts rise out of it and are rightly blurred by the depth of field, and their edges would otherwise
// dominate the variance.
struct Window {
  int x0 = 0, y0 = 0, x1 = 0, y1 = 0;  // [x0, x1) x [y0, y1)
  int pixels() const { return std::max(0, x1 - x0) * std::max(0, y1 - y0); }
};
constexpr int kWorkingAreaSide = 64;  // px at 800 x 600: 2.4 mm of the 30 mm field at zoom 1
Window workingArea(const Eigen::Vector2f& tip_px, int width, int height, int side = kWorkingAreaSide);
enum class PixelClass : std::uint8_t;
double laplacianVariance(const RgbImage& image, const Window& window, const std::vector<PixelClass>* classes = nullptr);

// Item 5: which pixels show the fundus, and which of those lie inside the light pipe's cone by the scoring's rule
// (vrm_sim::scenario::litByLightPipe with its kLightConeHalfAngleDeg). A pixel shows the fundus when its depth
// unprojects (through `camera`) to a point within `tolerance` of the retina sphere (centre, radius): the retina,
// not an instrument in front of it nor the background.
enum class PixelClass : std::uint8_t { kOther = 0, kFundusOutside = 1, kFundusInside = 2 };
std::vector<PixelClass> classifyFundus(const std::vector<float>& depth, const CameraView& camera,
                                       const Eigen::Vector3f& eye_centre, float eye_radius, bool light_on,
                                       const Eigen::Vector3f& light_tip, const Eigen::Vector3f& light_axis,
                                       double cone_half_angle_deg, float tolerance = 0.0004f);
struct ConeResult {
  int inside_px = 0;
  int outside_px = 0;
  double inside_grey = 0.0;   // mean over the fundus inside the cone
  double outside_grey = 0.0;  // mean over the fundus in the field outside it
  double ratio = 0.0;         // inside / outside (0 when either is empty)
  int saturated_px = 0;       // inside the cone with a channel at 255 (a blown-out disc)
  bool pass = false;          // inside_grey >= min_inside_grey and ratio >= min_ratio
};
struct ConeCriteria {
  double min_inside_grey = 90.0;
  double min_ratio = 2.0;
  int min_inside_px = 200;  // a cone that lights (almost) no visible fundus does not pass
};
ConeResult coneLighting(const RgbImage& image, const std::vector<PixelClass>& classes,
                        const ConeCriteria& criteria = {});

double grey(const std::uint8_t* rgb);

}  // namespace vrm_render
