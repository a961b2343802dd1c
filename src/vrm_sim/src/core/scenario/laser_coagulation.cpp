// laser_coagulation (issue 37): a barrier laser around a retinal break. EyeSi's vitreoretinal programme trains laser
// coagulation and scores placement and injuries (Deuchler 2016: "vessel hit by laser", phototoxicity). The trainee
// aims the endolaser's beam (laser probe in `laser`, the light pipe in the other hand) and fires with the pedal, to lay
// one row of burns around the break (`lesion`, a disc on the retina) at `ring_offset` beyond its edge, `spacing`
// apart, of a therapeutic grade (neither too weak nor too strong), without burning a major vessel, the macula, or the
// same spot twice. The row is divided into sectors `spacing` long; a sector counts when a good burn lies in it; a
// sector whose centre lies on a major vessel is excused (a surgeon leaves the gap there).

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <variant>

#include "common.h"
#include "scenarios.h"
#include "vrm_scene/scene_fundus.h"
#include "vrm_sim/scenario/laser.h"

namespace vrm_sim {
namespace scenario {
namespace {

class LaserCoagulation : public Scenario {
 public:
  explicit LaserCoagulation(const scene::SceneDescription& scene)
      : contacts_(scene.eye.radius), fundus_(scene::fundusParams(scene)), eye_radius_(scene.eye.radius) {
    Params params(scene);
    laser_ = params.slot("laser", "right");
    const scene::InstrumentDescription* probe =
        scene.findInstrument(laser_ == "left" ? scene::InstrumentSlot::kLeft : scene::InstrumentSlot::kRight);
    if (probe->type != scene::InstrumentType::kLaserProbe) {
      params.fail("laser", "slot '" + laser_ + "' must hold a laser_probe, not a " + toString(probe->type));
    }
    const scene::ObjectDescription& lesion = params.object("lesion", "retinal_break");
    const auto* disc = lesion.mesh.generator ? std::get_if<scene::DiscParams>(&*lesion.mesh.generator) : nullptr;
    if (disc == nullptr || lesion.frame != scene::ObjectFrame::kEye) {
      params.fail("lesion", "object '" + lesion.name + "' must be a disc (generator disc) in the eye frame");
    }
    const double ring_radius = disc->radius + params.number("ring_offset", 7.5e-4, 0.0, 5e-3);
    const double spacing = params.number("spacing", 6e-4, 1e-4, 5e-3);
    const double band = params.number("band", 3e-4, 5e-5, 3e-3);
    required_coverage_ = params.number("required_coverage", 0.9, 0.05, 1.0);
    weak_grade_ = params.number("weak_grade", 0.5, 0.0, 10.0);
    strong_grade_ = params.number("strong_grade", 2.0, 0.1, 100.0);
    if (!(strong_grade_ > weak_grade_)) params.fail("strong_grade", "must exceed weak_grade");
    min_vessel_radius_ = params.number("min_vessel_radius", 2.5e-5, 0.0, 1e-3);
    params.finish();
    row_.emplace(fundus_, lesion.pose.xyz, ring_radius, spacing, band, min_vessel_radius_);
    sector_burnt_.assign(row_->sectors(), false);
  }

  LaserCoagulation(const LaserCoagulation&) = delete;  // row_ points into fundus_
  LaserCoagulation& operator=(const LaserCoagulation&) = delete;

  std::vector<Measurement> items() const override { return measurements(0.0); }

  void update(const FrameView& frame, double elapsed) override {
    contacts_.update(frame);
    const InstrumentView* probe = frame.instrument(laser_);
    if (probe == nullptr || !probe->laser) return;
    const LaserSetting setting = laserSetting(*probe->laser);
    setting_ = setting;
    if (!trigger_.update(frame.pedals.travel, elapsed, setting)) return;
    ++shots_;
    std::optional<LaserAim> aim;
    if (probe->valid) aim = laserAim(probe->tip, probe->axis, eye_radius_);
    if (!aim || aim->distance > kMaxBeamLength) return;  // a shot into nothing (untracked, outside the eye)
    const LaserBurn burn = makeBurn(setting, aim->point, aim->distance, elapsed);
    const BurnCheck check = checkBurn(burn, burns_, fundus_, min_vessel_radius_);
    burns_.push_back(burn);
    if (!(burn.diameter > 0.0) || burn.grade < weak_grade_) {
      ++weak_;
      last_position_["weak_burns"] = burn.position;
    } else if (burn.grade > strong_grade_) {
      ++strong_;
      last_position_["strong_burns"] = burn.position;
    }
    if (check.overlaps) {
      ++overlaps_;
      last_position_["burn_overlaps"] = burn.position;
    }
    if (check.on_vessel) {
      ++vessel_;
      last_position_["vessel_burns"] = burn.position;
    }
    if (check.in_macula) {
      ++macula_;
      last_position_["macula_burns"] = burn.position;
    }
    const bool good = burn.diameter > 0.0 && burn.grade >= weak_grade_ && burn.grade <= strong_grade_ &&
                      !check.on_vessel && !check.in_macula;
    const std::optional<std::size_t> sector = row_->sectorOf(burn.position);
    if (burn.diameter > 0.0 && !sector) {
      ++off_row_;
      last_position_["off_row_burns"] = burn.position;
    }
    if (good && sector) {
      sector_burnt_[*sector] = true;
      row_burns_.push_back(burn.position);
    }
  }

  bool succeeded() const override { return coverage() >= required_coverage_; }

  std::string penaltySlot(const std::string& item) const override { return item == "retina_contacts" ? "" : laser_; }
  std::optional<Eigen::Vector3d> penaltyPosition(const std::string& item) const override {
    const auto found = last_position_.find(item);
    return found != last_position_.end() ? std::optional<Eigen::Vector3d>(found->second) : std::nullopt;
  }

  std::vector<Measurement> measurements(double) const override {
    return {{"coverage", coverage(), "1"},
            {"spacing_error", spacingError(), "1"},
            {"shots", static_cast<double>(shots_), "1"},
            {"off_row_burns", static_cast<double>(off_row_), "1"},
            {"weak_burns", static_cast<double>(weak_), "1"},
            {"strong_burns", static_cast<double>(strong_), "1"},
            {"burn_overlaps", static_cast<double>(overlaps_), "1"},
            {"vessel_burns", static_cast<double>(vessel_), "1"},
            {"macula_burns", static_cast<double>(macula_), "1"},
            {"retina_contacts", static_cast<double>(contacts_.count()), "1"}};
  }

  std::vector<LaserBurn> burns() const override { return burns_; }

  std::string progress() const override {
    std::size_t open = 0;
    for (std::size_t k = 0; k < sector_burnt_.size(); ++k) open += !sector_burnt_[k] && !row_->excused(k);
    if (succeeded()) return "the break is surrounded";
    return format("%zu of %zu places of the row still open; %.0f mW, %.0f ms", open, row_->countable(),
                  setting_.power * 1e3, setting_.duration * 1e3);
  }

  void hash(std::uint64_t& state) const override {
    trigger_.hash(state);
    contacts_.hash(state);
    hashValue(state, shots_);
    for (const LaserBurn& burn : burns_) {
      hashValue(state, burn.position.x());
      hashValue(state, burn.position.y());
      hashValue(state, burn.position.z());
      hashValue(state, burn.grade);
    }
  }

  // In place (the class cannot be copied: row_ points into fundus_). Every burn whole: checkBurn reads the earlier
  // burns' diameters, which the hash does not cover.
  void transferState(StateArchive& archive) override {
    archive.section("laser_coagulation").expect(sector_burnt_.size(), "the number of sectors of the row");
    archive(sector_burnt_)(trigger_)(setting_)(burns_)(row_burns_)(last_position_);
    archive(shots_)(off_row_)(weak_)(strong_)(overlaps_)(vessel_)(macula_)(contacts_);
  }

 private:
  double coverage() const {
    std::size_t burnt = 0;
    for (std::size_t k = 0; k < sector_burnt_.size(); ++k) burnt += sector_burnt_[k] && !row_->excused(k);
    return row_->countable() > 0 ? static_cast<double>(burnt) / static_cast<double>(row_->countable()) : 1.0;
  }
  // Mean |nearest-neighbour distance - spacing| / spacing over the good burns of the row; 1 with fewer than two.
  double spacingError() const {
    if (row_burns_.size() < 2) return 1.0;
    double sum = 0.0;
    for (std::size_t i = 0; i < row_burns_.size(); ++i) {
      double nearest = std::numeric_limits<double>::infinity();
      for (std::size_t j = 0; j < row_burns_.size(); ++j) {
        if (j != i) nearest = std::min(nearest, (row_burns_[i] - row_burns_[j]).norm());
      }
      sum += std::abs(nearest - row_->spacing()) / row_->spacing();
    }
    return sum / static_cast<double>(row_burns_.size());
  }

  RetinaContacts contacts_;
  anatomy::FundusAnatomy fundus_;
  double eye_radius_;
  std::string laser_;
  std::optional<BurnRow> row_;  // refers to fundus_
  double required_coverage_ = 0.9, weak_grade_ = 0.5, strong_grade_ = 2.0, min_vessel_radius_ = 2.5e-5;
  std::vector<bool> sector_burnt_;
  LaserTrigger trigger_;
  LaserSetting setting_;
  std::vector<LaserBurn> burns_;
  std::vector<Eigen::Vector3d> row_burns_;
  std::map<std::string, Eigen::Vector3d> last_position_;
  std::size_t shots_ = 0, off_row_ = 0, weak_ = 0, strong_ = 0, overlaps_ = 0, vessel_ = 0, macula_ = 0;
};

}  // namespace

std::unique_ptr<Scenario> makeLaserCoagulation(const scene::SceneDescription& scene) {
  return std::make_unique<LaserCoagulation>(scene);
}

}  // namespace scenario
}  // namespace vrm_sim
