// scenario_manager's collision detection in a manager: the light pipe, posed in the world frame of an eye rotated by
// 20°, is pushed 0.15 mm through the membrane along the membrane's normal. Expected: CollisionReports (stamped with the
// input stamps, in the eye frame, from the scene's detector) with colliding triangles and deformation vectors along
// the normal, no longer than the penetration; markers for exactly the colliding triangles; the membrane pushed
// along the normal; a collision stage in the StageTiming; and no collision once withdrawn. Every wait is on a
// condition with a timeout; nothing asserts on timing.
#include <gtest/gtest.h>
#include <ros/ros.h>
#include <visualization_msgs/MarkerArray.h>

#include <Eigen/Geometry>
#include <cmath>
#include <functional>
#include <mutex>
#include <set>

#include "vrm_msgs/CollisionReport.h"
#include "vrm_msgs/EyeState.h"
#include "vrm_msgs/InstrumentState.h"
#include "vrm_msgs/StageTiming.h"
#include "vrm_msgs/TissueMesh.h"
#include "vrm_scene/scene_loader.h"
#include "vrm_sim/conversions.h"
#include "vrm_sim/testing/graph_test.h"

namespace {

using Eigen::Vector3d;
using vrm_sim::testing::waitFor;
using vrm_sim::testing::waitForSubscribers;

struct Observed {
  int reports = 0, colliding_reports = 0, non_colliding_since_reset = 0;
  std::size_t max_triangles = 0;
  double max_deformation = 0.0;  // m
  double min_alignment = 1.0;    // cos of the angle between deformation vectors and the membrane normal
  double max_pixel_size = 0.0;   // m
  bool stamps_known = true, frames_ok = true, names_ok = true, sizes_ok = true;
  std::string bad_names;
  int markers_with_triangles = 0;
  bool markers_match = true;
  double displacement_along_normal = 0.0;  // membrane, peak over all meshes
  bool collision_stage = false;
};

class Watcher {
 public:
  Watcher(ros::NodeHandle& nh, const std::string& object, const std::string& detector, std::vector<Vector3d> rest,
          const Vector3d& normal)
      : object_(object), detector_(detector), rest_(std::move(rest)), normal_(normal) {
    report_subscriber_ = nh.subscribe("collision_report", 50, &Watcher::onReport, this);
    marker_subscriber_ = nh.subscribe("collision_markers", 50, &Watcher::onMarkers, this);
    mesh_subscriber_ = nh.subscribe("tissue/" + object, 10, &Watcher::onMesh, this);
    timing_subscriber_ = nh.subscribe("tissue_timing", 10, &Watcher::onTiming, this);
  }
  void published(const ros::Time& stamp) {
    std::lock_guard<std::mutex> lock(mutex_);
    stamps_.insert(stamp);
  }
  Observed observed() {
    std::lock_guard<std::mutex> lock(mutex_);
    return observed_;
  }
  void resetNonColliding() {
    std::lock_guard<std::mutex> lock(mutex_);
    observed_.non_colliding_since_reset = 0;
  }
  bool connected() const {
    return report_subscriber_.getNumPublishers() > 0 && marker_subscriber_.getNumPublishers() > 0 &&
           mesh_subscriber_.getNumPublishers() > 0;
  }

 private:
  void onReport(const vrm_msgs::CollisionReport::ConstPtr& report) {
    std::lock_guard<std::mutex> lock(mutex_);
    if (report->object_b != object_ || report->object_a != "instrument_left") return;
    ++observed_.reports;
    if (!stamps_.count(report->header.stamp)) observed_.stamps_known = false;
    if (report->header.frame_id != "eye") observed_.frames_ok = false;
    if (report->detector != detector_) {
      observed_.names_ok = false;
      observed_.bad_names = report->detector;
    }
    if (report->nodes.size() != report->deformations.size()) observed_.sizes_ok = false;
    observed_.max_pixel_size = std::max(observed_.max_pixel_size, report->pixel_size);
    if (!report->colliding) {
      ++observed_.non_colliding_since_reset;
      return;
    }
    ++observed_.colliding_reports;
    observed_.max_triangles = std::max(observed_.max_triangles, report->triangles.size());
    for (const auto& v : report->deformations) {
      const Vector3d d(v.x, v.y, v.z);
      observed_.max_deformation = std::max(observed_.max_deformation, d.norm());
      if (d.norm() > 1e-9) observed_.min_alignment = std::min(observed_.min_alignment, d.normalized().dot(normal_));
    }
  }
  void onMarkers(const visualization_msgs::MarkerArray::ConstPtr& markers) {
    std::lock_guard<std::mutex> lock(mutex_);
    for (const auto& marker : markers->markers) {
      if (marker.ns != object_ + "/left" || marker.action != visualization_msgs::Marker::ADD) continue;
      if (marker.type != visualization_msgs::Marker::TRIANGLE_LIST || marker.points.empty() ||
          marker.points.size() % 3 != 0 || marker.header.frame_id != "eye") {
        observed_.markers_match = false;
      }
      ++observed_.markers_with_triangles;
    }
  }
  void onMesh(const vrm_msgs::TissueMesh::ConstPtr& mesh) {
    std::lock_guard<std::mutex> lock(mutex_);
    if (mesh->positions.size() != 3 * rest_.size()) return;
    for (std::size_t i = 0; i < rest_.size(); ++i) {
      const Vector3d p(mesh->positions[3 * i], mesh->positions[3 * i + 1], mesh->positions[3 * i + 2]);
      observed_.displacement_along_normal = std::max(observed_.displacement_along_normal, (p - rest_[i]).dot(normal_));
    }
  }
  void onTiming(const vrm_msgs::StageTiming::ConstPtr& timing) {
    std::lock_guard<std::mutex> lock(mutex_);
    for (const auto& stage : timing->stages) {
      if (stage.stage == "collision_" + object_) observed_.collision_stage = true;
    }
  }

  const std::string object_, detector_;
  const std::vector<Vector3d> rest_;
  const Vector3d normal_;
  ros::Subscriber report_subscriber_, marker_subscriber_, mesh_subscriber_, timing_subscriber_;
  std::mutex mutex_;
  std::set<ros::Time> stamps_;
  Observed observed_;
};

TEST(CollisionGraph, PushedInstrumentReportsTrianglesAndNormalDeformations) {
  ros::NodeHandle nh;
  ros::NodeHandle private_nh("~");
  const std::string scene_name = private_nh.param<std::string>("scene", "membrane_peeling");
  const std::string object_name = private_nh.param<std::string>("object", "membrane");
  const std::string detector = private_nh.param<std::string>("detector", "zcoll_f");
  const auto scene = vrm_sim::scene::loadScene(vrm_sim::scene::shippedScenePath(scene_name));
  const auto* object = scene.findObject(object_name);
  ASSERT_NE(object, nullptr);
  const vrm_sim::TriangleMesh mesh = vrm_sim::scene::buildMesh(*object, vrm_sim::scene::MeshFrame::kParent);

  // The vertex nearest the centroid, and the membrane's area-weighted normal there, oriented away from the eye
  // centre (towards the retina): the light pipe points along it, so ZCOLL/F pushes the membrane that way.
  Vector3d centroid = Vector3d::Zero();
  for (const auto& v : mesh.vertices) centroid += v / static_cast<double>(mesh.vertexCount());
  std::size_t target = 0;
  for (std::size_t i = 0; i < mesh.vertices.size(); ++i) {
    if ((mesh.vertices[i] - centroid).norm() < (mesh.vertices[target] - centroid).norm()) target = i;
  }
  Vector3d normal = Vector3d::Zero();
  for (const auto& t : mesh.triangles) {
    if (t[0] != target && t[1] != target && t[2] != target) continue;
    normal += (mesh.vertices[t[1]] - mesh.vertices[t[0]]).cross(mesh.vertices[t[2]] - mesh.vertices[t[0]]);
  }
  normal.normalize();
  if (normal.dot(mesh.vertices[target]) < 0.0) normal = -normal;

  // The eye is rotated by 20° about x: a nodelet that ignored the world -> eye transform would miss the membrane by
  // ~4 mm (its radius is 2.5 mm) and push along a direction 20° off the normal.
  const Eigen::Quaterniond eye_rotation(Eigen::AngleAxisd(20.0 * M_PI / 180.0, Vector3d::UnitX()));
  Eigen::Isometry3d world_from_eye = Eigen::Isometry3d::Identity();
  world_from_eye.linear() = eye_rotation.toRotationMatrix();
  world_from_eye.translation() = scene.eye.centre_in_world;
  Eigen::Isometry3d tip_in_eye = Eigen::Isometry3d::Identity();
  tip_in_eye.linear() = Eigen::Quaterniond::FromTwoVectors(Vector3d::UnitZ(), normal).toRotationMatrix();

  Watcher watcher(nh, object_name, detector, mesh.vertices, normal);
  ros::Publisher instrument_publisher = nh.advertise<vrm_msgs::InstrumentState>("instrument_state", 20);
  ros::Publisher eye_publisher = nh.advertise<vrm_msgs::EyeState>("eye_state", 20);
  ASSERT_TRUE(waitForSubscribers(instrument_publisher, 30.0)) << "scenario_manager does not subscribe instrument_state";
  ASSERT_TRUE(waitForSubscribers(eye_publisher, 30.0)) << "scenario_manager does not subscribe eye_state";
  ASSERT_TRUE(waitFor([&] { return watcher.connected(); }, 30.0))
      << "scenario_manager does not advertise collision_report / collision_markers";
  ros::AsyncSpinner spinner(1);
  spinner.start();

  // Publishes eye and light pipe (tip at `offset` along the normal from the target vertex) at 100 Hz until `done`.
  const auto drive = [&](const std::function<double(double)>& offset, double duration,
                         const std::function<bool(const Observed&)>& done) {
    ros::Rate rate(100.0);
    const ros::WallTime start = ros::WallTime::now();
    while (ros::ok()) {
      const double t = (ros::WallTime::now() - start).toSec();
      if (done(watcher.observed())) return true;
      if (t > duration) return false;
      const ros::Time stamp = ros::Time::now();
      watcher.published(stamp);
      vrm_msgs::EyeState eye;
      eye.header.stamp = stamp;
      eye.header.frame_id = "world";
      eye.rotation.w = eye_rotation.w();
      eye.rotation.x = eye_rotation.x();
      eye.rotation.y = eye_rotation.y();
      eye.rotation.z = eye_rotation.z();
      eye.rotation_center.x = scene.eye.centre_in_world.x();
      eye.rotation_center.y = scene.eye.centre_in_world.y();
      eye.rotation_center.z = scene.eye.centre_in_world.z();
      eye.tracking_quality = 1.0f;
      eye.valid = true;
      eye_publisher.publish(eye);
      Eigen::Isometry3d tip = tip_in_eye;
      tip.translation() = mesh.vertices[target] + offset(t) * normal;
      vrm_msgs::InstrumentState state;
      state.header.stamp = stamp;
      state.header.frame_id = "world";
      state.instrument_id = "left";
      state.type = vrm_msgs::InstrumentState::LIGHT_PIPE;
      state.tip_pose = vrm_sim::toPoseMsg(world_from_eye * tip);
      state.valid = true;
      state.tracking_quality = 1.0f;
      instrument_publisher.publish(state);
      rate.sleep();
    }
    return false;
  };

  // 1 mm above the membrane (on the eye-centre side): reports, none colliding. The eye state is sent before every
  // instrument state, so after ten reports the nodelet knows the eye's rotation.
  ASSERT_TRUE(drive([](double) { return -1e-3; }, 20.0, [](const Observed& o) { return o.reports >= 10; }))
      << "no collision_report for the light pipe";
  EXPECT_EQ(watcher.observed().colliding_reports, 0) << "the light pipe 1 mm above the membrane collides";

  // Push to 0.15 mm through the membrane over 0.3 s, hold until the membrane gave way.
  const double depth = 1.5e-4;
  const bool pushed = drive([&](double t) { return -1e-3 + (1e-3 + depth) * std::min(t / 0.3, 1.0); }, 20.0,
                            [](const Observed& o) {
                              return o.colliding_reports >= 5 && o.markers_with_triangles >= 5 &&
                                     o.displacement_along_normal > 5e-5 && o.collision_stage;
                            });
  const Observed o = watcher.observed();
  EXPECT_TRUE(pushed) << "colliding reports " << o.colliding_reports << ", markers " << o.markers_with_triangles
                      << ", membrane displacement " << o.displacement_along_normal << " m, collision stage "
                      << o.collision_stage;
  EXPECT_GE(o.max_triangles, 2u) << "colliding triangles";
  EXPECT_GT(o.max_deformation, 0.0);
  // Eq. 4.2: along the instrument axis = the membrane normal, at most the penetration (+ a pixel and quantisation).
  EXPECT_GT(o.min_alignment, std::cos(2.0 * M_PI / 180.0)) << "deformation vectors not along the normal";
  EXPECT_LE(o.max_deformation, depth + 2.0 * o.max_pixel_size);
  EXPECT_GT(o.max_pixel_size, 0.0) << "image-space detectors report their pixel size";
  EXPECT_TRUE(o.stamps_known) << "report stamps must be input stamps";
  EXPECT_TRUE(o.frames_ok) << "reports in the membrane's frame (eye)";
  EXPECT_TRUE(o.names_ok) << "detector / object names: " << o.bad_names;
  EXPECT_TRUE(o.sizes_ok) << "one deformation per node";
  EXPECT_TRUE(o.markers_match) << "markers: TRIANGLE_LIST in the eye frame";

  // Withdraw: the collision ends.
  watcher.resetNonColliding();
  EXPECT_TRUE(
      drive([](double) { return -2e-3; }, 20.0, [](const Observed& o) { return o.non_colliding_since_reset >= 5; }))
      << "still colliding after the withdrawal";
}

}  // namespace

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_collision");
  return RUN_ALL_TESTS();
}
