#include <algorithm>
#include <limits>

#include "detector_internals.h"

namespace vrm_sim {
namespace collision {
namespace internal {

void analyzeCollisionMask(const ProjectionVolume& volume, const std::vector<std::uint8_t>& mask, const PixelRect& roi,
                          const float* zbuf_a, const std::int32_t* ids, const float* zbuf_b,
                          const Eigen::Isometry3d& pose, const SurfaceView& surface, const CollisionOptions& options,
                          AnalysisScratch& scratch, CollisionResult& result) {
  const int r = volume.resolution;
  const bool want_vectors = options.readback != ReadbackMode::kTrianglesOnly;
  const bool want_contacts = options.readback == ReadbackMode::kFull;
  const std::size_t triangle_count = surface.triangle_count;
  const std::size_t entries = triangle_count + AnalysisScratch::kSinkEntries;
  if (scratch.triangle_best.size() != entries) {
    scratch.triangle_best.assign(entries, -std::numeric_limits<float>::infinity());
    scratch.triangle_sum.assign(entries, 0.0);
    scratch.triangle_count.assign(entries, 0);
    scratch.best_pixel.assign(entries, 0);
  }
  if (want_vectors) scratch.accumulator.begin(surface.node_count);
  std::vector<std::uint32_t>& hit = result.triangles;
  // Eq. 4.2: d = M_P^-1 (0, 0, b_min - a)^T is (a - b_min) along the projection direction; in the surface frame:
  const Eigen::Vector3d direction = pose.linear() * Eigen::Vector3d(volume.axes.row(2));

  // One pass over the ROI rows whose cost does not depend on how many pixels collide (the thesis' severity
  // independence, §4.2.7; issue 15): every pixel does the same branch-free update; a pixel outside the mask (or with
  // a corrupt colour) adds a zero to a sink entry instead of being skipped. Skipping made the cost follow the
  // colliding area through mispredicted branches (light/heavy 0.82 at 100²). The sinks rotate with x so that a run
  // of non-colliding pixels does not chain its updates through one memory location.
  float* best = scratch.triangle_best.data();
  double* sum = scratch.triangle_sum.data();
  std::uint32_t* count = scratch.triangle_count.data();
  std::uint32_t* best_pixel = scratch.best_pixel.data();
  const std::uint8_t* colliding = mask.data();
  for (int y = roi.y0; y < roi.y1; ++y) {
    const std::size_t row = static_cast<std::size_t>(y) * r;
    for (int x = roi.x0; x < roi.x1; ++x) {
      const std::size_t i = row + x;
      const auto id = static_cast<std::uint32_t>(ids[i]);  // a negative id becomes huge: rejected like a corrupt one
      const bool valid = (colliding[i] != 0) & (id < triangle_count);
      const std::size_t t = valid
                                ? std::size_t{id}
                                : triangle_count + (static_cast<std::size_t>(x) & (AnalysisScratch::kSinkEntries - 1));
      const float penetration = valid ? zbuf_a[i] - zbuf_b[i] : 0.0f;  // a - b_min; > 0 on the mask
      // best starts at -inf, so a triangle's first pixel always wins, later ones only if strictly deeper.
      const bool deeper = penetration > best[t];
      best[t] = deeper ? penetration : best[t];
      best_pixel[t] = deeper ? static_cast<std::uint32_t>(i) : best_pixel[t];
      // Per triangle first: each pixel touches one triangle instead of three nodes (same max and mean per node).
      sum[t] += penetration;
      count[t] += valid ? 1u : 0u;
    }
  }
  // The hit list, sorted, by one branch-free scan over the per-triangle counters instead of sorting: O(triangles),
  // the same for a light and a heavy contact.
  const std::size_t first_new = hit.size();
  hit.resize(first_new + triangle_count);
  std::size_t found = first_new;
  for (std::size_t t = 0; t < triangle_count; ++t) {
    hit[found] = static_cast<std::uint32_t>(t);
    found += count[t] != 0 ? 1 : 0;
  }
  hit.resize(found);
  std::inplace_merge(hit.begin(), hit.begin() + first_new, hit.end());
  if (want_vectors) {
    for (std::uint32_t t : hit) {
      for (std::uint32_t n : surface.triangles[t]) {
        scratch.accumulator.add(n, scratch.triangle_best[t], scratch.triangle_sum[t], scratch.triangle_count[t]);
      }
    }
    scratch.accumulator.finish(options.reduction, direction, result);
  }
  if (want_contacts) {
    const std::size_t first_contact = result.contact_points.size();
    result.contact_points.resize(first_contact + hit.size());
    result.contact_normals.resize(first_contact + hit.size(), direction);
    Eigen::Vector3d* contact = result.contact_points.data() + first_contact;
    // Row = floor((i + 0.5) / r) by a multiplication: exact, the fraction stays 0.5 / r away from an integer, far
    // more than the rounding error; an integer division per contact was a sixth of the per-triangle cost.
    const double inverse_width = 1.0 / r;
    for (std::uint32_t t : hit) {
      const std::uint32_t i = scratch.best_pixel[t];
      const auto y = static_cast<int>((i + 0.5) * inverse_width);
      const int x = static_cast<int>(i) - y * r;
      *contact++ = pose * volume.fromPixel(x, y, zbuf_b[i]);
    }
  }
  for (std::uint32_t t : hit) {
    best[t] = -std::numeric_limits<float>::infinity();
    sum[t] = 0.0;
    count[t] = 0;
  }
  result.colliding = !hit.empty() || result.colliding;
}

}  // namespace internal
}  // namespace collision
}  // namespace vrm_sim
