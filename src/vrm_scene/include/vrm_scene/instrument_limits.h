#pragma once
// The instrument's mechanical limits, shared by its meshes here and by the tissue layer's grasp model above: one
// number, so the drawn jaws, the collision mesh and the jaw capsules that grasp stop at the same opening.

namespace vrm_sim {
namespace scene {

// The forceps open no further than this (rad, full opening).
constexpr double kMaxJawOpening = 1.5;

}  // namespace scene
}  // namespace vrm_sim
