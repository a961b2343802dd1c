// An abstract scenario of thesis §7.4.1 (a skill without anatomy). Geometry in the eye frame; the retina is the eye
// sphere unless the core simulates it.
#include <cmath>
#include <string>
#include <vector>

#include "common.h"
#include "scenarios.h"

namespace vrm_sim {
namespace scenario {
namespace {

// Hold the tip inside a small sphere (100 µm) for a while; the tremor (tip RMS, power in the 8-12 Hz band of
// physiological tremor, thesis §1.3) is measured from the tracked tip during the longest hold.
class SteadyHold : public Scenario {
 public:
  explicit SteadyHold(const scene::SceneDescription& scene) : contacts_(scene.eye.radius) {
    Params params(scene);
    const std::vector<Eigen::Vector3d> centre = params.points("centre");
    if (centre.size() != 1) params.fail("centre", "expected one point x, y, z");
    centre_ = centre.front();
    radius_ = params.number("radius", 1e-4, 1e-6, 5e-3);
    hold_time_ = params.number("hold_time", 10.0, 0.1, 600.0);
    band_low_ = params.number("band_low_hz", 8.0, 0.0, 1000.0);
    band_high_ = params.number("band_high_hz", 12.0, band_low_, 1000.0);
    tool_ = params.slot("tool", "right");
    params.finish();
  }

  std::vector<Measurement> items() const override { return measurements(0.0); }

  void update(const FrameView& frame, double elapsed) override {
    contacts_.update(frame);
    const InstrumentView* tool = frame.instrument(tool_);
    const bool inside = tool != nullptr && tool->valid && (tool->tip - centre_).norm() <= radius_;
    if (inside && !inside_) {
      hold_start_ = elapsed;
      samples_.clear();
      times_.clear();
    }
    if (!inside && inside_) {
      ++exits_;
      if (current_is_longest_) analyse();  // the longest hold's figures, however short it was
      current_is_longest_ = false;
    }
    inside_ = inside;
    if (!inside) return;
    samples_.push_back(tool->tip);
    times_.push_back(elapsed);  // running time: independent of where the stamps start
    if (elapsed - hold_start_ >= longest_hold_) {
      longest_hold_ = elapsed - hold_start_;
      current_is_longest_ = true;
    }
    held_ = longest_hold_ >= hold_time_;
    // The band power is a DFT over the hold: refreshed every 0.5 s of samples, and at the end of a hold.
    if (current_is_longest_ && (held_ || samples_.size() % 25 == 1)) analyse();
  }

  bool succeeded() const override { return held_; }

  std::string penaltySlot(const std::string& item) const override { return item == "exits" ? tool_ : ""; }

  std::vector<Measurement> measurements(double) const override {
    return {{"hold", longest_hold_, "s"},
            {"exits", static_cast<double>(exits_), "1"},
            {"tip_rms", rms_, "m"},
            {"tremor_band_power", band_power_, "m^2"},
            {"retina_contacts", static_cast<double>(contacts_.count()), "1"}};
  }

  std::string progress() const override {
    return inside_ ? format("holding %.1f of %.0f s", longest_hold_, hold_time_) : "bring the tip into the sphere";
  }

  void hash(std::uint64_t& state) const override {
    hashValue(state, longest_hold_);
    hashValue(state, exits_);
    hashValue(state, samples_.size());
    contacts_.hash(state);
  }

  // The current hold's samples and times whole: the next band power is a DFT over all of them.
  void transferState(StateArchive& archive) override {
    archive.section("steady_hold");
    archive(inside_)(held_)(current_is_longest_)(hold_start_)(longest_hold_)(rms_)(band_power_)(exits_);
    archive(samples_)(times_)(contacts_);
  }

 private:
  void analyse() {
    rms_ = rmsDistance(samples_, centre_);
    const double span = times_.size() > 1 ? times_.back() - times_.front() : 0.0;
    band_power_ =
        span > 0.0 ? bandPower(samples_, static_cast<double>(times_.size() - 1) / span, band_low_, band_high_) : 0.0;
  }

  Eigen::Vector3d centre_;
  double radius_ = 1e-4, hold_time_ = 10.0, band_low_ = 8.0, band_high_ = 12.0;
  std::string tool_;
  bool inside_ = false, held_ = false, current_is_longest_ = false;
  // Tremor figures of the longest hold; NaN (0 points) until the tip was ever inside.
  double hold_start_ = 0.0, longest_hold_ = 0.0, rms_ = std::nan(""), band_power_ = std::nan("");
  std::size_t exits_ = 0;
  std::vector<Eigen::Vector3d> samples_;
  std::vector<double> times_;
  RetinaContacts contacts_;
};

}  // namespace

std::unique_ptr<Scenario> makeSteadyHold(const scene::SceneDescription& scene) {
  return std::make_unique<SteadyHold>(scene);
}

}  // namespace scenario
}  // namespace vrm_sim
