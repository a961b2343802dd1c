#include "vrm_render/stereo_renderer.h"

#include <malloc.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstring>
#include <future>
#include <limits>
#include <map>
#include <unordered_map>

#include "depth_of_field.h"
#include "shaders.h"
#include "vrm_gl/gl_context.h"
#include "vrm_gl/gl_objects.h"

namespace vrm_render {
namespace {

using Clock = std::chrono::steady_clock;

double msSince(Clock::time_point start) {
  return std::chrono::duration<double, std::milli>(Clock::now() - start).count();
}

// A linked program with cached uniform locations.
class Program {
 public:
  void build(const char* vertex, const char* fragment, const char* name, const std::string& prefix = "") {
    // Sources that carry their own #version are used as they are.
    auto source = [&](const char* s) { return std::strncmp(s, "#version", 8) == 0 ? std::string(s) : prefix + s; };
    try {
      id_ = vrm_gl::linkProgram(source(vertex), source(fragment), name);
    } catch (const vrm_gl::GlError& e) {
      throw RenderError(e.what());
    }
  }
  void use() const { glUseProgram(id_); }
  GLint operator[](const char* uniform) {
    auto it = locations_.find(uniform);
    if (it != locations_.end()) return it->second;
    const GLint location = glGetUniformLocation(id_, uniform);
    locations_.emplace(uniform, location);
    return location;
  }

 private:
  GLuint id_ = 0;
  std::unordered_map<std::string, GLint> locations_;
};

struct RenderTarget {
  GLuint fbo = 0;
  GLuint color = 0;
  GLuint depth = 0;  // depth texture, 0 when the target has none
  int width = 0;
  int height = 0;

  void release() {
    if (fbo) glDeleteFramebuffers(1, &fbo);
    if (color) glDeleteTextures(1, &color);
    if (depth) glDeleteTextures(1, &depth);
    *this = RenderTarget();
  }
};

enum class DepthKind { kNone, kDepth };

RenderTarget makeTarget(int width, int height, bool with_color, DepthKind depth, const char* name) {
  RenderTarget target;
  target.width = width;
  target.height = height;
  glGenFramebuffers(1, &target.fbo);
  glBindFramebuffer(GL_FRAMEBUFFER, target.fbo);
  if (with_color) {
    target.color = vrm_gl::makeTexture(GL_RGBA8, width, height, GL_RGBA, GL_UNSIGNED_BYTE, GL_LINEAR);
    glFramebufferTexture2D(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_TEXTURE_2D, target.color, 0);
  } else {
    glDrawBuffer(GL_NONE);
    glReadBuffer(GL_NONE);
  }
  if (depth == DepthKind::kDepth) {
    target.depth =
        vrm_gl::makeTexture(GL_DEPTH_COMPONENT24, width, height, GL_DEPTH_COMPONENT, GL_UNSIGNED_INT, GL_NEAREST);
    glFramebufferTexture2D(GL_FRAMEBUFFER, GL_DEPTH_ATTACHMENT, GL_TEXTURE_2D, target.depth, 0);
  }
  try {
    vrm_gl::checkFramebufferComplete(std::string("render target ") + name);
  } catch (const vrm_gl::GlError& e) {
    target.release();
    throw RenderError(e.what());
  }
  return target;
}

struct Object {
  bool has_mesh = false;
  std::uint64_t version = 0;
  ObjectStyle style;
  Eigen::Isometry3f pose = Eigen::Isometry3f::Identity();            // as drawn this frame
  Eigen::Isometry3f requested_pose = Eigen::Isometry3f::Identity();  // setPose's
  bool anchored = false;  // cache_static: `pose` is the anchor, kept while requested_pose stays within tolerance
  bool visible = true;
  GLuint vao = 0;
  GLuint buffers[5] = {};  // positions, normals, colours, injury, indices
  std::size_t vertex_count = 0;
  std::size_t triangle_count = 0;
  bool has_colors = false;
  bool has_injury = false;
  std::vector<std::uint32_t> triangles;  // to notice topology changes of streamed meshes
  std::vector<float> positions;          // object frame, for the spotlight's partition
  bool in_cone = false;                  // this frame: the spotlight cone reaches the bounding sphere
  std::size_t shadowed_triangles = 0;    // this frame, in_cone: the triangle ranges of LightPartition
  std::size_t lit_triangles = 0;
  Eigen::Vector3f centre = Eigen::Vector3f::Zero();  // bounding sphere, object frame
  float radius = 0.0f;
};

struct Plane {
  Eigen::Vector3f n;
  float d;
};

std::array<Plane, 6> frustumPlanes(const Eigen::Matrix4f& m) {
  std::array<Plane, 6> planes;
  const Eigen::Vector4f rows[6] = {m.row(3) + m.row(0), m.row(3) - m.row(0), m.row(3) + m.row(1),
                                   m.row(3) - m.row(1), m.row(3) + m.row(2), m.row(3) - m.row(2)};
  for (int i = 0; i < 6; ++i) {
    const float length = rows[i].head<3>().norm();
    planes[i] = {rows[i].head<3>() / length, rows[i](3) / length};
  }
  return planes;
}

bool sphereVisible(const std::array<Plane, 6>& planes, const Eigen::Vector3f& centre, float radius) {
  for (const Plane& plane : planes) {
    if (plane.n.dot(centre) + plane.d < -radius) return false;
  }
  return true;
}

void computeNormals(const MeshView& mesh, std::vector<float>* normals) {
  normals->assign(mesh.vertex_count * 3, 0.0f);
  for (std::size_t t = 0; t < mesh.triangle_count; ++t) {
    const std::uint32_t* tri = mesh.triangles + 3 * t;
    const Eigen::Map<const Eigen::Vector3f> a(mesh.positions + 3 * tri[0]);
    const Eigen::Map<const Eigen::Vector3f> b(mesh.positions + 3 * tri[1]);
    const Eigen::Map<const Eigen::Vector3f> c(mesh.positions + 3 * tri[2]);
    const Eigen::Vector3f area_normal = (b - a).cross(c - a);  // area-weighted
    for (int k = 0; k < 3; ++k) Eigen::Map<Eigen::Vector3f>(normals->data() + 3 * tri[k]) += area_normal;
  }
  for (std::size_t v = 0; v < mesh.vertex_count; ++v) {
    Eigen::Map<Eigen::Vector3f> n(normals->data() + 3 * v);
    const float length = n.norm();
    n = length > 0.0f ? Eigen::Vector3f(n / length) : Eigen::Vector3f::UnitZ();
  }
}

bool allFinite(const float* values, std::size_t count) {
  for (std::size_t i = 0; i < count; ++i) {
    if (!std::isfinite(values[i])) return false;
  }
  return true;
}

void validateMesh(const std::string& id, const MeshView& mesh) {
  const std::string prefix = "mesh '" + id + "': ";
  if (mesh.vertex_count == 0 || mesh.triangle_count == 0 || !mesh.positions || !mesh.triangles) {
    throw RenderError(prefix + "empty (" + std::to_string(mesh.vertex_count) + " vertices, " +
                      std::to_string(mesh.triangle_count) + " triangles)");
  }
  if (mesh.vertex_count > StereoRenderer::kMaxVertices || mesh.triangle_count > StereoRenderer::kMaxTriangles) {
    throw RenderError(prefix + "too large (" + std::to_string(mesh.vertex_count) + " vertices, " +
                      std::to_string(mesh.triangle_count) + " triangles; limits " +
                      std::to_string(StereoRenderer::kMaxVertices) + ", " +
                      std::to_string(StereoRenderer::kMaxTriangles) + ")");
  }
  if (!allFinite(mesh.positions, mesh.vertex_count * 3)) throw RenderError(prefix + "non-finite vertex position");
  if (mesh.normals && !allFinite(mesh.normals, mesh.vertex_count * 3)) throw RenderError(prefix + "non-finite normal");
  if (mesh.colors && !allFinite(mesh.colors, mesh.vertex_count * 4)) throw RenderError(prefix + "non-finite colour");
  if (mesh.injury && !allFinite(mesh.injury, mesh.vertex_count)) throw RenderError(prefix + "non-finite injury");
  for (std::size_t i = 0; i < mesh.triangle_count * 3; ++i) {
    if (mesh.triangles[i] >= mesh.vertex_count) {
      throw RenderError(prefix + "triangle " + std::to_string(i / 3) + " refers to vertex " +
                        std::to_string(mesh.triangles[i]) + " of " + std::to_string(mesh.vertex_count));
    }
  }
}

void validateOptions(const RenderOptions& options) {
  const int k = StereoRenderer::kMaxImageSide;
  if (options.width <= 0 || options.height <= 0 || options.width > k || options.height > k) {
    throw RenderError("image size " + std::to_string(options.width) + "x" + std::to_string(options.height) +
                      " outside 1.." + std::to_string(k));
  }
  if (options.shadow_map_size < 16 || options.shadow_map_size > k) {
    throw RenderError("shadow_map_size " + std::to_string(options.shadow_map_size) + " outside 16.." +
                      std::to_string(k));
  }
  if (options.dof_downsample != 1 && options.dof_downsample != 2 && options.dof_downsample != 4) {
    throw RenderError("dof_downsample must be 1, 2 or 4");
  }
  if (options.dof_taps != 9 && options.dof_taps != 13) throw RenderError("dof_taps must be 9 or 13");
  if (!(options.dof_sigma_px > 0.0f) || !std::isfinite(options.dof_sigma_px)) {
    throw RenderError("dof_sigma_px must be positive");
  }
}

// The eight-sided pyramid that circumscribes the light pipe's cone (apex at the tip, half angle a): eight side
// planes tangent to the cone and the plane through the apex, as (n, d) with n.p + d >= 0 inside. Everything the
// spotlight can light lies inside.
constexpr int kPyramidSides = 8;
using Pyramid = std::array<Eigen::Vector4f, kPyramidSides + 1>;

Pyramid spotPyramid(const Eigen::Vector3f& tip, const Eigen::Vector3f& axis, float half_angle) {
  const Eigen::Vector3f u = axis.unitOrthogonal();
  const Eigen::Vector3f v = axis.cross(u);
  const float tan_half = std::tan(half_angle);
  Pyramid planes;
  for (int k = 0; k <= kPyramidSides; ++k) {
    const float phi = 2.0f * static_cast<float>(M_PI) * k / kPyramidSides;
    // Side k touches the cone along the line t (axis + tan(a) s), s = cos(phi) u + sin(phi) v.
    const Eigen::Vector3f n =
        k < kPyramidSides ? Eigen::Vector3f((tan_half * axis - std::cos(phi) * u - std::sin(phi) * v).normalized())
                          : axis;  // unit normals: render() compares plane distances with bounding-sphere radii
    planes[k] << n, -n.dot(tip);
  }
  return planes;
}

// Bilinear without mip-maps: at zoom 1 a fundus texel is ~0.6 pixel (mild minification; the vessels are drawn
// at least 0.8 texel wide), and llvmpipe's per-quad LOD selection costs ~? ms per stereo frame (bench_render).
constexpr GLint kFundusMinFilter = GL_NEAREST;

bool isMetal(const ObjectStyle& style) {
  return style.material.metallic > 0.0f || style.material.glow_tip_length > 0.0f;
}

// What the static layer (RenderOptions::cache_static) depends on: its objects (identity, mesh version, pose, the
// style terms of the ambient-only shader) and the eye's camera, microscope and fundus. Equal keys, equal layer.
struct StaticLayerKey {
  std::vector<const void*> objects;
  std::vector<std::uint64_t> versions;
  std::vector<float> values;
  bool operator==(const StaticLayerKey& other) const {
    return objects == other.objects && versions == other.versions && values == other.values;
  }
  void add(const float* data, std::size_t count) { values.insert(values.end(), data, data + count); }
  void add(float value) { values.push_back(value); }
};

// Objects the static layer holds (RenderOptions::cache_static): opaque, not deformable, not metal, casting no shadow.
bool isStatic(const ObjectStyle& style) {
  return !style.deformable && !style.casts_shadow && !style.ghost && style.material.diffuse.w() >= 1.0f &&
         !isMetal(style) && style.material.emission.isZero();
}

// An upper bound of how far (pixels at the focal plane) any point of a bounding sphere (centre, radius; object
// frame) moves between two poses: |b c - a c| + |b R - a R| r, with |ΔR| = 2 sin(θ/2) <= θ.
float displacementPx(const Eigen::Isometry3f& a, const Eigen::Isometry3f& b, const Eigen::Vector3f& centre,
                     float radius, float pixels_per_metre) {
  const Eigen::Matrix3f relative = a.linear().transpose() * b.linear();
  const float cos_angle = std::clamp(0.5f * (relative.trace() - 1.0f), -1.0f, 1.0f);
  const float angle = std::acos(cos_angle);
  return ((b * centre - a * centre).norm() + angle * radius) * pixels_per_metre;
}

// Where the shadow map can hold a caster: a rectangle in the light's normalised device coordinates (x0, y0, x1, y1),
// nowhere (no shadows) or anywhere (a caster reaches behind the light pipe tip).
struct ShadowBox {
  enum Kind { kNowhere, kRect, kAnywhere } kind = kNowhere;
  Eigen::Matrix4f light_view_proj = Eigen::Matrix4f::Identity();
  Eigen::Vector4f rect = Eigen::Vector4f::Zero();

  // Grows the box by a caster (object frame): its triangles clipped to the light's near plane (z >= -w in clip
  // coordinates), as the shadow pass rasterises them.
  void add(const std::vector<float>& positions, const std::vector<std::uint32_t>& triangles,
           const Eigen::Isometry3f& world_from_object) {
    if (kind == kAnywhere) return;
    const Eigen::Matrix4f m = light_view_proj * world_from_object.matrix();
    auto clip = [&](std::uint32_t v) {
      return Eigen::Vector4f(m * Eigen::Vector4f(positions[3 * v], positions[3 * v + 1], positions[3 * v + 2], 1.0f));
    };
    auto grow = [&](const Eigen::Vector4f& c) {
      if (!(c.w() > 1e-9f)) {
        kind = kAnywhere;
        return;
      }
      const float x = c.x() / c.w(), y = c.y() / c.w();
      if (kind == kNowhere) {
        rect << x, y, x, y;
        kind = kRect;
      }
      rect = Eigen::Vector4f(std::min(rect[0], x), std::min(rect[1], y), std::max(rect[2], x), std::max(rect[3], y));
    };
    for (std::size_t t = 0; t + 2 < triangles.size() && kind != kAnywhere; t += 3) {
      const Eigen::Vector4f c[3] = {clip(triangles[t]), clip(triangles[t + 1]), clip(triangles[t + 2])};
      for (int k = 0; k < 3; ++k) {
        const Eigen::Vector4f& a = c[k];
        const Eigen::Vector4f& b = c[(k + 1) % 3];
        const float da = a.z() + a.w(), db = b.z() + b.w();
        if (da >= 0.0f) grow(a);
        if ((da >= 0.0f) != (db >= 0.0f)) grow(a + (b - a) * (da / (da - db)));
      }
    }
  }
};

// The triangle ranges partitionForLight() produces: [0, shadowed) may be lit and shadowed, [shadowed, lit) may be lit
// but no shadow reaches them, [lit, count) are outside the spotlight's pyramid.
struct LightPartition {
  std::size_t shadowed = 0;
  std::size_t lit = 0;
};

// Orders a mesh's triangles for the spotlight into the three ranges of LightPartition (each in the original order;
// written to `out`). A triangle whose corners all lie outside one plane of the pyramid cannot be lit (the pyramid
// and the triangle are convex); one whose corners, seen from the light, all lie beyond one edge of the shadow box
// cannot be shadowed (the shadow lookup of its fragments returns exactly 1 there).
LightPartition partitionForLight(const std::vector<float>& positions, const std::vector<std::uint32_t>& triangles,
                                 const Eigen::Isometry3f& world_from_object, const Pyramid& world_planes,
                                 const ShadowBox& shadow_box, std::vector<std::uint16_t>* codes,
                                 std::array<std::vector<std::uint32_t>, 2>* scratch, std::vector<std::uint32_t>* out) {
  // Planes in the object frame: n.(R p + t) + d = (R^T n).p + (n.t + d).
  constexpr int kPlanes = kPyramidSides + 1;
  Pyramid planes;
  for (int i = 0; i < kPlanes; ++i) {
    const Eigen::Vector3f n = world_planes[i].head<3>();
    planes[i] << world_from_object.linear().transpose() * n,
        n.dot(world_from_object.translation()) + world_planes[i].w();
  }
  const Eigen::Matrix4f light_from_object = shadow_box.light_view_proj * world_from_object.matrix();
  const Eigen::Vector4f& box = shadow_box.rect;
  const std::size_t vertex_count = positions.size() / 3;
  // Bits 0-8: outside pyramid plane i; bits 9-12: left of, below, right of, above the shadow box.
  constexpr int kBoxShift = kPlanes;
  codes->resize(vertex_count);
  for (std::size_t v = 0; v < vertex_count; ++v) {
    const Eigen::Map<const Eigen::Vector3f> p(positions.data() + 3 * v);
    std::uint16_t code = 0;
    for (int i = 0; i < kPlanes; ++i) {
      if (planes[i].head<3>().dot(p) + planes[i].w() < 0.0f) code |= 1 << i;
    }
    if (shadow_box.kind == ShadowBox::kNowhere) {
      code |= 1 << kBoxShift;  // beyond every edge
    } else if (shadow_box.kind == ShadowBox::kRect) {
      const Eigen::Vector4f c = light_from_object * Eigen::Vector4f(p.x(), p.y(), p.z(), 1.0f);
      if (c.w() > 0.0f) {  // else no bit: maybe shadowed
        if (c.x() < box[0] * c.w()) code |= 1 << kBoxShift;
        if (c.y() < box[1] * c.w()) code |= 1 << (kBoxShift + 1);
        if (c.x() > box[2] * c.w()) code |= 1 << (kBoxShift + 2);
        if (c.y() > box[3] * c.w()) code |= 1 << (kBoxShift + 3);
      }
    }
    (*codes)[v] = code;
  }
  constexpr std::uint16_t kPyramidBits = (1 << kPlanes) - 1;
  out->clear();
  std::vector<std::uint32_t>& unshadowed = (*scratch)[0];
  std::vector<std::uint32_t>& unlit = (*scratch)[1];
  unshadowed.clear();
  unlit.clear();
  for (std::size_t t = 0; t + 2 < triangles.size(); t += 3) {
    const std::uint32_t* tri = triangles.data() + t;
    const std::uint16_t all = (*codes)[tri[0]] & (*codes)[tri[1]] & (*codes)[tri[2]];
    std::vector<std::uint32_t>* part = (all & kPyramidBits) ? &unlit : (all & ~kPyramidBits) ? &unshadowed : out;
    part->insert(part->end(), tri, tri + 3);
  }
  LightPartition partition;
  partition.shadowed = out->size() / 3;
  out->insert(out->end(), unshadowed.begin(), unshadowed.end());
  partition.lit = out->size() / 3;
  out->insert(out->end(), unlit.begin(), unlit.end());
  return partition;
}

}  // namespace

struct StereoRenderer::Impl {
  std::unique_ptr<vrm_gl::GlContext> context;
  // Scene program variants, index = lighting | shadows << 1 | bump << 2 | fundus << 3 | metal << 4: switched-off
  // features cost no varyings and no per-pixel branches (llvmpipe interpolates every varying of every fragment).
  static int variantKey(bool lighting, bool shadows, bool bump, bool fundus, bool metal) {
    return (lighting ? 1 : 0) | (lighting && shadows ? 2 : 0) | (lighting && bump ? 4 : 0) | (fundus ? 8 : 0) |
           (lighting && metal ? 16 : 0);
  }
  std::array<std::unique_ptr<Program>, 32> scene_variants;
  Program& sceneProgram(bool lighting, bool shadows, bool bump, bool fundus = false, bool metal = false) {
    const int key = variantKey(lighting, shadows, bump, fundus, metal);
    if (!scene_variants[key]) {
      auto program = std::make_unique<Program>();
      auto flag = [&](int bit) { return (key & bit) ? "1" : "0"; };
      program->build(shaders::kSceneVertex, shaders::kSceneFragment, "scene",
                     std::string("#version 330 core\n#define LIGHTING ") + flag(1) + "\n#define SHADOWS " + flag(2) +
                         "\n#define BUMP " + flag(4) + "\n#define FUNDUS " + flag(8) + "\n#define METAL " + flag(16) +
                         "\n");
      scene_variants[key] = std::move(program);
    }
    return *scene_variants[key];
  }
  // The fundus texture (FundusMap::texture), baked once and uploaded once per map.
  std::shared_ptr<const FundusMap> fundus;
  GLuint fundus_texture = 0;
  const FundusMap* uploaded_fundus = nullptr;
  double fundus_bake_ms = 0.0;
  Eigen::Vector3f fundus_mean = Eigen::Vector3f(0.7f, 0.3f, 0.15f);
  // Issue 37: the laser burns, painted onto a copy of the baked texture; painted_burns of them are in the GL texture.
  std::vector<FundusBurn> burns;
  std::vector<std::uint8_t> painted;  // the baked texture with the burns (empty until the first burn)
  std::size_t painted_burns = 0;
  std::uint64_t fundus_revision = 0;  // the static layer's key: a burn painted changes the retina's albedo
  void uploadFundus() {
    if (uploaded_fundus == fundus.get()) {
      paintNewBurns();
      return;
    }
    painted_burns = 0;
    painted.clear();
    if (!fundus_texture) glGenTextures(1, &fundus_texture);
    glActiveTexture(GL_TEXTURE1);
    glBindTexture(GL_TEXTURE_2D, fundus_texture);
    const int n = fundus->textureSize();
    glPixelStorei(GL_UNPACK_ALIGNMENT, 1);
    glTexImage2D(GL_TEXTURE_2D, 0, GL_RGBA8, n, n, 0, GL_RGBA, GL_UNSIGNED_BYTE, fundus->texture().data());
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, kFundusMinFilter);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, kFundusMinFilter);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);
    glActiveTexture(GL_TEXTURE0);
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    const auto& texels = fundus->texture();
    for (std::size_t k = 0; k < texels.size(); k += 4) sum += Eigen::Vector3d(texels[k], texels[k + 1], texels[k + 2]);
    fundus_mean = (sum / (255.0 * static_cast<double>(texels.size() / 4))).cast<float>();
    uploaded_fundus = fundus.get();
    ++fundus_revision;
    paintNewBurns();
  }
  // Paints the burns not yet in the texture and uploads the rectangles they changed.
  void paintNewBurns() {
    if (painted_burns >= burns.size()) return;
    if (painted.empty()) painted = fundus->texture();
    const int n = fundus->textureSize();
    glActiveTexture(GL_TEXTURE1);
    glBindTexture(GL_TEXTURE_2D, fundus_texture);
    glPixelStorei(GL_UNPACK_ALIGNMENT, 1);
    glPixelStorei(GL_UNPACK_ROW_LENGTH, n);
    for (; painted_burns < burns.size(); ++painted_burns) {
      const TexelRect rect = paintBurn(&painted, n, fundus->params().eye_radius, burns[painted_burns]);
      if (rect.width == 0) continue;
      glPixelStorei(GL_UNPACK_SKIP_PIXELS, rect.x);
      glPixelStorei(GL_UNPACK_SKIP_ROWS, rect.y);
      glTexSubImage2D(GL_TEXTURE_2D, 0, rect.x, rect.y, rect.width, rect.height, GL_RGBA, GL_UNSIGNED_BYTE,
                      painted.data());
    }
    glPixelStorei(GL_UNPACK_ROW_LENGTH, 0);
    glPixelStorei(GL_UNPACK_SKIP_PIXELS, 0);
    glPixelStorei(GL_UNPACK_SKIP_ROWS, 0);
    glActiveTexture(GL_TEXTURE0);
    ++fundus_revision;
  }
  Program shadow;
  Program copy;
  std::array<std::unique_ptr<Program>, 2> blur;  // 9 and 13 taps
  Program& blurProgram(int taps) {
    const int i = taps == 13 ? 1 : 0;
    if (!blur[i]) {
      blur[i] = std::make_unique<Program>();
      blur[i]->build(shaders::kFullscreenVertex, shaders::kBlurFragment, "blur",
                     std::string("#version 330 core\n#define PAIRS ") + (i ? "3" : "2") + "\n");
    }
    return *blur[i];
  }
  GLuint fullscreen_vao = 0;
  RenderTarget shadow_target;
  // Per eye, so that both eyes can be in flight at once.
  struct EyeTargets {
    RenderTarget scene;           // colour (alpha: DOF weight) + depth
    RenderTarget half_a;          // reduced: downsampled, then the blurred result
    RenderTarget half_b;          // reduced: after the horizontal blur
    RenderTarget static_layer;    // cache_static: the static objects ambient-only over the background (+ depth)
    StaticLayerKey static_key;    // what static_layer shows; valid only while static_valid
    StaticLayerKey previous_key;  // what the previous frame's static objects were
    bool static_valid = false;
  };
  std::array<EyeTargets, 2> eyes;
  std::map<std::string, Object> objects;
  std::vector<float> normal_scratch;
  std::vector<std::uint16_t> pyramid_codes;  // per vertex: outside which planes of the spotlight's pyramid
  std::array<std::vector<std::uint32_t>, 2> partition_scratch;
  std::vector<std::uint32_t> partitioned;  // an object's triangles, those the spotlight may reach first
  std::vector<std::uint8_t> sharp;         // RGBA readback of the scene
  std::vector<std::uint8_t> blurred;       // RGBA readback of the reduced, blurred scene
  std::vector<int> dof_columns;
  std::vector<float> dof_weights;
  std::array<std::vector<float>, 2> dof_rows;  // per blending thread
  double pending_upload_ms = 0.0;

  void allocateTargets(const RenderOptions& options) {
    shadow_target.release();
    for (EyeTargets& eye : eyes) {
      for (RenderTarget* t : {&eye.scene, &eye.half_a, &eye.half_b, &eye.static_layer}) t->release();
      eye.static_valid = false;
    }
    shadow_target = makeTarget(options.shadow_map_size, options.shadow_map_size, false, DepthKind::kDepth, "shadow");
    glBindTexture(GL_TEXTURE_2D, shadow_target.depth);
    // Hardware depth comparison with linear filtering: a 2x2 percentage-closer filter for free.
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_COMPARE_MODE, GL_COMPARE_REF_TO_TEXTURE);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_COMPARE_FUNC, GL_LEQUAL);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_LINEAR);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
    const int w = std::max(1, options.width / options.dof_downsample);
    const int h = std::max(1, options.height / options.dof_downsample);
    for (int e = 0; e < (options.stereo ? 2 : 1); ++e) {
      eyes[e].scene = makeTarget(options.width, options.height, true, DepthKind::kDepth, "scene");
      eyes[e].half_a = makeTarget(w, h, true, DepthKind::kNone, "blur_a");
      eyes[e].half_b = makeTarget(w, h, true, DepthKind::kNone, "blur_b");
      if (options.cache_static) {
        eyes[e].static_layer = makeTarget(options.width, options.height, true, DepthKind::kDepth, "static_layer");
      }
    }
    glBindFramebuffer(GL_FRAMEBUFFER, 0);
  }

  void invalidateStaticLayers() {
    for (EyeTargets& eye : eyes) {
      eye.static_valid = false;
      eye.static_key = StaticLayerKey();
      eye.previous_key = StaticLayerKey();
    }
  }

  void drawFullscreen() {
    glBindVertexArray(fullscreen_vao);
    glDrawArrays(GL_TRIANGLES, 0, 3);
  }

  // Triangles [first, first + count) of the object's index buffer.
  void drawObject(const Object& object, std::size_t first, std::size_t count) {
    if (count == 0) return;
    glBindVertexArray(object.vao);
    if (!object.has_colors) glVertexAttrib4f(2, 1.0f, 1.0f, 1.0f, 1.0f);
    if (!object.has_injury) glVertexAttrib1f(3, 0.0f);
    glDrawElements(GL_TRIANGLES, static_cast<GLsizei>(count * 3), GL_UNSIGNED_INT,
                   reinterpret_cast<const void*>(first * 3 * sizeof(std::uint32_t)));
  }
};

void retainFreedHeapMemory() {
  mallopt(M_MMAP_THRESHOLD, 256 << 20);
  mallopt(M_TRIM_THRESHOLD, 1 << 30);
}

StereoRenderer::StereoRenderer(const RenderOptions& options, const MicroscopeRig& rig)
    : impl_(std::make_unique<Impl>()), options_(options), rig_(rig) {
  validateOptions(options);
  try {
    impl_->context = std::make_unique<vrm_gl::GlContext>(vrm_gl::GlContextOptions{16, 16});
  } catch (const std::exception& e) {
    throw RenderError(std::string("no OpenGL context for the renderer: ") + e.what());
  }
  impl_->sceneProgram(false, false, false);  // compile errors surface here
  for (bool bump : {false, true}) {
    for (bool shadows : {false, true}) impl_->sceneProgram(true, shadows, bump);
  }
  impl_->shadow.build(shaders::kShadowVertex, shaders::kShadowFragment, "shadow");
  impl_->copy.build(shaders::kFullscreenVertex, shaders::kCopyFragment, "downsample");
  impl_->blurProgram(9);
  glGenVertexArrays(1, &impl_->fullscreen_vao);
  impl_->allocateTargets(options_);
  if (glGetError() != GL_NO_ERROR) throw RenderError("OpenGL error while setting up the renderer");
}

StereoRenderer::~StereoRenderer() = default;  // destroying the context frees its GL objects

void StereoRenderer::setOptions(const RenderOptions& options) {
  validateOptions(options);
  impl_->context->makeCurrent();
  const bool resize = options.width != options_.width || options.height != options_.height ||
                      options.shadow_map_size != options_.shadow_map_size ||
                      options.dof_downsample != options_.dof_downsample || options.stereo != options_.stereo ||
                      options.cache_static != options_.cache_static;
  options_ = options;
  if (resize) impl_->allocateTargets(options_);
}

void StereoRenderer::setMicroscope(const MicroscopeState& state) {
  microscopeCamera(rig_, state, 1, 1, Eye::kLeft, true);  // validates
  if (!std::isfinite(state.ambient_light)) throw RenderError("microscope: ambient_light must be finite");
  microscope_ = state;
}

CameraView StereoRenderer::camera(Eye eye) const {
  return microscopeCamera(rig_, microscope_, options_.width, options_.height, eye, options_.stereo);
}

bool StereoRenderer::updateMesh(const std::string& id, const MeshView& mesh, std::uint64_t version) {
  auto existing = impl_->objects.find(id);
  if (existing != impl_->objects.end() && existing->second.has_mesh && existing->second.version == version) {
    return false;  // the consumers-skip-equal-versions contract of vrm_msgs/TissueMesh
  }
  validateMesh(id, mesh);
  const auto start = Clock::now();
  impl_->context->makeCurrent();
  Object& object = impl_->objects[id];
  if (!object.vao) {
    glGenVertexArrays(1, &object.vao);
    glGenBuffers(5, object.buffers);
  }
  const GLenum usage = object.style.deformable ? GL_STREAM_DRAW : GL_STATIC_DRAW;
  const float* normals = mesh.normals;
  if (!normals) {
    computeNormals(mesh, &impl_->normal_scratch);
    normals = impl_->normal_scratch.data();
  }
  glBindVertexArray(object.vao);
  auto upload = [&](int slot, const float* data, int components) {
    glBindBuffer(GL_ARRAY_BUFFER, object.buffers[slot]);
    glBufferData(GL_ARRAY_BUFFER, static_cast<GLsizeiptr>(mesh.vertex_count * components * sizeof(float)), data, usage);
    glVertexAttribPointer(slot, components, GL_FLOAT, GL_FALSE, 0, nullptr);
    glEnableVertexAttribArray(slot);
  };
  upload(0, mesh.positions, 3);
  upload(1, normals, 3);
  object.has_colors = mesh.colors != nullptr;
  if (object.has_colors) {
    upload(2, mesh.colors, 4);
  } else {
    glDisableVertexAttribArray(2);
  }
  object.has_injury = mesh.injury != nullptr;
  if (object.has_injury) {
    upload(3, mesh.injury, 1);
  } else {
    glDisableVertexAttribArray(3);
  }
  const std::size_t index_count = mesh.triangle_count * 3;
  const bool same_topology =
      object.triangles.size() == index_count &&
      std::memcmp(object.triangles.data(), mesh.triangles, index_count * sizeof(std::uint32_t)) == 0;
  glBindBuffer(GL_ELEMENT_ARRAY_BUFFER, object.buffers[4]);
  if (!same_topology) {
    glBufferData(GL_ELEMENT_ARRAY_BUFFER, static_cast<GLsizeiptr>(index_count * sizeof(std::uint32_t)), mesh.triangles,
                 GL_STATIC_DRAW);
    object.triangles.assign(mesh.triangles, mesh.triangles + index_count);
  }
  glBindVertexArray(0);
  // Bounding sphere (box centre, max distance) for frustum culling.
  const Eigen::Map<const Eigen::Matrix3Xf> points(mesh.positions, 3, static_cast<Eigen::Index>(mesh.vertex_count));
  object.centre = 0.5f * (points.rowwise().minCoeff() + points.rowwise().maxCoeff());
  object.radius = std::sqrt((points.colwise() - object.centre).colwise().squaredNorm().maxCoeff());
  object.positions.assign(mesh.positions, mesh.positions + mesh.vertex_count * 3);
  object.vertex_count = mesh.vertex_count;
  object.triangle_count = mesh.triangle_count;
  object.version = version;
  object.has_mesh = true;
  impl_->pending_upload_ms += msSince(start);
  return true;
}

void StereoRenderer::setStyle(const std::string& id, const ObjectStyle& style) { impl_->objects[id].style = style; }

void StereoRenderer::setFundus(std::shared_ptr<const FundusMap> fundus) {
  if (!fundus) throw RenderError("setFundus: null fundus map");
  if (fundus != impl_->fundus) {
    // The texture and the static layer key know the uploaded map by address only: a map allocated where a freed one
    // lived would otherwise pass for it.
    impl_->uploaded_fundus = nullptr;
    impl_->invalidateStaticLayers();
  }
  impl_->fundus = std::move(fundus);
}

void StereoRenderer::setFundusBurns(const std::vector<FundusBurn>& burns) {
  std::vector<FundusBurn>& current = impl_->burns;
  const auto same = [](const FundusBurn& a, const FundusBurn& b) {
    return a.position == b.position && a.diameter == b.diameter && a.whiteness == b.whiteness;
  };
  const bool extends =
      burns.size() >= current.size() && std::equal(current.begin(), current.end(), burns.begin(), same);
  if (!extends) {
    // Repaint from the baked texture at the next upload (a reset session, a restored state).
    impl_->painted.clear();
    impl_->painted_burns = 0;
    impl_->uploaded_fundus = nullptr;
  }
  current = burns;
}

const std::vector<FundusBurn>& StereoRenderer::fundusBurns() const { return impl_->burns; }

const FundusMap& StereoRenderer::fundus() {
  if (!impl_->fundus) {
    const auto start = Clock::now();
    impl_->fundus = std::make_shared<const FundusMap>();
    impl_->fundus_bake_ms = msSince(start);
  }
  return *impl_->fundus;
}

void StereoRenderer::setPose(const std::string& id, const Eigen::Isometry3f& world_from_object) {
  if (!world_from_object.matrix().allFinite()) throw RenderError("pose of '" + id + "' is not finite");
  Object& object = impl_->objects[id];
  object.requested_pose = world_from_object;
  if (!object.anchored) object.pose = world_from_object;
}

void StereoRenderer::setVisible(const std::string& id, bool visible) { impl_->objects[id].visible = visible; }

bool StereoRenderer::hasObject(const std::string& id) const {
  auto it = impl_->objects.find(id);
  return it != impl_->objects.end() && it->second.has_mesh;
}

std::uint64_t StereoRenderer::version(const std::string& id) const {
  auto it = impl_->objects.find(id);
  return it == impl_->objects.end() ? 0 : it->second.version;
}

void StereoRenderer::removeObject(const std::string& id) {
  auto it = impl_->objects.find(id);
  if (it == impl_->objects.end()) return;
  Object& object = it->second;
  if (object.vao) {
    impl_->context->makeCurrent();
    glDeleteVertexArrays(1, &object.vao);
    glDeleteBuffers(5, object.buffers);
  }
  impl_->objects.erase(it);
  // The static layer key knows its objects by address and version: a new object at the freed address with the same
  // version and pose would pass for the removed one.
  impl_->invalidateStaticLayers();
}

std::vector<std::string> StereoRenderer::objectIds() const {
  std::vector<std::string> ids;
  ids.reserve(impl_->objects.size());
  for (const auto& entry : impl_->objects) ids.push_back(entry.first);  // std::map: sorted
  return ids;
}

std::size_t StereoRenderer::triangleCount(const std::string& id) const {
  auto it = impl_->objects.find(id);
  return it == impl_->objects.end() || !it->second.has_mesh ? 0 : it->second.triangle_count;
}

std::size_t StereoRenderer::triangleCount() const {
  std::size_t total = 0;
  for (const auto& entry : impl_->objects) {
    if (entry.second.has_mesh && entry.second.visible) total += entry.second.triangle_count;
  }
  return total;
}

struct StereoRenderer::FrameState {
  bool light_on = false;  // lighting on and a usable light pipe
  bool shadows = false;
  bool split = false;  // RenderOptions::light_partition applies
  bool fundus_in_view = false;
  Eigen::Matrix4f light_view_proj = Eigen::Matrix4f::Identity();
  float half_angle = 0.0f;  // of the spotlight's cone
  float cos_outer = 0.0f;
  float cos_inner = 0.0f;
  Eigen::Vector3f light_dir = -Eigen::Vector3f::UnitZ();
  Eigen::Vector3f light_pos = Eigen::Vector3f::Zero();
  float ambient = 0.0f;
  Eigen::Vector3f environment = Eigen::Vector3f::Zero();  // what metal mirrors
};

void StereoRenderer::render(StereoFrame* frame) {
  Impl& im = *impl_;
  im.context->makeCurrent();
  PassTimings timings;
  timings.ms_upload = im.pending_upload_ms;
  im.pending_upload_ms = 0.0;
  const auto frame_start = Clock::now();

  anchorStaticPoses();
  const FrameState state = beginFrame();
  partitionForSpotlight(state);
  if (state.shadows) renderShadowMap(state, &timings);
  // Both eyes are submitted before either is read back: llvmpipe rasterises one eye while this thread bins the next
  // and later blends and converts the previous one (with time_passes each pass is waited for instead).
  const int eye_count = options_.stereo ? 2 : 1;
  for (int e = 0; e < eye_count; ++e) {
    renderScene(e, state, &timings);
    if (options_.dof_pass) blurForDepthOfField(e, &timings);
    glFlush();  // start rasterising this eye now
  }
  for (int e = 0; e < eye_count; ++e) readBack(e, eye_count, frame, &timings);
  if (eye_count == 1) frame->images[1] = RgbImage();
  glBindFramebuffer(GL_FRAMEBUFFER, 0);
  const GLenum error = glGetError();
  timings.ms_total = msSince(frame_start) + timings.ms_upload;
  frame->timings = timings;
  if (error != GL_NO_ERROR) throw RenderError("OpenGL error " + std::to_string(error) + " while rendering");
}

void StereoRenderer::releaseContext() { vrm_gl::GlContext::releaseCurrent(); }

RenderState StereoRenderer::captureState() const {
  Impl& im = *impl_;
  im.context->makeCurrent();
  RenderState state;
  state.options = options_;
  state.rig = rig_;
  state.microscope = microscope_;
  state.light = light_;
  state.burns = im.burns;
  state.has_fundus = im.fundus != nullptr;
  if (im.fundus) {
    state.fundus = im.fundus->params();
    state.fundus_texture_hash = fundusTextureHash(*im.fundus);
  }
  auto readBuffer = [](GLuint buffer, std::size_t count, std::vector<float>* out) {
    out->resize(count);
    glBindBuffer(GL_ARRAY_BUFFER, buffer);
    glGetBufferSubData(GL_ARRAY_BUFFER, 0, static_cast<GLsizeiptr>(count * sizeof(float)), out->data());
  };
  for (const auto& entry : im.objects) {
    const Object& object = entry.second;
    RenderState::Object saved;
    saved.id = entry.first;
    saved.has_mesh = object.has_mesh;
    saved.version = object.version;
    saved.style = object.style;
    saved.pose = object.pose;
    saved.visible = object.visible;
    if (object.has_mesh) {
      saved.mesh.positions = object.positions;
      saved.mesh.triangles = object.triangles;
      readBuffer(object.buffers[1], object.vertex_count * 3, &saved.mesh.normals);
      if (object.has_colors) readBuffer(object.buffers[2], object.vertex_count * 4, &saved.mesh.colors);
      if (object.has_injury) readBuffer(object.buffers[3], object.vertex_count, &saved.mesh.injury);
    }
    state.objects.push_back(std::move(saved));
  }
  glBindBuffer(GL_ARRAY_BUFFER, 0);
  if (glGetError() != GL_NO_ERROR) throw RenderError("captureState: OpenGL error reading the mesh buffers");
  return state;
}

void StereoRenderer::restoreState(const RenderState& state, bool same_fundus) {
  validateRenderState(state);
  std::shared_ptr<const FundusMap> fundus;
  if (state.has_fundus) {
    fundus = std::make_shared<const FundusMap>(state.fundus);
    const std::uint64_t hash = fundusTextureHash(*fundus);
    if (same_fundus && hash != state.fundus_texture_hash) {
      throw RenderStateError(
          "restoreState: the fundus these parameters bake today differs from the saved frame's "
          "(texture hash " +
          std::to_string(hash) + " != " + std::to_string(state.fundus_texture_hash) + "): fundus generator changed");
    }
  }
  setOptions(state.options);
  rig_ = state.rig;
  setMicroscope(state.microscope);
  setLightPipe(state.light);
  for (const std::string& id : objectIds()) removeObject(id);
  setFundusBurns(state.burns);
  if (fundus) setFundus(fundus);
  impl_->invalidateStaticLayers();
  for (const RenderState::Object& object : state.objects) {
    setStyle(object.id, object.style);
    if (object.has_mesh) updateMesh(object.id, object.mesh.view(), object.version);
    setPose(object.id, object.pose);
    setVisible(object.id, object.visible);
  }
}

void StereoRenderer::readDepth(Eye eye, std::vector<float>* depth) const {
  const int e = eye == Eye::kRight && options_.stereo ? 1 : 0;
  const Impl::EyeTargets& target = impl_->eyes[e];
  if (!target.scene.fbo) throw RenderError("readDepth: no frame rendered");
  impl_->context->makeCurrent();
  const int w = options_.width, h = options_.height;
  std::vector<float> rows(static_cast<std::size_t>(w) * h);
  glBindFramebuffer(GL_READ_FRAMEBUFFER, target.scene.fbo);
  glPixelStorei(GL_PACK_ALIGNMENT, 4);
  glReadPixels(0, 0, w, h, GL_DEPTH_COMPONENT, GL_FLOAT, rows.data());
  glBindFramebuffer(GL_READ_FRAMEBUFFER, 0);
  if (glGetError() != GL_NO_ERROR) throw RenderError("readDepth: OpenGL error");
  depth->resize(rows.size());
  for (int y = 0; y < h; ++y) {  // GL's first row is the bottom one
    std::copy_n(rows.data() + static_cast<std::size_t>(h - 1 - y) * w, w,
                depth->data() + static_cast<std::size_t>(y) * w);
  }
}

// Tracked poses jitter by a fraction of a pixel from frame to frame (the tracker's noise), which would redraw the
// static layer every frame. A static object therefore keeps being drawn at its anchor pose while its requested pose
// stays within static_pose_tolerance_px of it (a sub-pixel, invisible lag that also steadies the jitter); beyond,
// the requested pose becomes the new anchor.
void StereoRenderer::anchorStaticPoses() {
  const bool cache = options_.cache_static && options_.lighting && options_.light_partition;
  const float pixels_per_metre =
      static_cast<float>(options_.width * microscope_.zoom) / std::max(1e-6f, rig_.field_width);
  for (auto& entry : impl_->objects) {
    Object& object = entry.second;
    const bool keep = cache && object.anchored && isStatic(object.style) && object.has_mesh &&
                      displacementPx(object.pose, object.requested_pose, object.centre, object.radius,
                                     pixels_per_metre) <= options_.static_pose_tolerance_px;
    if (!keep) object.pose = object.requested_pose;
    object.anchored = cache && isStatic(object.style);
  }
}

void StereoRenderer::waitForPass() const {
  if (options_.time_passes) glFinish();
}

StereoRenderer::FrameState StereoRenderer::beginFrame() {
  Impl& im = *impl_;
  FrameState state;
  state.light_on = options_.lighting && light_.enabled && light_.tip.allFinite() && light_.direction.allFinite() &&
                   light_.direction.norm() > 1e-6f;
  state.shadows = state.light_on && options_.shadow_pass;
  if (state.light_on) {
    const float half_angle = std::clamp(light_.cone_half_angle_rad, 0.01f, 1.4f);
    const float extent = std::tan(half_angle) * light_.shadow_near;
    state.light_view_proj = frustumMatrix(-extent, extent, -extent, extent, light_.shadow_near, light_.shadow_far) *
                            lookAtMatrix(light_.tip, light_.direction, Eigen::Vector3f::UnitY());
  }
  state.half_angle = std::clamp(light_.cone_half_angle_rad, 0.01f, 1.5f);
  state.cos_outer = std::cos(state.half_angle);
  state.cos_inner = std::cos(std::clamp(light_.cone_half_angle_rad * (1.0f - light_.cone_softness), 0.0f, 1.5f));
  state.light_dir = state.light_on ? Eigen::Vector3f(light_.direction.normalized()) : -Eigen::Vector3f::UnitZ();
  state.light_pos = state.light_on ? light_.tip : Eigen::Vector3f::Zero();
  state.ambient = static_cast<float>(std::clamp(microscope_.ambient_light, 0.0, 1.0));

  // The fundus texture: baked at the first frame that shows a fundus-styled object (or by setFundus), then reused.
  for (const auto& entry : im.objects) {
    state.fundus_in_view =
        state.fundus_in_view || (entry.second.has_mesh && entry.second.visible && entry.second.style.fundus);
  }
  state.fundus_in_view = state.fundus_in_view && options_.fundus;
  if (state.fundus_in_view) {
    fundus();  // bakes the default map if none was given
    im.uploadFundus();
    glActiveTexture(GL_TEXTURE1);
    glBindTexture(GL_TEXTURE_2D, im.fundus_texture);
    glActiveTexture(GL_TEXTURE0);
  }
  // What metal mirrors: the fundus lit by the light pipe and the coaxial light.
  state.environment = im.fundus_mean * (0.6f * state.ambient + (state.light_on ? 0.35f * light_.intensity : 0.0f));
  state.split = options_.lighting && options_.light_partition;
  return state;
}

// Where the spotlight can reach. llvmpipe evaluates both sides of a branch for every pixel, so the lit shader would
// cost the same outside the cone, where only the ambient term remains. Instead, the triangles of each object the cone
// reaches are split (every frame, both eyes share it) into those that may reach into the pyramid around the cone,
// drawn with the lit program, and the rest, drawn with the ambient-only one: every triangle is drawn once, and the
// image is the same for a fraction of the cost (the lit program adds nothing outside the cone). Before pass 1, so
// that rewriting an index buffer never waits for a draw that uses it.
void StereoRenderer::partitionForSpotlight(const FrameState& state) {
  Impl& im = *impl_;
  const auto pyramid = spotPyramid(state.light_pos, state.light_dir, state.half_angle);
  // Where a shadow can fall: the casters' rectangle in the shadow map, 2 texels wider (the 2x2 filter reaches 1).
  ShadowBox shadow_box;
  shadow_box.light_view_proj = state.light_view_proj;
  if (state.split && state.shadows) {
    for (const auto& entry : im.objects) {
      const Object& object = entry.second;
      if (!object.has_mesh || !object.visible || !object.style.casts_shadow || object.style.ghost) continue;
      shadow_box.add(object.positions, object.triangles, object.pose);
    }
    const float margin = 4.0f / im.shadow_target.width;
    shadow_box.rect += Eigen::Vector4f(-margin, -margin, margin, margin);
  }
  for (auto& entry : im.objects) {
    Object& object = entry.second;
    object.in_cone = false;
    object.shadowed_triangles = object.lit_triangles = object.triangle_count;
    if (!state.light_on || !object.has_mesh || !object.visible) continue;
    if (isMetal(object.style)) continue;  // drawn lit as a whole (SceneDraw::draw)
    const Eigen::Vector3f centre = object.pose * object.centre;
    bool reached = true;
    for (const Eigen::Vector4f& plane : pyramid)
      reached = reached && plane.head<3>().dot(centre) + plane.w() >= -object.radius;
    if (!reached) continue;
    object.in_cone = true;
    if (!state.split) continue;
    const LightPartition partition =
        partitionForLight(object.positions, object.triangles, object.pose, pyramid, shadow_box, &im.pyramid_codes,
                          &im.partition_scratch, &im.partitioned);
    object.shadowed_triangles = partition.shadowed;
    object.lit_triangles = partition.lit;
    glBindBuffer(GL_COPY_WRITE_BUFFER, object.buffers[4]);
    glBufferSubData(GL_COPY_WRITE_BUFFER, 0, static_cast<GLsizeiptr>(im.partitioned.size() * sizeof(std::uint32_t)),
                    im.partitioned.data());
  }
  glBindBuffer(GL_COPY_WRITE_BUFFER, 0);
}

// Pass 1: shadow map from the light pipe tip.
void StereoRenderer::renderShadowMap(const FrameState& state, PassTimings* timings) {
  Impl& im = *impl_;
  const auto start = Clock::now();
  glBindFramebuffer(GL_FRAMEBUFFER, im.shadow_target.fbo);
  glViewport(0, 0, im.shadow_target.width, im.shadow_target.height);
  glEnable(GL_DEPTH_TEST);
  glDepthMask(GL_TRUE);
  glClear(GL_DEPTH_BUFFER_BIT);
  glEnable(GL_POLYGON_OFFSET_FILL);
  // A constant bias only: a slope-scaled one pushed the thin forceps jaws, seen edge-on by the light, behind the
  // retina 1 mm below (their shadow vanished; test ShadowCue). Instruments, the casters that matter, do not look
  // their own shadow up (SceneDraw::draw), so they cannot self-shadow.
  glPolygonOffset(0.0f, 4.0f);
  // The light sees the casters' back faces: a caster that is also lit (a box, a ring, a key: the abstract objects
  // receive the instrument's shadow) then never finds its own lit face in the map, which striped grazing faces with
  // self-shadow ("acne"). The silhouette, and so the shadow on the retina, is the same. The meshes are closed.
  glEnable(GL_CULL_FACE);
  glCullFace(GL_FRONT);
  im.shadow.use();
  glUniformMatrix4fv(im.shadow["u_light_view_proj"], 1, GL_FALSE, state.light_view_proj.data());
  const auto planes = frustumPlanes(state.light_view_proj);
  for (const auto& entry : im.objects) {
    const Object& object = entry.second;
    if (!object.has_mesh || !object.visible || !object.style.casts_shadow || object.style.ghost) continue;
    if (!sphereVisible(planes, object.pose * object.centre, object.radius)) continue;
    glUniformMatrix4fv(im.shadow["u_model"], 1, GL_FALSE, object.pose.matrix().data());
    glBindVertexArray(object.vao);
    glDrawElements(GL_TRIANGLES, static_cast<GLsizei>(object.triangle_count * 3), GL_UNSIGNED_INT, nullptr);
  }
  glDisable(GL_POLYGON_OFFSET_FILL);
  glCullFace(GL_BACK);
  glDisable(GL_CULL_FACE);
  waitForPass();
  timings->ms_shadow = msSince(start);
}

// Pass 2 for one eye: which program variant draws what, with the eye's uniforms set once per variant.
struct StereoRenderer::SceneDraw {
  SceneDraw(StereoRenderer& renderer, const FrameState& state, Eye eye, PassTimings* timings)
      : r(renderer),
        im(*renderer.impl_),
        state(state),
        cam(renderer.camera(eye)),
        view_proj(cam.viewProjection()),
        timings(timings) {}

  Program& use(bool lit, bool bump, bool shadowed = true, bool fundus = false, bool metal = false);
  // Triangles [first, first + count) of the object with program p (clamped to the object's triangles).
  void drawWith(Program& p, const Object& object, float alpha_scale, bool opaque, std::size_t first = 0,
                std::size_t count = std::numeric_limits<std::size_t>::max());
  // Which of an object's triangles draw() draws: all (lit where the spotlight may reach, ambient elsewhere), all
  // ambient-only (the static layer), or only those the spotlight may reach, lit (over the static layer).
  enum class Part { kAll, kAmbientOnly, kLitOnly };
  // One object in the current depth / blend state.
  void draw(const Object& object, float alpha_scale, bool opaque, Part part = Part::kAll);

  StereoRenderer& r;
  Impl& im;
  const FrameState& state;
  const CameraView cam;
  const Eigen::Matrix4f view_proj;
  PassTimings* timings;
  std::array<bool, 32> prepared{};  // per-eye uniforms set, per program variant
  Program* current = nullptr;
};

Program& StereoRenderer::SceneDraw::use(bool lit, bool bump, bool shadowed, bool fundus, bool metal) {
  const RenderOptions& options = r.options_;
  const bool shadows_here = state.shadows && shadowed;
  const bool bump_here = options.bump_mapping && bump;
  Program& p = im.sceneProgram(lit, shadows_here, bump_here, fundus, metal);
  if (&p != current) {
    current = &p;
    p.use();
  }
  const int key = Impl::variantKey(lit, shadows_here, bump_here, fundus, metal);
  if (prepared[key]) return p;
  prepared[key] = true;
  const LightPipe& light = r.light_;
  glUniformMatrix4fv(p["u_view_proj"], 1, GL_FALSE, view_proj.data());
  glUniformMatrix4fv(p["u_light_view_proj"], 1, GL_FALSE, state.light_view_proj.data());
  glUniform1f(p["u_colour_scale"], options.lighting ? state.ambient : 1.0f);
  glUniform3fv(p["u_camera_pos"], 1, cam.position.data());
  glUniform1f(p["u_ambient"], state.ambient);
  glUniform3fv(p["u_light_pos"], 1, state.light_pos.data());
  glUniform3fv(p["u_light_dir"], 1, state.light_dir.data());
  // No light pipe: a cone that nothing lies in (cos > 1) leaves only the ambient term.
  glUniform1f(p["u_cos_outer"], state.light_on ? state.cos_outer : 2.0f);
  glUniform1f(p["u_cos_inner"], state.light_on ? state.cos_inner : 3.0f);
  glUniform1f(p["u_light_intensity"], light.intensity);
  glUniform1f(p["u_light_range"], light.range);
  glUniform1f(p["u_shadow_bias"], 2e-5f);
  glUniform1f(p["u_bump_amplitude"], 1.4e-5f);
  glUniform3fv(p["u_blood"], 1, options.blood_colour.data());
  glUniform1i(p["u_shadow_map"], 0);
  glUniform1f(p["u_near"], cam.near_plane);
  glUniform1f(p["u_far"], cam.far_plane);
  glUniform1f(p["u_focus"], cam.focus_depth);
  // Circle of confusion in pixels per unit of |z - s| / z (MicroscopeRig: aperture, zoom, field, image width).
  glUniform1f(p["u_coc_scale"],
              r.rig_.aperture_diameter * static_cast<float>(options.width * r.microscope_.zoom) / r.rig_.field_width);
  glUniform1i(p["u_fundus"], 1);
  if (im.fundus) {
    const float n = static_cast<float>(im.fundus->textureSize());
    glUniform1f(p["u_fundus_scale"], 0.5f * n / im.fundus->params().eye_radius);
    glUniform1f(p["u_fundus_offset"], 0.5f * n);
  }
  glUniform3fv(p["u_environment"], 1, state.environment.data());
  return p;
}

void StereoRenderer::SceneDraw::drawWith(Program& p, const Object& object, float alpha_scale, bool opaque,
                                         std::size_t first, std::size_t count) {
  count = std::min(count, object.triangle_count - std::min(first, object.triangle_count));
  if (count == 0) return;
  const Material& m = object.style.material;
  glUniformMatrix4fv(p["u_model"], 1, GL_FALSE, object.pose.matrix().data());
  const Eigen::Matrix3f normal_matrix = object.pose.linear().inverse().transpose();
  glUniformMatrix3fv(p["u_normal_matrix"], 1, GL_FALSE, normal_matrix.data());
  glUniform4fv(p["u_diffuse"], 1, m.diffuse.data());
  glUniform3fv(p["u_specular"], 1, m.specular.data());
  glUniform1f(p["u_shininess"], std::max(1.0f, m.shininess));
  glUniform1f(p["u_alpha_scale"], alpha_scale);
  glUniform1f(p["u_sheen"], m.sheen);
  glUniform1f(p["u_metallic"], m.metallic);
  glUniform1f(p["u_glow_length"], m.glow_tip_length);
  glUniform3fv(p["u_emission"], 1, m.emission.data());
  glUniform1f(p["u_coc_alpha"], opaque ? 1.0f : 0.0f);
  im.drawObject(object, first, count);
}

void StereoRenderer::SceneDraw::draw(const Object& object, float alpha_scale, bool opaque, Part part) {
  const RenderOptions& options = r.options_;
  const bool fundus = state.fundus_in_view && object.style.fundus;
  // The fundus texture replaces the procedural relief (its plane waves were the "wavy bump pattern" of the uniform
  // retina, issue 16): the lit fundus pixels save the seven sines of bumpGradient.
  const bool bump = object.style.bump_mapped && !fundus;
  if (part == Part::kAmbientOnly) {
    timings->triangles_drawn += object.triangle_count;
    drawWith(use(false, false, true, fundus), object, alpha_scale, opaque);
    return;
  }
  if (part == Part::kLitOnly) {
    if (!object.in_cone) return;
    timings->triangles_drawn += object.lit_triangles;
    drawWith(use(true, bump, true, fundus), object, alpha_scale, opaque, 0, object.shadowed_triangles);
    drawWith(use(true, bump, false, fundus), object, alpha_scale, opaque, object.shadowed_triangles,
             object.lit_triangles - object.shadowed_triangles);
    return;
  }
  timings->triangles_drawn += object.triangle_count;
  if (options.lighting && isMetal(object.style)) {
    // Instruments: few pixels, lit everywhere (the mirrored environment and the coaxial highlight are not bounded by
    // the spotlight's cone).
    drawWith(use(true, false, false, false, true), object, alpha_scale, opaque);
    return;
  }
  if (!state.split) {
    drawWith(use(options.lighting, bump, true, fundus), object, alpha_scale, opaque);
    return;
  }
  if (object.in_cone) {
    drawWith(use(true, bump, true, fundus), object, alpha_scale, opaque, 0, object.shadowed_triangles);
    drawWith(use(true, bump, false, fundus), object, alpha_scale, opaque, object.shadowed_triangles,
             object.lit_triangles - object.shadowed_triangles);
    drawWith(use(false, false, true, fundus), object, alpha_scale, opaque, object.lit_triangles);
  } else {
    drawWith(use(false, false, true, fundus), object, alpha_scale, opaque);
  }
}

// Pass 2: the scene. Opaque front to back (early depth rejects hidden fragments), translucent back to front.
void StereoRenderer::renderScene(int e, const FrameState& state, PassTimings* timings) {
  Impl& im = *impl_;
  Impl::EyeTargets& target = im.eyes[e];
  SceneDraw scene(*this, state, e == 0 ? Eye::kLeft : Eye::kRight, timings);
  const CameraView& cam = scene.cam;
  const auto planes = frustumPlanes(scene.view_proj);
  const auto start = Clock::now();
  // The static layer applies where the spotlight is partitioned (its lit triangles are drawn over the layer).
  bool cache = options_.cache_static && state.split && target.static_layer.fbo != 0;
  std::vector<std::pair<float, const Object*>> opaque, translucent, static_objects;
  for (const auto& entry : im.objects) {
    const Object& object = entry.second;
    if (!object.has_mesh || !object.visible) continue;
    const Eigen::Vector3f centre = object.pose * object.centre;
    if (!sphereVisible(planes, centre, object.radius)) {
      ++timings->objects_culled;
      continue;
    }
    const float depth = (centre - cam.position).dot(cam.forward);
    if (object.style.ghost || object.style.material.diffuse.w() < 1.0f) {
      translucent.emplace_back(-depth, &object);
    } else if (cache && isStatic(object.style)) {
      static_objects.emplace_back(depth - object.radius, &object);
    } else {
      opaque.emplace_back(depth - object.radius, &object);
    }
  }
  auto nearest_first = [](const auto& a, const auto& b) { return a.first < b.first; };
  std::sort(opaque.begin(), opaque.end(), nearest_first);
  std::sort(static_objects.begin(), static_objects.end(), nearest_first);
  std::sort(translucent.begin(), translucent.end(), nearest_first);

  // Alpha 1: the background counts as far from the focal plane (fully blurred).
  glClearColor(options_.background.x(), options_.background.y(), options_.background.z(), 1.0f);
  glEnable(GL_DEPTH_TEST);
  glDepthFunc(GL_LESS);
  glDepthMask(GL_TRUE);
  glDisable(GL_CULL_FACE);  // the retina is seen from inside, membranes from both sides
  glActiveTexture(GL_TEXTURE0);
  glBindTexture(GL_TEXTURE_2D, im.shadow_target.depth);
  glViewport(0, 0, options_.width, options_.height);
  if (cache) {
    StaticLayerKey key;
    key.add(scene.view_proj.data(), 16);
    key.add(cam.focus_depth);
    key.add(state.ambient);
    key.add(rig_.aperture_diameter * static_cast<float>(options_.width * microscope_.zoom) / rig_.field_width);
    key.add(state.fundus_in_view ? 1.0f : 0.0f);
    key.add(options_.background.data(), 3);
    key.add(options_.blood_colour.data(), 3);
    key.objects.push_back(im.uploaded_fundus);
    key.versions.push_back(im.fundus_revision);
    for (const auto& entry : static_objects) {
      const Object& object = *entry.second;
      key.objects.push_back(&object);
      key.versions.push_back(object.version);
      key.add(object.pose.matrix().data(), 16);
      key.add(object.style.material.diffuse.data(), 4);
      key.add(object.style.fundus ? 1.0f : 0.0f);
    }
    const bool hit = target.static_valid && key == target.static_key;
    // While the layer's content keeps changing (the eye turning), drawing it and copying it every frame would cost
    // more than drawing the frame directly: the layer is redrawn only once its content held still for a frame.
    const bool steady = key == target.previous_key;
    target.previous_key = key;
    if (!hit && !steady) {
      cache = false;
      opaque.insert(opaque.end(), static_objects.begin(), static_objects.end());
      std::sort(opaque.begin(), opaque.end(), nearest_first);
      static_objects.clear();
    } else if (!hit) {
      glBindFramebuffer(GL_FRAMEBUFFER, target.static_layer.fbo);
      glClear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
      for (const auto& entry : static_objects) scene.draw(*entry.second, 1.0f, true, SceneDraw::Part::kAmbientOnly);
      target.static_key = std::move(key);
      target.static_valid = true;
      ++timings->static_layers_drawn;
    }
  }
  if (cache) {
    // The frame starts as a copy of the layer (colour with its DOF weight, and depth): llvmpipe copies it.
    glBindFramebuffer(GL_READ_FRAMEBUFFER, target.static_layer.fbo);
    glBindFramebuffer(GL_DRAW_FRAMEBUFFER, target.scene.fbo);
    glBlitFramebuffer(0, 0, options_.width, options_.height, 0, 0, options_.width, options_.height,
                      GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT, GL_NEAREST);
    glBindFramebuffer(GL_FRAMEBUFFER, target.scene.fbo);
  } else {
    glBindFramebuffer(GL_FRAMEBUFFER, target.scene.fbo);
    glClear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
  }
  for (const auto& entry : opaque) scene.draw(*entry.second, 1.0f, true);
  if (!static_objects.empty()) {
    // The lit triangles over their own ambient-only fragments: equal depths pass (the vertex stage is invariant),
    // anything nearer (an instrument) keeps its pixel.
    glDepthFunc(GL_LEQUAL);
    for (const auto& entry : static_objects) scene.draw(*entry.second, 1.0f, true, SceneDraw::Part::kLitOnly);
    glDepthFunc(GL_LESS);
  }
  if (!translucent.empty()) {
    glEnable(GL_BLEND);
    // Colour blends; alpha keeps the DOF weight of the opaque surface behind (translucent objects write no depth).
    glBlendFuncSeparate(GL_SRC_ALPHA, GL_ONE_MINUS_SRC_ALPHA, GL_ZERO, GL_ONE);
    glDepthMask(GL_FALSE);
    for (const auto& entry : translucent) {
      const Object& object = *entry.second;
      if (object.style.ghost) {
        // Depth-only first, so a ghost shows only its nearest surface (like a glass instrument, not an x-ray).
        glColorMask(GL_FALSE, GL_FALSE, GL_FALSE, GL_FALSE);
        glDepthMask(GL_TRUE);
        scene.drawWith(scene.use(false, false), object, 1.0f, false);
        glColorMask(GL_TRUE, GL_TRUE, GL_TRUE, GL_TRUE);
        glDepthMask(GL_FALSE);
        glDepthFunc(GL_LEQUAL);
        scene.draw(object, options_.ghost_alpha, false);
        glDepthFunc(GL_LESS);
      } else {
        scene.draw(object, 1.0f, false);
      }
    }
    glDepthMask(GL_TRUE);
    glDisable(GL_BLEND);
  }
  waitForPass();
  timings->ms_scene += msSince(start);
}

// Pass 3a: depth of field, blurred at reduced resolution on the GPU; the blend happens in the readback (pass 3b).
void StereoRenderer::blurForDepthOfField(int e, PassTimings* timings) {
  Impl& im = *impl_;
  Impl::EyeTargets& target = im.eyes[e];
  const auto start = Clock::now();
  glDisable(GL_DEPTH_TEST);
  glDepthMask(GL_FALSE);
  glViewport(0, 0, target.half_a.width, target.half_a.height);
  // Downsampled copy first; at full resolution the horizontal blur reads the scene itself.
  const bool full_resolution = options_.dof_downsample == 1;
  if (!full_resolution) {
    glBindFramebuffer(GL_FRAMEBUFFER, target.half_a.fbo);
    im.copy.use();
    glBindTexture(GL_TEXTURE_2D, target.scene.color);
    glUniform1i(im.copy["u_src"], 0);
    im.drawFullscreen();
  }
  const int half = options_.dof_taps / 2;
  float weights[4];
  float offsets[4];
  dofBlurTaps(options_.dof_taps, options_.dof_sigma_px, weights, offsets);
  Program& blur = im.blurProgram(options_.dof_taps);
  blur.use();
  glUniform1fv(blur["u_weight"], half / 2 + 1, weights);
  glUniform1fv(blur["u_offset"], half / 2 + 1, offsets);
  glUniform1i(blur["u_src"], 0);
  glBindFramebuffer(GL_FRAMEBUFFER, target.half_b.fbo);
  glBindTexture(GL_TEXTURE_2D, full_resolution ? target.scene.color : target.half_a.color);
  glUniform2f(blur["u_step"], 1.0f / target.half_a.width, 0.0f);
  im.drawFullscreen();
  glBindFramebuffer(GL_FRAMEBUFFER, target.half_a.fbo);
  glBindTexture(GL_TEXTURE_2D, target.half_b.color);
  glUniform2f(blur["u_step"], 0.0f, 1.0f / target.half_a.height);
  im.drawFullscreen();
  glDepthMask(GL_TRUE);
  waitForPass();
  timings->ms_dof += msSince(start);
}

// Readback (RGBA, the format of the targets: a plain copy in llvmpipe), then on the CPU: DOF blend, RGB, flip.
void StereoRenderer::readBack(int e, int eye_count, StereoFrame* frame, PassTimings* timings) {
  Impl& im = *impl_;
  Impl::EyeTargets& target = im.eyes[e];
  const int width = options_.width, height = options_.height;
  auto start = Clock::now();
  RgbImage& image = frame->images[e];
  image.width = width;
  image.height = height;
  image.data.resize(static_cast<std::size_t>(width) * height * 3);
  im.sharp.resize(static_cast<std::size_t>(width) * height * 4);
  glPixelStorei(GL_PACK_ALIGNMENT, 1);
  glBindFramebuffer(GL_READ_FRAMEBUFFER, target.scene.fbo);
  glReadBuffer(GL_COLOR_ATTACHMENT0);
  glReadPixels(0, 0, width, height, GL_RGBA, GL_UNSIGNED_BYTE, im.sharp.data());
  if (!options_.dof_pass) {
    rgbaToRgbFlipped(im.sharp.data(), width, height, &image);
    timings->ms_readback += msSince(start);
    return;
  }
  DofBlend blend;
  blend.sharp = im.sharp.data();
  blend.width = width;
  blend.height = height;
  blend.blurred_width = target.half_a.width;
  blend.blurred_height = target.half_a.height;
  im.blurred.resize(static_cast<std::size_t>(blend.blurred_width) * blend.blurred_height * 4);
  blend.blurred = im.blurred.data();
  glBindFramebuffer(GL_READ_FRAMEBUFFER, target.half_a.fbo);
  glReadPixels(0, 0, blend.blurred_width, blend.blurred_height, GL_RGBA, GL_UNSIGNED_BYTE, im.blurred.data());
  timings->ms_readback += msSince(start);
  start = Clock::now();
  blend.prepareColumns(&im.dof_columns, &im.dof_weights);
  if (e + 1 < eye_count) {
    blend.rows(0, height, &im.dof_rows[0], &image);  // overlaps the rasterisation of the next eye
  } else {
    // Nothing left to overlap with: two threads.
    auto top = std::async(std::launch::async, [&] { blend.rows(0, height / 2, &im.dof_rows[1], &image); });
    blend.rows(height / 2, height, &im.dof_rows[0], &image);
    top.get();
  }
  timings->ms_dof += msSince(start);
}

}  // namespace vrm_render
