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
uniform float u_focus;
invariant gl_Position;
out vec4 v_base;
// 1 - s / z at the vertex (z = clip w, the distance along the optical axis): affine in screen space, so interpolated
// without perspective it is exact per pixel — the fragment needs no depth reconstruction for its blur.
noperspective out float v_defocus;
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
#if FUNDUS
uniform float u_fundus_scale;   // texels per metre
uniform float u_fundus_offset;  // texel coordinate of x = 0
out vec2 v_fundus_uv;
#endif
#if METAL
out float v_object_z;
#endif
void main() {
  vec4 world = u_model * vec4(a_position, 1.0);
#if FUNDUS
  // The texture is the albedo; alpha carries the bleeding (fundus objects are opaque), one varying less.
  v_base = vec4(a_color.rgb, clamp(a_injury, 0.0, 1.0));
#else
  v_base = u_diffuse * a_color;
#endif
#if FUNDUS
  // The fundus texture is an orthographic map of the eye frame's x, y (FundusMap::texture); bleeding is mixed in
  // after the texture so that blood is blood-coloured on vessels and disc alike.
  v_fundus_uv = a_position.xy * u_fundus_scale + u_fundus_offset;
#else
  v_base.rgb = mix(v_base.rgb, u_blood, clamp(a_injury, 0.0, 1.0));
#endif
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
#if METAL
  v_object_z = a_position.z;
#endif
  gl_Position = u_view_proj * world;
  v_defocus = 1.0 - u_focus / gl_Position.w;
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
noperspective in float v_defocus;
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
#if FUNDUS
in vec2 v_fundus_uv;
uniform sampler2D u_fundus;
uniform vec3 u_blood;
#endif
#if METAL
in float v_object_z;
uniform float u_metallic;
uniform vec3 u_environment;  // the glow of the lit fundus that the metal mirrors
uniform float u_glow_length;
#endif
out vec4 frag;
uniform vec3 u_emission;  // light the object gives off (the laser's aiming beam), added after shading
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
uniform float u_coc_scale;  // blur circle in pixels per unit of |z - focus| / z (MicroscopeRig)
uniform float u_sheen;

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

// Depth of field by the objective's circle of confusion c (pixels, MicroscopeRig): the pixel is mixed with the
// fully blurred image by w = 1 - exp(-2 pi^2 (c/4)^2 / 16), the contrast a Gaussian of the blur disc's width
// (sigma = c / 4) leaves of a pattern with a 4-pixel period: the mix then has the blur's fine-detail contrast.
float dofWeight() {
  float c = u_coc_scale * v_defocus;  // |z - s| / z = |1 - s / z|; squared below
  return 1.0 - exp(-0.0771 * c * c);
}

void main() {
  vec4 base = v_base;
#if FUNDUS
  // texelFetch: the nearest texel without the sampler's filter and wrap logic (the cheapest fetch on llvmpipe;
  // bench_render); the coordinates stay inside the texture on the retina (|x|, |y| <= R).
  base = vec4(mix(base.rgb * texelFetch(u_fundus, ivec2(v_fundus_uv), 0).rgb, u_blood, base.a), 1.0);
#endif
  float alpha = mix(base.a * u_alpha_scale, dofWeight(), u_coc_alpha);
#if !LIGHTING
  frag = vec4(base.rgb * u_colour_scale + u_emission, alpha);
#else
  vec3 colour = base.rgb * u_ambient;
  vec3 to_light = u_light_pos - v_world;
  float d = length(to_light);
  vec3 l = to_light / max(d, 1e-9);
  float cone = smoothstep(u_cos_outer, u_cos_inner, dot(-l, u_light_dir));
  vec3 v = normalize(u_camera_pos - v_world);
  vec3 n = normalize(v_normal);
  if (!gl_FrontFacing) n = -n;
#if METAL
  vec3 specular_colour = mix(u_specular, base.rgb, u_metallic);
#else
  vec3 specular_colour = u_specular;
#endif
  float reflex = 0.0;
  if (cone > 0.0) {
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
    // Phong's cos^s lobe in Schlick's rational form t / (s - s t + t): no pow() per pixel (Schlick 1994).
    float t = max(dot(r, v), 0.0);
    float specular = diffuse > 0.0 ? t / (u_shininess - u_shininess * t + t) : 0.0;
    // Sheen: the wet film's reflex of the endoillumination grows towards grazing view (Schlick's Fresnel factor
    // (1 - n.v)^5, softened to linear for a rough film): where a lifted membrane tilts away from the retina.
    float grazing = 1.0 - abs(dot(n, v));
    reflex = cone * attenuation * visibility * u_sheen * grazing * (0.3 + 0.7 * diffuse);
    colour += cone * attenuation * visibility * (base.rgb * diffuse + specular_colour * specular);
  }
#if METAL
  // A metal mirrors its surroundings: below, the fundus lit by the light pipe (orange-red), above, the dark pupil;
  // the microscope's coaxial light gives the highlight along the shaft where the surface faces the objective.
  vec3 rv = reflect(-v, n);
  float below = clamp(0.5 - 0.5 * rv.z, 0.0, 1.0);
  float facing = max(dot(n, v), 0.0);
  float coaxial = facing * facing;
  coaxial *= coaxial;
  coaxial *= coaxial;
  vec3 mirror = base.rgb * (u_environment * below * below + u_ambient * (0.15 + 1.6 * coaxial));
  colour = mix(colour, mirror + (colour - base.rgb * u_ambient), u_metallic);
  // The light pipe's polished fibre end glows with the light it emits.
  colour += vec3(1.0, 0.97, 0.88) * 1.3 * smoothstep(-u_glow_length, 0.0, v_object_z) * step(0.0, u_glow_length - 1e-9);
#endif
  // Highlight shoulder (issue 33): the light pipe is the main light, so close to the fundus it lights the pale disc
  // (albedo ~0.9) beyond 1. Colours up to 0.75 pass unchanged (the ambient-only fill, 0.3 x albedo, and the lit
  // fundus stay linear, so the ambient-only variant still matches the lit one outside the cone); above, they approach
  // 1 (rationally: x / (1 + 4x) above the knee, unit slope there; cheaper than exp on llvmpipe), so the disc keeps its
  // cup and vessels instead of clipping to white.
  vec3 over = max(colour - 0.75, vec3(0.0));
  colour = min(colour, vec3(0.75)) + over / (1.0 + 4.0 * over) + u_emission;
  // The reflex is light reflected at the film's surface: on a translucent film it adds to what shows through
  // instead of being diluted by the film's opacity (premultiplied: colour a + reflex over dst (1 - a - reflex)).
  float lifted_alpha = min(1.0, alpha + reflex);
  vec3 film = (colour * alpha + vec3(reflex)) / max(lifted_alpha, 1e-4);
  colour = mix(film, colour + vec3(reflex), u_coc_alpha);
  alpha = mix(lifted_alpha, alpha, u_coc_alpha);
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

// Separable Gaussian with bilinear tap pairs: PAIRS 2 = 9 taps (5 fetches per direction), 3 = 13 taps (7 fetches).
inline constexpr const char* kBlurFragment = R"(
in vec2 v_uv;
out vec4 frag;
uniform sampler2D u_src;
uniform vec2 u_step;
uniform float u_weight[PAIRS + 1];
uniform float u_offset[PAIRS + 1];
void main() {
  vec4 c = texture(u_src, v_uv) * u_weight[0];
  for (int i = 1; i <= PAIRS; ++i) {
    c += (texture(u_src, v_uv + u_step * u_offset[i]) + texture(u_src, v_uv - u_step * u_offset[i])) * u_weight[i];
  }
  frag = c;
}
)";

}  // namespace shaders
}  // namespace vrm_render
