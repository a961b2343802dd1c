#pragma once
// The procedural fundus (issue 16): optic disc with its cup, the retinal vessel tree in its four arcades, macula and
// fovea, choroidal pattern — generated once from a seed, no photographs. The anatomy (disc, vessels, macula) is
// vrm_sim's FundusAnatomy (issue 37: the laser scenario scores burns on the vessels drawn here); this map bakes it with
// the choroid into one texture at set-up.
//
// Geometry (eye frame of vrm_sim's eye_meshes.h: origin at the eye centre, +z towards the microscope, the fovea at
// the posterior pole (0, 0, -R)). Anatomy is laid out in *fundus coordinates*: the azimuthal equidistant map of
// the retina about the fovea — (x, y) in metres along the retinal surface, directions those of the eye frame's x
// and y. Figures used (cited where they are used in fundus.cpp):
//   [Hogan] Hogan, Alvarado, Weddell: Histology of the Human Eye (1971), ch. 9 — disc 1.5 x 1.75 mm, disc centre
//           ~4.0-4.5 mm nasal and ~0.5 mm superior of the fovea (≈15° of visual angle), fovea ~1.5 mm, foveola
//           0.35 mm, foveal avascular zone ~0.5 mm;
//   [Murray] Murray (1926) r0^3 = r1^3 + r2^3 at bifurcations; retinal vessels follow it closely (Zamir 1979);
//   [Jonas] Jonas et al. (1999) arteriole : venule calibre ~2 : 3; vein ~125-150 µm, artery ~90-110 µm at the
//           disc margin; cup-to-disc ratio ~0.3-0.4 in normal eyes;
//   [Kanski] Kanski: Clinical Ophthalmology, normal fundus — four arcades (superotemporal, inferotemporal,
//           superonasal, inferonasal) leaving the disc; the temporal arcades arch around the macula ~3 mm from
//           the fovea; arteries paler and with a brighter central reflex than veins; arteries cross over veins;
//   [Knudtson] Knudtson et al. (2003) revised formulas: CRAE / CRVE from the six largest arterioles / venules
//           crossing the zone 0.5-1 disc diameter from the disc margin; arteriole-to-venule ratio (AVR) of normal eyes
//           ~0.6-0.75 with them (issue 33's range);
//   [Hart]  Hart et al. (1999), Grisan et al. (2008): tortuosity measures of retinal vessels, the simplest the arc /
//           chord ratio; normal vessels are close to straight (a few % longer than their chords), tortuous ones in
//           hypertensive or diabetic retinas clearly more. The target used here: arc / chord of 2 mm chords along each
//           arcade trunk outside the disc, mean 1.005-1.08 per trunk (the arcade's own arch contributes ~1-2 %; a
//           ruler-straight trunk is 1.000), no chord above 1.30 (no loops: the bend off the disc reaches ~1.1-1.25).

#include <Eigen/Core>
#include <cstdint>
#include <string>
#include <vector>

#include "vrm_render/render_types.h"
#include "vrm_scene/anatomy/fundus_anatomy.h"

namespace vrm_render {

// The anatomy is vrm_sim's (one fundus for what is drawn and what is scored); the renderer adds its texture.
using FundusParams = vrm_sim::anatomy::FundusParams;
using VesselSegment = vrm_sim::anatomy::VesselSegment;
using VesselQuery = vrm_sim::anatomy::VesselQuery;
using vrm_sim::anatomy::fundusCoordinates;

class FundusMap {
 public:
  // Throws RenderError for parameters the anatomy refuses (see FundusAnatomy).
  explicit FundusMap(const FundusParams& params = {});

  const FundusParams& params() const { return anatomy_.params(); }
  const vrm_sim::anatomy::FundusAnatomy& anatomy() const { return anatomy_; }
  // Eye frame (on or near the retina sphere) <-> fundus coordinates.
  Eigen::Vector2f toFundus(const Eigen::Vector3f& point_in_eye) const { return anatomy_.toFundus(point_in_eye); }
  Eigen::Vector3f toEye(const Eigen::Vector2f& fundus) const { return anatomy_.toEye(fundus); }

  Eigen::Vector2f fovea() const { return anatomy_.fovea(); }
  Eigen::Vector2f discCentre() const { return anatomy_.discCentre(); }
  Eigen::Vector2f cupCentre() const { return anatomy_.cupCentre(); }
  const std::vector<VesselSegment>& vessels() const { return anatomy_.vessels(); }
  VesselQuery nearestVessel(const Eigen::Vector3f& point_in_eye) const { return anatomy_.nearestVessel(point_in_eye); }

  // Albedo texture, RGBA8, texture_size^2, row 0 at y = -R (GL's first row), texel (i, j) centred at
  // x = -R + (i + 0.5) * 2R / size: the retina samples it at its eye-frame (x, y) (orthographic from the
  // microscope's side, so no seam over the cap).
  const std::vector<std::uint8_t>& texture() const { return texture_; }
  int textureSize() const { return params().texture_size; }

 private:
  void bake();

  vrm_sim::anatomy::FundusAnatomy anatomy_;
  std::vector<std::uint8_t> texture_;
};

// Issue 37: paints a laser burn into a fundus texture (FundusMap::texture's layout, `size` texels across the eye's
// [-R, R] in x and y, R = `eye_radius`): texels whose retina point lies within the burn's radius take the burn's
// grey-white, strongest at its centre, fading over its outer 40 %. Returns the texel rectangle it changed
// (x0, y0, width, height; width 0 when none: off the texture, no lesion, or non-finite values).
struct TexelRect {
  int x = 0, y = 0, width = 0, height = 0;
};
TexelRect paintBurn(std::vector<std::uint8_t>* texture, int size, float eye_radius, const FundusBurn& burn);

}  // namespace vrm_render
