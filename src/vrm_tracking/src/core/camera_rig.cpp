#include "vrm_tracking/camera_rig.h"

#include <yaml-cpp/yaml.h>

#include <cmath>
#include <fstream>
#include <optional>
#include <sstream>
#include <stdexcept>

#include "vrm_scene/yaml/strict_reader.h"

namespace vrm_tracking {

namespace {
constexpr double kPi = 3.14159265358979323846;
constexpr double kMinDepth = 1e-3;  // m: a marker closer than this to a camera centre is not imaged

using vrm_sim::yaml::Field;
using vrm_sim::yaml::MapFields;

// A calibration matrix as camera_calibration_parsers writes it ({rows, cols, data: [...]}) or a plain list of its
// values; rows, cols < 0: any number of values (and any rows/cols given).
std::vector<double> readMatrix(const Field& field, int rows, int cols) {
  std::optional<Field> data;
  std::optional<MapFields> map;
  if (field.node().IsMap()) {
    map.emplace(field);
    data = map->required("data");
    // rows and cols are optional; when given they must be the expected shape.
    const std::optional<Field> rows_field = map->optional("rows"), cols_field = map->optional("cols");
    const int given_rows = rows_field ? rows_field->integer(1, 64) : rows;
    const int given_cols = cols_field ? cols_field->integer(1, 64) : cols;
    if (rows > 0 && (given_rows != rows || given_cols != cols)) {
      field.fail("expected a " + std::to_string(rows) + "x" + std::to_string(cols) + " matrix, got " +
                 std::to_string(given_rows) + "x" + std::to_string(given_cols));
    }
    map->finish();
  } else {
    data = field;
  }
  const std::vector<Field> items = data->items();
  if (rows > 0 && static_cast<int>(items.size()) != rows * cols) {
    data->fail("expected " + std::to_string(rows * cols) + " values, got " + std::to_string(items.size()));
  }
  std::vector<double> values;
  for (const Field& item : items) values.push_back(item.finite());
  return values;
}

CameraModel readCamera(const Field& field) {
  MapFields fields(field);
  CameraModel cam;
  cam.width = fields.required("image_width").integer(1, 100000);
  cam.height = fields.required("image_height").integer(1, 100000);
  if (auto name = fields.optional("camera_name")) cam.name = name->text();
  const Field k_field = fields.required("camera_matrix");
  const std::vector<double> k = readMatrix(k_field, 3, 3);
  cam.K = Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>(k.data());
  if (!(cam.K(0, 0) > 0.0 && cam.K(1, 1) > 0.0)) k_field.fail("the focal lengths must be positive");
  std::string model = "plumb_bob";
  if (auto model_field = fields.optional("distortion_model")) {
    // rational_polynomial files are accepted when their extra coefficients are zero (checked below).
    model = model_field->name({"plumb_bob", "rational_polynomial"});
  }
  if (auto d_field = fields.optional("distortion_coefficients")) {
    cam.distortion = readMatrix(*d_field, -1, -1);
    for (std::size_t i = 5; i < cam.distortion.size(); ++i) {
      if (cam.distortion[i] != 0.0) d_field->fail("only the 5 plumb_bob coefficients are supported");
    }
    cam.distortion.resize(5, 0.0);
  }
  // Written by the standard format; the rig's cameras are unrectified, so they are checked, not used.
  if (auto rectification = fields.optional("rectification_matrix")) readMatrix(*rectification, 3, 3);
  if (auto projection = fields.optional("projection_matrix")) readMatrix(*projection, 3, 4);
  if (auto extrinsics = fields.optional("world_to_camera")) {
    MapFields ext(*extrinsics);
    const Field rotation_field = ext.required("rotation");
    const std::vector<double> r = readMatrix(rotation_field, 3, 3);
    const Field translation_field = ext.required("translation");
    const std::vector<double> t = readMatrix(translation_field, -1, -1);
    if (t.size() != 3) translation_field.fail("expected 3 values");
    ext.finish();
    const Eigen::Matrix3d rotation = Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>(r.data());
    if ((rotation * rotation.transpose() - Eigen::Matrix3d::Identity()).norm() > 1e-6 || rotation.determinant() < 0.0) {
      rotation_field.fail("not a rotation matrix");
    }
    cam.world_to_camera.linear() = rotation;
    cam.world_to_camera.translation() = Eigen::Vector3d(t[0], t[1], t[2]);
  }
  fields.finish();
  return cam;
}

void emitMatrix(YAML::Emitter* out, const char* key, int rows, int cols, const std::vector<double>& data) {
  *out << YAML::Key << key << YAML::Value << YAML::BeginMap;
  *out << YAML::Key << "rows" << YAML::Value << rows << YAML::Key << "cols" << YAML::Value << cols;
  *out << YAML::Key << "data" << YAML::Value << YAML::Flow << YAML::BeginSeq;
  for (double v : data) *out << v;
  *out << YAML::EndSeq << YAML::EndMap;
}
}  // namespace

bool CameraModel::hasDistortion() const {
  for (double d : distortion) {
    if (d != 0.0) return true;
  }
  return false;
}

Eigen::Vector2d CameraModel::distortNormalised(const Eigen::Vector2d& xy) const {
  if (!hasDistortion()) return xy;
  auto k = [&](std::size_t i) { return i < distortion.size() ? distortion[i] : 0.0; };
  const double x = xy.x(), y = xy.y();
  const double r2 = x * x + y * y;
  const double radial = 1.0 + k(0) * r2 + k(1) * r2 * r2 + k(4) * r2 * r2 * r2;
  return {x * radial + 2.0 * k(2) * x * y + k(3) * (r2 + 2.0 * x * x),
          y * radial + k(2) * (r2 + 2.0 * y * y) + 2.0 * k(3) * x * y};
}

bool CameraModel::project(const Eigen::Vector3d& p_world, Eigen::Vector2d* pixel) const {
  const Eigen::Vector3d p = world_to_camera * p_world;
  if (!(p.z() > kMinDepth) || !p.allFinite()) return false;
  const Eigen::Vector2d xy = distortNormalised(Eigen::Vector2d(p.x() / p.z(), p.y() / p.z()));
  *pixel = Eigen::Vector2d(K(0, 0) * xy.x() + K(0, 1) * xy.y() + K(0, 2), K(1, 1) * xy.y() + K(1, 2));
  return true;
}

bool CameraModel::inImage(const Eigen::Vector2d& pixel, double margin) const {
  // Pixel centres at integers: the image spans [-0.5, width - 0.5).
  return pixel.x() >= margin - 0.5 && pixel.y() >= margin - 0.5 && pixel.x() < width - 0.5 - margin &&
         pixel.y() < height - 0.5 - margin;
}

Eigen::Vector2d CameraModel::normalise(const Eigen::Vector2d& pixel) const {
  const double y = (pixel.y() - K(1, 2)) / K(1, 1);
  const double x = (pixel.x() - K(0, 2) - K(0, 1) * y) / K(0, 0);
  const Eigen::Vector2d distorted(x, y);
  if (!hasDistortion()) return distorted;
  // Fixed-point inversion (as cv::undistortPoints); converges for the mild distortion of measurement optics.
  Eigen::Vector2d xy = distorted;
  for (int i = 0; i < 20; ++i) xy += distorted - distortNormalised(xy);
  return xy;
}

CameraModel lookAtCamera(const std::string& name, int width, int height, double focal_px,
                         const Eigen::Vector3d& position, const Eigen::Vector3d& target,
                         const Eigen::Vector3d& image_x_hint) {
  CameraModel cam;
  cam.name = name;
  cam.width = width;
  cam.height = height;
  cam.K << focal_px, 0.0, (width - 1) / 2.0, 0.0, focal_px, (height - 1) / 2.0, 0.0, 0.0, 1.0;
  const Eigen::Vector3d z = (target - position).normalized();
  Eigen::Vector3d x = image_x_hint - image_x_hint.dot(z) * z;
  if (x.squaredNorm() < 1e-12) x = z.unitOrthogonal();
  x.normalize();
  const Eigen::Vector3d y = z.cross(x);
  Eigen::Matrix3d camera_to_world;
  camera_to_world << x, y, z;
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.linear() = camera_to_world;
  pose.translation() = position;
  cam.world_to_camera = pose.inverse();
  return cam;
}

CameraRig makeDefaultRig(const DefaultRigGeometry& g) {
  CameraRig rig;
  const double tilt = g.tilt_deg * kPi / 180.0;
  for (int i = 0; i < 3; ++i) {
    const double az = (g.azimuth0_deg + 120.0 * i) * kPi / 180.0;
    const Eigen::Vector3d position(g.distance * std::sin(tilt) * std::cos(az),
                                   g.distance * std::sin(tilt) * std::sin(az), -g.distance * std::cos(tilt));
    const Eigen::Vector3d z = -position.normalized();
    const Eigen::Vector3d horizontal = z.cross(Eigen::Vector3d::UnitZ()).normalized();
    // Portrait: image x runs in the vertical plane of the camera (towards +z in the world).
    const Eigen::Vector3d hint = g.portrait ? Eigen::Vector3d(z.cross(horizontal)) : horizontal;
    rig.cameras.push_back(lookAtCamera("camera_" + std::to_string(i), g.width, g.height, g.focal_px, position,
                                       Eigen::Vector3d::Zero(), hint));
  }
  return rig;
}

CameraModel cameraFromYaml(const YAML::Node& node, const std::string& source) {
  return readCamera(Field(node, "", source));
}

void cameraToYaml(const CameraModel& cam, YAML::Emitter* out) {
  YAML::Emitter& o = *out;
  o << YAML::BeginMap;
  o << YAML::Key << "image_width" << YAML::Value << cam.width;
  o << YAML::Key << "image_height" << YAML::Value << cam.height;
  o << YAML::Key << "camera_name" << YAML::Value << cam.name;
  std::vector<double> k(9), p(12, 0.0), rect = {1, 0, 0, 0, 1, 0, 0, 0, 1};
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) {
      k[3 * r + c] = cam.K(r, c);
      p[4 * r + c] = cam.K(r, c);
    }
  }
  emitMatrix(out, "camera_matrix", 3, 3, k);
  o << YAML::Key << "distortion_model" << YAML::Value << "plumb_bob";
  std::vector<double> d = cam.distortion;
  d.resize(5, 0.0);
  emitMatrix(out, "distortion_coefficients", 1, 5, d);
  emitMatrix(out, "rectification_matrix", 3, 3, rect);
  emitMatrix(out, "projection_matrix", 3, 4, p);
  o << YAML::Key << "world_to_camera" << YAML::Value << YAML::BeginMap;
  std::vector<double> r(9);
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) r[3 * i + j] = cam.world_to_camera.linear()(i, j);
  }
  emitMatrix(out, "rotation", 3, 3, r);
  const Eigen::Vector3d t = cam.world_to_camera.translation();
  o << YAML::Key << "translation" << YAML::Value << YAML::Flow << YAML::BeginSeq << t.x() << t.y() << t.z()
    << YAML::EndSeq;
  o << YAML::EndMap;
  o << YAML::EndMap;
}

CameraModel loadCameraYaml(const std::string& path) {
  return readCamera(vrm_sim::yaml::parseText(vrm_sim::yaml::readFile(path, "camera calibration"), path));
}

void saveCameraYaml(const CameraModel& camera, const std::string& path) {
  YAML::Emitter out;
  out.SetDoublePrecision(17);
  cameraToYaml(camera, &out);
  std::ofstream file(path);
  if (!file) throw std::runtime_error(path + ": cannot write");
  file << out.c_str() << "\n";
}

CameraRig rigFromYamlString(const std::string& text, const std::string& source) {
  MapFields fields(vrm_sim::yaml::parseText(text, source));
  const Field cameras = fields.required("cameras");
  CameraRig rig;
  for (const Field& camera : cameras.items()) rig.cameras.push_back(readCamera(camera));
  if (rig.cameras.empty()) cameras.fail("expected a non-empty list of camera calibrations");
  fields.finish();
  return rig;
}

CameraRig loadRigYaml(const std::string& path) {
  return rigFromYamlString(vrm_sim::yaml::readFile(path, "rig calibration"), path);
}

std::string rigToYamlString(const CameraRig& rig) {
  YAML::Emitter out;
  out.SetDoublePrecision(17);
  out << YAML::BeginMap << YAML::Key << "cameras" << YAML::Value << YAML::BeginSeq;
  for (const CameraModel& cam : rig.cameras) cameraToYaml(cam, &out);
  out << YAML::EndSeq << YAML::EndMap;
  return std::string(out.c_str()) + "\n";
}

void saveRigYaml(const CameraRig& rig, const std::string& path) {
  std::ofstream file(path);
  if (!file) throw std::runtime_error(path + ": cannot write");
  file << rigToYamlString(rig);
}

}  // namespace vrm_tracking
