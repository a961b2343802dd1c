// The validity benchmark (issue 35): construct validity, the way simulators are judged (experts score higher than
// novices), without separation by construction. No cohort has a script of its own: every member carries out each
// module's expert plan (the scene's scenario.scripts.expert) with its own hands, drawn from its cohort's distributions
// (bench/validity_cohorts.yaml, committed before any scoring change: tremor amplitude and frequency, speed, path
// detours, hesitation, errors near the retina). The modules score what the members did, through the simulation core.
// The modules are the steps of a course (default: config/courses/basic_vitreoretinal.yaml, read with the console's
// course reader): each a scene at a level. Reported per module and cohort: median and IQR of the total over seeds
// 1-10, and the two-sided exact rank test (Mann-Whitney, ties by mid-ranks) against the novices. The course's battery
// pass mark (sum over its steps) is chosen on seeds 1-10 between experts and novices (contrasting groups: fewest
// misclassified, the middle of the best interval) and tested on seeds 11-20 under the course's rule (every step at its
// pass mark in a finished session, and the battery): false fails (experts failing), false passes (novices passing),
// intermediates passing; the course file's own battery mark is tested the same way.
// Usage: bench_validity [--quick] [--out FILE] [--cohorts FILE] [--course FILE]
//        (quick: the course's first two steps, seeds 1-3 and 11-12)
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <numeric>
#include <random>
#include <string>
#include <tuple>
#include <vector>

#include "eyesi_gui/records/course.h"
#include "vrm_scene/cli/cli.h"
#include "vrm_scene/scene_loader.h"
#include "vrm_scene/yaml/strict_reader.h"
#include "vrm_sim/world/offline.h"

using namespace vrm_sim;
using nlohmann::json;

namespace {

struct Normal {
  double mean = 0.0, sd = 0.0;
};

struct Cohort {
  std::string name;
  Normal tremor_rms_um, tremor_hz, time_scale, detour;
  double hesitation_probability = 0.0, pause_min = 0.0, pause_max = 0.0;
  double error_probability = 0.0, depth_min_mm = 0.0, depth_max_mm = 0.0;
};

Normal readNormal(yaml::MapFields& fields, const std::string& key) {
  const yaml::Field field = fields.required(key);
  yaml::MapFields values(field);
  Normal normal;
  normal.mean = values.required("mean").positive();
  normal.sd = values.required("sd").nonNegative();
  values.finish();
  return normal;
}

std::pair<double, double> readInterval(const yaml::Field& field) {
  const std::vector<double> interval = field.numbers(2, "a non-negative number", 0.0, 1e3);
  if (!(interval[0] <= interval[1])) field.fail("expected [min, max] with min <= max");
  return {interval[0], interval[1]};
}

std::vector<Cohort> readCohorts(const std::string& path) {
  const yaml::Field root = yaml::parseText(yaml::readFile(path, "cohort file"), path);
  yaml::MapFields top(root);
  const yaml::Field cohorts_field = top.required("cohorts");
  top.finish();
  std::vector<Cohort> cohorts;
  for (const std::string name : {"expert", "intermediate", "novice"}) {
    yaml::MapFields all(cohorts_field);
    const yaml::Field field = all.required(name);
    yaml::MapFields fields(field);
    Cohort cohort;
    cohort.name = name;
    cohort.tremor_rms_um = readNormal(fields, "tremor_rms_um");
    cohort.tremor_hz = readNormal(fields, "tremor_hz");
    cohort.time_scale = readNormal(fields, "time_scale");
    cohort.detour = readNormal(fields, "detour");
    {
      yaml::MapFields hesitation(fields.required("hesitation"));
      cohort.hesitation_probability = hesitation.required("probability").number("a probability", 0.0, 1.0);
      std::tie(cohort.pause_min, cohort.pause_max) = readInterval(hesitation.required("pause_s"));
      hesitation.finish();
    }
    {
      yaml::MapFields error(fields.required("error"));
      cohort.error_probability = error.required("probability").number("a probability", 0.0, 1.0);
      std::tie(cohort.depth_min_mm, cohort.depth_max_mm) = readInterval(error.required("depth_mm"));
      error.finish();
    }
    fields.finish();
    cohorts.push_back(cohort);
  }
  return cohorts;
}

// One member's hands, drawn from the cohort (seeded per cohort and member).
struct Hands {
  double tremor_amplitude = 0.0;  // m, per-axis sinusoid amplitude
  double tremor_hz = 10.0;
  double time_scale = 1.0;
  double detour = 0.0;
};

double draw(std::mt19937& rng, const Normal& normal, double lo, double hi) {
  std::normal_distribution<double> distribution(normal.mean, normal.sd > 0.0 ? normal.sd : 1e-12);
  return std::clamp(distribution(rng), lo, hi);
}

// The expert's plan carried out by `hands`: all instruments on one time grid (the union of their waypoint times, so
// the light pipe keeps following the working tip), slowed by time_scale, paused where the member hesitates (every
// instrument holds still), each move bent sideways by `detour` of its length, a dip towards the retina before some
// waypoints near it (the working instrument), and the member's tremor on every hand.
scene::ScriptedSession perform(const scene::ScriptedSession& plan, const Cohort& cohort, const Hands& hands,
                               std::mt19937& rng, double eye_radius, scene::InstrumentSlot tool) {
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  std::vector<double> knots;
  for (const scene::ScriptedInstrument& instrument : plan.instruments) {
    for (const scene::InstrumentWaypoint& waypoint : instrument.path) knots.push_back(waypoint.t);
  }
  std::sort(knots.begin(), knots.end());
  knots.erase(std::unique(knots.begin(), knots.end()), knots.end());
  // Where the member pauses (not at the start) and for how long; new time of each knot and of its hold copy.
  std::vector<double> pause(knots.size(), 0.0);
  for (std::size_t i = 1; i < knots.size(); ++i) {
    if (unit(rng) < cohort.hesitation_probability) {
      pause[i] = cohort.pause_min + unit(rng) * (cohort.pause_max - cohort.pause_min);
    }
  }
  std::vector<double> warped(knots.size());
  double shift = 0.0;
  for (std::size_t i = 0; i < knots.size(); ++i) {
    warped[i] = hands.time_scale * knots[i] + shift;
    shift += pause[i];
  }
  scene::ScriptedSession performed = plan;
  performed.name = plan.name + " (" + cohort.name + ")";
  const double inner = eye_radius - 0.0002;  // detours stay 0.2 mm inside the retina
  for (scene::ScriptedInstrument& instrument : performed.instruments) {
    const std::vector<scene::InstrumentWaypoint> original = instrument.path;
    std::vector<scene::InstrumentWaypoint> path;
    for (std::size_t i = 0; i < knots.size(); ++i) {
      scene::InstrumentWaypoint at = scene::samplePath(original, knots[i]);
      at.t = warped[i];
      if (!path.empty()) {
        const scene::InstrumentWaypoint& before = path.back();
        const Eigen::Vector3d move = at.tip_in_eye - before.tip_in_eye;
        if (hands.detour > 0.0 && move.norm() > 3e-4 && at.t - before.t > 0.02) {
          // A detour: the midpoint pushed sideways, perpendicular to the move, by detour x its length.
          Eigen::Vector3d side = move.cross(Eigen::Vector3d(unit(rng) - 0.5, unit(rng) - 0.5, unit(rng) - 0.5));
          if (side.norm() > 1e-12) {
            scene::InstrumentWaypoint middle = scene::samplePath(original, 0.5 * (knots[i - 1] + knots[i]));
            middle.t = 0.5 * (before.t + at.t);
            middle.tip_in_eye =
                0.5 * (before.tip_in_eye + at.tip_in_eye) + hands.detour * move.norm() * side.normalized();
            if (middle.tip_in_eye.norm() > inner) middle.tip_in_eye *= inner / middle.tip_in_eye.norm();
            path.push_back(middle);
          }
        }
        const bool near_retina = at.tip_in_eye.norm() > eye_radius - 0.0015;
        if (instrument.slot == tool && near_retina && at.t - path.back().t > 0.2 &&
            unit(rng) < cohort.error_probability) {
          // An error: on the way in, the tip dips towards the retina (radially out) before it reaches the waypoint.
          scene::InstrumentWaypoint dip = at;
          dip.t = at.t - 0.15;
          const double depth = 1e-3 * (cohort.depth_min_mm + unit(rng) * (cohort.depth_max_mm - cohort.depth_min_mm));
          dip.tip_in_eye = at.tip_in_eye + depth * at.tip_in_eye.normalized();
          if (dip.tip_in_eye.norm() > eye_radius + 5e-4) dip.tip_in_eye *= (eye_radius + 5e-4) / dip.tip_in_eye.norm();
          path.push_back(dip);
        }
      }
      path.push_back(at);
      if (pause[i] > 0.0) {
        scene::InstrumentWaypoint hold = at;
        hold.t = at.t + pause[i];
        path.push_back(hold);
      }
    }
    instrument.path = path;
    instrument.tremor.amplitude = hands.tremor_amplitude;
    instrument.tremor.frequency_hz = hands.tremor_hz;
  }
  return performed;
}

Hands drawHands(const Cohort& cohort, std::mt19937& rng) {
  Hands hands;
  hands.tremor_amplitude = 1e-6 * draw(rng, cohort.tremor_rms_um, 5.0, 400.0) / std::sqrt(1.5);
  hands.tremor_hz = draw(rng, cohort.tremor_hz, 6.0, 12.0);
  hands.time_scale = draw(rng, cohort.time_scale, 0.8, 3.0);
  hands.detour = draw(rng, cohort.detour, 0.0, 0.6);
  return hands;
}

double quantile(std::vector<double> values, double q) {
  std::sort(values.begin(), values.end());
  if (values.empty()) return std::nan("");
  const double position = q * (values.size() - 1);
  const std::size_t low = static_cast<std::size_t>(std::floor(position));
  const std::size_t high = std::min(low + 1, values.size() - 1);
  return values[low] + (position - low) * (values[high] - values[low]);
}

// Two-sided exact Mann-Whitney test by the rank sum of `a` (mid-ranks for ties): its distribution over every split of
// the pooled ranks, counted by dynamic programming on doubled ranks (integers).
double rankTestP(const std::vector<double>& a, const std::vector<double>& b) {
  std::vector<std::pair<double, int>> pooled;
  for (double v : a) pooled.push_back({v, 0});
  for (double v : b) pooled.push_back({v, 1});
  std::sort(pooled.begin(), pooled.end());
  const std::size_t n = pooled.size(), na = a.size();
  std::vector<int> doubled(n);
  for (std::size_t i = 0; i < n;) {
    std::size_t j = i;
    while (j < n && pooled[j].first == pooled[i].first) ++j;
    for (std::size_t k = i; k < j; ++k) doubled[k] = static_cast<int>(i + j + 1);  // 2 x mid-rank of ranks i+1..j
    i = j;
  }
  int observed = 0;
  for (std::size_t i = 0; i < n; ++i) {
    if (pooled[i].second == 0) observed += doubled[i];
  }
  const int max_sum = std::accumulate(doubled.begin(), doubled.end(), 0);
  // count[k][s]: subsets of size k with doubled rank sum s.
  std::vector<std::vector<double>> count(na + 1, std::vector<double>(max_sum + 1, 0.0));
  count[0][0] = 1.0;
  for (std::size_t i = 0; i < n; ++i) {
    for (std::size_t k = std::min(na, i + 1); k >= 1; --k) {
      for (int s = max_sum; s >= doubled[i]; --s) count[k][s] += count[k - 1][s - doubled[i]];
    }
  }
  double total = 0.0, extreme = 0.0;
  const double expected = na * (n + 1.0);  // doubled
  for (int s = 0; s <= max_sum; ++s) {
    total += count[na][s];
    if (std::abs(s - expected) >= std::abs(observed - expected) - 1e-9) extreme += count[na][s];
  }
  return total > 0.0 ? std::min(1.0, extreme / total) : 1.0;
}

// How many runs of the seeds ended each way.
json outcomeCounts(const std::map<int, std::string>& by_seed, const std::vector<int>& seeds) {
  std::map<std::string, int> counts;
  for (int seed : seeds) ++counts[by_seed.at(seed)];
  return counts;
}

}  // namespace

int main(int argc, char** argv) {
  bool quick = false;
  std::string out_path = "bench/results/validity.json";
  std::string cohorts_path = std::string(EYESI_GUI_SOURCE_DIR) + "/bench/validity_cohorts.yaml";
  std::string course_path = std::string(EYESI_GUI_SOURCE_DIR) + "/config/courses/basic_vitreoretinal.yaml";
  cli::CommandLine command_line(
      "bench_validity", "[--quick] [--out FILE] [--cohorts FILE] [--course FILE]",
      "Construct validity: seeded expert, intermediate and novice cohorts carry out every "
      "course step's expert plan; score distributions, rank tests and the course's pass mark.");
  command_line.add()("quick", cli::po::bool_switch(&quick), "a short smoke run (two steps, five members per cohort)")(
      "out", cli::po::value(&out_path)->value_name("FILE"), "the JSON results (default bench/results/validity.json)")(
      "cohorts", cli::po::value(&cohorts_path)->value_name("FILE"), "the cohort file")(
      "course", cli::po::value(&course_path)->value_name("FILE"), "the course whose steps are the modules");
  if (const auto status = command_line.parse(argc, argv)) return *status;
  const auto started = std::chrono::steady_clock::now();
  std::vector<Cohort> cohorts;
  eyesi_gui::records::Course course;
  try {
    cohorts = readCohorts(cohorts_path);
    course = eyesi_gui::records::readCourseFile(course_path);
  } catch (const YamlError& error) {
    std::fprintf(stderr, "bench_validity: %s\n", error.what());
    return 2;
  }
  std::vector<eyesi_gui::records::CourseStep> steps = course.steps;
  if (quick && steps.size() > 2) steps.resize(2);
  const auto label = [](const eyesi_gui::records::CourseStep& step) {
    return step.scene + (step.level.empty() ? "" : "/" + step.level);
  };
  std::vector<int> selection_seeds, test_seeds;
  for (int seed = 1; seed <= (quick ? 3 : 10); ++seed) selection_seeds.push_back(seed);
  for (int seed = 11; seed <= (quick ? 12 : 20); ++seed) test_seeds.push_back(seed);
  std::vector<int> seeds = selection_seeds;
  seeds.insert(seeds.end(), test_seeds.begin(), test_seeds.end());

  // totals[step][cohort][seed]; outcomes: how each run ended ("finished", "failed: <message>", "timeout: ...").
  std::vector<std::map<std::string, std::map<int, double>>> totals(steps.size());
  std::vector<std::map<std::string, std::map<int, std::string>>> outcomes(steps.size());
  for (std::size_t s = 0; s < steps.size(); ++s) {
    const scene::SceneDescription scene = scene::loadScene(steps[s].module, steps[s].level);
    const scene::ScriptedSession& plan = scene::findScript(scene, "expert");
    scene::InstrumentSlot tool = scene::InstrumentSlot::kRight;
    if (const scene::ScenarioParam* param = scene.scenario->param("tool"); param && param->names.size() == 1) {
      tool = param->names[0] == "left" ? scene::InstrumentSlot::kLeft : scene::InstrumentSlot::kRight;
    }
    for (std::size_t c = 0; c < cohorts.size(); ++c) {
      for (int seed : seeds) {
        // One stream per (cohort, member): the same member is the same hands in every step.
        std::mt19937 hands_rng(static_cast<std::uint32_t>(1000 * (c + 1) + seed));
        const Hands hands = drawHands(cohorts[c], hands_rng);
        // The member's slips differ per step (and are the same in every run of the benchmark).
        std::mt19937 rng(static_cast<std::uint32_t>(7919 * seed + 104729 * (c + 1) + 31 * s));
        world::ScenarioRunOptions options;
        options.script_file = perform(plan, cohorts[c], hands, rng, scene.eye.radius, tool);
        options.seed = static_cast<std::uint32_t>(seed);
        const world::ScenarioRunResult run = world::runScenario(scene, options);
        totals[s][cohorts[c].name][seed] = run.score.total;
        // "finished", or the message, which names the way it ended ("failed: retina_contacts reached 5", ...).
        outcomes[s][cohorts[c].name][seed] = run.state == "finished" || run.message.rfind(run.state, 0) == 0
                                                 ? (run.state == "finished" ? run.state : run.message)
                                                 : run.state + ": " + run.message;
      }
    }
    std::printf("%-24s done (%.0f s)\n", label(steps[s]).c_str(),
                std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count());
    std::fflush(stdout);
  }

  json rows = json::array();
  int separating = 0;
  std::printf("\n%-24s %-13s %3s %8s %8s %8s %10s\n", "module", "cohort", "n", "median", "q1", "q3", "p_vs_novice");
  for (std::size_t s = 0; s < steps.size(); ++s) {
    std::map<std::string, std::vector<double>> selected;
    for (const Cohort& cohort : cohorts) {
      for (int seed : selection_seeds) selected[cohort.name].push_back(totals[s][cohort.name][seed]);
    }
    for (const Cohort& cohort : cohorts) {
      const std::vector<double>& values = selected[cohort.name];
      json row = {{"suite", "validity"},
                  {"module", label(steps[s])},
                  {"cohort", cohort.name},
                  {"n", static_cast<int>(values.size())},
                  {"median", quantile(values, 0.5)},
                  {"q1", quantile(values, 0.25)},
                  {"q3", quantile(values, 0.75)},
                  {"step_pass_mark", steps[s].pass_mark},
                  {"outcomes", outcomeCounts(outcomes[s][cohort.name], selection_seeds)},
                  {"totals", values}};
      double p = std::nan("");
      if (cohort.name != "novice") {
        p = rankTestP(values, selected["novice"]);
        row["p_vs_novice"] = p;
        if (cohort.name == "expert" && p < 0.01 && quantile(values, 0.5) > quantile(selected["novice"], 0.5)) {
          ++separating;
        }
      } else {
        row["p_vs_novice"] = nullptr;
      }
      std::printf("%-24s %-13s %3zu %8.1f %8.1f %8.1f %10s\n", label(steps[s]).c_str(), cohort.name.c_str(),
                  values.size(), quantile(values, 0.5), quantile(values, 0.25), quantile(values, 0.75),
                  std::isnan(p) ? "-" : std::to_string(p).substr(0, 8).c_str());
      rows.push_back(row);
    }
  }

  // Contrasting groups: the threshold with the fewest misclassified members (experts below, novices at or above), the
  // middle of the best interval; returns (mark, misclassified).
  const auto contrastingGroups = [](const std::vector<double>& experts, const std::vector<double>& novices) {
    std::vector<double> candidates = experts;
    candidates.insert(candidates.end(), novices.begin(), novices.end());
    std::sort(candidates.begin(), candidates.end());
    int best_errors = 1 << 30;
    double best_low = 0.0, best_high = 0.0;
    for (std::size_t i = 0; i + 1 < candidates.size(); ++i) {
      const double mark = 0.5 * (candidates[i] + candidates[i + 1]);
      int errors = 0;
      for (double v : experts) errors += v < mark;
      for (double v : novices) errors += v >= mark;
      if (errors < best_errors) {
        best_errors = errors;
        best_low = best_high = mark;
      } else if (errors == best_errors) {
        best_high = mark;
      }
    }
    return std::make_pair(std::round(0.5 * (best_low + best_high)), best_errors);
  };
  // Each step's own mark by the same method, but never above the lowest expert total of the selection seeds (less a
  // point): a step mark is a floor every competent member clears; the battery is what separates (a step mark the
  // cohort's experts cannot reach fails the course for them whatever the battery).
  std::vector<double> chosen_step_marks(steps.size());
  for (std::size_t s = 0; s < steps.size(); ++s) {
    std::vector<double> experts, novices;
    for (int seed : selection_seeds) {
      experts.push_back(totals[s]["expert"][seed]);
      novices.push_back(totals[s]["novice"][seed]);
    }
    const auto [mark, errors] = contrastingGroups(experts, novices);
    const double floor = std::floor(*std::min_element(experts.begin(), experts.end())) - 1.0;
    chosen_step_marks[s] = std::max(0.0, std::min(mark, floor));
    for (json& row : rows) {
      if (row["module"] == label(steps[s])) row["step_mark_chosen"] = chosen_step_marks[s];
    }
    std::printf(
        "%-24s step mark chosen on seeds %d-%d: %.0f (contrasting groups %.0f, %d misclassified; lowest "
        "expert - 1: %.0f; the course file's %.0f)\n",
        label(steps[s]).c_str(), selection_seeds.front(), selection_seeds.back(), chosen_step_marks[s], mark, errors,
        floor, steps[s].pass_mark);
  }

  // The battery: the sum of the step totals (max 100 per step). The course rule: every step passed in a finished
  // session, and the battery at its mark.
  const auto battery = [&](const std::string& cohort, int seed) {
    double sum = 0.0;
    for (std::size_t s = 0; s < steps.size(); ++s) sum += totals[s].at(cohort).at(seed);
    return sum;
  };
  const auto passes = [&](const std::string& cohort, int seed, const std::vector<double>& step_marks,
                          double battery_mark) {
    for (std::size_t s = 0; s < steps.size(); ++s) {
      if (outcomes[s].at(cohort).at(seed) != "finished" || totals[s].at(cohort).at(seed) < step_marks[s]) {
        return false;
      }
    }
    return battery(cohort, seed) >= battery_mark;
  };
  std::vector<double> file_step_marks;
  for (const auto& step : steps) file_step_marks.push_back(step.pass_mark);
  std::vector<double> expert_sel, novice_sel;
  for (int seed : selection_seeds) {
    expert_sel.push_back(battery("expert", seed));
    novice_sel.push_back(battery("novice", seed));
  }
  const auto [pass_mark, best_errors] = contrastingGroups(expert_sel, novice_sel);
  struct Outcome {
    int false_fail = 0, false_pass = 0, intermediate_pass = 0;
  };
  const auto test = [&](const std::vector<double>& step_marks, double battery_mark) {
    Outcome outcome;
    for (int seed : test_seeds) {
      outcome.false_fail += !passes("expert", seed, step_marks, battery_mark);
      outcome.false_pass += passes("novice", seed, step_marks, battery_mark);
      outcome.intermediate_pass += passes("intermediate", seed, step_marks, battery_mark);
    }
    return outcome;
  };
  const Outcome chosen = test(chosen_step_marks, pass_mark);
  // Each held-out member under the chosen marks: battery, and the steps that stopped them.
  json held_out = json::array();
  for (const Cohort& cohort : cohorts) {
    for (int seed : test_seeds) {
      json failed_steps = json::array();
      for (std::size_t s = 0; s < steps.size(); ++s) {
        const std::string& outcome = outcomes[s].at(cohort.name).at(seed);
        if (outcome != "finished" || totals[s].at(cohort.name).at(seed) < chosen_step_marks[s]) {
          failed_steps.push_back(label(steps[s]) + " (" + outcome + ", " +
                                 std::to_string(static_cast<int>(std::round(totals[s].at(cohort.name).at(seed)))) +
                                 ")");
        }
      }
      held_out.push_back({{"cohort", cohort.name},
                          {"seed", seed},
                          {"battery", battery(cohort.name, seed)},
                          {"passed", passes(cohort.name, seed, chosen_step_marks, pass_mark)},
                          {"failed_steps", failed_steps}});
    }
  }
  const double shipped_mark = course.battery_pass_mark.value_or(0.0);
  const Outcome shipped = test(file_step_marks, shipped_mark);
  const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
  const std::size_t max = 100 * steps.size();
  std::printf("\nseparating modules (expert vs novice, p < 0.01): %d of %zu (target >= 70 %%: %s)\n", separating,
              steps.size(), separating >= 0.7 * steps.size() ? "met" : "NOT met");
  std::printf(
      "course '%s' (%zu steps, battery max %zu): battery pass mark %.0f chosen on seeds %d-%d (%d of %zu "
      "misclassified); on seeds %d-%d under the course rule: false fails %d of %zu experts, false passes %d "
      "of %zu novices, intermediates passing %d of %zu (chosen step and battery marks); with the file's marks (battery "
      "%.0f): %d / %d / %d\n",
      course.name.c_str(), steps.size(), max, pass_mark, selection_seeds.front(), selection_seeds.back(), best_errors,
      2 * selection_seeds.size(), test_seeds.front(), test_seeds.back(), chosen.false_fail, test_seeds.size(),
      chosen.false_pass, test_seeds.size(), chosen.intermediate_pass, test_seeds.size(), shipped_mark,
      shipped.false_fail, shipped.false_pass, shipped.intermediate_pass);
  json result = {{"suite", "validity"},
                 {"command", std::string("./scripts/bench.sh") + (quick ? " --quick" : "") + " validity"},
                 {"quick", quick},
                 {"cohorts_file", "src/eyesi_gui/bench/validity_cohorts.yaml"},
                 {"wall_seconds", wall},
                 {"separating_modules", separating},
                 {"modules", static_cast<int>(steps.size())},
                 {"target_separating_fraction", 0.7},
                 {"course",
                  {{"name", course.name},
                   {"file", "src/eyesi_gui/config/courses/" + std::filesystem::path(course_path).filename().string()},
                   {"max", static_cast<int>(max)},
                   {"pass_mark", pass_mark},
                   {"selection_seeds", {selection_seeds.front(), selection_seeds.back()}},
                   {"test_seeds", {test_seeds.front(), test_seeds.back()}},
                   {"misclassified_on_selection", best_errors},
                   {"false_pass", chosen.false_pass},
                   {"false_fail", chosen.false_fail},
                   {"intermediate_pass", chosen.intermediate_pass},
                   {"n_test", static_cast<int>(test_seeds.size())},
                   {"step_marks", chosen_step_marks},
                   {"file_battery_pass_mark", shipped_mark},
                   {"file_step_marks", file_step_marks},
                   {"file_mark_false_pass", shipped.false_pass},
                   {"file_mark_false_fail", shipped.false_fail},
                   {"file_mark_intermediate_pass", shipped.intermediate_pass},
                   {"held_out", held_out}}},
                 {"rows", rows}};
  std::ofstream out(out_path);
  out << result.dump(1) << "\n";
  return out ? 0 : 1;
}
