// ZCOLL (thesis Alg. 4.2), ZCOLL/F (Alg. 4.3) and the two-pass volume test of Myszkowski et al. 1995 (Alg. 4.1) on a
// software rasterizer: the "z-buffer" and "colour buffer" are float / int32 arrays, so readback is free and the
// reductions of §4.2.5 only trim work and output.
#include <algorithm>
#include <cmath>

#include "detector_internals.h"
#include "vrm_sim/collision/image_space.h"

namespace vrm_sim {
namespace collision {
namespace internal {
namespace {

using Eigen::Vector3d;

class ZcollCpuDetector : public CollisionDetector {
 public:
  explicit ZcollCpuDetector(ZcollMode mode) : mode_(mode), front_only_(mode == ZcollMode::kFrontOnly) {}

  std::string name() const override {
    return mode_ == ZcollMode::kFrontOnly ? "zcoll_f_cpu"
           : mode_ == ZcollMode::kParity  ? "zcoll_cpu"
                                          : "myszkowski_cpu";
  }
  // Alg. 4.1 answers only which pixels collide; ZCOLL and ZCOLL/F push nodes out of the instrument.
  bool producesDeformations() const override { return mode_ != ZcollMode::kVolume; }

  void setInstrument(const InstrumentModel& instrument) override {
    instrument_ = instrument;
    has_instrument_ = true;
    cache_valid_ = false;  // Alg. 4.2 line 4: B's shape or the z direction changed
  }

  void setOptions(const CollisionOptions& options) override {
    if (volumeOptionsDiffer(options, options_)) cache_valid_ = false;
    options_ = options;
  }

  CollisionResult collide(const Eigen::Isometry3d& pose, const SurfaceView& surface) override {
    Stopwatch total, phase;
    CollisionResult result;
    result.status = validateMeshQuery(has_instrument_, instrument_, pose, surface);
    if (result.status != CollisionStatus::kOk) return result;
    if (!cache_valid_) renderInstrument();
    result.pixel_size = volume_.pixel_size;
    result.resolution = volume_.resolution;
    if (volume_.resolution <= 0 || b_roi_.empty()) {
      result.status = CollisionStatus::kEmptyInput;
      return result;
    }

    // Alg. 4.3 lines 1, 6: clear z to infinity, render A with z test "<" into depth and triangle id. A is rendered
    // only inside the ROI of B's footprint (the OR-folded rows/columns of B's mask, §4.2.5): no collision elsewhere.
    const int r = volume_.resolution;
    // One affine map surface frame -> (pixel x, pixel y, depth): M_P of Eq. 4.2.
    const Eigen::Isometry3d surface_to_instrument = pose.inverse();
    Eigen::Matrix3d linear = volume_.axes * surface_to_instrument.linear();
    Vector3d offset = volume_.axes * surface_to_instrument.translation();
    linear.topRows<2>() /= volume_.pixel_size;
    offset.x() = (offset.x() - volume_.x_min) / volume_.pixel_size;
    offset.y() = (offset.y() - volume_.y_min) / volume_.pixel_size;
    linear.row(2) = -linear.row(2);
    offset.z() = volume_.near_z - offset.z();
    projected_.resize(surface.node_count);
    for (std::size_t i = 0; i < surface.node_count; ++i) projected_[i] = linear * surface.positions[i] + offset;
    zbuf_a_.clear(b_roi_);
    const bool volume_mode = mode_ == ZcollMode::kVolume;
    if (volume_mode) zbuf_a_max_.clear(b_roi_);
    bool any_fragment = false;
    for (std::size_t t = 0; t < surface.triangle_count; ++t) {
      const auto& tri = surface.triangles[t];
      const std::int32_t id = static_cast<std::int32_t>(t);
      rasterizeTriangle(
          projected_[tri[0]], projected_[tri[1]], projected_[tri[2]], b_roi_, volume_.far_depth,
          [&](int x, int y, double depth) {
            const std::size_t i = static_cast<std::size_t>(y) * r + x;
            any_fragment = true;
            if (depth < zbuf_a_.depth[i]) {
              zbuf_a_.depth[i] = static_cast<float>(depth);
              zbuf_a_.id[i] = id;
            }
            // Alg. 4.1 line 1: A's far side with z test ">=" (the other end of A's z interval).
            if (volume_mode && (zbuf_a_max_.id[i] < 0 || depth >= zbuf_a_max_.depth[i])) {
              zbuf_a_max_.depth[i] = static_cast<float>(depth);
              zbuf_a_max_.id[i] = id;
            }
          },
          volume_mode);  // Alg. 4.1: a closed A cut by the near plane starts there (depth clamp)
    }
    result.timing.ms_raster = phase.lap();
    if (!any_fragment) {
      result.status = CollisionStatus::kOutsideVolume;
      result.timing.ms_total = total.lap();
      return result;
    }

    // "Readback" of the collision mask: condition (*) of Alg. 4.3, or odd stencil parity of Alg. 4.2.
    mask_.assign(static_cast<std::size_t>(r) * r, 0);
    for (int y = b_roi_.y0; y < b_roi_.y1; ++y) {
      for (int x = b_roi_.x0; x < b_roi_.x1; ++x) {
        const std::size_t i = static_cast<std::size_t>(y) * r + x;
        mask_[i] = isColliding(i) ? 1 : 0;
      }
    }
    if (options_.readback == ReadbackMode::kYesNo) {
      result.colliding = orFoldYesNo(mask_, r, r);
      result.timing.ms_readback = phase.lap();
      result.timing.ms_total = total.lap();
      return result;
    }
    const PixelRect roi = orFoldRoi(mask_, r, r);
    result.timing.ms_readback = phase.lap();
    if (roi.empty()) {
      result.timing.ms_total = total.lap();
      return result;
    }
    result.colliding = true;

    // The analysis scans B's whole footprint (b_roi_), not the colliding ROI: the ROI grows with the contact, the
    // footprint does not, so a light and a heavy contact cost the same (§4.2.7, issue 15). The colliding ROI still
    // answers "any collision" above.
    if (volume_mode) {
      // Alg. 4.1 only answers "which pixels collide"; its depth difference is no deformation (A is a volume).
      CollisionOptions triangles_only = options_;
      triangles_only.readback = ReadbackMode::kTrianglesOnly;
      analyzeCollisionMask(volume_, mask_, b_roi_, zbuf_a_.depth.data(), zbuf_a_.id.data(), zbuf_b_.data(), pose,
                           surface, triangles_only, scratch_, result);
    } else {
      analyzeCollisionMask(volume_, mask_, b_roi_, zbuf_a_.depth.data(), zbuf_a_.id.data(), zbuf_b_.data(), pose,
                           surface, options_, scratch_, result);
    }
    result.timing.ms_analysis = phase.lap();
    result.timing.ms_total = total.lap();
    return result;
  }

 private:
  bool isColliding(std::size_t i) const {
    const float a = zbuf_a_.depth[i];
    if (!(a < DepthIdBuffer::kInfinity)) return false;
    if (front_only_) return zbuf_b_[i] < a;  // condition (*) of Alg. 4.3
    // Alg. 4.2 lines 11-15: the stencil counts B's fragments passing the z test against A; odd = A inside B.
    int count = 0;
    for (std::uint32_t k = layer_offset_[i]; k < layer_offset_[i + 1] && layers_[k] < a; ++k) ++count;
    if (mode_ != ZcollMode::kVolume) return (count & 1) != 0;
    // Alg. 4.1 (z-convex volume A with interval [a_min, a_max]): the stencil against a_max odd -> collision; even
    // but different from the count against a_min (second pass) -> a surface of B lies inside A's interval.
    const float a_max = zbuf_a_max_.depth[i];
    int count_max = 0;
    for (std::uint32_t k = layer_offset_[i]; k < layer_offset_[i + 1] && layers_[k] < a_max; ++k) ++count_max;
    return (count_max & 1) != 0 || count_max != count;
  }

  // Alg. 4.2 lines 4-7 / Alg. 4.3 lines 3-5: B's depth (and for ZCOLL all its depth layers, the input of the
  // stencil pass) in instrument coordinates, kept until shape, z direction or resolution change.
  void renderInstrument() {
    cache_valid_ = true;
    volume_ = fitProjectionVolume(instrument_.mesh, instrument_.projection_direction,
                                  chooseResolution(instrument_, options_), instrument_.tip_region_length);
    b_roi_ = PixelRect{};
    const int r = volume_.resolution;
    if (r <= 0) return;
    const std::size_t pixels = static_cast<std::size_t>(r) * r;
    zbuf_b_.assign(pixels, DepthIdBuffer::kInfinity);
    zbuf_a_.reset(r, r);
    std::vector<Vector3d> px(instrument_.mesh.vertices.size());
    for (std::size_t i = 0; i < px.size(); ++i) px[i] = volume_.toPixel(instrument_.mesh.vertices[i]);
    const PixelRect all{0, 0, r, r};
    std::vector<std::uint32_t> counts(pixels, 0);
    for (const auto& t : instrument_.mesh.triangles) {
      rasterizeTriangle(px[t[0]], px[t[1]], px[t[2]], all, volume_.far_depth, [&](int x, int y, double depth) {
        const std::size_t i = static_cast<std::size_t>(y) * r + x;
        zbuf_b_[i] = std::min(zbuf_b_[i], static_cast<float>(depth));
        ++counts[i];
      });
    }
    std::vector<std::uint8_t> b_mask(pixels);
    for (std::size_t i = 0; i < pixels; ++i) b_mask[i] = counts[i] > 0;
    b_roi_ = orFoldRoi(b_mask, r, r);
    layer_offset_.clear();
    layers_.clear();
    if (front_only_) return;
    zbuf_a_max_.reset(r, r);
    layer_offset_.assign(pixels + 1, 0);
    for (std::size_t i = 0; i < pixels; ++i) layer_offset_[i + 1] = layer_offset_[i] + counts[i];
    layers_.assign(layer_offset_.back(), 0.0f);
    std::vector<std::uint32_t> fill(layer_offset_.begin(), layer_offset_.end() - 1);
    for (const auto& t : instrument_.mesh.triangles) {
      rasterizeTriangle(px[t[0]], px[t[1]], px[t[2]], all, volume_.far_depth, [&](int x, int y, double depth) {
        const std::size_t i = static_cast<std::size_t>(y) * r + x;
        layers_[fill[i]++] = static_cast<float>(depth);
      });
    }
    for (std::size_t i = 0; i < pixels; ++i) {
      std::sort(layers_.begin() + layer_offset_[i], layers_.begin() + layer_offset_[i + 1]);
    }
  }

  const ZcollMode mode_;
  const bool front_only_;
  InstrumentModel instrument_;
  bool has_instrument_ = false;
  bool cache_valid_ = false;
  ProjectionVolume volume_;
  std::vector<float> zbuf_b_;
  PixelRect b_roi_;
  std::vector<std::uint32_t> layer_offset_;
  std::vector<float> layers_;
  DepthIdBuffer zbuf_a_;
  DepthIdBuffer zbuf_a_max_;  // Alg. 4.1 only
  std::vector<Vector3d> projected_;
  std::vector<std::uint8_t> mask_;
  AnalysisScratch scratch_;
};

}  // namespace

std::unique_ptr<CollisionDetector> makeZcollCpuDetector(ZcollMode mode) {
  return std::make_unique<ZcollCpuDetector>(mode);
}

}  // namespace internal
}  // namespace collision
}  // namespace vrm_sim
