#pragma once
// Which colour markers EyeSi tracks and where they sit (thesis §7.3.2): two peripheral markers on the mechanical
// eye (their positions about the fixed rotation centre give the eye rotation) and one marker at each instrument
// tip (with the trocar fixed in the eye frame it gives the instrument pose). Each marker has its own colour class,
// so a centroid identifies its marker without correspondence search. The same table drives the synthetic
// renderer (colour, size) and the detector (HSV ranges, area, roundness).

#include <Eigen/Geometry>
#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "vrm_tracking/surgeon_script.h"

namespace vrm_tracking {

struct ColourClass {
  int id = 0;
  std::string name;
  std::array<std::uint8_t, 3> bgr = {{0, 0, 255}};  // rendered colour of a fully lit marker
  // Detection ranges on a 0..360° hue circle (h_min > h_max wraps through 0), chroma = max - min channel (0..255),
  // saturation = chroma / max (0..1), value = max channel (0..255).
  double h_min = 0.0;
  double h_max = 360.0;
  double chroma_min = 40.0;
  double s_min = 0.3;
  double v_min = 40.0;
  // Blob acceptance (distractor rejection): area in px², roundness = sqrt(λmin/λmax) of the weighted covariance.
  double area_min = 6.0;
  double area_max = 2000.0;
  double roundness_min = 0.5;
};

struct EyeMarker {
  int class_id = 0;
  Eigen::Vector3d position = Eigen::Vector3d::Zero();  // eye frame, m (relative to the rotation centre)
};

struct InstrumentMarker {
  std::string slot;
  int class_id = 0;
  Eigen::Vector3d trocar = Eigen::Vector3d::Zero();  // eye frame, m: the fixed insertion hole
  // The layout names no trocar for this slot (the shipped files don't: the scene is the one source of the trocars):
  // applySceneTrocars (scene_trocars.h) must fill it in before a PoseTracker takes the layout.
  bool trocar_from_scene = false;
};

struct MarkerLayout {
  std::vector<ColourClass> classes;    // indexed by id (classes[i].id == i)
  std::vector<EyeMarker> eye_markers;  // exactly two for a pose
  std::vector<InstrumentMarker> instruments;
  Eigen::Vector3d rotation_center = Eigen::Vector3d::Zero();  // world, m
  double eye_marker_radius = 0.0005;                          // m, sphere radius of the rendered marker
  double tip_marker_radius = 0.0004;                          // m
  double shaft_radius = 0.00045;                              // m (23 G ≈ 0.64 mm diameter; 20 G ≈ 0.9 mm)
  double shaft_length = 0.03;                                 // m, shaft beyond the trocar that can occlude markers

  const ColourClass* findClass(int id) const;
  const InstrumentMarker* findSlot(const std::string& slot) const;
};

// Eye markers 60° from the posterior pole, 90° apart in azimuth (visible from below; a wide angle between them
// conditions the rotation); tips of the slots "left" and "right" through the default trocars of the demo scripts
// and vrm_sim scenes (45° from the optical axis, azimuth 150° / 30°). Colours: red, blue (eye), green (left),
// yellow (right); magenta is left free for distractors.
MarkerLayout makeDefaultLayout();
// YAML: {classes: [{name, bgr, h_min, h_max, chroma_min, s_min, v_min, area_min, area_max, roundness_min}],
// eye_markers: [{class, position}], instruments: [{slot, class, trocar}], rotation_center, eye_marker_radius,
// tip_marker_radius, shaft_radius, shaft_length}; every key optional except a class's name and a marker's class
// (and slot); classes are referenced by name; trocar is optional (absent: trocar_from_scene). Read by the strict
// reader (vrm_scene/yaml/strict_reader.h): unknown keys, duplicate names or slots and out-of-range values throw
// vrm_sim::YamlError (a std::runtime_error) reading "<file>:<line>:<column>: <field>: <problem>", with a typo hint.
MarkerLayout layoutFromYamlString(const std::string& text, const std::string& source = "<string>");
MarkerLayout loadLayoutYaml(const std::string& path);

// One marker in world coordinates, as the renderer and the evaluation see it.
struct WorldMarker {
  int class_id = 0;
  Eigen::Vector3d position = Eigen::Vector3d::Zero();  // world, m
  Eigen::Vector3d velocity = Eigen::Vector3d::Zero();  // world, m/s (motion blur)
  double radius = 0.0005;                              // m
};

// A shaft segment (world), drawn as an occluder.
struct WorldSegment {
  Eigen::Vector3d a = Eigen::Vector3d::Zero();
  Eigen::Vector3d b = Eigen::Vector3d::Zero();
  double radius = 0.00045;
};

struct WorldScene {
  std::vector<WorldMarker> markers;
  std::vector<WorldSegment> shafts;
};

// The ground truth markers of a surgeon snapshot (instrument slots not in the layout are ignored). The eye rotation
// maps eye to world about snapshot.rotation_center (surgeon_script.h).
WorldScene worldSceneFromSnapshot(const SurgeonSnapshot& snapshot, const MarkerLayout& layout);
// Adds velocities by a central difference of two snapshots dt apart (same marker order).
void setVelocities(const WorldScene& before, const WorldScene& after, double dt, WorldScene* scene);

}  // namespace vrm_tracking
