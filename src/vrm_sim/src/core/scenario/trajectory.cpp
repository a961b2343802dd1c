// An abstract scenario of thesis §7.4.1 (a skill without anatomy). Geometry in the eye frame; the retina is the eye
// sphere unless the core simulates it.
#include <algorithm>
#include <string>
#include <vector>

#include "common.h"
#include "scenarios.h"

namespace vrm_sim {
namespace scenario {
namespace {

// Follow a path marked on the retina at a given height above it: from its first point to its last.
class Trajectory : public Scenario {
 public:
  explicit Trajectory(const scene::SceneDescription& scene) : contacts_(scene.eye.radius) {
    Params params(scene);
    const std::vector<Eigen::Vector3d> marked = params.points("path");
    if (marked.size() < 2) params.fail("path", "expected at least two points");
    const double height = params.number("height", 5e-4, 0.0, 5e-3);
    for (const Eigen::Vector3d& point : marked) {
      if (!(point.norm() > height)) params.fail("path", "a path point lies at the eye centre");
      path_.push_back(point * (1.0 - height / point.norm()));  // towards the eye centre, i.e. above the retina
    }
    length_ = pathLength(path_);
    tool_ = params.slot("tool", "right");
    tolerance_ = params.number("end_tolerance", 3e-4, 1e-5, 5e-3);
    finish_fraction_ = params.number("finish_fraction", 0.95, 0.1, 1.0);
    params.finish();
  }

  std::vector<Measurement> items() const override { return measurements(0.0); }

  void update(const FrameView& frame, double) override {
    contacts_.update(frame);
    const InstrumentView* tool = frame.instrument(tool_);
    if (tool == nullptr || !tool->valid) return;
    if (!started_) {
      started_ = (tool->tip - path_.front()).norm() < tolerance_;
      last_tip_ = tool->tip;
      if (!started_) return;
    }
    const PolylineProjection projection = projectOnPolyline(path_, tool->tip);
    deviation_.add(projection.distance);
    if (projection.distance < 3.0 * tolerance_) progress_ = std::max(progress_, projection.arc);
    if (frame.dt > 0.0) speed_.add((tool->tip - last_tip_).norm() / frame.dt);
    last_tip_ = tool->tip;
    finished_ = progress_ >= finish_fraction_ * length_ && (tool->tip - path_.back()).norm() < tolerance_;
  }

  bool succeeded() const override { return finished_; }

  std::vector<Measurement> measurements(double) const override {
    return {{"progress", length_ > 0.0 ? progress_ / length_ : 0.0, "1"},
            {"mean_deviation", deviation_.mean(), "m"},
            {"max_deviation", deviation_.max(), "m"},
            {"speed_variability", speed_.coefficientOfVariation(), "1"},
            {"retina_contacts", static_cast<double>(contacts_.count()), "1"}};
  }

  std::string progress() const override {
    if (!started_) return "bring the tip to the start of the path";
    return format("%.0f %% of the path", 100.0 * (length_ > 0.0 ? progress_ / length_ : 0.0));
  }

  void hash(std::uint64_t& state) const override {
    hashValue(state, started_);
    hashValue(state, progress_);
    hashValue(state, deviation_.mean());
    hashValue(state, deviation_.max());
    contacts_.hash(state);
  }

  void transferState(StateArchive& archive) override {
    archive.section("trajectory");
    archive(started_)(finished_)(progress_)(last_tip_)(deviation_)(speed_)(contacts_);
  }

 private:
  std::vector<Eigen::Vector3d> path_;
  double length_ = 0.0, tolerance_ = 3e-4, finish_fraction_ = 0.95;
  std::string tool_;
  bool started_ = false, finished_ = false;
  double progress_ = 0.0;
  Eigen::Vector3d last_tip_ = Eigen::Vector3d::Zero();
  RunningStats deviation_, speed_;
  RetinaContacts contacts_;
};

}  // namespace

std::unique_ptr<Scenario> makeTrajectory(const scene::SceneDescription& scene) {
  return std::make_unique<Trajectory>(scene);
}

}  // namespace scenario
}  // namespace vrm_sim
