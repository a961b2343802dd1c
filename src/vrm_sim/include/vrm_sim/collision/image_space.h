#pragma once
// Building blocks of the image-space detectors (thesis §4.1.4, §4.2): the orthographic rendering volume fitted
// around the instrument tip, a small software rasterizer writing depth + triangle id into arrays, and the readback
// reductions of §4.2.5 (yes/no by OR-folding quadrants, ROI by OR-folding rows and columns) plus the additive
// z-convexity check (§4.1.4: no pixel covered more than once).

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <optional>
#include <vector>

#include "vrm_scene/meshes/triangle_mesh.h"

namespace vrm_sim {
namespace collision {

// Orthographic volume, fixed to the instrument (thesis Fig. 4.8). Projection frame: rows of `axes` are the pixel x,
// y and the projection direction z (towards the tip) in instrument coordinates. Depth of a point q (instrument
// coordinates) is near_z - z(q): 0 at the near plane just ahead of the tip, growing towards the handle, so the
// instrument front (b_min) has the smallest depth and a z test "<" keeps it (Alg. 4.2/4.3).
struct ProjectionVolume {
  Eigen::Matrix3d axes = Eigen::Matrix3d::Identity();
  double x_min = 0.0;
  double y_min = 0.0;
  double near_z = 0.0;
  double far_depth = 0.0;  // depths >= far_depth are clipped
  double pixel_size = 0.0;
  int resolution = 0;

  // Pixel coordinates (x, y in pixels, pixel centres at i + 0.5) and depth [m] of an instrument-frame point.
  Eigen::Vector3d toPixel(const Eigen::Vector3d& instrument_point) const;
  // Instrument-frame point of pixel centre (x, y) at `depth`. Inline: the analysis calls it once per colliding
  // triangle (contact points), and the call was a third of the per-triangle cost.
  Eigen::Vector3d fromPixel(int x, int y, double depth) const {
    const Eigen::Vector3d q(x_min + (x + 0.5) * pixel_size, y_min + (y + 0.5) * pixel_size, near_z - depth);
    return axes.transpose() * q;
  }
  // Deformation vector of Eq. 4.2 in instrument coordinates for a depth difference b_min - a (< 0 when colliding).
  Eigen::Vector3d deformation(double b_minus_a) const { return -b_minus_a * Eigen::Vector3d(axes.row(2)); }
};

// Fits a square volume of resolution^2 pixels around the part of `mesh` within `tip_region_length` of its most
// distal point along `direction`, with a margin of one pixel on each side. Returns resolution 0 for an empty mesh.
ProjectionVolume fitProjectionVolume(const TriangleMesh& mesh, const Eigen::Vector3d& direction, int resolution,
                                     double tip_region_length);

struct PixelRect {
  int x0 = 0, y0 = 0, x1 = 0, y1 = 0;  // [x0, x1) x [y0, y1); empty if x0 >= x1 or y0 >= y1
  bool empty() const { return x0 >= x1 || y0 >= y1; }
};

// Rasterizes one triangle given in pixel coordinates + depth (ProjectionVolume::toPixel): calls
// fragment(x, y, depth) for every pixel centre inside the triangle (top-left fill rule on 1/256-pixel fixed point: a
// centre on a shared edge belongs to exactly one triangle) and inside `clip`, with depth in [0, far_depth). Degenerate
// triangles give none. With clamp_near, fragments in front of the near plane get depth 0 (GL_DEPTH_CLAMP) instead
// of being clipped: a closed object cut by the near plane then keeps the start of its z interval (Alg. 4.1).
template <class Fragment>
void rasterizeTriangle(const Eigen::Vector3d& v0, const Eigen::Vector3d& v1, const Eigen::Vector3d& v2,
                       const PixelRect& clip, double far_depth, Fragment&& fragment, bool clamp_near = false);

// Depth + triangle id buffer (the CPU stand-in for z- and colour buffer; id -1 = background, GL uses id + 1 as a
// 24-bit colour).
struct DepthIdBuffer {
  int width = 0, height = 0;
  std::vector<float> depth;
  std::vector<std::int32_t> id;
  void reset(int w, int h);
  void clear(const PixelRect& rect);
  static constexpr float kInfinity = std::numeric_limits<float>::infinity();
};

// Thesis §4.2.5, yes/no: OR-fold the mask's quadrants onto each other until one pixel remains (the buffer is
// padded to a power of two as the thesis requires 2^n dimensions).
bool orFoldYesNo(const std::vector<std::uint8_t>& mask, int width, int height);
// Thesis §4.2.5, ROI: OR-fold all rows onto one row and all columns onto one column; the set bits bound the region
// of interest that needs a full readback.
PixelRect orFoldRoi(const std::vector<std::uint8_t>& mask, int width, int height);
// Thesis §4.1.4: a surface is z-convex in the volume if no pixel is covered more than once (additive stencil).
// Returns the maximum coverage count (0 = not visible, 1 = z-convex).
int maxCoverage(const TriangleMesh& mesh_in_instrument_frame, const ProjectionVolume& volume);
// The same check on OpenGL (OSMesa), as the thesis does it: the mesh into the stencil with GL_INCR and no depth
// test, a stencil-tested full-screen pass marks pixels covered more than once, OR-folded on the GPU to one pixel (two
// bytes read back). True = z-convex. nullopt if no GL context can be created.
std::optional<bool> zConvexOnGl(const TriangleMesh& mesh_in_instrument_frame, const ProjectionVolume& volume);

// ---------------------------------------------------------------------------------------------------------------
template <class Fragment>
void rasterizeTriangle(const Eigen::Vector3d& v0_in, const Eigen::Vector3d& v1_in, const Eigen::Vector3d& v2_in,
                       const PixelRect& clip, double far_depth, Fragment&& fragment, bool clamp_near) {
  // Vertices snap to 1/256 pixel as on GPUs; integer edge functions then decide shared edges exactly, so the
  // top-left rule gives every pixel centre to exactly one triangle of a closed fan (no double ids, no holes).
  constexpr double kSubpixels = 256.0;
  constexpr double kLimit = 1e6;  // pixels; keeps the products of 64-bit edge functions exact
  const Eigen::Vector3d* v[3] = {&v0_in, &v1_in, &v2_in};
  std::int64_t X[3], Y[3];
  for (int k = 0; k < 3; ++k) {
    if (!(std::abs(v[k]->x()) < kLimit && std::abs(v[k]->y()) < kLimit && std::isfinite(v[k]->z()))) return;
    // Round half away from zero by truncation (cheaper than llround; equal inputs give equal outputs).
    const double fx = v[k]->x() * kSubpixels, fy = v[k]->y() * kSubpixels;
    X[k] = static_cast<std::int64_t>(fx + (fx >= 0.0 ? 0.5 : -0.5));
    Y[k] = static_cast<std::int64_t>(fy + (fy >= 0.0 ? 0.5 : -0.5));
  }
  std::int64_t area = (X[1] - X[0]) * (Y[2] - Y[0]) - (Y[1] - Y[0]) * (X[2] - X[0]);
  if (area == 0) return;
  int i0 = 0, i1 = 1, i2 = 2;
  if (area < 0) {
    std::swap(i1, i2);
    area = -area;
  }
  const std::int64_t ax = X[i0], ay = Y[i0], bx = X[i1], by = Y[i1], cx = X[i2], cy = Y[i2];
  const double az = v[i0]->z(), bz = v[i1]->z(), cz = v[i2]->z();
  const std::int64_t half = static_cast<std::int64_t>(kSubpixels / 2);
  const std::int64_t step = static_cast<std::int64_t>(kSubpixels);
  auto floor_div = [](std::int64_t a, std::int64_t b) { return a >= 0 ? a / b : -((-a + b - 1) / b); };
  auto ceil_div = [](std::int64_t a, std::int64_t b) { return a >= 0 ? (a + b - 1) / b : -((-a) / b); };
  // Pixel i has its centre at (i + 0.5) * 256 in fixed point.
  const int x0 = std::max<std::int64_t>(clip.x0, ceil_div(std::min({ax, bx, cx}) - half, step));
  const int x1 = std::min<std::int64_t>(clip.x1 - 1, floor_div(std::max({ax, bx, cx}) - half, step));
  const int y0 = std::max<std::int64_t>(clip.y0, ceil_div(std::min({ay, by, cy}) - half, step));
  const int y1 = std::min<std::int64_t>(clip.y1 - 1, floor_div(std::max({ay, by, cy}) - half, step));
  if (x0 > x1 || y0 > y1) return;
  // Top-left rule for a counter-clockwise triangle (y up): an edge owns the centres on it if it is a "left" edge
  // (going down) or a horizontal "top" edge (going left).
  auto owns = [](std::int64_t px, std::int64_t py, std::int64_t qx, std::int64_t qy) {
    return qy < py || (qy == py && qx < px);
  };
  const bool own0 = owns(bx, by, cx, cy), own1 = owns(cx, cy, ax, ay), own2 = owns(ax, ay, bx, by);
  auto edge = [](std::int64_t px, std::int64_t py, std::int64_t qx, std::int64_t qy, std::int64_t x, std::int64_t y) {
    return (qx - px) * (y - py) - (qy - py) * (x - px);
  };
  const std::int64_t e0_dx = -(cy - by) * step, e1_dx = -(ay - cy) * step, e2_dx = -(by - ay) * step;
  const double inv_area = 1.0 / static_cast<double>(area);
  const std::int64_t fx0 = x0 * step + half;
  for (int y = y0; y <= y1; ++y) {
    const std::int64_t fy = y * step + half;
    std::int64_t e0 = edge(bx, by, cx, cy, fx0, fy), e1 = edge(cx, cy, ax, ay, fx0, fy),
                 e2 = edge(ax, ay, bx, by, fx0, fy);
    for (int x = x0; x <= x1; ++x, e0 += e0_dx, e1 += e1_dx, e2 += e2_dx) {
      if (e0 < 0 || e1 < 0 || e2 < 0) continue;
      if ((e0 == 0 && !own0) || (e1 == 0 && !own1) || (e2 == 0 && !own2)) continue;
      const double depth =
          (static_cast<double>(e0) * az + static_cast<double>(e1) * bz + static_cast<double>(e2) * cz) * inv_area;
      if (depth >= far_depth || (depth < 0.0 && !clamp_near)) continue;  // near/far clipping
      fragment(x, y, std::max(depth, 0.0));
    }
  }
}

}  // namespace collision
}  // namespace vrm_sim
