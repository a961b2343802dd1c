// laser_scripts (issue 37): writes the expert and novice sessions of a laser_coagulation scene from its geometry, the
// fundus's vessels and the burn model, as the `scripts:` block of the scene file (printed on stdout, indented for it).
//
// Both hold the light pipe still, 6 mm from the break on the line from its trocar, and aim the probe through its trocar
// at each place of the row (scenario/laser.h BurnRow), the tip `distance` from the retina along the beam, and fire one
// shot there (a pedal press of 0.15 s).
//  * expert: every place not excused (a major vessel), in order around the row, from 2.0 mm (a moderate burn);
//  * novice: slower; places in the same order but with the mistakes of a beginner: a shot from too far (3.8 mm: too
//    weak, not counted), one from too close (0.8 mm: too strong), a shot fired twice on one place (overlap), one
//    0.5 mm off the row, one on the vessel the row crosses; then back to the places the weak and the off-row shots
//    missed. With the row's 14 places and one excused (the shipped scene), it covers the row with these errors.

#include <Eigen/Geometry>
#include <cmath>
#include <cstdio>
#include <exception>
#include <string>
#include <vector>

#include "vrm_scene/cli/cli.h"
#include "vrm_scene/package_data.h"
#include "vrm_scene/scene_fundus.h"
#include "vrm_scene/scene_loader.h"
#include "vrm_sim/scenario/laser.h"

namespace {

using vrm_sim::scenario::BurnRow;
using vrm_sim::scene::SceneDescription;

double param(const SceneDescription& scene, const std::string& name, double fallback) {
  const vrm_sim::scene::ScenarioParam* found = scene.scenario->param(name);
  return found != nullptr && found->numbers.size() == 1 ? found->numbers.front() : fallback;
}

struct Shot {
  Eigen::Vector3d target;  // on the retina
  double distance;         // tip to target along the beam
  int presses;             // 1, or 2 for a double shot
};

struct Session {
  std::vector<std::pair<double, Eigen::Vector3d>> probe;  // t, tip
  std::vector<std::pair<double, double>> pedal;           // t, travel
};

Session play(const std::vector<Shot>& shots, const Eigen::Vector3d& trocar, double move, double dwell) {
  Session session;
  const auto tipFor = [&](const Shot& shot) {
    return Eigen::Vector3d(shot.target + shot.distance * (trocar - shot.target).normalized());
  };
  // Enter 2 mm through the trocar towards the first place, then move there.
  session.probe.emplace_back(0.0, trocar + 0.002 * (shots.front().target - trocar).normalized());
  session.pedal.emplace_back(0.0, 0.0);
  double t = 1.5;
  for (const Shot& shot : shots) {
    const Eigen::Vector3d tip = tipFor(shot);
    session.probe.emplace_back(t, tip);
    double press = t + 0.15;
    for (int k = 0; k < shot.presses; ++k) {
      // 5 ms edges: no input tick (every 10 or 20 ms) samples a travel near kPressTravel, where a nanosecond of stamp
      // rounding would decide the frame a shot fires in.
      session.pedal.emplace_back(press, 0.0);
      session.pedal.emplace_back(press + 0.005, 1.0);
      session.pedal.emplace_back(press + 0.15, 1.0);
      session.pedal.emplace_back(press + 0.155, 0.0);
      press += 0.35;
    }
    t = press - 0.35 + 0.17 + dwell;
    session.probe.emplace_back(t, tip);
    t += move;
  }
  return session;
}

void print(const char* name, const Session& session, const Eigen::Vector3d& light_tip) {
  std::printf("    %s:\n      playback: once\n      instruments:\n", name);
  std::printf("        - slot: left\n          path:\n            - {t: 0.00, tip: [%.6f, %.6f, %.6f]}\n",
              light_tip.x(), light_tip.y(), light_tip.z());
  std::printf("        - slot: right\n          path:\n");
  for (const auto& [t, tip] : session.probe) {
    std::printf("            - {t: %.2f, tip: [%.6f, %.6f, %.6f]}\n", t, tip.x(), tip.y(), tip.z());
  }
  std::printf("      pedals:\n");
  for (const auto& [t, travel] : session.pedal) std::printf("        - {t: %.3f, travel: %.0f}\n", t, travel);
}

}  // namespace

int main(int argc, char** argv) {
  vrm_sim::usePackageData();
  namespace po = vrm_sim::cli::po;
  std::string scene_argument = "laser_coagulation";
  vrm_sim::cli::CommandLine cli(
      "laser_scripts", "[--scene NAME_OR_PATH]",
      "Prints the expert and novice sessions of a laser_coagulation scene (its scripts block).");
  cli.add()("scene", po::value(&scene_argument)->value_name("NAME_OR_PATH"), "default laser_coagulation");
  if (const auto status = cli.parse(argc, argv)) return *status;
  try {
    const SceneDescription scene = vrm_sim::scene::loadScene(scene_argument);
    if (!scene.scenario || scene.scenario->type != "laser_coagulation") {
      std::fprintf(stderr, "laser_scripts: %s is no laser_coagulation scene\n", scene.source_file.c_str());
      return 1;
    }
    const vrm_sim::anatomy::FundusAnatomy fundus(vrm_sim::scene::fundusParams(scene));
    const vrm_sim::scene::ObjectDescription* lesion = scene.findObject("retinal_break");
    const double lesion_radius = std::get<vrm_sim::scene::DiscParams>(*lesion->mesh.generator).radius;
    const BurnRow row(fundus, lesion->pose.xyz, lesion_radius + param(scene, "ring_offset", 7.5e-4),
                      param(scene, "spacing", 6e-4), param(scene, "band", 3e-4),
                      param(scene, "min_vessel_radius", 2.5e-5));
    const Eigen::Vector3d light_trocar = scene.findTrocar("left")->position_in_eye;
    const Eigen::Vector3d laser_trocar = scene.findTrocar("right")->position_in_eye;
    const Eigen::Vector3d break_centre = lesion->pose.xyz;
    const Eigen::Vector3d light_tip = break_centre + 0.006 * (light_trocar - break_centre).normalized();

    std::vector<Shot> expert, novice;
    std::vector<std::size_t> places, excused;
    for (std::size_t k = 0; k < row.sectors(); ++k) (row.excused(k) ? excused : places).push_back(k);
    for (std::size_t k : places) expert.push_back({row.point(k), 0.002, 1});
    // The novice's mistakes, by position in the order of places.
    const auto offRow = [&](std::size_t k, double radial) {
      // Along the retina away from the break: the row's point pushed outwards, back onto the sphere.
      const Eigen::Vector3d p = row.point(k);
      const Eigen::Vector3d outward = (p - break_centre - (p - break_centre).dot(p.normalized()) * p.normalized());
      return Eigen::Vector3d((p + radial * outward.normalized()).normalized() * p.norm());
    };
    std::vector<std::size_t> redo;
    for (std::size_t i = 0; i < places.size(); ++i) {
      const std::size_t k = places[i];
      if (i == 2) {
        novice.push_back({row.point(k), 0.0038, 1});  // too far: too weak
        redo.push_back(k);
      } else if (i == 5) {
        novice.push_back({row.point(k), 0.0008, 1});  // too close: too strong
      } else if (i == 7) {
        novice.push_back({row.point(k), 0.002, 2});  // fired twice: overlap
      } else if (i == 9) {
        novice.push_back({offRow(k, 5e-4), 0.002, 1});  // off the row
        redo.push_back(k);
      } else {
        novice.push_back({row.point(k), 0.002, 1});
      }
    }
    if (!excused.empty()) novice.push_back({row.point(excused.front()), 0.002, 1});  // on the vessel
    for (std::size_t k : redo) novice.push_back({row.point(k), 0.0021, 1});

    std::printf("  # Written by `rosrun vrm_sim laser_scripts` (tools/laser_scripts.cpp): %zu places, %zu excused.\n",
                row.sectors(), excused.size());
    std::printf("  scripts:\n");
    print("expert", play(expert, laser_trocar, 0.3, 0.15), light_tip);
    print("novice", play(novice, laser_trocar, 0.6, 0.3), light_tip);
    return 0;
  } catch (const std::exception& error) {
    std::fprintf(stderr, "laser_scripts: %s\n", error.what());
    return 1;
  }
}
