// The OpenGL (OSMesa) backends against the CPU backends: same triangles, same vectors up to rasterization ties and
// depth quantisation; ZCOLL's stencil parity on GL.
#include <gtest/gtest.h>

#include <set>

#include "vrm_sim/collision/collision_detector.h"
#include "vrm_sim/collision/primitives.h"
#include "vrm_sim/scene/instrument_meshes.h"
#include "vrm_sim/scene/mesh_utils.h"
#include "vrm_sim/scene/primitive_meshes.h"

namespace vrm_sim {
namespace collision {
namespace {

using Eigen::Vector3d;
constexpr double kPi = 3.14159265358979323846;

CollisionResult run(const std::string& name, const InstrumentModel& model, const Eigen::Isometry3d& pose,
                    const TriangleMesh& surface, int resolution) {
  CollisionOptions options;
  options.resolution = resolution;
  auto detector = makeCollisionDetector(name, options);
  detector->setInstrument(model);
  return detector->collide(pose, SurfaceView::of(surface));
}

TEST(ZcollGl, AgreesWithCpuBackend) {
  InstrumentModel capsule;
  capsule.mesh = primitiveMesh(Primitive::capsule(Vector3d(0, 0, -0.0035), Vector3d(0, 0, -0.0005), 0.0005), 48);
  scene::PlaneParams params;
  params.size_x = params.size_y = 0.004;
  params.subdivisions = 50;
  TriangleMesh surface = scene::makePlane(params);
  for (Vector3d& v : surface.vertices) v.z() += 0.0001 * std::sin(2000.0 * v.x());  // not flat
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.linear() = (Eigen::AngleAxisd(0.1, Vector3d::UnitZ()) * Eigen::AngleAxisd(kPi, Vector3d::UnitX()) *
                   Eigen::AngleAxisd(0.2, Vector3d::UnitY()))
                      .toRotationMatrix();
  pose.translation() = Vector3d(0.0001, 0, -0.0002);
  for (int resolution : {32, 100}) {
    for (const auto& [cpu_name, gl_name] : {std::pair<std::string, std::string>{"zcoll_f_cpu", "zcoll_f_gl"},
                                            std::pair<std::string, std::string>{"zcoll_cpu", "zcoll_gl"}}) {
      SCOPED_TRACE(gl_name + " r=" + std::to_string(resolution));
      const CollisionResult cpu = run(cpu_name, capsule, pose, surface, resolution);
      const CollisionResult gl = run(gl_name, capsule, pose, surface, resolution);
      ASSERT_EQ(gl.status, CollisionStatus::kOk) << toString(gl.status);
      ASSERT_TRUE(gl.colliding);
      EXPECT_EQ(gl.pixel_size, cpu.pixel_size);
      std::vector<std::uint32_t> diff;
      std::set_symmetric_difference(cpu.triangles.begin(), cpu.triangles.end(), gl.triangles.begin(),
                                    gl.triangles.end(), std::back_inserter(diff));
      EXPECT_LE(diff.size(), 2 + cpu.triangles.size() / 50) << cpu.triangles.size() << " vs " << gl.triangles.size();
      // Common nodes: same vector up to a pixel's worth of depth change on the slopes.
      std::size_t j = 0, common = 0;
      for (std::size_t i = 0; i < cpu.nodes.size(); ++i) {
        while (j < gl.nodes.size() && gl.nodes[j] < cpu.nodes[i]) ++j;
        if (j == gl.nodes.size() || gl.nodes[j] != cpu.nodes[i]) continue;
        ++common;
        EXPECT_LE((cpu.deformations[i] - gl.deformations[j]).norm(), 2.0 * cpu.pixel_size);
      }
      EXPECT_GE(common, cpu.nodes.size() * 95 / 100);
    }
  }
}

TEST(ZcollGl, StencilParityOnVitrectorPort) {
  scene::VitrectorParams params;
  InstrumentModel vitrector;
  vitrector.mesh = scene::makeVitrector(params);
  const double z = -params.port_distance_from_tip - 0.5 * params.port_length;
  const double x = 0.5 * params.shaft.diameter - 0.5 * params.port_depth;
  scene::PlaneParams patch_params;
  patch_params.size_x = patch_params.size_y = 0.00004;
  patch_params.subdivisions = 2;
  TriangleMesh patch = scene::makePlane(patch_params);
  scene::transformMesh(patch, Eigen::Isometry3d(Eigen::Translation3d(x, 0.0, z)));
  EXPECT_TRUE(run("zcoll_f_gl", vitrector, Eigen::Isometry3d::Identity(), patch, 128).colliding);
  EXPECT_FALSE(run("zcoll_gl", vitrector, Eigen::Isometry3d::Identity(), patch, 128).colliding);
  // Inside the solid wall next to the port, both see it.
  TriangleMesh wall = patch;
  scene::transformMesh(wall, Eigen::Isometry3d(Eigen::Translation3d(-2.0 * x, 0.0, 0.0)));
  EXPECT_TRUE(run("zcoll_gl", vitrector, Eigen::Isometry3d::Identity(), wall, 128).colliding);
  EXPECT_TRUE(run("zcoll_cpu", vitrector, Eigen::Isometry3d::Identity(), wall, 128).colliding);
}

}  // namespace
}  // namespace collision
}  // namespace vrm_sim
