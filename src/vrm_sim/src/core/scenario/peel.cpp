#include "peel.h"

#include <algorithm>

namespace vrm_sim {
namespace scenario {

Peel::Peel(const scene::SceneDescription& scene, Params& params, const std::string& fallback)
    : contacts_(scene.eye.radius), unlit_(scene, params, params.slot("tool", "right")) {
  object_ = deformableObject(params, "tissue", fallback).name;
}

void Peel::update(const FrameView& frame, double) {
  contacts_.update(frame);
  unlit_.update(frame);
  bleeding_area_ = frame.retina.injured_area;
  const TissueView* tissue = frame.tissue(object_);
  if (tissue == nullptr) return;
  if (!initial_adhesions_) initial_adhesions_ = tissue->adhesion_points + tissue->released_adhesions;
  remaining_ = tissue->adhesion_points;
  released_ = tissue->released_adhesions;
  torn_ = tissue->torn_springs;
  max_force_ = tissue->max_adhesion_force;
  lifted_fraction_ = tissue->lifted_fraction;
  updateShape(*tissue);
}

// Detached from every adhesion point: each one peeled off, or the rest cut free with the vitrector — a tear that
// isolates an adhesion point also removes it, but that is a torn membrane, not a detached one.
bool Peel::succeeded() const {
  if (!initial_adhesions_ || *initial_adhesions_ == 0) return false;
  return released_ >= *initial_adhesions_ || (remaining_ == 0 && torn_ == 0);
}

std::vector<Measurement> Peel::items() const { return measurements(0.0); }

std::string Peel::penaltySlot(const std::string& item) const { return item == "unlit_work" ? unlit_.tool() : ""; }

std::vector<Measurement> Peel::measurements(double) const {
  const double initial = initial_adhesions_ ? static_cast<double>(*initial_adhesions_) : 0.0;
  const double detached = torn_ > 0 ? static_cast<double>(released_) : initial - static_cast<double>(remaining_);
  return {{"detached_fraction", initial > 0.0 ? std::clamp(detached / initial, 0.0, 1.0) : 0.0, "1"},
          {"torn_springs", static_cast<double>(torn_), "1"},
          {"max_adhesion_force", max_force_, "N"},
          {"lifted_fraction", lifted_fraction_, "1"},
          {"retina_contacts", static_cast<double>(contacts_.count()), "1"},
          {"bleeding_area", bleeding_area_, "m^2"},
          {"unlit_work", unlit_.seconds(), "s"}};
}

std::string Peel::progress() const {
  const std::size_t initial = initial_adhesions_ ? *initial_adhesions_ : 0;
  return format("%zu of %zu adhesion points detached%s", initial - std::min(initial, remaining_), initial,
                torn_ > 0 ? " (torn)" : "");
}

// initial_adhesions_ is not hashed, and cannot be rebuilt after a checkpoint: the first frame fixed it.
void Peel::transferState(StateArchive& archive) {
  archive.section("peel");
  archive(initial_adhesions_)(remaining_)(released_)(torn_)(max_force_)(lifted_fraction_)(bleeding_area_);
  archive(contacts_)(unlit_);
}

void Peel::hash(std::uint64_t& state) const {
  hashValue(state, remaining_);
  hashValue(state, torn_);
  hashValue(state, max_force_);
  hashValue(state, bleeding_area_);
  contacts_.hash(state);
  unlit_.hash(state);
}

}  // namespace scenario
}  // namespace vrm_sim
