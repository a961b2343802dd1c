// scenario_manager in a manager: a scripted grasp-and-pull with the forceps must deform the membrane (published on
// tissue/<object> with increasing versions), keep it finite, and let it return toward rest after the release.
// Every wait is on a condition with a timeout; nothing asserts on timing.
#include <gtest/gtest.h>
#include <ros/ros.h>

#include <Eigen/Geometry>
#include <cmath>
#include <functional>
#include <mutex>
#include <stdexcept>
#include <variant>

#include "vrm_msgs/InstrumentState.h"
#include "vrm_msgs/ScenarioCommand.h"
#include "vrm_msgs/StageTiming.h"
#include "vrm_msgs/TissueMesh.h"
#include "vrm_scene/scene_loader.h"
#include "vrm_sim/conversions.h"
#include "vrm_sim/testing/graph_test.h"
#include "vrm_sim/testing/sanitizer.h"

namespace {

using vrm_sim::testing::waitForSubscribers;

class MeshWatcher {
 public:
  MeshWatcher(ros::NodeHandle& nh, const std::string& topic, std::vector<float> rest) : rest_(std::move(rest)) {
    subscriber_ = nh.subscribe(topic, 10, &MeshWatcher::onMesh, this);
    timing_subscriber_ = nh.subscribe("tissue_timing", 10, &MeshWatcher::onTiming, this);
  }
  double displacement() {
    std::lock_guard<std::mutex> lock(mutex_);
    return displacement_;
  }
  double peak() {
    std::lock_guard<std::mutex> lock(mutex_);
    return peak_;
  }
  bool finite() {
    std::lock_guard<std::mutex> lock(mutex_);
    return finite_;
  }
  bool versionsIncrease() {
    std::lock_guard<std::mutex> lock(mutex_);
    return versions_increase_;
  }
  int meshes() {
    std::lock_guard<std::mutex> lock(mutex_);
    return meshes_;
  }
  int timings() {
    std::lock_guard<std::mutex> lock(mutex_);
    return timings_;
  }

 private:
  void onMesh(const vrm_msgs::TissueMesh::ConstPtr& mesh) {
    std::lock_guard<std::mutex> lock(mutex_);
    ++meshes_;
    if (mesh->version <= last_version_) versions_increase_ = false;
    last_version_ = mesh->version;
    if (mesh->positions.size() != rest_.size()) {
      finite_ = false;
      return;
    }
    double max_displacement = 0.0;
    for (std::size_t i = 0; i + 2 < rest_.size(); i += 3) {
      const double dx = mesh->positions[i] - rest_[i];
      const double dy = mesh->positions[i + 1] - rest_[i + 1];
      const double dz = mesh->positions[i + 2] - rest_[i + 2];
      const double d = std::sqrt(dx * dx + dy * dy + dz * dz);
      if (!std::isfinite(d)) finite_ = false;
      max_displacement = std::max(max_displacement, d);
    }
    displacement_ = max_displacement;
    peak_ = std::max(peak_, max_displacement);
  }
  void onTiming(const vrm_msgs::StageTiming::ConstPtr&) {
    std::lock_guard<std::mutex> lock(mutex_);
    ++timings_;
  }

  std::vector<float> rest_;
  ros::Subscriber subscriber_, timing_subscriber_;
  std::mutex mutex_;
  double displacement_ = 0.0, peak_ = 0.0;
  bool finite_ = true, versions_increase_ = true;
  std::uint64_t last_version_ = 0;
  int meshes_ = 0, timings_ = 0;
};

// Publishes the forceps state at 100 Hz (stamps from now) until `done` or the timeout.
bool drive(ros::Publisher& publisher, const std::function<void(double, vrm_msgs::InstrumentState&)>& script,
           double duration, const std::function<bool()>& done = nullptr) {
  ros::Rate rate(100.0);
  const ros::Time start = ros::Time::now();
  while (ros::ok()) {
    const double t = (ros::Time::now() - start).toSec();
    if (t > duration) return false;
    vrm_msgs::InstrumentState state;
    state.header.stamp = ros::Time::now();
    state.header.frame_id = "eye";
    state.instrument_id = "right";
    state.type = vrm_msgs::InstrumentState::FORCEPS;
    state.valid = true;
    state.tracking_quality = 1.0f;
    script(t, state);
    publisher.publish(state);
    if (done && done()) return true;
    rate.sleep();
  }
  return false;
}

// The membrane under test (params scene/object) and the vertex nearest its centroid, where the instruments work;
// the membrane faces the eye centre, so `inward` points from that vertex towards it.
struct MembraneUnderTest {
  std::string object_name;
  vrm_sim::TriangleMesh mesh;
  Eigen::Vector3d target = Eigen::Vector3d::Zero();
  Eigen::Vector3d inward = Eigen::Vector3d::Zero();
  // Instrument frame with +z (handle -> tip) pointing outward, towards the retina; origin at the eye centre.
  Eigen::Isometry3d outwardFacing() const {
    Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
    pose.linear() = Eigen::Quaterniond::FromTwoVectors(Eigen::Vector3d::UnitZ(), -inward).toRotationMatrix();
    return pose;
  }
};

MembraneUnderTest membraneUnderTest() {
  ros::NodeHandle private_nh("~");
  MembraneUnderTest membrane;
  const std::string scene_name = private_nh.param<std::string>("scene", "membrane_peeling");
  membrane.object_name = private_nh.param<std::string>("object", "membrane");
  const auto scene = vrm_sim::scene::loadScene(vrm_sim::scene::shippedScenePath(scene_name));
  const auto* object = scene.findObject(membrane.object_name);
  if (object == nullptr) throw std::runtime_error("scene has no object " + membrane.object_name);
  membrane.mesh = vrm_sim::scene::buildMesh(*object, vrm_sim::scene::MeshFrame::kParent);
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
  for (const auto& v : membrane.mesh.vertices) centroid += v / static_cast<double>(membrane.mesh.vertexCount());
  membrane.target = membrane.mesh.vertices.front();
  for (const auto& v : membrane.mesh.vertices) {
    if ((v - centroid).norm() < (membrane.target - centroid).norm()) membrane.target = v;
  }
  membrane.inward = -membrane.target.normalized();
  return membrane;
}

TEST(TissueDeformationGraph, GraspPullDeformsAndReleaseReturnsTowardRest) {
  ros::NodeHandle nh;
  const MembraneUnderTest membrane = membraneUnderTest();
  std::vector<float> rest;
  for (const auto& v : membrane.mesh.vertices) {
    rest.insert(rest.end(), {static_cast<float>(v.x()), static_cast<float>(v.y()), static_cast<float>(v.z())});
  }
  const Eigen::Vector3d& inward = membrane.inward;
  const double jaw_length = 0.0015;
  // The jaw centre straddles the membrane.
  const Eigen::Isometry3d pose = membrane.outwardFacing();
  const Eigen::Vector3d grasp_tip = membrane.target - inward * (0.5 * jaw_length);

  MeshWatcher watcher(nh, "tissue/" + membrane.object_name, rest);
  ros::Publisher publisher = nh.advertise<vrm_msgs::InstrumentState>("instrument_state", 20);
  ASSERT_TRUE(waitForSubscribers(publisher, 30.0)) << "scenario_manager does not subscribe instrument_state";
  ros::AsyncSpinner spinner(1);
  spinner.start();

  auto at = [&](const Eigen::Vector3d& tip, double jaw, vrm_msgs::InstrumentState& state) {
    Eigen::Isometry3d p = pose;
    p.translation() = tip;
    state.tip_pose = vrm_sim::toPoseMsg(p);
    state.jaw_angle = jaw;
  };
  // Jaws open at the membrane, then closed (grasp), then pull 1 mm inward over 0.5 s.
  drive(
      publisher, [&](double, vrm_msgs::InstrumentState& s) { at(grasp_tip, 0.5, s); }, 0.3);
  drive(
      publisher, [&](double, vrm_msgs::InstrumentState& s) { at(grasp_tip, 0.0, s); }, 0.2);
  drive(
      publisher,
      [&](double t, vrm_msgs::InstrumentState& s) { at(grasp_tip + inward * 1e-3 * std::min(t / 0.5, 1.0), 0.0, s); },
      0.7);
  // Wait (driving the held pose) until the membrane is deformed.
  drive(
      publisher, [&](double, vrm_msgs::InstrumentState& s) { at(grasp_tip + inward * 1e-3, 0.0, s); }, 20.0,
      [&] { return watcher.peak() > 4e-4; });
  const double peak = watcher.peak();
  EXPECT_GT(peak, 4e-4) << "the grasped membrane did not follow the forceps";
  EXPECT_TRUE(watcher.finite());
  // Release: open the jaws, withdraw; wait for the membrane to come back toward rest.
  const bool returned = drive(
      publisher, [&](double, vrm_msgs::InstrumentState& s) { at(grasp_tip + inward * 3e-3, 0.6, s); }, 30.0,
      [&] { return watcher.displacement() < 0.7 * peak; });
  EXPECT_TRUE(returned) << "displacement " << watcher.displacement() << " after release, peak " << peak;
  EXPECT_TRUE(watcher.finite());
  EXPECT_TRUE(watcher.versionsIncrease());
  EXPECT_GT(watcher.meshes(), 10);
  EXPECT_GT(watcher.timings(), 10);
}

// Topology of the published membrane: versions, triangle count, index validity.
class TopologyWatcher {
 public:
  TopologyWatcher(ros::NodeHandle& nh, const std::string& topic) {
    subscriber_ = nh.subscribe(topic, 10, &TopologyWatcher::onMesh, this);
  }
  std::uint64_t topologyVersion() {
    std::lock_guard<std::mutex> lock(mutex_);
    return topology_version_;
  }
  std::size_t triangles() {
    std::lock_guard<std::mutex> lock(mutex_);
    return triangles_;
  }
  bool consistent() {
    std::lock_guard<std::mutex> lock(mutex_);
    return consistent_;
  }

 private:
  void onMesh(const vrm_msgs::TissueMesh::ConstPtr& mesh) {
    std::lock_guard<std::mutex> lock(mutex_);
    topology_version_ = mesh->topology_version;
    triangles_ = mesh->triangles.size() / 3;
    const std::size_t nodes = mesh->positions.size() / 3;
    if (mesh->positions.size() % 3 != 0 || mesh->triangles.size() % 3 != 0) consistent_ = false;
    for (std::uint32_t index : mesh->triangles) consistent_ = consistent_ && index < nodes;
    for (float value : mesh->positions) consistent_ = consistent_ && std::isfinite(value);
  }

  ros::Subscriber subscriber_;
  std::mutex mutex_;
  std::uint64_t topology_version_ = 0;
  std::size_t triangles_ = 0;
  bool consistent_ = true;
};

// The vitrector (an alternative of the forceps' slot in this scene) removes membrane only while it aspirates and
// cuts: switched in by the message's type, held at the membrane with suction 0 (nothing removed), then with
// suction and cutter on (triangles removed, topology_version raised, indices valid).
TEST(TissueDeformationGraph, VitrectorCutsOnlyWithSuctionAndKeepsTheMeshConsistent) {
  ros::NodeHandle nh;
  const MembraneUnderTest membrane = membraneUnderTest();
  const auto vitrector = std::get<vrm_sim::scene::VitrectorParams>(
      vrm_sim::scene::defaultInstrumentParams(vrm_sim::scene::InstrumentType::kVitrector));
  // The port (cut_offset .. cut_offset + port_length behind the tip) straddles the membrane.
  Eigen::Isometry3d pose = membrane.outwardFacing();
  pose.translation() =
      membrane.target - membrane.inward * (vitrector.port_distance_from_tip + 0.5 * vitrector.port_length);

  TopologyWatcher watcher(nh, "tissue/" + membrane.object_name);
  ros::Publisher publisher = nh.advertise<vrm_msgs::InstrumentState>("instrument_state", 20);
  ASSERT_TRUE(waitForSubscribers(publisher, 30.0)) << "scenario_manager does not subscribe instrument_state";
  // The other test may have peeled this membrane: start from the rest state (applied with the next frame).
  ros::Publisher commands = nh.advertise<vrm_msgs::ScenarioCommand>("scenario_command", 1, true);
  ASSERT_TRUE(waitForSubscribers(commands, 30.0)) << "scenario_manager does not subscribe scenario_command";
  vrm_msgs::ScenarioCommand reset;
  reset.header.stamp = ros::Time::now();
  reset.command = vrm_msgs::ScenarioCommand::RESET;
  commands.publish(reset);
  ros::AsyncSpinner spinner(1);
  spinner.start();
  auto vitrectorAt = [&](double suction, vrm_msgs::InstrumentState& state) {
    state.type = vrm_msgs::InstrumentState::VITRECTOR;
    state.tip_pose = vrm_sim::toPoseMsg(pose);
    state.suction = suction;
    state.cut_rate = suction > 0.0 ? 2500.0 : 0.0;
  };
  // No suction: the vitrector only pushes; wait until the membrane is published whole (the RESET applied: a
  // membrane published before it is the other test's, which may be torn — on a slow machine that one can still come).
  // Under ASan the simulation runs far behind its inputs (the torn membrane was still published after 20 s there,
  // 2026-12-02), so it gets longer.
  const double reset_timeout = vrm_sim::testing::kUnderSanitizer ? 90.0 : 20.0;
  ASSERT_TRUE(drive(
      publisher, [&](double, vrm_msgs::InstrumentState& s) { vitrectorAt(0.0, s); }, reset_timeout,
      [&] { return watcher.topologyVersion() > 0 && watcher.triangles() == membrane.mesh.triangleCount(); }))
      << "the membrane was not published whole within " << reset_timeout << " s of the RESET (" << watcher.triangles()
      << " of " << membrane.mesh.triangleCount() << " triangles)";
  drive(
      publisher, [&](double, vrm_msgs::InstrumentState& s) { vitrectorAt(0.0, s); }, 0.3);
  const std::uint64_t version_before = watcher.topologyVersion();
  const std::size_t triangles_before = watcher.triangles();
  ASSERT_GT(version_before, 0u) << "no membrane published";
  ASSERT_EQ(triangles_before, membrane.mesh.triangleCount()) << "the membrane lost triangles without suction";
  // Suction and cutter on: tissue in the port is removed.
  const bool cut = drive(
      publisher, [&](double, vrm_msgs::InstrumentState& s) { vitrectorAt(0.6, s); }, 20.0,
      [&] { return watcher.topologyVersion() > version_before && watcher.triangles() < triangles_before; });
  EXPECT_TRUE(cut) << "topology_version " << watcher.topologyVersion() << ", triangles " << watcher.triangles();
  EXPECT_TRUE(watcher.consistent()) << "a published mesh had an index past its nodes or a non-finite position";
}

}  // namespace

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_tissue_deformation");
  return RUN_ALL_TESTS();
}
