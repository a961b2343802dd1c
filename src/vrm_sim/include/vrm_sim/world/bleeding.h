#pragma once
// Retinal injuries (thesis §7.4: "retina injuries bleed"; §6: shown as bleeding colour on the retina). An instrument
// that presses on the retina, or a vitrector that aspirates it, starts a bleeding spot there: a Gaussian of the
// per-vertex injury field (0..1) whose radius grows with time since the injury until it stops spreading. Each
// uninterrupted contact of one instrument is one event (start, end, duration, deepest penetration) — what a
// scenario scores.
//
// Deterministic: the field is a function of the contacts and the simulated time only.

#include <Eigen/Core>
#include <string>
#include <vector>

#include "vrm_sim/state/state_archive.h"

namespace vrm_sim {
namespace world {

struct BleedingParameters {
  double depth_full = 1e-4;           // m: a contact this deep starts a spot of full intensity (1.0)
  double min_intensity = 0.3;         // a grazing contact still leaves a visible spot
  double initial_radius = 1.5e-4;     // m: sigma of a new spot (at least half the contact footprint's extent)
  double spread_rate = 1.5e-4;        // m/s: sigma grows this fast ...
  double max_radius = 1e-3;           // ... up to this
  double aspiration_distance = 2e-4;  // m: a vitrector port with suction closer than this to the retina injures it
  double new_spot_distance = 3e-4;    // m: a contact that moved this far from its last spot starts another one
};

struct ContactEvent {
  std::string instrument;  // slot
  std::string object;
  double start = 0.0, end = 0.0;                    // s (simulated time)
  double max_depth = 0.0;                           // m
  Eigen::Vector3d point = Eigen::Vector3d::Zero();  // first contact, object frame
  bool aspiration = false;                          // vitrector suction rather than pressure
  bool ongoing = true;
  double duration() const { return end - start; }
  void transferState(StateArchive& archive) {
    archive(instrument)(object)(start)(end)(max_depth)(point)(aspiration)(ongoing);
  }
};

class BleedingField {
 public:
  // `vertices`: the retina's vertex positions (object frame); copied.
  BleedingField(std::string object, std::vector<Eigen::Vector3d> vertices, BleedingParameters parameters = {});

  // A contact of `instrument` in the current frame centred at `point` (object frame), `depth` m deep, over a
  // footprint of `extent` m (the largest distance of a touched vertex from `point`).
  void contact(const std::string& instrument, const Eigen::Vector3d& point, double depth, bool aspiration, double time,
               double extent = 0.0);
  // Closes the frame at `time`: contacts not renewed in it end (appended to `ended`), the field is recomputed
  // where spots still spread. Returns whether the field changed.
  bool update(double time, std::vector<ContactEvent>* ended = nullptr);
  void clear();

  const std::vector<float>& field() const { return field_; }
  const std::vector<ContactEvent>& events() const { return events_; }
  double maxInjury() const { return max_injury_; }
  std::size_t vertexCount() const { return vertices_.size(); }
  // Distance from `point` to the nearest vertex (for the aspiration test).
  double distanceToSurface(const Eigen::Vector3d& point) const;
  // Checkpoints (issue 39 §1): the field, its spots (its future), the ongoing contacts and the events.
  void transferState(StateArchive& archive) {
    archive.section("bleeding").expect(vertices_.size(), "the bleeding surface's vertex count");
    archive(field_)(spots_)(active_)(events_)(dirty_)(max_injury_);
    if (archive.loading() && field_.size() != vertices_.size()) archive.fail("a bleeding field of another size");
    for (const Active& active : active_) {
      if (archive.loading() && (active.event >= events_.size() || active.spot >= spots_.size())) {
        archive.fail("an ongoing contact without its event or spot");
      }
    }
  }

 private:
  struct Spot {
    Eigen::Vector3d centre = Eigen::Vector3d::Zero();
    double onset = 0.0;
    double intensity = 0.0;
    double initial_radius = 0.0;
    bool spreading = true;
    void transferState(StateArchive& archive) { archive(centre)(onset)(intensity)(initial_radius)(spreading); }
  };
  struct Active {
    std::string instrument;
    std::size_t event = 0;  // index into events_
    std::size_t spot = 0;   // the spot it feeds
    bool renewed = false;
    void transferState(StateArchive& archive) { archive(instrument)(event)(spot)(renewed); }
  };
  double radiusAt(const Spot& spot, double time) const;

  std::string object_;
  std::vector<Eigen::Vector3d> vertices_;
  BleedingParameters parameters_;
  std::vector<float> field_;
  std::vector<Spot> spots_;
  std::vector<Active> active_;
  std::vector<ContactEvent> events_;
  bool dirty_ = false;
  double max_injury_ = 0.0;
};

}  // namespace world
}  // namespace vrm_sim
