// The OpenGL (OSMesa) backends against the CPU backends: same triangles, same vectors up to rasterization ties and
// depth quantisation; ZCOLL's stencil parity on GL.
#include <gtest/gtest.h>

#include <set>

#include "vrm_scene/meshes/instrument_meshes.h"
#include "vrm_scene/meshes/mesh_utils.h"
#include "vrm_scene/meshes/primitive_meshes.h"
#include "vrm_sim/collision/collision_detector.h"
#include "vrm_sim/collision/image_space.h"
#include "vrm_sim/collision/primitives.h"

namespace vrm_sim {
namespace collision {
namespace {

using Eigen::Vector3d;
constexpr double kPi = 3.14159265358979323846;

CollisionResult run(const std::string& name, const InstrumentModel& model, const Eigen::Isometry3d& pose,
                    const TriangleMesh& surface, int resolution, ReadbackMode readback = ReadbackMode::kFull) {
  CollisionOptions options;
  options.resolution = resolution;
  options.readback = readback;
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

// The GPU-side reductions (mask pass, OR-folded quadrants for yes/no, OR-folded rows/columns for the ROI, reduced
// readback) give the CPU backend's answer in every readback mode, for colliding, touching-free and outside poses.
TEST(ZcollGl, GpuReductionsMatchCpuInEveryReadbackMode) {
  InstrumentModel sphere;
  sphere.mesh = primitiveMesh(Primitive::sphere(Vector3d(0, 0, -0.0005), 0.0005), 48);
  scene::PlaneParams params;
  params.size_x = params.size_y = 0.004;
  params.subdivisions = 40;
  const TriangleMesh surface = scene::makePlane(params);
  const Eigen::Isometry3d down(Eigen::AngleAxisd(kPi, Vector3d::UnitX()));
  const Eigen::Isometry3d pressing = Eigen::Translation3d(0.0003, -0.0002, -0.0002) * down;
  const Eigen::Isometry3d touching = Eigen::Translation3d(0.0001, 0, -0.00002) * down;  // 20 um deep
  const Eigen::Isometry3d above = Eigen::Translation3d(0, 0, 0.0002) * down;       // volume reaches the plane: no hit
  const Eigen::Isometry3d beside = Eigen::Translation3d(0.01, 0, -0.0002) * down;  // plane outside the volume
  for (const std::string& method : {std::string("zcoll_f"), std::string("zcoll")}) {
    for (ReadbackMode mode :
         {ReadbackMode::kYesNo, ReadbackMode::kTrianglesOnly, ReadbackMode::kDeformationsOnly, ReadbackMode::kFull}) {
      SCOPED_TRACE(method + " mode " + std::to_string(static_cast<int>(mode)));
      const CollisionResult cpu = run(method + "_cpu", sphere, pressing, surface, 64, mode);
      const CollisionResult gl = run(method + "_gl", sphere, pressing, surface, 64, mode);
      ASSERT_EQ(gl.status, CollisionStatus::kOk) << toString(gl.status);
      EXPECT_TRUE(cpu.colliding);
      EXPECT_TRUE(gl.colliding);
      // The same GL rendering without GPU reductions (the footprint's depth, colour and stencil read, mask made on
      // the CPU): identical answer; the reduced readback is never larger (beyond the 4 r bytes of the folded row and
      // column) and much smaller for a light contact, whose ROI is small.
      CollisionOptions plain;
      plain.resolution = 64;
      plain.readback = mode;
      plain.gpu_reductions = false;
      auto plain_detector = makeCollisionDetector(method + "_gl", plain);
      plain_detector->setInstrument(sphere);
      const CollisionResult unreduced = plain_detector->collide(pressing, SurfaceView::of(surface));
      EXPECT_EQ(unreduced.triangles, gl.triangles);
      EXPECT_EQ(unreduced.nodes, gl.nodes);
      EXPECT_EQ(unreduced.colliding, gl.colliding);
      EXPECT_LE(gl.readback_bytes, unreduced.readback_bytes + 4 * 64);
      CollisionOptions reduced = plain;
      reduced.gpu_reductions = true;
      auto reduced_detector = makeCollisionDetector(method + "_gl", reduced);
      reduced_detector->setInstrument(sphere);
      const CollisionResult light_reduced = reduced_detector->collide(touching, SurfaceView::of(surface));
      const CollisionResult light_unreduced = plain_detector->collide(touching, SurfaceView::of(surface));
      EXPECT_TRUE(light_reduced.colliding);
      EXPECT_EQ(light_reduced.triangles, light_unreduced.triangles);
      EXPECT_LT(3 * light_reduced.readback_bytes, light_unreduced.readback_bytes)
          << light_reduced.readback_bytes << " vs " << light_unreduced.readback_bytes;
      if (mode == ReadbackMode::kYesNo) EXPECT_EQ(light_reduced.readback_bytes, 2u);
      std::vector<std::uint32_t> diff;
      std::set_symmetric_difference(cpu.triangles.begin(), cpu.triangles.end(), gl.triangles.begin(),
                                    gl.triangles.end(), std::back_inserter(diff));
      EXPECT_LE(diff.size(), 2u) << cpu.triangles.size() << " vs " << gl.triangles.size();
      if (mode == ReadbackMode::kYesNo || mode == ReadbackMode::kTrianglesOnly) {
        EXPECT_TRUE(gl.nodes.empty());
        EXPECT_TRUE(gl.contact_points.empty());
      } else {
        EXPECT_FALSE(gl.nodes.empty());
        EXPECT_EQ(gl.contact_points.empty(), mode != ReadbackMode::kFull);
        double cpu_max = 0.0, gl_max = 0.0;
        for (const Vector3d& d : cpu.deformations) cpu_max = std::max(cpu_max, d.norm());
        for (const Vector3d& d : gl.deformations) gl_max = std::max(gl_max, d.norm());
        EXPECT_NEAR(gl_max, cpu_max, cpu.pixel_size);
      }
      for (const Eigen::Isometry3d& miss : {above, beside}) {
        const CollisionResult c = run(method + "_cpu", sphere, miss, surface, 64, mode);
        const CollisionResult g = run(method + "_gl", sphere, miss, surface, 64, mode);
        EXPECT_FALSE(c.colliding);
        EXPECT_FALSE(g.colliding);
        EXPECT_EQ(g.status, c.status) << toString(g.status) << " vs " << toString(c.status);
        EXPECT_TRUE(g.triangles.empty());
      }
    }
  }
}

// §4.1.4 z-convexity by additive stencil on the GPU agrees with the CPU count: one sheet is z-convex, two stacked
// sheets are not, and neither is the vitrector along its axis (its port pocket).
TEST(ZcollGl, ZConvexityByAdditiveStencilMatchesCpu) {
  scene::PlaneParams params;
  params.size_x = params.size_y = 0.002;
  params.subdivisions = 10;
  TriangleMesh sheet = scene::makePlane(params);
  scene::transformMesh(sheet, Eigen::Isometry3d(Eigen::Translation3d(0, 0, -0.001)));
  const ProjectionVolume v = fitProjectionVolume(sheet, Vector3d::UnitZ(), 40, 0.002);
  TriangleMesh folded = sheet, second = sheet;
  scene::transformMesh(second, Eigen::Isometry3d(Eigen::Translation3d(0, 0, -0.0005)));
  scene::appendMesh(folded, second);
  const auto sheet_gl = zConvexOnGl(sheet, v);
  ASSERT_TRUE(sheet_gl.has_value()) << "no OSMesa context";
  EXPECT_TRUE(*sheet_gl);
  EXPECT_EQ(maxCoverage(sheet, v), 1);
  EXPECT_EQ(zConvexOnGl(folded, v), std::optional<bool>(false));
  EXPECT_EQ(maxCoverage(folded, v), 2);
  scene::VitrectorParams vitrector_params;
  const TriangleMesh vitrector = scene::makeVitrector(vitrector_params);
  const ProjectionVolume tip = fitProjectionVolume(vitrector, Vector3d::UnitZ(), 64, 0.001);
  EXPECT_EQ(zConvexOnGl(vitrector, tip), std::optional<bool>(maxCoverage(vitrector, tip) <= 1));
  EXPECT_EQ(zConvexOnGl(TriangleMesh{}, tip), std::optional<bool>(true));
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
