#pragma once
// Shared by the detector implementations (not public API): input validation, per-node reduction of deformation
// vectors (thesis §4.2.2) and the factory functions of the individual detectors.

#include <algorithm>
#include <chrono>
#include <memory>
#include <string>
#include <vector>

#include "vrm_sim/collision/collision_detector.h"
#include "vrm_sim/collision/image_space.h"

namespace vrm_sim {
namespace collision {
namespace internal {

// Checks pose, positions and indices; returns kOk or the status to report.
CollisionStatus validate(const Eigen::Isometry3d& pose, const SurfaceView& surface);
// The image-space detectors' precondition: an instrument with a mesh to rasterize, then validate().
CollisionStatus validateMeshQuery(bool has_instrument, const InstrumentModel& instrument, const Eigen::Isometry3d& pose,
                                  const SurfaceView& surface);
bool isFinite(const Eigen::Isometry3d& pose);
// Image-space resolution for `instrument` (CPU and GL alike): options.resolution, raised (up to max_resolution) until
// the pixel size is at most options.max_pixel_size when that bound is set (bounded error, issue 4). The volume's
// extent does not depend on r, so one fit gives the pixel size for any r.
int chooseResolution(const InstrumentModel& instrument, const CollisionOptions& options);
// True if the options change the rendering volume (cached instrument depth must be re-rendered).
bool volumeOptionsDiffer(const CollisionOptions& a, const CollisionOptions& b);

// Thesis §4.2.2: every contribution to a triangle is a candidate vector for each of its nodes; per node the set
// D_v is reduced by max or mean. In image space all vectors of one query are parallel to z (Eq. 4.2), so only their
// lengths are accumulated. Buffers are reused between queries; only touched nodes are reset.
class NodeAccumulator {
 public:
  void begin(std::size_t node_count);
  // Adds `count` vectors of total length `sum` and maximum length `max` (one triangle's pixels at once).
  void add(std::uint32_t node, float max, double sum, std::uint32_t count) {
    // Branch-free append of a node seen for the first time (touched_ has room for every node): a branch here
    // mispredicted once per node and made the cost follow the contact size.
    touched_[touched_count_] = node;
    touched_count_ += count_[node] == 0 ? 1 : 0;
    count_[node] += count;
    sum_[node] += sum;
    max_[node] = std::max(max_[node], max);
  }
  // Appends the reduced vectors length * direction (nodes sorted) to `result`.
  void finish(DeformationReduction reduction, const Eigen::Vector3d& direction, CollisionResult& result);

 private:
  std::vector<double> sum_;
  std::vector<float> max_;
  std::vector<std::uint32_t> count_;
  std::vector<std::uint32_t> touched_;
  std::size_t touched_count_ = 0;
};

class Stopwatch {
 public:
  Stopwatch() : start_(std::chrono::steady_clock::now()) {}
  // Milliseconds since construction or the last lap.
  double lap() {
    const auto now = std::chrono::steady_clock::now();
    const double ms = std::chrono::duration<double, std::milli>(now - start_).count();
    start_ = now;
    return ms;
  }

 private:
  std::chrono::steady_clock::time_point start_;
};

// Scratch buffers of analyzeCollisionMask, reused between queries: one entry per surface triangle, then
// kSinkEntries entries that absorb the pixels outside the mask (a power of two).
struct AnalysisScratch {
  static constexpr std::uint32_t kSinkEntries = 16;
  std::vector<float> triangle_best;  // -inf = no pixel yet
  std::vector<double> triangle_sum;
  std::vector<std::uint32_t> triangle_count;
  std::vector<std::uint32_t> best_pixel;
  NodeAccumulator accumulator;
};

// Alg. 4.2 lines 14-17 / Alg. 4.3 lines 9-12, shared by the CPU and GL backends: for every pixel of `mask` (inside
// `roi`), T = triangle id, add the vector of Eq. 4.2 for the depth difference zbuf_B - zbuf_A to T's nodes. Buffers
// are r x r, row 0 at the bottom; ids are triangle indices. Fills triangles, nodes/deformations and contacts of
// `result` according to options.readback.
void analyzeCollisionMask(const ProjectionVolume& volume, const std::vector<std::uint8_t>& mask, const PixelRect& roi,
                          const float* zbuf_a, const std::int32_t* ids, const float* zbuf_b,
                          const Eigen::Isometry3d& pose, const SurfaceView& surface, const CollisionOptions& options,
                          AnalysisScratch& scratch, CollisionResult& result);

enum class ZcollMode {
  kFrontOnly,  // ZCOLL/F, Alg. 4.3
  kParity,     // ZCOLL, Alg. 4.2
  kVolume,     // Myszkowski et al. 1995, Alg. 4.1: A a closed z-convex volume
};
std::unique_ptr<CollisionDetector> makeZcollCpuDetector(ZcollMode mode);
std::unique_ptr<CollisionDetector> makeZcollGlDetector(bool front_only);
std::unique_ptr<CollisionDetector> makeGeometricDetector();
// bv: "aabb", "obbrss", "kios"
std::unique_ptr<CollisionDetector> makeFclDetector(const std::string& bv);
std::unique_ptr<CollisionDetector> makeNoneDetector();

}  // namespace internal
}  // namespace collision
}  // namespace vrm_sim
