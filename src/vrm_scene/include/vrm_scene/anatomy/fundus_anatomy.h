#pragma once
// The fundus's anatomy (issues 16, 33, 37): optic disc with its cup, the retinal vessel tree in its four arcades,
// macula and fovea — generated once from a seed, no photographs. One anatomy for the renderer (vrm_render::FundusMap
// bakes it into its texture) and the simulation (the laser scenario scores burns on vessels and in the macula), so the
// vessel a trainee sees is the vessel that is scored. Needs only Eigen (library vrm_anatomy): the renderer's core links
// no simulation for it.
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
#include <vector>

namespace vrm_sim {
namespace anatomy {

struct FundusParams {
  std::uint32_t seed = 1;  // the scene's seed: vessel branching, tortuosity, choroidal pattern
  float eye_radius = 0.012f;
  float nasal_sign = 1.0f;  // +1: the disc lies towards +x (right eye as the microscope shows it), -1: left eye
  float disc_diameter = 0.00165f;
  float cup_to_disc = 0.35f;
  // The disc centre in fundus coordinates: disc_fovea_distance nasal (x, times nasal_sign) and disc_above_fovea
  // superior (y) of the fovea. Defaults [Hogan]; a scene's `optic_disc` object overrides them (scene_setup.h:
  // fundusParams), and the arcades are laid out relative to wherever the disc is.
  float disc_fovea_distance = 0.0045f;  // along the retina
  float disc_above_fovea = 0.0005f;
  float macula_radius = 0.0015f;  // the darker, xanthophyll-pigmented centre
  float fovea_radius = 0.00035f;  // foveola
  int texture_size = 1024;        // texels across [-R, R] of the eye frame's x and y
};

// One straight piece of a vessel's centre line, in fundus coordinates (metres), radii at both ends.
struct VesselSegment {
  Eigen::Vector2f a = Eigen::Vector2f::Zero();
  Eigen::Vector2f b = Eigen::Vector2f::Zero();
  float radius_a = 0.0f;
  float radius_b = 0.0f;
  bool artery = false;
  int arcade = -1;     // 0 superotemporal, 1 inferotemporal, 2 superonasal, 3 inferonasal, -1 small disc vessel
  int generation = 0;  // 0: a trunk leaving the disc, +1 per bifurcation
};

struct VesselQuery {
  bool inside = false;    // the point lies within a vessel's lumen
  float distance = 1e9f;  // from the vessel's centre line (m, along the retina)
  float radius = 0.0f;    // of that vessel there
  bool artery = false;
  int segment = -1;  // index into vessels(), -1 when there is none
};

// Eye frame (a point on or near the retina sphere of `eye_radius`) -> fundus coordinates: the azimuthal equidistant
// map about the posterior pole (0, 0, -R), (x, y) in metres along the retina.
Eigen::Vector2f fundusCoordinates(const Eigen::Vector3f& point_in_eye, float eye_radius);

class FundusAnatomy {
 public:
  // Throws std::invalid_argument for a non-positive eye radius or disc diameter, a texture size outside 16..4096 or a
  // non-finite disc distance.
  explicit FundusAnatomy(const FundusParams& params = {});

  const FundusParams& params() const { return params_; }
  // Eye frame (on or near the retina sphere) <-> fundus coordinates.
  Eigen::Vector2f toFundus(const Eigen::Vector3f& point_in_eye) const;
  Eigen::Vector3f toEye(const Eigen::Vector2f& fundus) const;

  Eigen::Vector2f fovea() const { return Eigen::Vector2f::Zero(); }
  Eigen::Vector2f discCentre() const { return disc_; }
  Eigen::Vector2f cupCentre() const;  // of radius cup_to_disc * disc_diameter / 2; the vessels emerge at its margin
  const std::vector<VesselSegment>& vessels() const { return vessels_; }
  // The nearest vessel to a point on the retina (eye frame); O(segments), meant for events (a contact, a laser burn),
  // not for every vertex of every frame.
  VesselQuery nearestVessel(const Eigen::Vector3f& point_in_eye) const;

 private:
  void growVessels();

  FundusParams params_;
  Eigen::Vector2f disc_;
  std::vector<VesselSegment> vessels_;
};

}  // namespace anatomy
}  // namespace vrm_sim
