#include "vrm_sim/scenario/factor_groups.h"

#include <cstring>

#include "vrm_scene/scene_description.h"
#include "vrm_sim/scenario/runner.h"

namespace vrm_sim {
namespace scenario {

const std::vector<ItemRole>& itemRoles() {
  // Every item any scenario type reports (scenario.h items(), plus the runner's time and completed). A new item must
  // be added here: the ScenarioRunner refuses a scenario type with an item this table lacks.
  static const std::vector<ItemRole> roles = {
      // Target achievement: how much of the task was done.
      {"completed", "target_achievement", nullptr, false},
      {"targets_touched", "target_achievement", nullptr, false},
      {"progress", "target_achievement", nullptr, false},
      {"placed", "target_achievement", nullptr, false},
      {"hold", "target_achievement", nullptr, false},
      {"detached_fraction", "target_achievement", nullptr, false},
      {"lifted_fraction", "target_achievement", nullptr, false},
      {"peel_radius", "target_achievement", nullptr, false},
      {"continuity", "target_achievement", nullptr, false},
      {"removed_fraction", "target_achievement", nullptr, false},
      {"wrong_touches", "target_achievement", "wrong_target", false},
      {"tasks_done", "target_achievement", nullptr, false},
      {"handovers", "target_achievement", nullptr, false},
      {"orientation_error", "target_achievement", nullptr, false},
      {"coverage", "target_achievement", nullptr, false},
      {"spacing_error", "target_achievement", nullptr, false},
      {"off_row_burns", "target_achievement", "burn_off_row", false},
      {"bleb_diameter", "target_achievement", nullptr, false},
      {"size_error", "target_achievement", nullptr, false},
      {"site_error", "target_achievement", nullptr, false},
      {"bleb_offset", "target_achievement", nullptr, false},
      {"bleb_height", "target_achievement", nullptr, false},
      {"fluid_volume", "target_achievement", nullptr, false},
      {"released_adhesions", "target_achievement", nullptr, false},
      // Efficiency: time and motion spent on it.
      {"time", "efficiency", nullptr, false},
      {"path_length", "efficiency", nullptr, false},
      {"shots", "efficiency", nullptr, false},
      // Tissue treatment: injuries to the retina and the tissue worked on.
      {"retina_contacts", "tissue_treatment", "retina_touched", false},
      {"retina_damage", "tissue_treatment", "retina_pressed", true},  // the injury field's peak: pressure or suction
      {"bleeding_area", "tissue_treatment", "bleeding", true},
      {"damaged_area", "tissue_treatment", "bleeding", true},
      {"max_adhesion_force", "tissue_treatment", "retinal_traction", true},
      {"torn_springs", "tissue_treatment", "membrane_torn", true},  // a tear runs on over frames
      {"ball_impacts", "tissue_treatment", "sphere_fell_on_retina", false},
      {"object_impacts", "tissue_treatment", "object_fell_on_retina", false},
      {"strong_burns", "tissue_treatment", "burn_too_strong", false},
      {"burn_overlaps", "tissue_treatment", "burns_overlap", false},
      {"vessel_burns", "tissue_treatment", "vessel_hit_by_laser", false},
      {"macula_burns", "tissue_treatment", "macula_burned", false},
      {"retina_injuries", "tissue_treatment", "retina_torn_by_traction", false},
      {"retina_tears", "tissue_treatment", "retina_torn_by_needle", true},  // a slice runs on over frames
      // Instrument handling: control of the instruments and of the light.
      {"unlit_touches", "instrument_handling", "unlit_touch", false},
      {"weak_burns", "instrument_handling", "burn_too_weak", false},
      {"unlit_work", "instrument_handling", "unlit_work", true},
      {"drops", "instrument_handling", "sphere_dropped", false},
      {"object_drops", "instrument_handling", "object_dropped", false},
      {"post_collisions", "instrument_handling", "ring_hit_post", false},
      {"max_key_force", "instrument_handling", "key_forced", true},  // a new peak force on the lock
      {"instrument_collisions", "instrument_handling", "instruments_collided", false},
      {"exits", "instrument_handling", "left_hold_zone", false},
      {"warnings", "instrument_handling", "port_near_retina", false},
      {"injected_outside", "instrument_handling", "injected_into_vitreous", true},
      {"mean_deviation", "instrument_handling", nullptr, false},
      {"max_deviation", "instrument_handling", nullptr, false},
      {"speed_variability", "instrument_handling", nullptr, false},
      {"tip_rms", "instrument_handling", nullptr, false},
      {"tremor_band_power", "instrument_handling", nullptr, false},
      // Microscope handling: no scenario type measures the microscope yet (FrameView carries no microscope state),
      // so the group has no item and is omitted from every shipped scene's result.
  };
  return roles;
}

const ItemRole* itemRole(const std::string& item) {
  for (const ItemRole& role : itemRoles()) {
    if (item == role.item) return &role;
  }
  return nullptr;
}

std::vector<GroupScore> groupScores(const std::vector<ScoreItem>& items) {
  std::vector<GroupScore> groups;
  for (const char* group : kFactorGroups) {
    double weighted = 0.0, weights = 0.0;
    for (const ScoreItem& item : items) {
      const ItemRole* role = itemRole(item.name);
      if (role == nullptr || std::strcmp(role->group, group) != 0 || !(item.weight > 0.0)) continue;
      weighted += item.weight * item.points;
      weights += item.weight;
    }
    if (weights > 0.0) groups.push_back({group, weighted / weights, weights});
  }
  return groups;
}

void PenaltyLog::record(const std::vector<ScoreItem>& before, const std::vector<ScoreItem>& after, double time,
                        const InstrumentOf& instrument_of, std::vector<PenaltyEvent>& events, std::size_t& dropped) {
  double weights = 0.0;
  for (const ScoreItem& item : after) weights += item.weight;
  for (const ScoreItem& now : after) {
    const ItemRole* role = itemRole(now.name);
    if (role == nullptr || role->penalty_kind == nullptr) continue;
    const ScoreItem* previous = nullptr;
    for (const ScoreItem& candidate : before) {
      if (candidate.name == now.name) previous = &candidate;
    }
    if (previous == nullptr || !(now.value > previous->value)) continue;  // NaN before or after: no rise to judge
    // Not a mistake: an unscored item, or a rise still within the item's best value (a peel pulls on its adhesion
    // points; only a pull beyond the scene's best costs points).
    if (!(now.weight > 0.0) || !(now.points < 100.0)) continue;
    const double points = weights > 0.0 ? now.weight * (previous->points - now.points) / weights : 0.0;
    const auto open = open_.find(now.name);
    if (role->continuous && open != open_.end() && time - open->second.last_rise <= kEpisodeGap) {
      if (open->second.index < events.size()) events[open->second.index].points += points;
      open->second.last_rise = time;
      continue;
    }
    if (events.size() >= kMaxEvents) {
      ++dropped;
      if (role->continuous) open_[now.name] = {kMaxEvents, time};
      continue;
    }
    PenaltyEvent event;
    event.time = time;
    event.kind = role->penalty_kind;
    event.item = now.name;
    event.points = points;
    if (const InstrumentView* instrument = instrument_of(now.name)) {
      event.slot = instrument->slot;
      event.instrument = scene::toString(instrument->type);
      event.position = instrument->tip;
    }
    if (role->continuous) open_[now.name] = {events.size(), time};
    events.push_back(std::move(event));
  }
}

}  // namespace scenario
}  // namespace vrm_sim
