#include "vrm_gl/gl_context.h"

#define GL_GLEXT_PROTOTYPES
#include <GL/gl.h>
#include <GL/osmesa.h>
#include <dlfcn.h>

#include <cstdio>
#include <string>

namespace vrm_gl {

struct GlContext::Impl {
  OSMesaContext context = nullptr;
};

GlContext::GlContext(const GlContextOptions& options) : impl_(std::make_unique<Impl>()) {
  if (options.width <= 0 || options.height <= 0) {
    throw GlContextError("GlContext: size must be positive, got " + std::to_string(options.width) + "x" +
                         std::to_string(options.height));
  }
  const int attributes[] = {OSMESA_FORMAT,
                            OSMESA_RGBA,
                            OSMESA_DEPTH_BITS,
                            options.depth_bits,
                            OSMESA_STENCIL_BITS,
                            options.stencil_bits,
                            OSMESA_ACCUM_BITS,
                            0,
                            OSMESA_PROFILE,
                            OSMESA_CORE_PROFILE,
                            OSMESA_CONTEXT_MAJOR_VERSION,
                            options.gl_major,
                            OSMESA_CONTEXT_MINOR_VERSION,
                            options.gl_minor,
                            0};
  impl_->context = OSMesaCreateContextAttribs(attributes, nullptr);
  if (!impl_->context) {
    throw GlContextError("OSMesaCreateContextAttribs failed for an OpenGL " + std::to_string(options.gl_major) + "." +
                         std::to_string(options.gl_minor) + " core profile context");
  }
  resize(options.width, options.height);
  // glGetString answers null (and glGetError 0) when the GL symbols of this process bound to another GL library than
  // OSMesa: glvnd's libOpenGL/libGL stubs do nothing without a glvnd context. It happened in nodelet managers whose
  // nodelet libraries (loaded RTLD_GLOBAL) brought libOpenGL into the global scope before libOSMesa (2026-12-02: the
  // ASan build, linked without --as-needed until scripts/sanitizers/run_tests.sh added it). Assigning that null to a std::string is undefined behaviour: a context
  // that cannot answer is a clear error, naming the library glGetString resolved to.
  const GLubyte* version = glGetString(GL_VERSION);
  const GLubyte* renderer = glGetString(GL_RENDERER);
  if (!version || !renderer) {
    const GLenum error = glGetError();
    OSMesaDestroyContext(impl_->context);
    impl_->context = nullptr;
    char code[16];
    std::snprintf(code, sizeof code, "0x%04x", error);
    Dl_info symbol{};
    const std::string provider = dladdr(reinterpret_cast<void*>(&glGetString), &symbol) && symbol.dli_fname
                                     ? symbol.dli_fname
                                     : "an unknown library";
    throw GlContextError(std::string("OSMesa context made current, but glGetString answered null (glGetError ") + code +
                         "): no usable OpenGL " + std::to_string(options.gl_major) + "." +
                         std::to_string(options.gl_minor) + " context on this thread; glGetString resolves to " +
                         provider +
                         (provider.find("OSMesa") == std::string::npos
                              ? " (a GL library ahead of libOSMesa in this process's symbol scope)"
                              : ""));
  }
  version_ = reinterpret_cast<const char*>(version);
  renderer_ = reinterpret_cast<const char*>(renderer);
}

GlContext::~GlContext() {
  if (impl_ && impl_->context) OSMesaDestroyContext(impl_->context);
}

void GlContext::makeCurrent() {
  if (!OSMesaMakeCurrent(impl_->context, color_.data(), GL_UNSIGNED_BYTE, width_, height_)) {
    throw GlContextError("OSMesaMakeCurrent failed");
  }
}

void GlContext::releaseCurrent() {
  // OSMesa's documented way to unbind: no context and no buffer.
  if (!OSMesaMakeCurrent(nullptr, nullptr, GL_UNSIGNED_BYTE, 0, 0)) throw GlContextError("OSMesa unbind failed");
}

void GlContext::resize(int width, int height) {
  if (width <= 0 || height <= 0) throw GlContextError("GlContext::resize: size must be positive");
  width_ = width;
  height_ = height;
  color_.assign(static_cast<std::size_t>(width) * height * 4, 0);
  makeCurrent();
}

}  // namespace vrm_gl
