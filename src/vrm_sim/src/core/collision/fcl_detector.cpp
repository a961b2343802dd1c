// FCL facade: the modern stand-in for the thesis' RAPID (OBB tree) and SOLID (AABB tree) facades (§4.2.7). The
// surface's BVH is built once and refitted after every deformation (what SOLID does; RAPID had to rebuild, 48 ms).
// FCL's mesh-mesh test finds triangle pairs that intersect: a surface triangle lying entirely inside the
// instrument is not reported, and no deformation vectors are produced (only the contact set).
#include <fcl/geometry/bvh/BVH_model.h>
#include <fcl/math/bv/AABB.h>
#include <fcl/math/bv/OBBRSS.h>
#include <fcl/math/bv/kIOS.h>
#include <fcl/narrowphase/collision.h>
#include <fcl/narrowphase/collision_object.h>

#include <algorithm>

#include "detector_internals.h"

namespace vrm_sim {
namespace collision {
namespace internal {
namespace {

using Eigen::Vector3d;

template <class BV>
class FclDetector : public CollisionDetector {
 public:
  explicit FclDetector(std::string name) : name_(std::move(name)) {}

  std::string name() const override { return name_; }

  void setInstrument(const InstrumentModel& instrument) override {
    instrument_model_.reset();
    if (instrument.mesh.triangles.empty()) return;
    auto model = std::make_shared<fcl::BVHModel<BV>>();
    std::vector<fcl::Triangle> triangles;
    for (const auto& t : instrument.mesh.triangles) triangles.emplace_back(t[0], t[1], t[2]);
    model->beginModel();
    model->addSubModel(instrument.mesh.vertices, triangles);
    model->endModel();
    instrument_model_ = model;
  }

  CollisionResult collide(const Eigen::Isometry3d& pose, const SurfaceView& surface) override {
    Stopwatch total, phase;
    CollisionResult result;
    if (!instrument_model_) {
      result.status = CollisionStatus::kNoInstrument;
      return result;
    }
    result.status = validate(pose, surface);
    if (result.status != CollisionStatus::kOk) return result;

    points_.assign(surface.positions, surface.positions + surface.node_count);
    const bool same_topology = surface_model_ && surface.triangles == last_triangles_ &&
                               surface.triangle_count == last_triangle_count_ && surface.node_count == last_node_count_;
    if (!same_topology) {
      // Build (also after cutting / tearing changed the topology).
      auto model = std::make_shared<fcl::BVHModel<BV>>();
      std::vector<fcl::Triangle> triangles;
      triangles.reserve(surface.triangle_count);
      for (std::size_t t = 0; t < surface.triangle_count; ++t) {
        const auto& tri = surface.triangles[t];
        triangles.emplace_back(tri[0], tri[1], tri[2]);
      }
      model->beginModel(static_cast<int>(surface.triangle_count), static_cast<int>(surface.node_count));
      model->addSubModel(points_, triangles);
      model->endModel();
      surface_model_ = model;
      last_triangles_ = surface.triangles;
      last_triangle_count_ = surface.triangle_count;
      last_node_count_ = surface.node_count;
    } else if (!surface.static_geometry) {
      // Refit bottom-up after a deformation (no rebuild).
      surface_model_->beginUpdateModel();
      surface_model_->updateSubModel(points_);
      surface_model_->endUpdateModel(true, true);
    }
    result.timing.ms_raster = phase.lap();

    fcl::CollisionObjectd instrument(instrument_model_, pose.linear(), pose.translation());
    fcl::CollisionObjectd tissue(surface_model_, Eigen::Matrix3d::Identity(), Vector3d::Zero());
    const bool yes_no = options_.readback == ReadbackMode::kYesNo;
    fcl::CollisionRequestd request(yes_no ? 1 : static_cast<std::size_t>(options_.fcl_max_contacts), !yes_no);
    fcl::CollisionResultd fcl_result;
    fcl::collide(&instrument, &tissue, request, fcl_result);
    result.timing.ms_analysis = phase.lap();

    result.colliding = fcl_result.isCollision();
    if (!yes_no) {
      std::vector<fcl::Contactd> contacts;
      fcl_result.getContacts(contacts);
      for (const auto& c : contacts) {
        result.triangles.push_back(static_cast<std::uint32_t>(c.b2));
        if (options_.readback == ReadbackMode::kFull) {
          result.contact_points.push_back(c.pos);
          result.contact_normals.push_back(c.normal);
        }
      }
      std::sort(result.triangles.begin(), result.triangles.end());
      result.triangles.erase(std::unique(result.triangles.begin(), result.triangles.end()), result.triangles.end());
    }
    result.timing.ms_readback = phase.lap();
    result.timing.ms_total = total.lap();
    return result;
  }

 private:
  std::string name_;
  std::shared_ptr<fcl::BVHModel<BV>> instrument_model_;
  std::shared_ptr<fcl::BVHModel<BV>> surface_model_;
  std::vector<Vector3d> points_;
  const std::array<std::uint32_t, 3>* last_triangles_ = nullptr;
  std::size_t last_triangle_count_ = 0;
  std::size_t last_node_count_ = 0;
};

}  // namespace

std::unique_ptr<CollisionDetector> makeFclDetector(const std::string& bv) {
  if (bv == "aabb") return std::make_unique<FclDetector<fcl::AABBd>>("fcl_aabb");
  if (bv == "kios") return std::make_unique<FclDetector<fcl::kIOSd>>("fcl_kios");
  return std::make_unique<FclDetector<fcl::OBBRSSd>>("fcl_obbrss");
}

}  // namespace internal
}  // namespace collision
}  // namespace vrm_sim
