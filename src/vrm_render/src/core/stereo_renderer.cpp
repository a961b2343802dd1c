#include "vrm_render/stereo_renderer.h"

#define GL_GLEXT_PROTOTYPES
#include <GL/gl.h>
#include <GL/glext.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstring>
#include <map>
#include <unordered_map>

#include "shaders.h"
#include "vrm_gl/gl_context.h"

namespace vrm_render {
namespace {

using Clock = std::chrono::steady_clock;

double msSince(Clock::time_point start) {
  return std::chrono::duration<double, std::milli>(Clock::now() - start).count();
}

GLuint compileShader(GLenum type, const char* source, const char* name) {
  GLuint shader = glCreateShader(type);
  glShaderSource(shader, 1, &source, nullptr);
  glCompileShader(shader);
  GLint ok = 0;
  glGetShaderiv(shader, GL_COMPILE_STATUS, &ok);
  if (!ok) {
    char log[2048] = {};
    glGetShaderInfoLog(shader, sizeof(log), nullptr, log);
    glDeleteShader(shader);
    throw RenderError(std::string("shader ") + name + " does not compile: " + log);
  }
  return shader;
}

// A linked program with cached uniform locations.
class Program {
 public:
  void build(const char* vertex, const char* fragment, const char* name, const std::string& prefix = "") {
    GLuint vs = compileShader(GL_VERTEX_SHADER, (prefix + vertex).c_str(), name);
    GLuint fs = compileShader(GL_FRAGMENT_SHADER, (prefix + fragment).c_str(), name);
    id_ = glCreateProgram();
    glAttachShader(id_, vs);
    glAttachShader(id_, fs);
    glLinkProgram(id_);
    glDeleteShader(vs);
    glDeleteShader(fs);
    GLint ok = 0;
    glGetProgramiv(id_, GL_LINK_STATUS, &ok);
    if (!ok) {
      char log[2048] = {};
      glGetProgramInfoLog(id_, sizeof(log), nullptr, log);
      throw RenderError(std::string("program ") + name + " does not link: " + log);
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
  GLuint depth = 0;  // depth texture (0 when the target has none)
  int width = 0;
  int height = 0;

  void release() {
    if (fbo) glDeleteFramebuffers(1, &fbo);
    if (color) glDeleteTextures(1, &color);
    if (depth) glDeleteTextures(1, &depth);
    *this = RenderTarget();
  }
};

GLuint makeTexture(GLint internal_format, int width, int height, GLenum format, GLenum type, GLint filter) {
  GLuint texture = 0;
  glGenTextures(1, &texture);
  glBindTexture(GL_TEXTURE_2D, texture);
  glTexImage2D(GL_TEXTURE_2D, 0, internal_format, width, height, 0, format, type, nullptr);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, filter);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, filter);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);
  return texture;
}

RenderTarget makeTarget(int width, int height, bool with_color, bool with_depth, const char* name) {
  RenderTarget target;
  target.width = width;
  target.height = height;
  glGenFramebuffers(1, &target.fbo);
  glBindFramebuffer(GL_FRAMEBUFFER, target.fbo);
  if (with_color) {
    target.color = makeTexture(GL_RGBA8, width, height, GL_RGBA, GL_UNSIGNED_BYTE, GL_LINEAR);
    glFramebufferTexture2D(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_TEXTURE_2D, target.color, 0);
  } else {
    glDrawBuffer(GL_NONE);
    glReadBuffer(GL_NONE);
  }
  if (with_depth) {
    target.depth = makeTexture(GL_DEPTH_COMPONENT24, width, height, GL_DEPTH_COMPONENT, GL_UNSIGNED_INT, GL_NEAREST);
    glFramebufferTexture2D(GL_FRAMEBUFFER, GL_DEPTH_ATTACHMENT, GL_TEXTURE_2D, target.depth, 0);
  }
  const GLenum status = glCheckFramebufferStatus(GL_FRAMEBUFFER);
  if (status != GL_FRAMEBUFFER_COMPLETE) {
    target.release();
    throw RenderError(std::string("render target ") + name + " is incomplete (status " + std::to_string(status) + ")");
  }
  return target;
}

struct Object {
  bool has_mesh = false;
  std::uint64_t version = 0;
  ObjectStyle style;
  Eigen::Isometry3f pose = Eigen::Isometry3f::Identity();
  bool visible = true;
  GLuint vao = 0;
  GLuint buffers[5] = {};  // positions, normals, colours, injury, indices
  std::size_t vertex_count = 0;
  std::size_t triangle_count = 0;
  bool has_colors = false;
  bool has_injury = false;
  std::vector<std::uint32_t> triangles;              // to notice topology changes of streamed meshes
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
  if (!(options.dof_sigma_px > 0.0f) || !std::isfinite(options.dof_sigma_px)) {
    throw RenderError("dof_sigma_px must be positive");
  }
}

}  // namespace

struct StereoRenderer::Impl {
  std::unique_ptr<vrm_gl::GlContext> context;
  // Scene program variants, index = lighting | shadows << 1 | bump << 2: switched-off features cost no varyings
  // and no per-pixel branches (llvmpipe interpolates every varying of every fragment).
  std::array<std::unique_ptr<Program>, 8> scene_variants;
  Program& sceneProgram(bool lighting, bool shadows, bool bump) {
    const int key = (lighting ? 1 : 0) | (lighting && shadows ? 2 : 0) | (lighting && bump ? 4 : 0);
    if (!scene_variants[key]) {
      auto program = std::make_unique<Program>();
      program->build(shaders::kSceneVertex, shaders::kSceneFragment, "scene",
                     std::string("#version 330 core\n#define LIGHTING ") + ((key & 1) ? "1" : "0") +
                         "\n#define SHADOWS " + ((key & 2) ? "1" : "0") + "\n#define BUMP " + ((key & 4) ? "1" : "0") +
                         "\n");
      scene_variants[key] = std::move(program);
    }
    return *scene_variants[key];
  }
  Program shadow;
  Program copy;
  Program blur;
  Program composite;
  GLuint fullscreen_vao = 0;
  RenderTarget shadow_target;
  RenderTarget scene_target;
  RenderTarget half_a;
  RenderTarget half_b;
  RenderTarget output_target;
  std::map<std::string, Object> objects;
  std::vector<float> normal_scratch;
  std::vector<std::uint8_t> readback;
  double pending_upload_ms = 0.0;

  void allocateTargets(const RenderOptions& options) {
    for (RenderTarget* t : {&shadow_target, &scene_target, &half_a, &half_b, &output_target}) t->release();
    shadow_target = makeTarget(options.shadow_map_size, options.shadow_map_size, false, true, "shadow");
    glBindTexture(GL_TEXTURE_2D, shadow_target.depth);
    // Hardware depth comparison with linear filtering: a 2x2 percentage-closer filter for free.
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_COMPARE_MODE, GL_COMPARE_REF_TO_TEXTURE);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_COMPARE_FUNC, GL_LEQUAL);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_LINEAR);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
    scene_target = makeTarget(options.width, options.height, true, true, "scene");
    const int w = std::max(1, options.width / options.dof_downsample);
    const int h = std::max(1, options.height / options.dof_downsample);
    half_a = makeTarget(w, h, true, false, "blur_a");
    half_b = makeTarget(w, h, true, false, "blur_b");
    output_target = makeTarget(options.width, options.height, true, false, "output");
    glBindFramebuffer(GL_FRAMEBUFFER, 0);
  }

  void drawFullscreen() {
    glBindVertexArray(fullscreen_vao);
    glDrawArrays(GL_TRIANGLES, 0, 3);
  }

  void drawObject(const Object& object) {
    glBindVertexArray(object.vao);
    if (!object.has_colors) glVertexAttrib4f(2, 1.0f, 1.0f, 1.0f, 1.0f);
    if (!object.has_injury) glVertexAttrib1f(3, 0.0f);
    glDrawElements(GL_TRIANGLES, static_cast<GLsizei>(object.triangle_count * 3), GL_UNSIGNED_INT, nullptr);
  }
};

StereoRenderer::StereoRenderer(const RenderOptions& options, const MicroscopeRig& rig)
    : impl_(std::make_unique<Impl>()), options_(options), rig_(rig) {
  validateOptions(options);
  try {
    impl_->context = std::make_unique<vrm_gl::GlContext>(vrm_gl::GlContextOptions{16, 16});
  } catch (const std::exception& e) {
    throw RenderError(std::string("no OpenGL context for the renderer: ") + e.what());
  }
  for (bool lighting : {false, true}) {
    for (bool bump : {false, true}) impl_->sceneProgram(lighting, true, bump);  // compile errors surface here
  }
  impl_->shadow.build(shaders::kShadowVertex, shaders::kShadowFragment, "shadow");
  impl_->copy.build(shaders::kFullscreenVertex, shaders::kCopyFragment, "downsample");
  impl_->blur.build(shaders::kFullscreenVertex, shaders::kBlurFragment, "blur");
  impl_->composite.build(shaders::kFullscreenVertex, shaders::kCompositeFragment, "composite");
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
                      options.dof_downsample != options_.dof_downsample;
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
  object.vertex_count = mesh.vertex_count;
  object.triangle_count = mesh.triangle_count;
  object.version = version;
  object.has_mesh = true;
  impl_->pending_upload_ms += msSince(start);
  return true;
}

void StereoRenderer::setStyle(const std::string& id, const ObjectStyle& style) { impl_->objects[id].style = style; }

void StereoRenderer::setPose(const std::string& id, const Eigen::Isometry3f& world_from_object) {
  if (!world_from_object.matrix().allFinite()) throw RenderError("pose of '" + id + "' is not finite");
  impl_->objects[id].pose = world_from_object;
}

void StereoRenderer::setVisible(const std::string& id, bool visible) { impl_->objects[id].visible = visible; }

void StereoRenderer::removeObject(const std::string& id) {
  auto it = impl_->objects.find(id);
  if (it == impl_->objects.end()) return;
  impl_->context->makeCurrent();
  if (it->second.vao) {
    glDeleteVertexArrays(1, &it->second.vao);
    glDeleteBuffers(5, it->second.buffers);
  }
  impl_->objects.erase(it);
}

bool StereoRenderer::hasObject(const std::string& id) const {
  auto it = impl_->objects.find(id);
  return it != impl_->objects.end() && it->second.has_mesh;
}

std::uint64_t StereoRenderer::version(const std::string& id) const {
  auto it = impl_->objects.find(id);
  return it == impl_->objects.end() ? 0 : it->second.version;
}

std::size_t StereoRenderer::triangleCount() const {
  std::size_t total = 0;
  for (const auto& entry : impl_->objects) {
    if (entry.second.has_mesh && entry.second.visible) total += entry.second.triangle_count;
  }
  return total;
}

void StereoRenderer::render(StereoFrame* frame) {
  Impl& im = *impl_;
  im.context->makeCurrent();
  PassTimings timings;
  timings.ms_upload = im.pending_upload_ms;
  im.pending_upload_ms = 0.0;
  const auto frame_start = Clock::now();
  auto barrier = [&]() {
    if (options_.time_passes) glFinish();
  };

  // Pass 1: shadow map from the light pipe tip.
  const bool light_on = options_.lighting && light_.enabled && light_.tip.allFinite() && light_.direction.allFinite() &&
                        light_.direction.norm() > 1e-6f;
  const bool shadows = light_on && options_.shadow_pass;
  Eigen::Matrix4f light_view_proj = Eigen::Matrix4f::Identity();
  if (light_on) {
    const float half_angle = std::clamp(light_.cone_half_angle_rad, 0.01f, 1.4f);
    const float extent = std::tan(half_angle) * light_.shadow_near;
    light_view_proj = frustumMatrix(-extent, extent, -extent, extent, light_.shadow_near, light_.shadow_far) *
                      lookAtMatrix(light_.tip, light_.direction, Eigen::Vector3f::UnitY());
  }
  if (shadows) {
    const auto start = Clock::now();
    glBindFramebuffer(GL_FRAMEBUFFER, im.shadow_target.fbo);
    glViewport(0, 0, im.shadow_target.width, im.shadow_target.height);
    glEnable(GL_DEPTH_TEST);
    glDepthMask(GL_TRUE);
    glClear(GL_DEPTH_BUFFER_BIT);
    glEnable(GL_POLYGON_OFFSET_FILL);
    glPolygonOffset(2.0f, 4.0f);  // slope-scaled bias against self-shadowing of the casters
    im.shadow.use();
    glUniformMatrix4fv(im.shadow["u_light_view_proj"], 1, GL_FALSE, light_view_proj.data());
    const auto planes = frustumPlanes(light_view_proj);
    for (const auto& entry : im.objects) {
      const Object& object = entry.second;
      if (!object.has_mesh || !object.visible || !object.style.casts_shadow || object.style.ghost) continue;
      if (!sphereVisible(planes, object.pose * object.centre, object.radius)) continue;
      glUniformMatrix4fv(im.shadow["u_model"], 1, GL_FALSE, object.pose.matrix().data());
      glBindVertexArray(object.vao);
      glDrawElements(GL_TRIANGLES, static_cast<GLsizei>(object.triangle_count * 3), GL_UNSIGNED_INT, nullptr);
    }
    glDisable(GL_POLYGON_OFFSET_FILL);
    barrier();
    timings.ms_shadow = msSince(start);
  }

  const int eye_count = options_.stereo ? 2 : 1;
  const float cos_outer = std::cos(std::clamp(light_.cone_half_angle_rad, 0.01f, 1.5f));
  const float cos_inner = std::cos(std::clamp(light_.cone_half_angle_rad * (1.0f - light_.cone_softness), 0.0f, 1.5f));
  const Eigen::Vector3f light_dir =
      light_on ? Eigen::Vector3f(light_.direction.normalized()) : -Eigen::Vector3f::UnitZ();
  const Eigen::Vector3f light_pos = light_on ? light_.tip : Eigen::Vector3f::Zero();
  for (int e = 0; e < eye_count; ++e) {
    const CameraView cam = camera(e == 0 ? Eye::kLeft : Eye::kRight);
    const Eigen::Matrix4f view_proj = cam.viewProjection();
    const auto planes = frustumPlanes(view_proj);

    // Pass 2: the scene. Opaque front to back (early depth rejects hidden fragments), translucent back to front.
    auto start = Clock::now();
    std::vector<std::pair<float, const Object*>> opaque, translucent;
    for (const auto& entry : im.objects) {
      const Object& object = entry.second;
      if (!object.has_mesh || !object.visible) continue;
      const Eigen::Vector3f centre = object.pose * object.centre;
      if (!sphereVisible(planes, centre, object.radius)) {
        ++timings.objects_culled;
        continue;
      }
      const float depth = (centre - cam.position).dot(cam.forward);
      if (object.style.ghost || object.style.material.diffuse.w() < 1.0f) {
        translucent.emplace_back(-depth, &object);
      } else {
        opaque.emplace_back(depth - object.radius, &object);
      }
    }
    std::sort(opaque.begin(), opaque.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
    std::sort(translucent.begin(), translucent.end(), [](const auto& a, const auto& b) { return a.first < b.first; });

    glBindFramebuffer(GL_FRAMEBUFFER, im.scene_target.fbo);
    glViewport(0, 0, options_.width, options_.height);
    glClearColor(options_.background.x(), options_.background.y(), options_.background.z(), 1.0f);
    glEnable(GL_DEPTH_TEST);
    glDepthFunc(GL_LESS);
    glDepthMask(GL_TRUE);
    glDisable(GL_CULL_FACE);  // the retina is seen from inside, membranes from both sides
    glClear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
    Program* current = nullptr;
    auto use = [&](bool bump) -> Program& {
      Program& p = im.sceneProgram(options_.lighting, shadows, options_.bump_mapping && bump);
      if (&p == current) return p;
      current = &p;
      p.use();
      glUniformMatrix4fv(p["u_view_proj"], 1, GL_FALSE, view_proj.data());
      glUniformMatrix4fv(p["u_light_view_proj"], 1, GL_FALSE, light_view_proj.data());
      glUniform3fv(p["u_camera_pos"], 1, cam.position.data());
      glUniform1f(p["u_ambient"], static_cast<float>(std::clamp(microscope_.ambient_light, 0.0, 1.0)));
      glUniform3fv(p["u_light_pos"], 1, light_pos.data());
      glUniform3fv(p["u_light_dir"], 1, light_dir.data());
      // No light pipe: a cone that nothing lies in (cos > 1) leaves only the ambient term.
      glUniform1f(p["u_cos_outer"], light_on ? cos_outer : 2.0f);
      glUniform1f(p["u_cos_inner"], light_on ? cos_inner : 3.0f);
      glUniform1f(p["u_light_intensity"], light_.intensity);
      glUniform1f(p["u_light_range"], light_.range);
      glUniform1f(p["u_shadow_bias"], 2e-5f);
      glUniform1f(p["u_bump_amplitude"], 1.4e-5f);
      glUniform3fv(p["u_blood"], 1, options_.blood_colour.data());
      glUniform1i(p["u_shadow_map"], 0);
      return p;
    };
    glActiveTexture(GL_TEXTURE0);
    glBindTexture(GL_TEXTURE_2D, im.shadow_target.depth);
    auto draw = [&](const Object& object, float alpha_scale) {
      Program& p = use(object.style.bump_mapped);
      const Material& m = object.style.material;
      glUniformMatrix4fv(p["u_model"], 1, GL_FALSE, object.pose.matrix().data());
      const Eigen::Matrix3f normal_matrix = object.pose.linear().inverse().transpose();
      glUniformMatrix3fv(p["u_normal_matrix"], 1, GL_FALSE, normal_matrix.data());
      glUniform4fv(p["u_diffuse"], 1, m.diffuse.data());
      glUniform3fv(p["u_specular"], 1, m.specular.data());
      glUniform1f(p["u_shininess"], std::max(1.0f, m.shininess));
      glUniform1f(p["u_alpha_scale"], alpha_scale);
      im.drawObject(object);
      timings.triangles_drawn += object.triangle_count;
    };
    for (const auto& entry : opaque) draw(*entry.second, 1.0f);
    if (!translucent.empty()) {
      glEnable(GL_BLEND);
      glBlendFunc(GL_SRC_ALPHA, GL_ONE_MINUS_SRC_ALPHA);
      glDepthMask(GL_FALSE);
      for (const auto& entry : translucent) {
        if (entry.second->style.ghost) {
          // Depth-only first, so a ghost shows only its nearest surface (like a glass instrument, not an x-ray).
          glColorMask(GL_FALSE, GL_FALSE, GL_FALSE, GL_FALSE);
          glDepthMask(GL_TRUE);
          draw(*entry.second, 1.0f);
          glColorMask(GL_TRUE, GL_TRUE, GL_TRUE, GL_TRUE);
          glDepthMask(GL_FALSE);
          glDepthFunc(GL_LEQUAL);
          draw(*entry.second, options_.ghost_alpha);
          glDepthFunc(GL_LESS);
        } else {
          draw(*entry.second, 1.0f);
        }
      }
      glDepthMask(GL_TRUE);
      glDisable(GL_BLEND);
    }
    barrier();
    timings.ms_scene += msSince(start);

    // Pass 3: depth of field.
    GLuint result_fbo = im.scene_target.fbo;
    if (options_.dof_pass) {
      start = Clock::now();
      glDisable(GL_DEPTH_TEST);
      glDepthMask(GL_FALSE);
      glViewport(0, 0, im.half_a.width, im.half_a.height);
      glBindFramebuffer(GL_FRAMEBUFFER, im.half_a.fbo);
      im.copy.use();
      glBindTexture(GL_TEXTURE_2D, im.scene_target.color);
      glUniform1i(im.copy["u_src"], 0);
      im.drawFullscreen();
      // Gaussian weights of taps 0..4, pairs (1,2) and (3,4) merged into one bilinear fetch each.
      float g[5];
      float sum = 0.0f;
      for (int i = 0; i < 5; ++i) {
        g[i] = std::exp(-0.5f * i * i / (options_.dof_sigma_px * options_.dof_sigma_px));
        sum += i == 0 ? g[i] : 2.0f * g[i];
      }
      const float weights[3] = {g[0] / sum, (g[1] + g[2]) / sum, (g[3] + g[4]) / sum};
      const float offsets[3] = {0.0f, (g[1] * 1.0f + g[2] * 2.0f) / (g[1] + g[2]),
                                (g[3] * 3.0f + g[4] * 4.0f) / (g[3] + g[4])};
      im.blur.use();
      glUniform1fv(im.blur["u_weight"], 3, weights);
      glUniform1fv(im.blur["u_offset"], 3, offsets);
      glUniform1i(im.blur["u_src"], 0);
      glBindFramebuffer(GL_FRAMEBUFFER, im.half_b.fbo);
      glBindTexture(GL_TEXTURE_2D, im.half_a.color);
      glUniform2f(im.blur["u_step"], 1.0f / im.half_a.width, 0.0f);
      im.drawFullscreen();
      glBindFramebuffer(GL_FRAMEBUFFER, im.half_a.fbo);
      glBindTexture(GL_TEXTURE_2D, im.half_b.color);
      glUniform2f(im.blur["u_step"], 0.0f, 1.0f / im.half_a.height);
      im.drawFullscreen();

      glViewport(0, 0, options_.width, options_.height);
      glBindFramebuffer(GL_FRAMEBUFFER, im.output_target.fbo);
      Program& c = im.composite;
      c.use();
      glActiveTexture(GL_TEXTURE0);
      glBindTexture(GL_TEXTURE_2D, im.scene_target.color);
      glActiveTexture(GL_TEXTURE1);
      glBindTexture(GL_TEXTURE_2D, im.half_a.color);
      glActiveTexture(GL_TEXTURE2);
      glBindTexture(GL_TEXTURE_2D, im.scene_target.depth);
      glUniform1i(c["u_sharp"], 0);
      glUniform1i(c["u_blurred"], 1);
      glUniform1i(c["u_depth"], 2);
      glUniform1f(c["u_near"], cam.near_plane);
      glUniform1f(c["u_far"], cam.far_plane);
      glUniform1f(c["u_focus"], cam.focus_depth);
      glUniform1f(c["u_dof_range"], rig_.depth_of_field / static_cast<float>(microscope_.zoom));
      im.drawFullscreen();
      glActiveTexture(GL_TEXTURE0);
      glDepthMask(GL_TRUE);
      barrier();
      timings.ms_dof += msSince(start);
      result_fbo = im.output_target.fbo;
    }

    // Readback, flipped to top row first.
    start = Clock::now();
    RgbImage& image = frame->images[e];
    image.width = options_.width;
    image.height = options_.height;
    const std::size_t row = static_cast<std::size_t>(options_.width) * 3;
    image.data.resize(row * options_.height);
    im.readback.resize(row * options_.height);
    glBindFramebuffer(GL_READ_FRAMEBUFFER, result_fbo);
    glReadBuffer(GL_COLOR_ATTACHMENT0);
    glPixelStorei(GL_PACK_ALIGNMENT, 1);
    glReadPixels(0, 0, options_.width, options_.height, GL_RGB, GL_UNSIGNED_BYTE, im.readback.data());
    for (int y = 0; y < options_.height; ++y) {
      std::memcpy(image.data.data() + row * y, im.readback.data() + row * (options_.height - 1 - y), row);
    }
    timings.ms_readback += msSince(start);
  }
  if (eye_count == 1) frame->images[1] = RgbImage();
  glBindFramebuffer(GL_FRAMEBUFFER, 0);
  const GLenum error = glGetError();
  timings.ms_total = msSince(frame_start) + timings.ms_upload;
  frame->timings = timings;
  if (error != GL_NO_ERROR) throw RenderError("OpenGL error " + std::to_string(error) + " while rendering");
}

}  // namespace vrm_render
