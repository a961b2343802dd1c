#pragma once
// EyeSi-style factor groups and penalty events (issue 35). Every score item belongs to one of five factor groups —
// target achievement, efficiency, tissue treatment, instrument handling, microscope handling — by ONE fixed table
// (itemRoles()); a group scores the weighted mean of its scored items' points with the sum of their weights as its
// weight, so the weighted mean of the groups is the session's total. Items whose value only grows with a mistake
// (a retina contact, bleeding, a dropped sphere, ...) are penalty items: each rise is a penalty event (see
// PenaltyLog). doc/session_result.md lists the table for trainers.

#include <Eigen/Core>
#include <cmath>
#include <cstddef>
#include <functional>
#include <map>
#include <string>
#include <vector>

#include "vrm_sim/state/state_archive.h"

namespace vrm_sim {
namespace scenario {

struct ScoreItem;
struct InstrumentView;

// In the order a result lists them.
constexpr const char* kFactorGroups[] = {"target_achievement", "efficiency", "tissue_treatment", "instrument_handling",
                                         "microscope_handling"};

struct ItemRole {
  const char* item;
  const char* group;         // one of kFactorGroups
  const char* penalty_kind;  // nullptr: not a penalty item (its points are lost gradually, not by events)
  // A continuous penalty (bleeding area, unlit seconds, a spreading tear, ...) rises over many frames, not all of
  // them consecutive: rises less than PenaltyLog::kEpisodeGap apart are one event. A count (contacts, drops, ...)
  // rises once per mistake: every rise is an event.
  bool continuous;
};

const std::vector<ItemRole>& itemRoles();
const ItemRole* itemRole(const std::string& item);  // nullptr: the table lacks the item

struct GroupScore {
  std::string name;
  double points = 0.0;  // 0..100: weighted mean of the group's scored items
  double weight = 0.0;  // the sum of their weights

  void transferState(StateArchive& archive) { archive(name)(points)(weight); }
};

// The groups with at least one scored item (weight > 0), in kFactorGroups order; a group none of whose items is
// scored (e.g. microscope_handling where no session operates the microscope) is omitted, not reported as a constant.
// Items the table lacks are left out (the ScenarioRunner refuses a scenario type with such an item).
std::vector<GroupScore> groupScores(const std::vector<ScoreItem>& items);

struct PenaltyEvent {
  double time = 0.0;       // s of running time since the session started (pauses excluded), at the event's first frame
  std::string kind;        // ItemRole::penalty_kind
  std::string item;        // the score item that rose
  std::string slot;        // the instrument's slot ("" when the frame had none)
  std::string instrument;  // its type (scene instrument type name)
  Eigen::Vector3d position = Eigen::Vector3d::Constant(std::nan(""));  // m, eye frame: its tip (NaN: no instrument)
  double points = 0.0;  // drop of the total it caused (>= 0; 0 when the item was already at its worst)

  void transferState(StateArchive& archive) { archive(time)(kind)(item)(slot)(instrument)(position)(points); }
};

// Turns the rises of penalty items between two score tables into events: a rise of a scored penalty item that leaves
// it short of its best value (points < 100). An event's points are the item's share of
// the total's drop: weight * (points before - points after) / (sum of all weights) — the total is that weighted mean,
// so the points of all events of an item add up to what the item lost since the session started (the whole of it
// unless events were dropped). At most kMaxEvents are kept, the first ones; later ones are counted in `dropped`.
class PenaltyLog {
 public:
  static constexpr std::size_t kMaxEvents = 200;
  // s of running time: a bleeding spreads in steps a few frames apart while the jaws press; a second touch a moment
  // later is a new event.
  static constexpr double kEpisodeGap = 1.0;
  // The instrument an item's event is charged to (nullptr: none).
  using InstrumentOf = std::function<const InstrumentView*(const std::string& item)>;

  void record(const std::vector<ScoreItem>& before, const std::vector<ScoreItem>& after, double time,
              const InstrumentOf& instrument_of, std::vector<PenaltyEvent>& events, std::size_t& dropped);
  void reset() { open_.clear(); }
  // The open episodes: a continuous item rising within kEpisodeGap after a checkpoint adds to the event before it.
  void transferState(StateArchive& archive) {
    archive.section("penalty_log");
    archive(open_);
  }

 private:
  struct Episode {
    std::size_t index;  // into the events (kMaxEvents: the event was dropped)
    double last_rise;   // s
    void transferState(StateArchive& archive) { archive(index)(last_rise); }
  };
  // The latest event of each continuous item.
  std::map<std::string, Episode> open_;
};

}  // namespace scenario
}  // namespace vrm_sim
