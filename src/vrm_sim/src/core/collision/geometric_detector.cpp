// Exact primitives vs triangle surface (thesis §4.1: simple objects are tested geometrically). Used for simple
// instruments and as the exact reference of the image-space detectors: deformation vectors follow ZCOLL/F's
// definition exactly (move a penetrated node along z to the instrument's front surface on its z line), evaluated at
// the node instead of at pixel centres.
#include <algorithm>
#include <cmath>
#include <limits>

#include "detector_internals.h"
#include "vrm_sim/collision/primitives.h"

namespace vrm_sim {
namespace collision {
namespace internal {
namespace {

using Eigen::Vector3d;

class GeometricDetector : public CollisionDetector {
 public:
  std::string name() const override { return "geometric"; }

  void setInstrument(const InstrumentModel& instrument) override {
    instrument_ = instrument;
    has_instrument_ = true;
  }

  CollisionResult collide(const Eigen::Isometry3d& pose, const SurfaceView& surface) override {
    Stopwatch total, phase;
    CollisionResult result;
    if (!has_instrument_ || instrument_.primitives.empty()) {
      result.status = CollisionStatus::kNoInstrument;
      return result;
    }
    result.status = validate(pose, surface);
    if (result.status != CollisionStatus::kOk) return result;

    std::vector<Primitive> solids;
    std::vector<Eigen::AlignedBox3d> boxes;
    Eigen::AlignedBox3d all;
    for (const Primitive& p : instrument_.primitives) {
      solids.push_back(transformed(p, pose));
      boxes.push_back(bounds(solids.back()));
      all.extend(boxes.back());
    }
    const Vector3d z = (pose.linear() * instrument_.projection_direction).normalized();
    result.timing.ms_raster = phase.lap();

    bool any_near = false;
    for (std::size_t t = 0; t < surface.triangle_count; ++t) {
      const auto& tri = surface.triangles[t];
      const Vector3d& p0 = surface.positions[tri[0]];
      const Vector3d& p1 = surface.positions[tri[1]];
      const Vector3d& p2 = surface.positions[tri[2]];
      Eigen::AlignedBox3d tb(p0);
      tb.extend(p1);
      tb.extend(p2);
      if (!tb.intersects(all)) continue;
      any_near = true;
      for (std::size_t k = 0; k < solids.size(); ++k) {
        if (!tb.intersects(boxes[k]) || !overlapsTriangle(solids[k], p0, p1, p2)) continue;
        result.triangles.push_back(static_cast<std::uint32_t>(t));
        if (options_.readback == ReadbackMode::kFull) {
          const bool axial = solids[k].type == Primitive::Type::kCapsule ||
                             solids[k].type == Primitive::Type::kCylinder || solids[k].type == Primitive::Type::kCone;
          const Vector3d centre = axial ? Vector3d(0.5 * (solids[k].a + solids[k].b)) : solids[k].a;
          const Vector3d c = closestPointOnTriangle(centre, p0, p1, p2);
          const Vector3d n = c - centre;
          result.contact_points.push_back(c);
          result.contact_normals.push_back(n.norm() > 0.0 ? Vector3d(n.normalized()) : z);
        }
        break;
      }
    }
    if (!any_near) result.status = CollisionStatus::kOutsideVolume;
    result.colliding = !result.triangles.empty();
    result.timing.ms_analysis = phase.lap();

    if (result.colliding && options_.readback != ReadbackMode::kTrianglesOnly &&
        options_.readback != ReadbackMode::kYesNo) {
      for (std::size_t n = 0; n < surface.node_count; ++n) {
        const Vector3d& p = surface.positions[n];
        if (!all.contains(p)) continue;
        bool inside = false;
        for (const Primitive& s : solids) inside = inside || signedDistance(s, p) < 0.0;
        if (!inside) continue;
        // The front surface on the node's z line is the most distal end of all primitives' line intervals.
        double front = 0.0;
        for (const Primitive& s : solids) {
          // A half-space reaches infinitely far: it gives no finite push.
          if (auto interval = lineInterval(s, p, z); interval && std::isfinite((*interval)[1])) {
            front = std::max(front, (*interval)[1]);
          }
        }
        result.nodes.push_back(static_cast<std::uint32_t>(n));
        result.deformations.push_back(front * z);
      }
    }
    result.timing.ms_analysis += phase.lap();
    result.timing.ms_total = total.lap();
    return result;
  }

 private:
  static Eigen::AlignedBox3d bounds(const Primitive& p) {
    switch (p.type) {
      case Primitive::Type::kSphere:
        return Eigen::AlignedBox3d(p.a - Vector3d::Constant(p.radius), p.a + Vector3d::Constant(p.radius));
      case Primitive::Type::kCapsule: {
        Eigen::AlignedBox3d box(p.a.cwiseMin(p.b), p.a.cwiseMax(p.b));
        return Eigen::AlignedBox3d(box.min() - Vector3d::Constant(p.radius), box.max() + Vector3d::Constant(p.radius));
      }
      case Primitive::Type::kBox: {
        const Vector3d half = p.rotation.cwiseAbs() * p.half_extents;
        return Eigen::AlignedBox3d(p.a - half, p.a + half);
      }
      case Primitive::Type::kCylinder:
      case Primitive::Type::kCone: {  // conservative: the capsule around the axis
        Eigen::AlignedBox3d box(p.a.cwiseMin(p.b), p.a.cwiseMax(p.b));
        return Eigen::AlignedBox3d(box.min() - Vector3d::Constant(p.radius), box.max() + Vector3d::Constant(p.radius));
      }
      case Primitive::Type::kPlane: {
        const double inf = std::numeric_limits<double>::infinity();
        return Eigen::AlignedBox3d(Vector3d::Constant(-inf), Vector3d::Constant(inf));
      }
    }
    return {};
  }

  InstrumentModel instrument_;
  bool has_instrument_ = false;
};

}  // namespace

std::unique_ptr<CollisionDetector> makeGeometricDetector() { return std::make_unique<GeometricDetector>(); }

}  // namespace internal
}  // namespace collision
}  // namespace vrm_sim
