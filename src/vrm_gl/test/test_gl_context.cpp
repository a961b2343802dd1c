#define GL_GLEXT_PROTOTYPES
#include <GL/gl.h>
#include <GL/glext.h>
#include <gtest/gtest.h>

#include "vrm_gl/gl_context.h"

namespace {

TEST(GlContext, CreatesCoreProfileWithStencil) {
  vrm_gl::GlContext context({64, 32});
  EXPECT_EQ(context.width(), 64);
  EXPECT_EQ(context.height(), 32);
  EXPECT_NE(context.version().find("Core"), std::string::npos) << context.version();
  GLint stencil_bits = 0;
  glGetFramebufferAttachmentParameteriv(GL_FRAMEBUFFER, GL_STENCIL, GL_FRAMEBUFFER_ATTACHMENT_STENCIL_SIZE,
                                        &stencil_bits);
  EXPECT_GE(stencil_bits, 8);
}

TEST(GlContext, ClearColourReachesTheBufferAndDepthReadsBack) {
  vrm_gl::GlContext context({16, 16});
  glClearColor(1.0f, 0.5f, 0.0f, 1.0f);
  glClearDepth(0.25);
  glClear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
  glFinish();
  const std::uint8_t* rgba = context.colorBuffer();
  EXPECT_EQ(rgba[0], 255);
  EXPECT_NEAR(rgba[1], 128, 1);
  EXPECT_EQ(rgba[2], 0);
  float depth = 0.0f;
  glReadPixels(3, 3, 1, 1, GL_DEPTH_COMPONENT, GL_FLOAT, &depth);
  EXPECT_NEAR(depth, 0.25f, 1e-6f);
  EXPECT_EQ(glGetError(), static_cast<GLenum>(GL_NO_ERROR));
}

TEST(GlContext, ResizeKeepsTheContextUsable) {
  vrm_gl::GlContext context({8, 8});
  context.resize(40, 20);
  GLint viewport[4] = {};
  glViewport(0, 0, 40, 20);
  glGetIntegerv(GL_VIEWPORT, viewport);
  EXPECT_EQ(viewport[2], 40);
  glClearColor(0, 0, 1, 1);
  glClear(GL_COLOR_BUFFER_BIT);
  glFinish();
  const std::uint8_t* last_pixel = context.colorBuffer() + (40 * 20 - 1) * 4;
  EXPECT_EQ(last_pixel[2], 255);
}

TEST(GlContext, RejectsNonPositiveSize) { EXPECT_THROW(vrm_gl::GlContext({0, 10}), vrm_gl::GlContextError); }

}  // namespace
