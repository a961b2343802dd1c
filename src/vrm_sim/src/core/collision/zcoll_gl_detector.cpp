// ZCOLL (thesis Alg. 4.2) and ZCOLL/F (Alg. 4.3) on OpenGL through the project's one OSMesa context helper
// (vrm_gl::GlContext, core profile), rendering into an own framebuffer object of r x r pixels:
//
//   colour 0  RGBA8  the tissue's triangle ids as 24-bit colours (gl_PrimitiveID + 1, §4.2.3)
//   colour 1  RG8    the collision mask: R = collision at the pixel, G = tissue present
//   depth/stencil    A's depth; stencil bit 7 = A present, bits 0-6 = ZCOLL's parity count (increment on z pass,
//                    Alg. 4.2 line 11)
//
// The instrument's depth profile is rendered once and cached as a texture (Alg. 4.2 line 4). The collision mask is
// made on the GPU: a full-screen pass writes R where B's front depth (gl_FragDepth from the cached texture) passes
// the z test "<" against A (condition (*) of Alg. 4.3), or where the stencil count is odd (ZCOLL), and G where A
// was rendered. The mask is then reduced on the GPU before anything is read back (§4.2.5): yes/no by OR-folding
// 2 x 2 quadrants down to one pixel (2 bytes read), the region of interest by OR-folding all rows onto one row and
// all columns onto one column (4 r bytes read). Only the ROI of the collision is read back in full (mask, colour
// ids and, if deformation vectors are wanted, depth); the pixel analysis is the one of the CPU backend.
#include <algorithm>
#include <cmath>

#include "detector_internals.h"
#include "vrm_gl/gl_context.h"
#include "vrm_gl/gl_objects.h"

namespace vrm_sim {
namespace collision {
namespace internal {
namespace {

using Eigen::Vector3d;

const char* kIdVertexShader = R"(#version 330 core
layout(location = 0) in vec3 position;
uniform mat4 to_clip;
void main() { gl_Position = to_clip * vec4(position, 1.0); }
)";

const char* kIdFragmentShader = R"(#version 330 core
layout(location = 0) out vec4 colour;
void main() {
  int id = gl_PrimitiveID + 1;
  colour = vec4(float(id & 255), float((id >> 8) & 255), float((id >> 16) & 255), 255.0) / 255.0;
}
)";

// A triangle covering the viewport (no vertex buffer needed).
const char* kFullScreenVertexShader = R"(#version 330 core
void main() {
  vec2 corner = vec2(float((gl_VertexID << 1) & 2), float(gl_VertexID & 2));
  gl_Position = vec4(corner * 2.0 - 1.0, 0.0, 1.0);
}
)";

// Mask pass: writes `value` into colour attachment 1; with b_depth_test the fragment lies at B's front depth, so
// the fixed-function z test "<" against A decides condition (*) of Alg. 4.3.
const char* kMaskFragmentShader = R"(#version 330 core
uniform sampler2D b_depth;
uniform bool b_depth_test;
uniform vec2 value;
layout(location = 1) out vec2 mask;
void main() {
  if (b_depth_test) gl_FragDepth = texelFetch(b_depth, ivec2(gl_FragCoord.xy), 0).r;
  else gl_FragDepth = gl_FragCoord.z;
  mask = value;
}
)";

// OR-fold (max) of factor.x x factor.y source texels into one (Fig. 4.12); texels beyond src_size count as 0, so
// sizes need not be powers of two.
const char* kFoldFragmentShader = R"(#version 330 core
uniform sampler2D source;
uniform ivec2 factor;
uniform ivec2 source_size;
layout(location = 0) out vec2 folded;
void main() {
  ivec2 base = ivec2(gl_FragCoord.xy) * factor;
  vec2 m = vec2(0.0);
  for (int j = 0; j < factor.y; ++j) {
    for (int i = 0; i < factor.x; ++i) {
      ivec2 p = base + ivec2(i, j);
      if (p.x < source_size.x && p.y < source_size.y) m = max(m, texelFetch(source, p, 0).rg);
    }
  }
  folded = m;
}
)";

// A render target of one RG8 texture (the fold passes' output).
struct FoldTarget {
  int width = 0, height = 0;
  GLuint texture = 0, fbo = 0;
};

// A mesh on the GPU: positions (floats) and the triangle index array.
struct GpuMesh {
  GLuint vao = 0, vbo = 0, ebo = 0;
  GLsizei index_count = 0;
  std::size_t vertex_count = 0;
  const void* uploaded_indices = nullptr;
  std::size_t uploaded_triangle_count = 0;
};

constexpr GLuint kAPresent = 0x80;    // stencil bit: A was rendered here
constexpr GLuint kParityBits = 0x7f;  // stencil bits: B's fragments in front of A (ZCOLL)

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
    releaseTargets();
    glDeleteVertexArrays(1, &empty_vao_);
    for (GLuint program : {id_program_, mask_program_, fold_program_}) glDeleteProgram(program);
  }

  std::string name() const override { return front_only_ ? "zcoll_f_gl" : "zcoll_gl"; }
  bool producesDeformations() const override { return true; }

  // Thesis §4.1.4 on the GPU: additive stencil, then "any entry > 1" by a stencil-tested pass and the OR-fold.
  std::optional<bool> zConvex(const TriangleMesh& mesh, const ProjectionVolume& volume) {
    if (volume.resolution <= 0 || mesh.triangles.empty()) return true;
    if (!ensureContext()) return std::nullopt;
    volume_ = volume;
    cache_valid_ = false;  // volume_ is the check's now
    const int r = volume.resolution;
    makeTargets(r);
    GpuMesh gpu;
    glGenVertexArrays(1, &gpu.vao);
    glGenBuffers(1, &gpu.vbo);
    glGenBuffers(1, &gpu.ebo);
    upload(gpu, mesh.vertices.data(), mesh.vertices.size(), mesh.triangles.data(), mesh.triangles.size(), true);
    glBindFramebuffer(GL_FRAMEBUFFER, fbo_);
    glViewport(0, 0, r, r);
    restoreState();
    const GLfloat zero[4] = {0, 0, 0, 0};
    glClearBufferfv(GL_COLOR, 1, zero);
    glClearBufferfi(GL_DEPTH_STENCIL, 0, 1.0f, 0);
    const GLenum none[2] = {GL_NONE, GL_NONE};
    glDrawBuffers(2, none);
    glEnable(GL_STENCIL_TEST);
    glStencilFunc(GL_ALWAYS, 0, 0xff);
    glStencilOp(GL_INCR, GL_INCR, GL_INCR);  // every fragment counts (saturating at 255)
    drawMesh(gpu, clipMatrix());
    const GLenum mask_only[2] = {GL_NONE, GL_COLOR_ATTACHMENT1};
    glDrawBuffers(2, mask_only);
    glStencilOp(GL_KEEP, GL_KEEP, GL_KEEP);
    glStencilFunc(GL_LESS, 1, 0xff);  // passes where 1 < stencil
    glUseProgram(mask_program_);
    glUniform1i(mask_b_depth_test_, GL_FALSE);
    glUniform2f(mask_value_, 1.0f, 1.0f);
    glBindVertexArray(empty_vao_);
    glDrawArrays(GL_TRIANGLES, 0, 3);
    restoreState();
    glPixelStorei(GL_PACK_ALIGNMENT, 1);
    std::uint8_t covered_twice[2] = {0, 0};
    foldYesNo(covered_twice);
    glDeleteBuffers(1, &gpu.vbo);
    glDeleteBuffers(1, &gpu.ebo);
    glDeleteVertexArrays(1, &gpu.vao);
    return covered_twice[0] == 0;
  }

  void setInstrument(const InstrumentModel& instrument) override {
    instrument_ = instrument;
    has_instrument_ = true;
    cache_valid_ = false;
    instrument_uploaded_ = false;
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

    // Geometry transfer and Alg. 4.3 line 6: A into z and colour (ids), z test "<", marking the stencil.
    upload(surface_gpu_, surface.positions, surface.node_count, surface.triangles, surface.triangle_count, false);
    const Eigen::Matrix4f to_clip = clipMatrix() * pose.inverse().matrix().cast<float>();
    glBindFramebuffer(GL_FRAMEBUFFER, fbo_);
    glViewport(0, 0, r, r);
    glDisable(GL_SCISSOR_TEST);
    const GLfloat zero[4] = {0, 0, 0, 0};
    glClearBufferfv(GL_COLOR, 1, zero);  // the whole mask: the folds read all of it
    // A is rendered only inside the ROI of B's footprint (OR-folded at caching time): no collision elsewhere.
    glEnable(GL_SCISSOR_TEST);
    glScissor(b_roi_.x0, b_roi_.y0, b_roi_.x1 - b_roi_.x0, b_roi_.y1 - b_roi_.y0);
    glClearBufferfv(GL_COLOR, 0, zero);
    glClearBufferfi(GL_DEPTH_STENCIL, 0, 1.0f, 0);
    const GLenum ids_only[2] = {GL_COLOR_ATTACHMENT0, GL_NONE};
    glDrawBuffers(2, ids_only);
    glColorMask(GL_TRUE, GL_TRUE, GL_TRUE, GL_TRUE);
    glDepthMask(GL_TRUE);
    glEnable(GL_DEPTH_TEST);
    glDepthFunc(GL_LESS);
    glEnable(GL_STENCIL_TEST);
    glStencilMask(kAPresent);
    glStencilFunc(GL_ALWAYS, kAPresent, 0xff);
    glStencilOp(GL_KEEP, GL_KEEP, GL_REPLACE);
    drawMesh(surface_gpu_, to_clip);
    if (!front_only_) {
      // Alg. 4.2 lines 11-12: B into the stencil only, incrementing where B's fragment passes the z test against A.
      glColorMask(GL_FALSE, GL_FALSE, GL_FALSE, GL_FALSE);
      glDepthMask(GL_FALSE);
      glStencilMask(kParityBits);
      glStencilFunc(GL_ALWAYS, 0, 0xff);
      glStencilOp(GL_KEEP, GL_KEEP, GL_INCR_WRAP);
      drawMesh(instrument_gpu_, clipMatrix());
      glColorMask(GL_TRUE, GL_TRUE, GL_TRUE, GL_TRUE);
    }
    glFinish();
    result.timing.ms_raster = phase.lap();

    glPixelStorei(GL_PACK_ALIGNMENT, 1);
    if (!options_.gpu_reductions) {
      readFootprint(result);
      restoreState();
      result.timing.ms_readback = phase.lap();
      if (result.status == CollisionStatus::kOk && options_.readback == ReadbackMode::kYesNo) {
        result.colliding = orFoldYesNo(mask_, r, r);
      } else if (result.status == CollisionStatus::kOk) {
        const PixelRect roi = orFoldRoi(mask_, r, r);
        if (!roi.empty()) {
          analyzeCollisionMask(volume_, mask_, roi, zbuf_a_.data(), ids_.data(), zbuf_b_.data(), pose, surface,
                               options_, scratch_, result);
        }
      }
      result.timing.ms_analysis = phase.lap();
      result.timing.ms_total = total.lap();
      return result;
    }

    // The collision mask on the GPU: G where A is present, R where it collides (condition (*) / odd parity).
    const GLenum mask_only[2] = {GL_NONE, GL_COLOR_ATTACHMENT1};
    glDrawBuffers(2, mask_only);
    glDepthMask(GL_FALSE);
    glStencilMask(0);
    glStencilOp(GL_KEEP, GL_KEEP, GL_KEEP);
    glUseProgram(mask_program_);
    glActiveTexture(GL_TEXTURE0);
    glBindTexture(GL_TEXTURE_2D, b_depth_texture_);
    glUniform1i(glGetUniformLocation(mask_program_, "b_depth"), 0);
    glBindVertexArray(empty_vao_);
    glDisable(GL_DEPTH_TEST);
    glStencilFunc(GL_EQUAL, kAPresent, kAPresent);
    glColorMaski(1, GL_FALSE, GL_TRUE, GL_FALSE, GL_FALSE);
    glUniform1i(mask_b_depth_test_, GL_FALSE);
    glUniform2f(mask_value_, 0.0f, 1.0f);
    glDrawArrays(GL_TRIANGLES, 0, 3);
    glColorMaski(1, GL_TRUE, GL_FALSE, GL_FALSE, GL_FALSE);
    glUniform2f(mask_value_, 1.0f, 0.0f);
    if (front_only_) {
      glEnable(GL_DEPTH_TEST);
      glDepthFunc(GL_LESS);
      glUniform1i(mask_b_depth_test_, GL_TRUE);
    } else {
      glStencilFunc(GL_EQUAL, kAPresent | 1, kAPresent | 1);  // A present and an odd count (Alg. 4.2 line 15)
    }
    glDrawArrays(GL_TRIANGLES, 0, 3);
    glColorMaski(1, GL_TRUE, GL_TRUE, GL_TRUE, GL_TRUE);
    restoreState();

    // §4.2.5 reductions on the GPU, then the reduced readback.
    if (options_.readback == ReadbackMode::kYesNo) {
      std::uint8_t yes_no[2] = {0, 0};
      foldYesNo(yes_no);
      result.readback_bytes = 2;
      result.timing.ms_readback = phase.lap();
      if (!yes_no[1]) result.status = CollisionStatus::kOutsideVolume;
      result.colliding = yes_no[0] != 0;
      result.timing.ms_total = total.lap();
      return result;
    }
    bool any_fragment = false;
    const PixelRect roi = foldRoi(any_fragment);
    result.readback_bytes = 4 * static_cast<std::size_t>(r);
    if (!any_fragment) {
      result.status = CollisionStatus::kOutsideVolume;
      result.timing.ms_readback = phase.lap();
      result.timing.ms_total = total.lap();
      return result;
    }
    if (roi.empty()) {
      result.timing.ms_readback = phase.lap();
      result.timing.ms_total = total.lap();
      return result;
    }
    result.readback_bytes += readRoi(roi);
    result.timing.ms_readback = phase.lap();

    analyzeCollisionMask(volume_, mask_, roi, zbuf_a_.data(), ids_.data(), zbuf_b_.data(), pose, surface, options_,
                         scratch_, result);
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
        options.width = options.height = 16;  // rendering goes to the own framebuffer object
        context_ = std::make_unique<vrm_gl::GlContext>(options);
        id_program_ = vrm_gl::linkProgram(kIdVertexShader, kIdFragmentShader, "zcoll_gl id");
        mask_program_ = vrm_gl::linkProgram(kFullScreenVertexShader, kMaskFragmentShader, "zcoll_gl mask");
        fold_program_ = vrm_gl::linkProgram(kFullScreenVertexShader, kFoldFragmentShader, "zcoll_gl fold");
        to_clip_location_ = glGetUniformLocation(id_program_, "to_clip");
        mask_b_depth_test_ = glGetUniformLocation(mask_program_, "b_depth_test");
        mask_value_ = glGetUniformLocation(mask_program_, "value");
        glGenVertexArrays(1, &empty_vao_);
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

  void releaseTargets() {
    glDeleteFramebuffers(1, &fbo_);
    glDeleteTextures(1, &id_texture_);
    glDeleteTextures(1, &mask_texture_);
    glDeleteTextures(1, &b_depth_texture_);
    glDeleteRenderbuffers(1, &depth_stencil_);
    for (FoldTarget* t : allFoldTargets()) {
      glDeleteFramebuffers(1, &t->fbo);
      glDeleteTextures(1, &t->texture);
    }
    fold_chain_.clear();
    fbo_ = id_texture_ = mask_texture_ = b_depth_texture_ = depth_stencil_ = 0;
    rows_ = columns_ = FoldTarget{};
    target_size_ = 0;
  }

  std::vector<FoldTarget*> allFoldTargets() {
    std::vector<FoldTarget*> targets = {&rows_, &columns_};
    for (FoldTarget& t : fold_chain_) targets.push_back(&t);
    return targets;
  }

  FoldTarget makeFoldTarget(int width, int height) {
    FoldTarget target;
    target.width = width;
    target.height = height;
    target.texture = vrm_gl::makeTexture(GL_RG8, width, height, GL_RG, GL_UNSIGNED_BYTE);
    target.fbo = vrm_gl::makeColorFramebuffer(target.texture, "zcoll_gl fold");
    return target;
  }

  // The framebuffer object and the reduction targets for r x r.
  void makeTargets(int r) {
    if (target_size_ == r) return;
    releaseTargets();
    target_size_ = r;
    id_texture_ = vrm_gl::makeTexture(GL_RGBA8, r, r, GL_RGBA, GL_UNSIGNED_BYTE);
    mask_texture_ = vrm_gl::makeTexture(GL_RG8, r, r, GL_RG, GL_UNSIGNED_BYTE);
    b_depth_texture_ = vrm_gl::makeTexture(GL_R32F, r, r, GL_RED, GL_FLOAT);
    glGenRenderbuffers(1, &depth_stencil_);
    glBindRenderbuffer(GL_RENDERBUFFER, depth_stencil_);
    glRenderbufferStorage(GL_RENDERBUFFER, GL_DEPTH24_STENCIL8, r, r);
    glGenFramebuffers(1, &fbo_);
    glBindFramebuffer(GL_FRAMEBUFFER, fbo_);
    glFramebufferTexture2D(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_TEXTURE_2D, id_texture_, 0);
    glFramebufferTexture2D(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT1, GL_TEXTURE_2D, mask_texture_, 0);
    glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_DEPTH_STENCIL_ATTACHMENT, GL_RENDERBUFFER, depth_stencil_);
    vrm_gl::checkFramebufferComplete("zcoll_gl");
    // Fig. 4.12 (1): halve both edges per pass (quadrants onto the lower left one) down to 1 x 1.
    for (int size = r; size > 1;) {
      size = (size + 1) / 2;
      fold_chain_.push_back(makeFoldTarget(size, size));
    }
    // Fig. 4.12 (2): all rows onto one row (r x 1), all columns onto one column (1 x r).
    rows_ = makeFoldTarget(r, 1);
    columns_ = makeFoldTarget(1, r);
  }

  void fold(GLuint source, int source_width, int source_height, const FoldTarget& target, int fx, int fy) {
    glBindFramebuffer(GL_FRAMEBUFFER, target.fbo);
    glViewport(0, 0, target.width, target.height);
    glUseProgram(fold_program_);
    glActiveTexture(GL_TEXTURE0);
    glBindTexture(GL_TEXTURE_2D, source);
    glUniform1i(glGetUniformLocation(fold_program_, "source"), 0);
    glUniform2i(glGetUniformLocation(fold_program_, "factor"), fx, fy);
    glUniform2i(glGetUniformLocation(fold_program_, "source_size"), source_width, source_height);
    glBindVertexArray(empty_vao_);
    glDrawArrays(GL_TRIANGLES, 0, 3);
  }

  // Yes/no (R) and "A anywhere" (G), two bytes read back.
  void foldYesNo(std::uint8_t* out) {
    const int r = volume_.resolution;
    GLuint source = mask_texture_;
    int size = r;
    for (const FoldTarget& target : fold_chain_) {
      fold(source, size, size, target, 2, 2);
      source = target.texture;
      size = target.width;
    }
    if (fold_chain_.empty()) {  // r == 1 cannot happen (r >= 4), kept for completeness
      glBindFramebuffer(GL_FRAMEBUFFER, fbo_);
      glReadBuffer(GL_COLOR_ATTACHMENT1);
    } else {
      glBindFramebuffer(GL_FRAMEBUFFER, fold_chain_.back().fbo);
      glReadBuffer(GL_COLOR_ATTACHMENT0);
    }
    glReadPixels(0, 0, 1, 1, GL_RG, GL_UNSIGNED_BYTE, out);
  }

  // The collision's ROI from one row and one column (2 x 2 r bytes); any_fragment = A was rendered anywhere.
  PixelRect foldRoi(bool& any_fragment) {
    const int r = volume_.resolution;
    fold(mask_texture_, r, r, rows_, 1, r);
    fold(mask_texture_, r, r, columns_, r, 1);
    row_.resize(2 * static_cast<std::size_t>(r));
    column_.resize(2 * static_cast<std::size_t>(r));
    glBindFramebuffer(GL_FRAMEBUFFER, rows_.fbo);
    glReadBuffer(GL_COLOR_ATTACHMENT0);
    glReadPixels(0, 0, r, 1, GL_RG, GL_UNSIGNED_BYTE, row_.data());
    glBindFramebuffer(GL_FRAMEBUFFER, columns_.fbo);
    glReadBuffer(GL_COLOR_ATTACHMENT0);
    glReadPixels(0, 0, 1, r, GL_RG, GL_UNSIGNED_BYTE, column_.data());
    PixelRect rect{r, r, 0, 0};
    any_fragment = false;
    for (int i = 0; i < r; ++i) {
      any_fragment = any_fragment || row_[2 * i + 1] != 0;
      if (row_[2 * i]) {
        rect.x0 = std::min(rect.x0, i);
        rect.x1 = std::max(rect.x1, i + 1);
      }
      if (column_[2 * i]) {
        rect.y0 = std::min(rect.y0, i);
        rect.y1 = std::max(rect.y1, i + 1);
      }
    }
    return rect.empty() ? PixelRect{} : rect;
  }

  void restoreState() {
    glDisable(GL_STENCIL_TEST);
    glDisable(GL_DEPTH_TEST);
    glDisable(GL_SCISSOR_TEST);
    glStencilMask(0xff);
    glDepthMask(GL_TRUE);
  }

  // Without GPU reductions: depth, colour ids and stencil of B's whole footprint, the mask made on the CPU.
  void readFootprint(CollisionResult& result) {
    const int r = volume_.resolution;
    const PixelRect& roi = b_roi_;
    const int w = roi.x1 - roi.x0, h = roi.y1 - roi.y0;
    const std::size_t n = static_cast<std::size_t>(w) * h;
    depth_roi_.resize(n);
    colour_roi_.resize(4 * n);
    stencil_roi_.resize(n);
    glBindFramebuffer(GL_FRAMEBUFFER, fbo_);
    glReadBuffer(GL_COLOR_ATTACHMENT0);
    glReadPixels(roi.x0, roi.y0, w, h, GL_RGBA, GL_UNSIGNED_BYTE, colour_roi_.data());
    glReadPixels(roi.x0, roi.y0, w, h, GL_DEPTH_COMPONENT, GL_FLOAT, depth_roi_.data());
    result.readback_bytes = 8 * n;
    if (!front_only_) {
      glReadPixels(roi.x0, roi.y0, w, h, GL_STENCIL_INDEX, GL_UNSIGNED_BYTE, stencil_roi_.data());
      result.readback_bytes += n;
    }
    bool any_fragment = false;
    for (int y = 0; y < h; ++y) {
      for (int x = 0; x < w; ++x) {
        const std::size_t k = static_cast<std::size_t>(y) * w + x;
        const std::size_t i = static_cast<std::size_t>(y + roi.y0) * r + x + roi.x0;
        const std::uint8_t* c = &colour_roi_[4 * k];
        const std::int32_t id = (c[0] | (c[1] << 8) | (c[2] << 16)) - 1;
        ids_[i] = id;
        zbuf_a_[i] = id >= 0 ? static_cast<float>(depth_roi_[k] * volume_.far_depth) : DepthIdBuffer::kInfinity;
        any_fragment = any_fragment || id >= 0;
        // Condition (*) of Alg. 4.3, or odd stencil parity (Alg. 4.2 line 15).
        mask_[i] = id >= 0 && (front_only_ ? zbuf_b_[i] < zbuf_a_[i] : (stencil_roi_[k] & 1) != 0);
      }
    }
    if (!any_fragment) result.status = CollisionStatus::kOutsideVolume;
  }

  // Mask, ids and (if vectors are wanted) A's depth of the collision ROI into the r x r analysis buffers; returns
  // the bytes read.
  std::size_t readRoi(const PixelRect& roi) {
    const int r = volume_.resolution;
    const int w = roi.x1 - roi.x0, h = roi.y1 - roi.y0;
    const std::size_t n = static_cast<std::size_t>(w) * h;
    mask_roi_.resize(n);
    colour_roi_.resize(3 * n);
    glBindFramebuffer(GL_FRAMEBUFFER, fbo_);
    glReadBuffer(GL_COLOR_ATTACHMENT1);
    glReadPixels(roi.x0, roi.y0, w, h, GL_RED, GL_UNSIGNED_BYTE, mask_roi_.data());
    glReadBuffer(GL_COLOR_ATTACHMENT0);
    glReadPixels(roi.x0, roi.y0, w, h, GL_RGB, GL_UNSIGNED_BYTE, colour_roi_.data());  // 24-bit ids
    // §4.2.5: triangles only need no depth.
    const bool want_depth = options_.readback != ReadbackMode::kTrianglesOnly;
    if (want_depth) {
      depth_roi_.resize(n);
      glReadPixels(roi.x0, roi.y0, w, h, GL_DEPTH_COMPONENT, GL_FLOAT, depth_roi_.data());
    }
    for (int y = 0; y < h; ++y) {
      for (int x = 0; x < w; ++x) {
        const std::size_t k = static_cast<std::size_t>(y) * w + x;
        const std::size_t i = static_cast<std::size_t>(y + roi.y0) * r + x + roi.x0;
        const std::uint8_t* c = &colour_roi_[3 * k];
        ids_[i] = (c[0] | (c[1] << 8) | (c[2] << 16)) - 1;
        mask_[i] = mask_roi_[k] != 0 && ids_[i] >= 0;
        zbuf_a_[i] = want_depth && ids_[i] >= 0 ? static_cast<float>(depth_roi_[k] * volume_.far_depth)
                                                : DepthIdBuffer::kInfinity;
      }
    }
    return (want_depth ? 8 : 4) * n;
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

  void drawMesh(const GpuMesh& m, const Eigen::Matrix4f& to_clip) {
    glUseProgram(id_program_);
    glUniformMatrix4fv(to_clip_location_, 1, GL_FALSE, to_clip.data());
    glBindVertexArray(m.vao);
    glDrawElements(GL_TRIANGLES, m.index_count, GL_UNSIGNED_INT, nullptr);
  }

  // Alg. 4.2 lines 4-7: B's depth profile, read back once and kept (CPU copy for the analysis, texture for the
  // GPU mask pass) until shape, z direction or resolution change.
  void renderInstrument() {
    cache_valid_ = true;
    volume_ = fitProjectionVolume(instrument_.mesh, instrument_.projection_direction,
                                  chooseResolution(instrument_, options_), instrument_.tip_region_length);
    b_roi_ = PixelRect{};
    const int r = volume_.resolution;
    if (r <= 0) return;
    makeTargets(r);
    glBindFramebuffer(GL_FRAMEBUFFER, fbo_);
    glViewport(0, 0, r, r);
    const std::size_t pixels = static_cast<std::size_t>(r) * r;
    if (!instrument_uploaded_) {
      upload(instrument_gpu_, instrument_.mesh.vertices.data(), instrument_.mesh.vertices.size(),
             instrument_.mesh.triangles.data(), instrument_.mesh.triangles.size(), true);
      instrument_uploaded_ = true;
    }
    glDisable(GL_SCISSOR_TEST);
    glDisable(GL_STENCIL_TEST);
    const GLenum none[2] = {GL_NONE, GL_NONE};
    glDrawBuffers(2, none);
    glDepthMask(GL_TRUE);
    glClearBufferfi(GL_DEPTH_STENCIL, 0, 1.0f, 0);
    glEnable(GL_DEPTH_TEST);
    glDepthFunc(GL_LESS);
    drawMesh(instrument_gpu_, clipMatrix());
    std::vector<float> depth(pixels);
    glPixelStorei(GL_PACK_ALIGNMENT, 1);
    glReadPixels(0, 0, r, r, GL_DEPTH_COMPONENT, GL_FLOAT, depth.data());
    glBindTexture(GL_TEXTURE_2D, b_depth_texture_);
    glPixelStorei(GL_UNPACK_ALIGNMENT, 1);
    glTexSubImage2D(GL_TEXTURE_2D, 0, 0, 0, r, r, GL_RED, GL_FLOAT, depth.data());
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
    mask_.assign(pixels, 0);
  }

  const bool front_only_;
  InstrumentModel instrument_;
  bool has_instrument_ = false;
  bool cache_valid_ = false;
  bool instrument_uploaded_ = false;
  bool context_failed_ = false;
  std::unique_ptr<vrm_gl::GlContext> context_;
  GLuint id_program_ = 0, mask_program_ = 0, fold_program_ = 0, empty_vao_ = 0;
  GLint to_clip_location_ = -1, mask_b_depth_test_ = -1, mask_value_ = -1;
  GpuMesh instrument_gpu_, surface_gpu_;
  int target_size_ = 0;
  GLuint fbo_ = 0, id_texture_ = 0, mask_texture_ = 0, b_depth_texture_ = 0, depth_stencil_ = 0;
  std::vector<FoldTarget> fold_chain_;
  FoldTarget rows_, columns_;
  ProjectionVolume volume_;
  PixelRect b_roi_;
  std::vector<float> zbuf_b_, zbuf_a_, depth_roi_, positions_f_;
  std::vector<std::int32_t> ids_;
  std::vector<std::uint8_t> colour_roi_, mask_roi_, stencil_roi_, mask_, row_, column_;
  AnalysisScratch scratch_;
};

}  // namespace

std::unique_ptr<CollisionDetector> makeZcollGlDetector(bool front_only) {
  return std::make_unique<ZcollGlDetector>(front_only);
}

}  // namespace internal

std::optional<bool> zConvexOnGl(const TriangleMesh& mesh_in_instrument_frame, const ProjectionVolume& volume) {
  internal::ZcollGlDetector gl(true);
  return gl.zConvex(mesh_in_instrument_frame, volume);
}
}  // namespace collision
}  // namespace vrm_sim
