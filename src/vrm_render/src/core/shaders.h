#pragma once
// GLSL 3.30 core sources of the renderer's passes (thesis §7.4.2).

namespace vrm_render {
namespace shaders {

// Pass 2: per-vertex transform; lighting happens per pixel. The material colour, vertex colour and bleeding are
// combined per vertex (one varying instead of two, no per-pixel mix). gl_Position is invariant so the ambient-only
// and the lit variants rasterise exactly the same depths.
inline constexpr const char* kSceneVertex = R"(
layout(location = 0) in vec3 a_position;
layout(location = 1) in vec3 a_normal;
layout(location = 2) in vec4 a_color;
layout(location = 3) in float a_injury;
uniform mat4 u_model;
uniform mat3 u_normal_matrix;
uniform mat4 u_view_proj;
uniform mat4 u_light_view_proj;
uniform vec4 u_diffuse;
uniform vec3 u_blood;
invariant gl_Position;
out vec4 v_base;
#if LIGHTING
out vec3 v_world;
out vec3 v_normal;
#endif
#if BUMP
out vec3 v_object;
#endif
#if SHADOWS
out vec4 v_light_clip;
#endif
void main() {
  vec4 world = u_model * vec4(a_position, 1.0);
  v_base = u_diffuse * a_color;
  v_base.rgb = mix(v_base.rgb, u_blood, clamp(a_injury, 0.0, 1.0));
#if LIGHTING
  v_world = world.xyz;
  v_normal = u_normal_matrix * a_normal;
#endif
#if BUMP
  v_object = a_position;
#endif
#if SHADOWS
  v_light_clip = u_light_view_proj * world;
#endif
  gl_Position = u_view_proj * world;
}
)";

// Pass 2: Phong shading under the light pipe's spotlight (per pixel, with a soft cone edge and distance fall-off),
// shadow-map lookup with hardware 2x2 PCF, procedural bump mapping, vertex colour and bleeding. LIGHTING 0 is the
// ambient-only variant (u_colour_scale = ambient light; 1 for flat shading): the renderer draws it wherever the
// spotlight cone cannot reach, because llvmpipe evaluates both sides of every branch for every pixel.
// Alpha: the object's opacity for translucent objects (blended, destination alpha kept); for opaque ones the
// depth-of-field blend weight of the pixel (0 = on the focal plane .. 1 = fully blurred), read back with the colour.
inline constexpr const char* kSceneFragment = R"(
in vec4 v_base;
#if LIGHTING
in vec3 v_world;
in vec3 v_normal;
#endif
#if BUMP
in vec3 v_object;
#endif
#if SHADOWS
in vec4 v_light_clip;
#endif
out vec4 frag;
uniform float u_colour_scale;
uniform vec3 u_camera_pos;
uniform vec3 u_specular;
uniform float u_shininess;
uniform float u_ambient;
uniform vec3 u_light_pos;
uniform vec3 u_light_dir;
uniform float u_cos_outer;
uniform float u_cos_inner;
uniform float u_light_intensity;
uniform float u_light_range;
uniform sampler2DShadow u_shadow_map;
uniform float u_shadow_bias;
uniform float u_bump_amplitude;
uniform float u_alpha_scale;
uniform float u_coc_alpha;  // 1: opaque, alpha = DOF weight; 0: translucent, alpha = opacity
uniform float u_near;
uniform float u_far;
uniform float u_focus;
uniform float u_dof_range;

#if BUMP
// Gradient of a height field made of four plane waves in object coordinates (wavelengths 0.3-0.9 mm, directions
// and wavelengths not commensurate, so no visible grid): a cheap procedural normal map for the retina's fine relief,
// no texture memory and no seams.
vec3 bumpGradient(vec3 p) {
  const vec3 k1 = vec3(9100.0, 4300.0, 2100.0);
  const vec3 k2 = vec3(-3700.0, 8800.0, -5200.0);
  const vec3 k3 = vec3(2500.0, -1900.0, 12500.0);
  const vec3 k4 = vec3(-13100.0, -6900.0, 4700.0);
  vec3 q = p + 0.00012 * sin(vec3(dot(k2, p), dot(k3, p), dot(k1, p)) * 0.37);
  return k1 * cos(dot(k1, q)) + 0.7 * k2 * cos(dot(k2, q)) + 0.5 * k3 * cos(dot(k3, q)) + 0.4 * k4 * cos(dot(k4, q));
}
#endif

float dofWeight() {
  float z_ndc = gl_FragCoord.z * 2.0 - 1.0;
  float z = 2.0 * u_near * u_far / (u_far + u_near - z_ndc * (u_far - u_near));
  float w = clamp(abs(z - u_focus) / u_dof_range, 0.0, 1.0);
  return w * w * (3.0 - 2.0 * w);
}

void main() {
  vec4 base = v_base;
  float alpha = mix(base.a * u_alpha_scale, dofWeight(), u_coc_alpha);
#if !LIGHTING
  frag = vec4(base.rgb * u_colour_scale, alpha);
#else
  vec3 colour = base.rgb * u_ambient;
  vec3 to_light = u_light_pos - v_world;
  float d = length(to_light);
  vec3 l = to_light / max(d, 1e-9);
  float cone = smoothstep(u_cos_outer, u_cos_inner, dot(-l, u_light_dir));
  if (cone > 0.0) {
    vec3 n = normalize(v_normal);
    if (!gl_FrontFacing) n = -n;
#if BUMP
    vec3 g = u_bump_amplitude * bumpGradient(v_object);
    n = normalize(n - (g - dot(g, n) * n));
#endif
    float visibility = 1.0;
#if SHADOWS
    if (v_light_clip.w > 0.0) {
      vec3 s = v_light_clip.xyz / v_light_clip.w * 0.5 + 0.5;
      if (all(greaterThan(s, vec3(0.0))) && all(lessThan(s, vec3(1.0)))) {
        visibility = texture(u_shadow_map, vec3(s.xy, s.z - u_shadow_bias));
      }
    }
#endif
    float attenuation = u_light_intensity / (1.0 + d * d / (u_light_range * u_light_range));
    float diffuse = max(dot(n, l), 0.0);
    vec3 r = reflect(-l, n);
    vec3 v = normalize(u_camera_pos - v_world);
    // Phong's cos^s lobe in Schlick's rational form t / (s - s t + t): no pow() per pixel (Schlick 1994).
    float t = max(dot(r, v), 0.0);
    float specular = diffuse > 0.0 ? t / (u_shininess - u_shininess * t + t) : 0.0;
    colour += cone * attenuation * visibility * (base.rgb * diffuse + u_specular * specular);
  }
  frag = vec4(colour, alpha);
#endif
}
)";

// Pass 1: depth only, from the light pipe tip.
inline constexpr const char* kShadowVertex = R"(#version 330 core
layout(location = 0) in vec3 a_position;
uniform mat4 u_model;
uniform mat4 u_light_view_proj;
void main() { gl_Position = u_light_view_proj * u_model * vec4(a_position, 1.0); }
)";

inline constexpr const char* kShadowFragment = R"(#version 330 core
void main() {}
)";

// Pass 3 (depth of field) at reduced resolution: downsample, separable blur. The blend with the sharp image by the
// per-pixel weight (scene alpha) happens on the CPU while reading back (composeDepthOfField).
// One triangle covering the viewport, no vertex buffer.
inline constexpr const char* kFullscreenVertex = R"(#version 330 core
out vec2 v_uv;
void main() {
  vec2 p = vec2(float((gl_VertexID << 1) & 2), float(gl_VertexID & 2));
  v_uv = p;
  gl_Position = vec4(p * 2.0 - 1.0, 0.0, 1.0);
}
)";

inline constexpr const char* kCopyFragment = R"(#version 330 core
in vec2 v_uv;
out vec4 frag;
uniform sampler2D u_src;
void main() { frag = texture(u_src, v_uv); }
)";

// Separable 9-tap Gaussian with bilinear tap pairs: 5 fetches per direction.
inline constexpr const char* kBlurFragment = R"(#version 330 core
in vec2 v_uv;
out vec4 frag;
uniform sampler2D u_src;
uniform vec2 u_step;
uniform float u_weight[3];
uniform float u_offset[3];
void main() {
  vec4 c = texture(u_src, v_uv) * u_weight[0];
  for (int i = 1; i < 3; ++i) {
    c += (texture(u_src, v_uv + u_step * u_offset[i]) + texture(u_src, v_uv - u_step * u_offset[i])) * u_weight[i];
  }
  frag = c;
}
)";

}  // namespace shaders
}  // namespace vrm_render
