#include "vrm_render/render_state.h"

#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <iterator>
#include <sstream>
#include <type_traits>

#include "vrm_render/stereo_renderer.h"
#include "vrm_scene/hash.h"

namespace vrm_render {
namespace {

constexpr char kMagic[8] = {'V', 'R', 'M', 'F', 'R', 'A', 'M', 'E'};

// A field added to one of these structs must be added to the file too (and kRenderStateFormatVersion raised): these
// sizes fail the build until the serialisation below is looked at (x86-64 / aarch64 layouts).
static_assert(sizeof(RenderOptions) == 68, "RenderOptions changed: update render_state.cpp");
static_assert(sizeof(MicroscopeRig) == 60, "MicroscopeRig changed: update render_state.cpp");
static_assert(sizeof(MicroscopeState) == 32, "MicroscopeState changed: update render_state.cpp");
static_assert(sizeof(LightPipe) == 52, "LightPipe changed: update render_state.cpp");
static_assert(sizeof(FundusParams) == 40, "FundusParams changed: update render_state.cpp");
static_assert(sizeof(Material) == 64, "Material changed: update render_state.cpp");
static_assert(sizeof(ObjectStyle) == 80, "ObjectStyle changed: update render_state.cpp");
static_assert(sizeof(FundusBurn) == 20, "FundusBurn changed: update render_state.cpp");

class Writer {
 public:
  template <typename T>
  void put(const T& value) {
    static_assert(std::is_arithmetic<T>::value, "scalars only");
    bytes_.append(reinterpret_cast<const char*>(&value), sizeof(T));
  }
  void put(bool value) { put<std::uint8_t>(value ? 1 : 0); }
  template <typename Derived>
  void putMatrix(const Eigen::MatrixBase<Derived>& m) {
    for (Eigen::Index i = 0; i < m.size(); ++i) put<float>(m(i));
  }
  void put(const std::string& s) {
    put<std::uint64_t>(s.size());
    bytes_.append(s);
  }
  template <typename T>
  void putArray(const std::vector<T>& values) {
    put<std::uint64_t>(values.size());
    bytes_.append(reinterpret_cast<const char*>(values.data()), values.size() * sizeof(T));
  }
  std::string take() { return std::move(bytes_); }

 private:
  std::string bytes_;
};

class Reader {
 public:
  Reader(const std::string& bytes, const std::string& what) : bytes_(bytes), what_(what) {}
  [[noreturn]] void fail(const std::string& message) const {
    throw RenderStateError(what_ + ": " + message + " (at byte " + std::to_string(offset_) + " of " +
                           std::to_string(bytes_.size()) + ")");
  }
  void need(std::size_t n, const char* field) const {
    if (n > bytes_.size() - offset_) fail(std::string("truncated while reading ") + field);
  }
  template <typename T>
  T get(const char* field) {
    need(sizeof(T), field);
    T value;
    std::memcpy(&value, bytes_.data() + offset_, sizeof(T));
    offset_ += sizeof(T);
    return value;
  }
  bool getBool(const char* field) {
    const auto v = get<std::uint8_t>(field);
    if (v > 1) fail(std::string("bad boolean in ") + field);
    return v == 1;
  }
  template <typename Derived>
  void getMatrix(Eigen::MatrixBase<Derived>& m, const char* field) {
    for (Eigen::Index i = 0; i < m.size(); ++i) m(i) = get<float>(field);
  }
  std::string getString(const char* field) {
    const auto n = get<std::uint64_t>(field);
    need(n, field);
    std::string s = bytes_.substr(offset_, n);
    offset_ += n;
    return s;
  }
  template <typename T>
  std::vector<T> getArray(const char* field, std::size_t limit) {
    const auto n = get<std::uint64_t>(field);
    if (n > limit) fail(std::string(field) + ": " + std::to_string(n) + " values, more than " + std::to_string(limit));
    need(n * sizeof(T), field);
    std::vector<T> values(n);
    // An empty vector's data() may be null, and memcpy from or to null is undefined even for 0 bytes (UBSan).
    if (n > 0) std::memcpy(values.data(), bytes_.data() + offset_, n * sizeof(T));
    offset_ += n * sizeof(T);
    return values;
  }
  bool atEnd() const { return offset_ == bytes_.size(); }

 private:
  const std::string& bytes_;
  std::string what_;
  std::size_t offset_ = 0;
};

void putOptions(Writer& w, const RenderOptions& o) {
  w.put(o.width), w.put(o.height), w.put(o.stereo), w.put(o.shadow_pass), w.put(o.lighting), w.put(o.bump_mapping);
  w.put(o.fundus), w.put(o.dof_pass), w.put(o.light_partition), w.put(o.cache_static);
  w.put(o.static_pose_tolerance_px), w.put(o.shadow_map_size), w.put(o.dof_downsample), w.put(o.dof_sigma_px);
  w.put(o.dof_taps), w.put(o.ghost_alpha), w.putMatrix(o.background), w.putMatrix(o.blood_colour);
  w.put(o.time_passes);
}
RenderOptions getOptions(Reader& r) {
  RenderOptions o;
  o.width = r.get<int>("options.width");
  o.height = r.get<int>("options.height");
  o.stereo = r.getBool("options.stereo");
  o.shadow_pass = r.getBool("options.shadow_pass");
  o.lighting = r.getBool("options.lighting");
  o.bump_mapping = r.getBool("options.bump_mapping");
  o.fundus = r.getBool("options.fundus");
  o.dof_pass = r.getBool("options.dof_pass");
  o.light_partition = r.getBool("options.light_partition");
  o.cache_static = r.getBool("options.cache_static");
  o.static_pose_tolerance_px = r.get<float>("options.static_pose_tolerance_px");
  o.shadow_map_size = r.get<int>("options.shadow_map_size");
  o.dof_downsample = r.get<int>("options.dof_downsample");
  o.dof_sigma_px = r.get<float>("options.dof_sigma_px");
  o.dof_taps = r.get<int>("options.dof_taps");
  o.ghost_alpha = r.get<float>("options.ghost_alpha");
  r.getMatrix(o.background, "options.background");
  r.getMatrix(o.blood_colour, "options.blood_colour");
  o.time_passes = r.getBool("options.time_passes");
  return o;
}

void putRig(Writer& w, const MicroscopeRig& g) {
  w.putMatrix(g.objective), w.putMatrix(g.view_direction), w.putMatrix(g.up);
  w.put(g.field_width), w.put(g.stereo_baseline), w.put(g.near_plane), w.put(g.far_plane);
  w.put(g.objective_focal_length), w.put(g.aperture_diameter);
}
MicroscopeRig getRig(Reader& r) {
  MicroscopeRig g;
  r.getMatrix(g.objective, "rig.objective");
  r.getMatrix(g.view_direction, "rig.view_direction");
  r.getMatrix(g.up, "rig.up");
  g.field_width = r.get<float>("rig.field_width");
  g.stereo_baseline = r.get<float>("rig.stereo_baseline");
  g.near_plane = r.get<float>("rig.near_plane");
  g.far_plane = r.get<float>("rig.far_plane");
  g.objective_focal_length = r.get<float>("rig.objective_focal_length");
  g.aperture_diameter = r.get<float>("rig.aperture_diameter");
  return g;
}

void putLight(Writer& w, const LightPipe& l) {
  w.put(l.enabled), w.putMatrix(l.tip), w.putMatrix(l.direction), w.put(l.cone_half_angle_rad), w.put(l.cone_softness);
  w.put(l.intensity), w.put(l.range), w.put(l.shadow_near), w.put(l.shadow_far);
}
LightPipe getLight(Reader& r) {
  LightPipe l;
  l.enabled = r.getBool("light.enabled");
  r.getMatrix(l.tip, "light.tip");
  r.getMatrix(l.direction, "light.direction");
  l.cone_half_angle_rad = r.get<float>("light.cone_half_angle_rad");
  l.cone_softness = r.get<float>("light.cone_softness");
  l.intensity = r.get<float>("light.intensity");
  l.range = r.get<float>("light.range");
  l.shadow_near = r.get<float>("light.shadow_near");
  l.shadow_far = r.get<float>("light.shadow_far");
  return l;
}

void putFundus(Writer& w, const FundusParams& f) {
  w.put(f.seed), w.put(f.eye_radius), w.put(f.nasal_sign), w.put(f.disc_diameter), w.put(f.cup_to_disc);
  w.put(f.disc_fovea_distance), w.put(f.disc_above_fovea), w.put(f.macula_radius), w.put(f.fovea_radius);
  w.put(f.texture_size);
}
FundusParams getFundus(Reader& r) {
  FundusParams f;
  f.seed = r.get<std::uint32_t>("fundus.seed");
  f.eye_radius = r.get<float>("fundus.eye_radius");
  f.nasal_sign = r.get<float>("fundus.nasal_sign");
  f.disc_diameter = r.get<float>("fundus.disc_diameter");
  f.cup_to_disc = r.get<float>("fundus.cup_to_disc");
  f.disc_fovea_distance = r.get<float>("fundus.disc_fovea_distance");
  f.disc_above_fovea = r.get<float>("fundus.disc_above_fovea");
  f.macula_radius = r.get<float>("fundus.macula_radius");
  f.fovea_radius = r.get<float>("fundus.fovea_radius");
  f.texture_size = r.get<int>("fundus.texture_size");
  return f;
}

void putStyle(Writer& w, const ObjectStyle& s) {
  const Material& m = s.material;
  w.putMatrix(m.diffuse), w.putMatrix(m.specular), w.put(m.shininess), w.put(m.metallic), w.put(m.sheen);
  w.put(m.glow_tip_length);
  w.putMatrix(m.emission);
  w.put(s.casts_shadow), w.put(s.bump_mapped), w.put(s.fundus), w.put(s.ghost), w.put(s.deformable);
}
ObjectStyle getStyle(Reader& r, std::uint32_t version) {
  ObjectStyle s;
  Material& m = s.material;
  r.getMatrix(m.diffuse, "style.diffuse");
  r.getMatrix(m.specular, "style.specular");
  m.shininess = r.get<float>("style.shininess");
  m.metallic = r.get<float>("style.metallic");
  m.sheen = r.get<float>("style.sheen");
  m.glow_tip_length = r.get<float>("style.glow_tip_length");
  if (version >= 2) r.getMatrix(m.emission, "style.emission");
  s.casts_shadow = r.getBool("style.casts_shadow");
  s.bump_mapped = r.getBool("style.bump_mapped");
  s.fundus = r.getBool("style.fundus");
  s.ghost = r.getBool("style.ghost");
  s.deformable = r.getBool("style.deformable");
  return s;
}

bool finite(const std::vector<float>& v) {
  for (float x : v) {
    if (!std::isfinite(x)) return false;
  }
  return true;
}

}  // namespace

void validateRenderState(const RenderState& state) {
  auto fail = [](const std::string& message) { throw RenderStateError("render state: " + message); };
  const RenderOptions& o = state.options;
  if (o.width <= 0 || o.height <= 0 || o.width > StereoRenderer::kMaxImageSide ||
      o.height > StereoRenderer::kMaxImageSide) {
    fail("image size " + std::to_string(o.width) + "x" + std::to_string(o.height) + " out of range");
  }
  const MicroscopeState& m = state.microscope;
  if (!std::isfinite(m.focus_distance) || !std::isfinite(m.zoom) || !std::isfinite(m.ambient_light) ||
      !std::isfinite(m.disparity_scale)) {
    fail("non-finite microscope knob");
  }
  const LightPipe& l = state.light;
  if (!l.tip.allFinite() || !l.direction.allFinite() || !std::isfinite(l.cone_half_angle_rad) ||
      !std::isfinite(l.cone_softness) || !std::isfinite(l.intensity) || !std::isfinite(l.range)) {
    fail("non-finite light pipe");
  }
  if (state.has_fundus && (state.fundus.texture_size < 16 || state.fundus.texture_size > 8192 ||
                           !std::isfinite(state.fundus.eye_radius) || state.fundus.eye_radius <= 0.0f)) {
    fail("bad fundus parameters (texture_size " + std::to_string(state.fundus.texture_size) + ")");
  }
  for (const FundusBurn& burn : state.burns) {
    if (!burn.position.allFinite() || !std::isfinite(burn.diameter) || !std::isfinite(burn.whiteness)) {
      fail("non-finite burn");
    }
  }
  for (const RenderState::Object& object : state.objects) {
    const std::string prefix = "object '" + object.id + "': ";
    if (!object.pose.matrix().allFinite()) fail(prefix + "non-finite pose");
    if (!object.has_mesh) continue;
    const MeshData& mesh = object.mesh;
    const std::size_t vertices = mesh.positions.size() / 3;
    if (vertices == 0 || mesh.positions.size() % 3 || mesh.triangles.empty() || mesh.triangles.size() % 3) {
      fail(prefix + "empty or ragged mesh");
    }
    if ((!mesh.normals.empty() && mesh.normals.size() != 3 * vertices) ||
        (!mesh.colors.empty() && mesh.colors.size() != 4 * vertices) ||
        (!mesh.injury.empty() && mesh.injury.size() != vertices)) {
      fail(prefix + "attribute arrays of the wrong length");
    }
    if (!finite(mesh.positions) || !finite(mesh.normals) || !finite(mesh.colors) || !finite(mesh.injury)) {
      fail(prefix + "non-finite mesh values");
    }
    for (std::uint32_t index : mesh.triangles) {
      if (index >= vertices) fail(prefix + "triangle index " + std::to_string(index) + " out of range");
    }
  }
}

std::string encodeRenderState(const RenderState& state) {
  Writer w;
  std::string magic(kMagic, sizeof(kMagic));
  std::string bytes = magic;
  w.put(kRenderStateFormatVersion);
  putOptions(w, state.options);
  putRig(w, state.rig);
  w.put(state.microscope.focus_distance), w.put(state.microscope.zoom), w.put(state.microscope.ambient_light);
  w.put(state.microscope.disparity_scale);
  putLight(w, state.light);
  w.put(state.has_fundus);
  putFundus(w, state.fundus);
  w.put(state.fundus_texture_hash);
  w.put<std::uint64_t>(state.objects.size());
  for (const RenderState::Object& object : state.objects) {
    w.put(object.id);
    w.put(object.has_mesh), w.put(object.version), w.put(object.visible);
    putStyle(w, object.style);
    w.putMatrix(Eigen::Matrix<float, 3, 4>(object.pose.matrix().topRows<3>()));
    w.putArray(object.mesh.positions), w.putArray(object.mesh.normals), w.putArray(object.mesh.colors);
    w.putArray(object.mesh.injury), w.putArray(object.mesh.triangles);
  }
  w.put<std::uint64_t>(state.burns.size());
  for (const FundusBurn& burn : state.burns) {
    w.putMatrix(burn.position);
    w.put(burn.diameter), w.put(burn.whiteness);
  }
  return bytes + w.take();
}

RenderState decodeRenderState(const std::string& bytes, const std::string& what) {
  if (bytes.size() < sizeof(kMagic) || std::memcmp(bytes.data(), kMagic, sizeof(kMagic)) != 0) {
    throw RenderStateError(what + ": not a render state file (no VRMFRAME magic)");
  }
  const std::string body = bytes.substr(sizeof(kMagic));
  Reader r(body, what);
  const auto version = r.get<std::uint32_t>("format version");
  if (version != kRenderStateFormatVersion && version != 1) {
    r.fail("format version " + std::to_string(version) + ", this reader knows 1 to " +
           std::to_string(kRenderStateFormatVersion));
  }
  RenderState state;
  state.options = getOptions(r);
  state.rig = getRig(r);
  state.microscope.focus_distance = r.get<double>("microscope.focus_distance");
  state.microscope.zoom = r.get<double>("microscope.zoom");
  state.microscope.ambient_light = r.get<double>("microscope.ambient_light");
  state.microscope.disparity_scale = r.get<double>("microscope.disparity_scale");
  state.light = getLight(r);
  state.has_fundus = r.getBool("has_fundus");
  state.fundus = getFundus(r);
  state.fundus_texture_hash = r.get<std::uint64_t>("fundus texture hash");
  const auto count = r.get<std::uint64_t>("object count");
  if (count > 100000) r.fail(std::to_string(count) + " objects");
  constexpr std::size_t kV = StereoRenderer::kMaxVertices;
  for (std::uint64_t i = 0; i < count; ++i) {
    RenderState::Object object;
    object.id = r.getString("object id");
    object.has_mesh = r.getBool("object.has_mesh");
    object.version = r.get<std::uint64_t>("object.version");
    object.visible = r.getBool("object.visible");
    object.style = getStyle(r, version);
    Eigen::Matrix<float, 3, 4> pose;
    r.getMatrix(pose, "object.pose");
    object.pose.matrix().topRows<3>() = pose;
    object.mesh.positions = r.getArray<float>("mesh.positions", 3 * kV);
    object.mesh.normals = r.getArray<float>("mesh.normals", 3 * kV);
    object.mesh.colors = r.getArray<float>("mesh.colors", 4 * kV);
    object.mesh.injury = r.getArray<float>("mesh.injury", kV);
    object.mesh.triangles = r.getArray<std::uint32_t>("mesh.triangles", 3 * StereoRenderer::kMaxTriangles);
    state.objects.push_back(std::move(object));
  }
  if (version >= 2) {
    const auto burns = r.get<std::uint64_t>("burn count");
    if (burns > 1000000) r.fail(std::to_string(burns) + " burns");
    for (std::uint64_t i = 0; i < burns; ++i) {
      FundusBurn burn;
      r.getMatrix(burn.position, "burn.position");
      burn.diameter = r.get<float>("burn.diameter");
      burn.whiteness = r.get<float>("burn.whiteness");
      state.burns.push_back(burn);
    }
  }
  if (!r.atEnd()) r.fail("trailing bytes after the last burn");
  try {
    validateRenderState(state);
  } catch (const RenderStateError& e) {
    throw RenderStateError(what + ": " + e.what());
  }
  return state;
}

void writeRenderState(const RenderState& state, const std::string& path) {
  validateRenderState(state);
  const std::string bytes = encodeRenderState(state);
  const std::string temporary = path + ".tmp";
  {
    std::ofstream out(temporary, std::ios::binary | std::ios::trunc);
    out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
    if (!out) throw RenderStateError("cannot write " + temporary);
  }
  if (std::rename(temporary.c_str(), path.c_str()) != 0) throw RenderStateError("cannot rename to " + path);
}

RenderState readRenderState(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw RenderStateError(path + ": cannot open");
  const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  return decodeRenderState(bytes, path);
}

std::uint64_t fundusTextureHash(const FundusMap& fundus) {
  const auto& texels = fundus.texture();
  return vrm_sim::hashBytes(vrm_sim::kHashSeed, texels.data(), texels.size());
}

}  // namespace vrm_render
