#pragma once
// The GL context helper lives in package vrm_gl, so that vrm_sim's image-space collision detection and this
// renderer share one helper without a package cycle. Link it through catkin (COMPONENTS vrm_gl).
#include "vrm_gl/gl_context.h"

namespace vrm_render {
using vrm_gl::GlContext;
using vrm_gl::GlContextError;
using vrm_gl::GlContextOptions;
}  // namespace vrm_render
