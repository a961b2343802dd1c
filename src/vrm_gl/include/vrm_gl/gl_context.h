#pragma once
// The one offscreen OpenGL context helper of the project, shared by the renderer (vrm_render, thesis §6) and the
// image-space collision detectors (vrm_sim, ZCOLL, thesis §4); its own package, so neither depends on the other.
// OSMesa renders on the CPU (llvmpipe), so this works on machines without a GPU and in CI.

#include <cstdint>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

namespace vrm_gl {

class GlContextError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct GlContextOptions {
  int width = 256;
  int height = 256;
  int gl_major = 3;  // core profile 3.3 gives llvmpipe's 4.5 core
  int gl_minor = 3;
  int depth_bits = 24;
  int stencil_bits = 8;  // ZCOLL's parity test needs a stencil buffer
};

// An OSMesa context with its own RGBA colour buffer. A context is current on one thread at a time; makeCurrent()
// binds it to the calling thread (a nodelet's callback thread may differ between calls).
class GlContext {
 public:
  explicit GlContext(const GlContextOptions& options = {});
  ~GlContext();
  GlContext(const GlContext&) = delete;
  GlContext& operator=(const GlContext&) = delete;

  void makeCurrent();
  // Unbinds the context current on the calling thread (any). A thread that used a context briefly (start-up, a
  // snapshot) must let it go: left bound, the context is flushed from that thread whenever the thread binds another
  // one, possibly while its owner is drawing with it on another thread.
  static void releaseCurrent();
  // Changes the size of the default framebuffer; reallocates the colour buffer and rebinds.
  void resize(int width, int height);

  int width() const { return width_; }
  int height() const { return height_; }
  // GL_VERSION / GL_RENDERER strings (valid after construction).
  const std::string& version() const { return version_; }
  const std::string& renderer() const { return renderer_; }
  // Colour buffer of the default framebuffer, RGBA8, bottom row first (OpenGL convention).
  const std::uint8_t* colorBuffer() const { return color_.data(); }

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  int width_ = 0;
  int height_ = 0;
  std::vector<std::uint8_t> color_;
  std::string version_;
  std::string renderer_;
};

}  // namespace vrm_gl
