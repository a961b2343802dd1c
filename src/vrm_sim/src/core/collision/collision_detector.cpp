#include "vrm_sim/collision/collision_detector.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "detector_internals.h"
#include "vrm_sim/mge/membrane.h"

namespace vrm_sim {
namespace collision {

SurfaceView SurfaceView::of(const TriangleMesh& mesh) {
  SurfaceView view;
  view.positions = mesh.vertices.data();
  view.node_count = mesh.vertices.size();
  view.triangles = mesh.triangles.data();
  view.triangle_count = mesh.triangles.size();
  return view;
}

SurfaceView SurfaceView::of(mge::Membrane& membrane) {
  SurfaceView view;
  view.positions = membrane.positions();
  view.node_count = membrane.nodeCount();
  view.triangles = membrane.triangleNodeSlots();
  view.triangle_count = membrane.triangleCount();
  return view;
}

const char* toString(CollisionStatus status) {
  switch (status) {
    case CollisionStatus::kOk:
      return "ok";
    case CollisionStatus::kEmptyInput:
      return "empty input";
    case CollisionStatus::kInvalidInput:
      return "invalid input";
    case CollisionStatus::kNoInstrument:
      return "no instrument";
    case CollisionStatus::kOutsideVolume:
      return "outside volume";
    case CollisionStatus::kBackendUnavailable:
      return "backend unavailable";
  }
  return "unknown";
}

const Registry<DetectorFactory>& detectorRegistry() {
  using internal::ZcollMode;
  // The scene files' names first (the thesis' algorithms on the fastest backend here, the CPU), then one entry per
  // backend.
  static const Registry<DetectorFactory> registry(
      "collision detector",
      {{"zcoll", [] { return internal::makeZcollCpuDetector(ZcollMode::kParity); }, "ZCOLL (Alg. 4.2) = zcoll_cpu"},
       {"zcoll_f", [] { return internal::makeZcollCpuDetector(ZcollMode::kFrontOnly); },
        "ZCOLL/F (Alg. 4.3) = zcoll_f_cpu"},
       {"zcoll_cpu", [] { return internal::makeZcollCpuDetector(ZcollMode::kParity); },
        "ZCOLL on the software rasterizer"},
       {"zcoll_f_cpu", [] { return internal::makeZcollCpuDetector(ZcollMode::kFrontOnly); },
        "ZCOLL/F on the software rasterizer"},
       {"zcoll_gl", [] { return internal::makeZcollGlDetector(false); }, "ZCOLL on OpenGL (OSMesa)"},
       {"zcoll_f_gl", [] { return internal::makeZcollGlDetector(true); }, "ZCOLL/F on OpenGL (OSMesa)"},
       {"myszkowski_cpu", [] { return internal::makeZcollCpuDetector(ZcollMode::kVolume); },
        "Myszkowski's stencil test (Alg. 4.1): collision and triangles only"},
       {"geometric", internal::makeGeometricDetector, "exact primitives vs the surface triangles"},
       {"fcl", [] { return internal::makeFclDetector("obbrss"); }, "FCL mesh-mesh, OBBRSS = fcl_obbrss"},
       {"fcl_aabb", [] { return internal::makeFclDetector("aabb"); }, "FCL mesh-mesh, AABB tree"},
       {"fcl_obbrss", [] { return internal::makeFclDetector("obbrss"); }, "FCL mesh-mesh, OBBRSS tree"},
       {"fcl_kios", [] { return internal::makeFclDetector("kios"); }, "FCL mesh-mesh, kIOS tree"},
       {"none", internal::makeNoneDetector, "never collides"}});
  return registry;
}

std::vector<std::string> collisionDetectorNames() { return detectorRegistry().names(); }

std::unique_ptr<CollisionDetector> makeCollisionDetector(const std::string& name, const CollisionOptions& options) {
  std::unique_ptr<CollisionDetector> detector = detectorRegistry().at(name).make();
  detector->setOptions(options);
  return detector;
}

namespace internal {

bool isFinite(const Eigen::Isometry3d& pose) { return pose.matrix().allFinite(); }

int chooseResolution(const InstrumentModel& instrument, const CollisionOptions& options) {
  int r = std::max(4, options.resolution);
  if (options.max_pixel_size > 0.0) {
    const ProjectionVolume probe =
        fitProjectionVolume(instrument.mesh, instrument.projection_direction, r, instrument.tip_region_length);
    if (probe.resolution > 0) {
      // pixel_size = extent / (r - 2) (one pixel margin on each side).
      const double extent = probe.pixel_size * (r - 2);
      const double needed = std::ceil(extent / options.max_pixel_size) + 2.0;
      r = static_cast<int>(std::clamp<double>(needed, r, std::max(r, options.max_resolution)));
    }
  }
  return r;
}

bool volumeOptionsDiffer(const CollisionOptions& a, const CollisionOptions& b) {
  return a.resolution != b.resolution || a.max_pixel_size != b.max_pixel_size || a.max_resolution != b.max_resolution;
}

CollisionStatus validate(const Eigen::Isometry3d& pose, const SurfaceView& surface) {
  if (!isFinite(pose)) return CollisionStatus::kInvalidInput;
  if (surface.triangle_count == 0 || surface.node_count == 0 || !surface.positions || !surface.triangles) {
    return CollisionStatus::kEmptyInput;
  }
  for (std::size_t i = 0; i < surface.node_count; ++i) {
    if (!surface.positions[i].allFinite()) return CollisionStatus::kInvalidInput;
  }
  for (std::size_t t = 0; t < surface.triangle_count; ++t) {
    for (std::uint32_t n : surface.triangles[t]) {
      if (n >= surface.node_count) return CollisionStatus::kInvalidInput;
    }
  }
  return CollisionStatus::kOk;
}

CollisionStatus validateMeshQuery(bool has_instrument, const InstrumentModel& instrument, const Eigen::Isometry3d& pose,
                                  const SurfaceView& surface) {
  if (!has_instrument) return CollisionStatus::kNoInstrument;
  if (instrument.mesh.triangles.empty()) return CollisionStatus::kEmptyInput;
  return validate(pose, surface);
}

void NodeAccumulator::begin(std::size_t node_count) {
  if (sum_.size() != node_count) {
    sum_.assign(node_count, 0.0);
    max_.assign(node_count, 0.0f);
    count_.assign(node_count, 0);
    touched_.assign(node_count + 1, 0);  // + 1: add() writes one entry past the last node it keeps
  }
  touched_count_ = 0;
}

void NodeAccumulator::finish(DeformationReduction reduction, const Eigen::Vector3d& direction,
                             CollisionResult& result) {
  // Sorted by a branch-free scan over all nodes when that is cheaper than sorting the touched ones (a heavy contact).
  const std::size_t touched = touched_count_;
  if (touched * 8 > count_.size()) {
    std::size_t kept = 0;
    for (std::size_t n = 0; n < count_.size(); ++n) {
      touched_[kept] = static_cast<std::uint32_t>(n);
      kept += count_[n] != 0 ? 1 : 0;
    }
  } else {
    std::sort(touched_.begin(), touched_.begin() + static_cast<std::ptrdiff_t>(touched));
  }
  const std::size_t first = result.nodes.size();
  result.nodes.resize(first + touched);
  result.deformations.resize(first + touched);
  for (std::size_t k = 0; k < touched; ++k) {
    const std::uint32_t node = touched_[k];
    result.nodes[first + k] = node;
    const double length = reduction == DeformationReduction::kMax ? max_[node] : sum_[node] / count_[node];
    result.deformations[first + k] = length * direction;
    sum_[node] = 0.0;
    max_[node] = 0.0f;
    count_[node] = 0;
  }
  touched_count_ = 0;
}

namespace {

class NoneDetector : public CollisionDetector {
 public:
  std::string name() const override { return "none"; }
  void setInstrument(const InstrumentModel&) override {}
  CollisionResult collide(const Eigen::Isometry3d&, const SurfaceView&) override { return {}; }
};

}  // namespace

std::unique_ptr<CollisionDetector> makeNoneDetector() { return std::make_unique<NoneDetector>(); }

}  // namespace internal
}  // namespace collision
}  // namespace vrm_sim
