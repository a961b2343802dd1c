#pragma once
// Shader programs, textures and framebuffer objects: the GL set-up the renderer (vrm_render) and the image-space
// collision detectors (vrm_sim, ZCOLL) share. Needs a current context (vrm_gl::GlContext). Objects are plain GL
// names; they die with their context (or glDelete*). ROS-free.

#ifndef GL_GLEXT_PROTOTYPES
#define GL_GLEXT_PROTOTYPES
#endif
#include <GL/gl.h>
#include <GL/glext.h>

#include <stdexcept>
#include <string>

namespace vrm_gl {

// A shader that does not compile, a program that does not link, an incomplete framebuffer; the message carries
// GL's info log or status.
class GlError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// One shader stage (GL_VERTEX_SHADER, GL_FRAGMENT_SHADER, ...). Throws GlError "shader '<name>' (<stage>) does not
// compile: <info log>"; nothing is left allocated then.
GLuint compileShader(GLenum stage, const std::string& source, const std::string& name);

// Compiles both stages and links them; the shaders are deleted again (the program keeps them). Throws GlError
// "program '<name>' does not link: <info log>" (or a compile error); nothing is left allocated then.
GLuint linkProgram(const std::string& vertex_source, const std::string& fragment_source, const std::string& name);

// A 2D texture of one level (GL_TEXTURE_MAX_LEVEL 0), uninitialised, min and mag filter `filter`, clamped to the
// edge; left bound to GL_TEXTURE_2D of the active unit.
GLuint makeTexture(GLint internal_format, int width, int height, GLenum format, GLenum type, GLint filter = GL_NEAREST);

// Throws GlError "framebuffer '<name>' is incomplete (status 0x...)" unless the framebuffer bound to GL_FRAMEBUFFER is
// complete.
void checkFramebufferComplete(const std::string& name);

// A framebuffer object with `texture` as colour attachment 0, left bound; checked for completeness.
GLuint makeColorFramebuffer(GLuint texture, const std::string& name);

}  // namespace vrm_gl
