#include "vrm_sim/collision/image_space.h"

#include <algorithm>
#include <cmath>

namespace vrm_sim {
namespace collision {

using Eigen::Vector3d;

Vector3d ProjectionVolume::toPixel(const Vector3d& p) const {
  const Vector3d q = axes * p;
  return Vector3d((q.x() - x_min) / pixel_size, (q.y() - y_min) / pixel_size, near_z - q.z());
}

ProjectionVolume fitProjectionVolume(const TriangleMesh& mesh, const Vector3d& direction, int resolution,
                                     double tip_region_length) {
  ProjectionVolume volume;
  if (mesh.vertices.empty() || mesh.triangles.empty() || resolution <= 0 || !(direction.norm() > 0.0)) return volume;
  const Vector3d z = direction.normalized();
  // Any right-handed frame with z as its third axis; x follows the instrument x where possible.
  Vector3d x = Vector3d::UnitX() - Vector3d::UnitX().dot(z) * z;
  if (x.norm() < 1e-6) x = Vector3d::UnitY() - Vector3d::UnitY().dot(z) * z;
  x.normalize();
  const Vector3d y = z.cross(x);
  volume.axes.row(0) = x;
  volume.axes.row(1) = y;
  volume.axes.row(2) = z;

  double z_max = -std::numeric_limits<double>::infinity();
  std::vector<Vector3d> q(mesh.vertices.size());
  for (std::size_t i = 0; i < q.size(); ++i) {
    q[i] = volume.axes * mesh.vertices[i];
    z_max = std::max(z_max, q[i].z());
  }
  // Thesis Fig. 4.11 (1): V as tight as possible around the relevant (tip) part of the instrument. The lateral
  // extent is that of the triangles clipped to the tip slab (an edge crossing the back plane adds its crossing).
  const double z_back = z_max - tip_region_length;
  Eigen::Vector2d lo = Eigen::Vector2d::Constant(std::numeric_limits<double>::infinity());
  Eigen::Vector2d hi = -lo;
  auto add = [&](const Vector3d& p) {
    lo = lo.cwiseMin(p.head<2>());
    hi = hi.cwiseMax(p.head<2>());
  };
  for (const auto& t : mesh.triangles) {
    for (int k = 0; k < 3; ++k) {
      const Vector3d& a = q[t[k]];
      const Vector3d& b = q[t[(k + 1) % 3]];
      if (a.z() >= z_back) add(a);
      if ((a.z() - z_back) * (b.z() - z_back) < 0.0) add(a + (z_back - a.z()) / (b.z() - a.z()) * (b - a));
    }
  }
  if (!(lo.x() <= hi.x())) return volume;
  const double extent = std::max({hi.x() - lo.x(), hi.y() - lo.y(), 1e-9});
  // One pixel margin on each side so the silhouette never touches the border.
  volume.pixel_size = extent / std::max(1, resolution - 2);
  volume.resolution = resolution;
  const Eigen::Vector2d centre = 0.5 * (lo + hi);
  volume.x_min = centre.x() - 0.5 * resolution * volume.pixel_size;
  volume.y_min = centre.y() - 0.5 * resolution * volume.pixel_size;
  // Half a pixel ahead of the tip: nothing further ahead can be penetrated.
  volume.near_z = z_max + 0.5 * volume.pixel_size;
  volume.far_depth = tip_region_length + 0.5 * volume.pixel_size;
  return volume;
}

void DepthIdBuffer::reset(int w, int h) {
  width = w;
  height = h;
  depth.assign(static_cast<std::size_t>(w) * h, kInfinity);
  id.assign(static_cast<std::size_t>(w) * h, -1);
}

void DepthIdBuffer::clear(const PixelRect& rect) {
  for (int y = rect.y0; y < rect.y1; ++y) {
    std::fill_n(depth.begin() + static_cast<std::size_t>(y) * width + rect.x0, rect.x1 - rect.x0, kInfinity);
    std::fill_n(id.begin() + static_cast<std::size_t>(y) * width + rect.x0, rect.x1 - rect.x0, -1);
  }
}

bool orFoldYesNo(const std::vector<std::uint8_t>& mask, int width, int height) {
  if (width <= 0 || height <= 0) return false;
  int size = 1;
  while (size < std::max(width, height)) size *= 2;
  std::vector<std::uint8_t> buffer(static_cast<std::size_t>(size) * size, 0);
  for (int y = 0; y < height; ++y) {
    std::copy_n(mask.begin() + static_cast<std::size_t>(y) * width, width,
                buffer.begin() + static_cast<std::size_t>(y) * size);
  }
  // Fig. 4.12 (1): copy the upper and right quadrants onto the lower left one with OR, halving the edge each time.
  for (int half = size / 2; half >= 1; half /= 2) {
    for (int y = 0; y < half; ++y) {
      for (int x = 0; x < half; ++x) {
        std::uint8_t& dst = buffer[static_cast<std::size_t>(y) * size + x];
        dst |= buffer[static_cast<std::size_t>(y) * size + x + half] |
               buffer[static_cast<std::size_t>(y + half) * size + x] |
               buffer[static_cast<std::size_t>(y + half) * size + x + half];
      }
    }
  }
  return buffer[0] != 0;
}

PixelRect orFoldRoi(const std::vector<std::uint8_t>& mask, int width, int height) {
  // Fig. 4.12 (2): all rows ORed onto one row give the occupied columns, all columns onto one column the rows.
  std::vector<std::uint8_t> row(width, 0), column(height, 0);
  for (int y = 0; y < height; ++y) {
    const std::uint8_t* line = mask.data() + static_cast<std::size_t>(y) * width;
    std::uint8_t any = 0;
    for (int x = 0; x < width; ++x) {
      row[x] |= line[x];
      any |= line[x];
    }
    column[y] = any;
  }
  PixelRect rect{width, height, 0, 0};
  for (int x = 0; x < width; ++x) {
    if (row[x]) {
      rect.x0 = std::min(rect.x0, x);
      rect.x1 = std::max(rect.x1, x + 1);
    }
  }
  for (int y = 0; y < height; ++y) {
    if (column[y]) {
      rect.y0 = std::min(rect.y0, y);
      rect.y1 = std::max(rect.y1, y + 1);
    }
  }
  if (rect.empty()) return PixelRect{};
  return rect;
}

int maxCoverage(const TriangleMesh& mesh, const ProjectionVolume& volume) {
  if (volume.resolution <= 0) return 0;
  const int r = volume.resolution;
  std::vector<int> stencil(static_cast<std::size_t>(r) * r, 0);
  const PixelRect clip{0, 0, r, r};
  std::vector<Vector3d> px(mesh.vertices.size());
  for (std::size_t i = 0; i < px.size(); ++i) px[i] = volume.toPixel(mesh.vertices[i]);
  for (const auto& t : mesh.triangles) {
    // Additive stencil, no depth test: every fragment counts.
    rasterizeTriangle(px[t[0]], px[t[1]], px[t[2]], clip, volume.far_depth,
                      [&](int x, int y, double) { ++stencil[static_cast<std::size_t>(y) * r + x]; });
  }
  return stencil.empty() ? 0 : *std::max_element(stencil.begin(), stencil.end());
}

}  // namespace collision
}  // namespace vrm_sim
