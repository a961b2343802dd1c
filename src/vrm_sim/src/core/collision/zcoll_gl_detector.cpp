// ZCOLL (thesis Alg. 4.2) and ZCOLL/F (Alg. 4.3) on OpenGL through the project's one OSMesa context helper
// (vrm_gl::GlContext, core profile). The tissue's triangle ids are 24-bit colours (gl_PrimitiveID + 1, §4.2.3), the
// instrument's depth profile is read back once and cached (Alg. 4.2 line 4), the stencil parity pass of ZCOLL
// increments on z pass (Alg. 4.2 line 11). Readback covers only the ROI of the instrument's footprint (§4.2.5); the
// pixel analysis is the one of the CPU backend.
#define GL_GLEXT_PROTOTYPES
#include <GL/gl.h>
#include <GL/glext.h>

#include <algorithm>
#include <cmath>

#include "detector_internals.h"
#include "vrm_gl/gl_context.h"

namespace vrm_sim {
namespace collision {
namespace internal {
namespace {

using Eigen::Vector3d;

const char* kVertexShader = R"(#version 330 core
layout(location = 0) in vec3 position;
uniform mat4 to_clip;
void main() { gl_Position = to_clip * vec4(position, 1.0); }
)";

const char* kFragmentShader = R"(#version 330 core
out vec4 colour;
void main() {
  int id = gl_PrimitiveID + 1;
  colour = vec4(float(id & 255), float((id >> 8) & 255), float((id >> 16) & 255), 255.0) / 255.0;
}
)";

GLuint compile(GLenum type, const char* source) {
  const GLuint shader = glCreateShader(type);
  glShaderSource(shader, 1, &source, nullptr);
  glCompileShader(shader);
  GLint ok = 0;
  glGetShaderiv(shader, GL_COMPILE_STATUS, &ok);
  if (!ok) throw vrm_gl::GlContextError("zcoll_gl: shader compilation failed");
  return shader;
}

// A mesh on the GPU: positions (floats) and the triangle index array.
struct GpuMesh {
  GLuint vao = 0, vbo = 0, ebo = 0;
  GLsizei index_count = 0;
  std::size_t vertex_count = 0;
  const void* uploaded_indices = nullptr;
  std::size_t uploaded_triangle_count = 0;
};

class ZcollGlDetector : public CollisionDetector {
 public:
  explicit ZcollGlDetector(bool front_only) : front_only_(front_only) {}
  ~ZcollGlDetector() override {
    if (!context_) return;
    context_->makeCurrent();
    for (GpuMesh* m : {&instrument_gpu_, &surface_gpu_}) {
      glDeleteBuffers(1, &m->vbo);
      glDeleteBuffers(1, &m->ebo);
      glDeleteVertexArrays(1, &m->vao);
    }
    glDeleteProgram(program_);
  }

  std::string name() const override { return front_only_ ? "zcoll_f_gl" : "zcoll_gl"; }

  void setInstrument(const InstrumentModel& instrument) override {
    instrument_ = instrument;
    has_instrument_ = true;
    cache_valid_ = false;
    instrument_uploaded_ = false;
  }

  void setOptions(const CollisionOptions& options) override {
    if (options.resolution != options_.resolution) cache_valid_ = false;
    options_ = options;
  }

  CollisionResult collide(const Eigen::Isometry3d& pose, const SurfaceView& surface) override {
    Stopwatch total, phase;
    CollisionResult result;
    result.status = validateMeshQuery(has_instrument_, instrument_, pose, surface);
    if (result.status != CollisionStatus::kOk) return result;
    if (!ensureContext()) {
      result.status = CollisionStatus::kBackendUnavailable;
      return result;
    }
    if (!cache_valid_) renderInstrument();
    const int r = volume_.resolution;
    result.pixel_size = volume_.pixel_size;
    result.resolution = r;
    if (r <= 0 || b_roi_.empty()) {
      result.status = CollisionStatus::kEmptyInput;
      return result;
    }

    // Geometry transfer and Alg. 4.3 line 6: A into z and colour (ids), z test "<".
    upload(surface_gpu_, surface.positions, surface.node_count, surface.triangles, surface.triangle_count, false);
    const Eigen::Matrix4f to_clip = clipMatrix() * pose.inverse().matrix().cast<float>();
    glEnable(GL_SCISSOR_TEST);
    glScissor(b_roi_.x0, b_roi_.y0, b_roi_.x1 - b_roi_.x0, b_roi_.y1 - b_roi_.y0);
    glClearColor(0, 0, 0, 0);
    glClearDepth(1.0);
    glClearStencil(0);
    glColorMask(GL_TRUE, GL_TRUE, GL_TRUE, GL_TRUE);
    glDepthMask(GL_TRUE);
    glClear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT | GL_STENCIL_BUFFER_BIT);
    glEnable(GL_DEPTH_TEST);
    glDepthFunc(GL_LESS);
    glDisable(GL_STENCIL_TEST);
    draw(surface_gpu_, to_clip);
    if (!front_only_) {
      // Alg. 4.2 lines 11-12: B into the stencil only, incrementing where B's fragment passes the z test against A.
      glColorMask(GL_FALSE, GL_FALSE, GL_FALSE, GL_FALSE);
      glDepthMask(GL_FALSE);
      glEnable(GL_STENCIL_TEST);
      glStencilFunc(GL_ALWAYS, 0, 0xff);
      glStencilOp(GL_KEEP, GL_KEEP, GL_INCR_WRAP);
      draw(instrument_gpu_, clipMatrix());
      glDisable(GL_STENCIL_TEST);
    }
    glFinish();
    result.timing.ms_raster = phase.lap();

    // Readback of the ROI: depth, colour and (ZCOLL) stencil.
    const int w = b_roi_.x1 - b_roi_.x0, h = b_roi_.y1 - b_roi_.y0;
    depth_roi_.resize(static_cast<std::size_t>(w) * h);
    colour_roi_.resize(static_cast<std::size_t>(w) * h * 4);
    glPixelStorei(GL_PACK_ALIGNMENT, 1);
    glReadPixels(b_roi_.x0, b_roi_.y0, w, h, GL_DEPTH_COMPONENT, GL_FLOAT, depth_roi_.data());
    glReadPixels(b_roi_.x0, b_roi_.y0, w, h, GL_RGBA, GL_UNSIGNED_BYTE, colour_roi_.data());
    if (!front_only_) {
      stencil_roi_.resize(static_cast<std::size_t>(w) * h);
      glReadPixels(b_roi_.x0, b_roi_.y0, w, h, GL_STENCIL_INDEX, GL_UNSIGNED_BYTE, stencil_roi_.data());
    }
    result.timing.ms_readback = phase.lap();

    // Unpack into full-size buffers (the analysis indexes r x r) and build the collision mask.
    mask_.assign(static_cast<std::size_t>(r) * r, 0);
    bool any_fragment = false;
    for (int y = 0; y < h; ++y) {
      for (int x = 0; x < w; ++x) {
        const std::size_t k = static_cast<std::size_t>(y) * w + x;
        const std::size_t i = static_cast<std::size_t>(y + b_roi_.y0) * r + x + b_roi_.x0;
        const std::uint8_t* c = &colour_roi_[4 * k];
        const std::int32_t id = (c[0] | (c[1] << 8) | (c[2] << 16)) - 1;
        ids_[i] = id;
        zbuf_a_[i] = id >= 0 ? static_cast<float>(depth_roi_[k] * volume_.far_depth) : DepthIdBuffer::kInfinity;
        if (id < 0) continue;
        any_fragment = true;
        // Condition (*) of Alg. 4.3, or odd stencil parity (Alg. 4.2 line 15).
        mask_[i] = front_only_ ? zbuf_b_[i] < zbuf_a_[i] : (stencil_roi_[k] & 1);
      }
    }
    if (!any_fragment) {
      result.status = CollisionStatus::kOutsideVolume;
    } else if (options_.readback == ReadbackMode::kYesNo) {
      result.colliding = orFoldYesNo(mask_, r, r);
    } else {
      const PixelRect roi = orFoldRoi(mask_, r, r);
      if (!roi.empty()) {
        analyzeCollisionMask(volume_, mask_, roi, zbuf_a_.data(), ids_.data(), zbuf_b_.data(), pose, surface, options_,
                             scratch_, result);
      }
    }
    result.timing.ms_analysis = phase.lap();
    result.timing.ms_total = total.lap();
    return result;
  }

 private:
  bool ensureContext() {
    if (context_failed_) return false;
    try {
      if (!context_) {
        vrm_gl::GlContextOptions options;
        options.width = options.height = 64;
        context_ = std::make_unique<vrm_gl::GlContext>(options);
        const GLuint vs = compile(GL_VERTEX_SHADER, kVertexShader);
        const GLuint fs = compile(GL_FRAGMENT_SHADER, kFragmentShader);
        program_ = glCreateProgram();
        glAttachShader(program_, vs);
        glAttachShader(program_, fs);
        glLinkProgram(program_);
        glDeleteShader(vs);
        glDeleteShader(fs);
        GLint ok = 0;
        glGetProgramiv(program_, GL_LINK_STATUS, &ok);
        if (!ok) throw vrm_gl::GlContextError("zcoll_gl: program link failed");
        to_clip_location_ = glGetUniformLocation(program_, "to_clip");
        for (GpuMesh* m : {&instrument_gpu_, &surface_gpu_}) {
          glGenVertexArrays(1, &m->vao);
          glGenBuffers(1, &m->vbo);
          glGenBuffers(1, &m->ebo);
        }
      } else {
        context_->makeCurrent();
      }
    } catch (const std::exception&) {
      context_failed_ = true;
      context_.reset();
      return false;
    }
    return true;
  }

  // Instrument frame -> clip space of the fitted volume (orthographic, thesis Fig. 4.8).
  Eigen::Matrix4f clipMatrix() const {
    const double r = volume_.resolution, p = volume_.pixel_size;
    Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
    m.block<1, 3>(0, 0) = volume_.axes.row(0) * (2.0 / (r * p));
    m(0, 3) = -2.0 * volume_.x_min / (r * p) - 1.0;
    m.block<1, 3>(1, 0) = volume_.axes.row(1) * (2.0 / (r * p));
    m(1, 3) = -2.0 * volume_.y_min / (r * p) - 1.0;
    // depth = near_z - z maps [0, far_depth] to [-1, 1].
    m.block<1, 3>(2, 0) = -volume_.axes.row(2) * (2.0 / volume_.far_depth);
    m(2, 3) = 2.0 * volume_.near_z / volume_.far_depth - 1.0;
    return m.cast<float>();
  }

  void upload(GpuMesh& m, const Vector3d* positions, std::size_t node_count, const std::array<std::uint32_t, 3>* tris,
              std::size_t triangle_count, bool force) {
    glBindVertexArray(m.vao);
    positions_f_.resize(node_count * 3);
    for (std::size_t i = 0; i < node_count; ++i) {
      for (int k = 0; k < 3; ++k) positions_f_[3 * i + k] = static_cast<float>(positions[i][k]);
    }
    glBindBuffer(GL_ARRAY_BUFFER, m.vbo);
    if (force || node_count != m.vertex_count) {
      glBufferData(GL_ARRAY_BUFFER, positions_f_.size() * sizeof(float), positions_f_.data(), GL_STREAM_DRAW);
      m.vertex_count = node_count;
    } else {
      glBufferSubData(GL_ARRAY_BUFFER, 0, positions_f_.size() * sizeof(float), positions_f_.data());
    }
    glEnableVertexAttribArray(0);
    glVertexAttribPointer(0, 3, GL_FLOAT, GL_FALSE, 3 * sizeof(float), nullptr);
    glBindBuffer(GL_ELEMENT_ARRAY_BUFFER, m.ebo);
    if (force || tris != m.uploaded_indices || triangle_count != m.uploaded_triangle_count) {
      // Topology changes (cutting) are rare: the index array is re-sent only then.
      glBufferData(GL_ELEMENT_ARRAY_BUFFER, triangle_count * sizeof(std::array<std::uint32_t, 3>), tris,
                   GL_STATIC_DRAW);
      m.uploaded_indices = tris;
      m.uploaded_triangle_count = triangle_count;
      m.index_count = static_cast<GLsizei>(triangle_count * 3);
    }
  }

  void draw(const GpuMesh& m, const Eigen::Matrix4f& to_clip) {
    glUseProgram(program_);
    glUniformMatrix4fv(to_clip_location_, 1, GL_FALSE, to_clip.data());
    glBindVertexArray(m.vao);
    glDrawElements(GL_TRIANGLES, m.index_count, GL_UNSIGNED_INT, nullptr);
  }

  // Alg. 4.2 lines 4-7: B's depth profile, read back and kept until shape, z direction or resolution change.
  void renderInstrument() {
    cache_valid_ = true;
    volume_ = fitProjectionVolume(instrument_.mesh, instrument_.projection_direction, std::max(4, options_.resolution),
                                  instrument_.tip_region_length);
    b_roi_ = PixelRect{};
    const int r = volume_.resolution;
    if (r <= 0) return;
    if (context_->width() != r || context_->height() != r) context_->resize(r, r);
    glViewport(0, 0, r, r);
    const std::size_t pixels = static_cast<std::size_t>(r) * r;
    if (!instrument_uploaded_) {
      upload(instrument_gpu_, instrument_.mesh.vertices.data(), instrument_.mesh.vertices.size(),
             instrument_.mesh.triangles.data(), instrument_.mesh.triangles.size(), true);
      instrument_uploaded_ = true;
    }
    glDisable(GL_SCISSOR_TEST);
    glColorMask(GL_FALSE, GL_FALSE, GL_FALSE, GL_FALSE);
    glDepthMask(GL_TRUE);
    glClearDepth(1.0);
    glClear(GL_DEPTH_BUFFER_BIT);
    glEnable(GL_DEPTH_TEST);
    glDepthFunc(GL_LESS);
    draw(instrument_gpu_, clipMatrix());
    std::vector<float> depth(pixels);
    glPixelStorei(GL_PACK_ALIGNMENT, 1);
    glReadPixels(0, 0, r, r, GL_DEPTH_COMPONENT, GL_FLOAT, depth.data());
    zbuf_b_.assign(pixels, DepthIdBuffer::kInfinity);
    std::vector<std::uint8_t> b_mask(pixels, 0);
    for (std::size_t i = 0; i < pixels; ++i) {
      if (depth[i] < 1.0f) {
        zbuf_b_[i] = static_cast<float>(depth[i] * volume_.far_depth);
        b_mask[i] = 1;
      }
    }
    b_roi_ = orFoldRoi(b_mask, r, r);
    zbuf_a_.assign(pixels, DepthIdBuffer::kInfinity);
    ids_.assign(pixels, -1);
  }

  const bool front_only_;
  InstrumentModel instrument_;
  bool has_instrument_ = false;
  bool cache_valid_ = false;
  bool instrument_uploaded_ = false;
  bool context_failed_ = false;
  std::unique_ptr<vrm_gl::GlContext> context_;
  GLuint program_ = 0;
  GLint to_clip_location_ = -1;
  GpuMesh instrument_gpu_, surface_gpu_;
  ProjectionVolume volume_;
  PixelRect b_roi_;
  std::vector<float> zbuf_b_, zbuf_a_, depth_roi_, positions_f_;
  std::vector<std::int32_t> ids_;
  std::vector<std::uint8_t> colour_roi_, stencil_roi_, mask_;
  AnalysisScratch scratch_;
};

}  // namespace

std::unique_ptr<CollisionDetector> makeZcollGlDetector(bool front_only) {
  return std::make_unique<ZcollGlDetector>(front_only);
}

}  // namespace internal
}  // namespace collision
}  // namespace vrm_sim
