#pragma once
// The peel scenarios' common part (membrane_peeling.cpp, ilm_peeling.cpp; not installed).
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "common.h"

namespace vrm_sim {
namespace scenario {

// What a peel is scored on (membrane and ILM alike). `tool` (default right) is the working instrument whose work
// outside the light pipe's cone is measured (unlit_work, see UnlitWork).
class Peel : public Scenario {
 public:
  Peel(const scene::SceneDescription& scene, Params& params, const std::string& fallback);

  void update(const FrameView& frame, double) override;
  bool succeeded() const override;
  std::vector<Measurement> items() const override;
  std::string penaltySlot(const std::string& item) const override;
  std::vector<Measurement> measurements(double) const override;
  std::string progress() const override;
  void hash(std::uint64_t& state) const override;
  // A subclass with state of its own overrides this and calls it first.
  void transferState(StateArchive& archive) override;

 protected:
  virtual void updateShape(const TissueView&) {}

  std::string object_;
  std::optional<std::size_t> initial_adhesions_;
  std::size_t remaining_ = 0;
  std::uint64_t released_ = 0, torn_ = 0;
  double max_force_ = 0.0, lifted_fraction_ = 0.0, bleeding_area_ = 0.0;
  RetinaContacts contacts_;
  UnlitWork unlit_;
};

}  // namespace scenario
}  // namespace vrm_sim
