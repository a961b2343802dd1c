#include <gtest/gtest.h>

#include <cstdint>
#include <string>

#include "vrm_gl/gl_context.h"
#include "vrm_gl/gl_objects.h"

namespace {

constexpr const char* kVertex = R"(#version 330 core
void main() { gl_Position = vec4(vec2(gl_VertexID == 1, gl_VertexID == 2) * 4.0 - 1.0, 0.0, 1.0); }
)";
constexpr const char* kFragment = R"(#version 330 core
out vec4 colour;
uniform vec4 u_colour;
void main() { colour = u_colour; }
)";

class GlObjects : public testing::Test {
 protected:
  vrm_gl::GlContext context_{{16, 16}};
};

TEST_F(GlObjects, LinkedProgramDrawsIntoAColourFramebuffer) {
  const GLuint program = vrm_gl::linkProgram(kVertex, kFragment, "fill");
  ASSERT_NE(program, 0u);
  const GLuint texture = vrm_gl::makeTexture(GL_RGBA8, 8, 4, GL_RGBA, GL_UNSIGNED_BYTE);
  GLint filter = 0, max_level = -1;
  glGetTexParameteriv(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, &filter);
  glGetTexParameteriv(GL_TEXTURE_2D, GL_TEXTURE_MAX_LEVEL, &max_level);
  EXPECT_EQ(filter, GL_NEAREST);
  EXPECT_EQ(max_level, 0);
  const GLuint fbo = vrm_gl::makeColorFramebuffer(texture, "fill");
  ASSERT_NE(fbo, 0u);
  GLuint vao = 0;
  glGenVertexArrays(1, &vao);
  glBindVertexArray(vao);
  glViewport(0, 0, 8, 4);
  glUseProgram(program);
  glUniform4f(glGetUniformLocation(program, "u_colour"), 1.0f, 0.0f, 1.0f, 1.0f);
  glDrawArrays(GL_TRIANGLES, 0, 3);
  std::uint8_t pixel[4] = {};
  glReadPixels(5, 2, 1, 1, GL_RGBA, GL_UNSIGNED_BYTE, pixel);
  EXPECT_EQ(pixel[0], 255);
  EXPECT_EQ(pixel[1], 0);
  EXPECT_EQ(pixel[2], 255);
  EXPECT_EQ(glGetError(), static_cast<GLenum>(GL_NO_ERROR));
}

TEST_F(GlObjects, CompileErrorNamesTheShaderAndCarriesTheInfoLog) {
  const std::string broken = "#version 330 core\nout vec4 c;\nvoid main() { c = undeclared_thing; }\n";
  try {
    vrm_gl::linkProgram(kVertex, broken, "broken");
    FAIL() << "a fragment shader with an undeclared identifier compiled";
  } catch (const vrm_gl::GlError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("shader 'broken' (fragment) does not compile"), std::string::npos) << what;
    EXPECT_NE(what.find("undeclared_thing"), std::string::npos) << "the info log is missing: " << what;
  }
  EXPECT_EQ(glGetError(), static_cast<GLenum>(GL_NO_ERROR));
}

TEST_F(GlObjects, LinkErrorCarriesTheInfoLog) {
  // The fragment shader compiles (a stage may be one of several objects) but has no main(): only linking fails.
  const std::string fragment = "#version 330 core\nout vec4 c;\nvoid helper() { c = vec4(1.0); }\n";
  try {
    vrm_gl::linkProgram(kVertex, fragment, "unlinked");
    FAIL() << "a program without main() linked";
  } catch (const vrm_gl::GlError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("program 'unlinked' does not link: "), std::string::npos) << what;
    EXPECT_GT(what.size(), std::string("program 'unlinked' does not link: ").size()) << "empty info log";
  }
}

TEST_F(GlObjects, IncompleteFramebufferIsReportedWithItsStatus) {
  // A framebuffer without any attachment is incomplete (GL_FRAMEBUFFER_INCOMPLETE_MISSING_ATTACHMENT).
  GLuint fbo = 0;
  glGenFramebuffers(1, &fbo);
  glBindFramebuffer(GL_FRAMEBUFFER, fbo);
  try {
    vrm_gl::checkFramebufferComplete("empty");
    FAIL() << "a framebuffer without attachments passed as complete";
  } catch (const vrm_gl::GlError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("framebuffer 'empty' is incomplete (status 0x8CD7)"), std::string::npos) << what;
  }
  // A depth format is no colour attachment: makeColorFramebuffer refuses it and leaves no framebuffer bound.
  const GLuint depth = vrm_gl::makeTexture(GL_DEPTH_COMPONENT24, 4, 4, GL_DEPTH_COMPONENT, GL_UNSIGNED_INT);
  EXPECT_THROW(vrm_gl::makeColorFramebuffer(depth, "depth_as_colour"), vrm_gl::GlError);
  GLint bound = -1;
  glGetIntegerv(GL_FRAMEBUFFER_BINDING, &bound);
  EXPECT_EQ(bound, 0);
}

}  // namespace
