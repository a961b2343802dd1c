// Scenario checkpoints (issue 39 §1): a ScenarioRunner saved at a frame boundary and loaded into a runner freshly built
// from the same scene continues bit for bit — same hash, same status, same saved bytes — for every scenario type.
//
// The sessions are the shipped scenes' own scripts (expert and novice, the ones test_scenarios plays through the
// World), sampled into FrameViews here, with the tissue and the bleeding retina the surgical types score made up by a
// small deterministic model, so the scenario layer runs alone. A checkpoint is taken at EVERY frame and continued for
// a short window (a member that matters only in the frame after it, such as the jaws' last opening, is caught where
// it matters), and kFullCheckpoints of them to the end of the session (a member read only at the end, such as the
// peel's initial adhesion count).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <list>
#include <memory>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "vrm_scene/scene_loader.h"
#include "vrm_sim/scenario/runner.h"
#include "vrm_sim/scenario/scenario.h"
#include "vrm_sim/state/state_archive.h"
#include "vrm_sim/world/offline.h"

namespace vrm_sim {
namespace {

using scenario::FrameView;
using scenario::ScenarioRunner;

constexpr double kRate = 50.0;                                // Hz, as scenario_offline plays the scripts
constexpr double kGrace = 2.0;                                // s after the script's end
constexpr std::size_t kWindow = 30;                           // frames every checkpoint is continued for
constexpr std::size_t kFullCheckpoints = 8;                   // checkpoints per session continued to its end
constexpr std::int64_t kEpochNs = 1'700'000'000'000'000'000;  // live stamps: a lost time base is not near zero

const std::vector<std::string>& scenarioTypes() {
  static const std::vector<std::string> types = {"navigation",        "trajectory",          "pick_and_place",
                                                 "steady_hold",       "object_manipulation", "bimanual",
                                                 "membrane_peeling",  "ilm_peeling",         "vitrectomy",
                                                 "laser_coagulation", "retina_relocation",   "posterior_hyaloid"};
  return types;
}

bool surgical(const std::string& type) {
  return type == "membrane_peeling" || type == "ilm_peeling" || type == "vitrectomy" || type == "retina_relocation" ||
         type == "posterior_hyaloid";
}

// ---- the session: frames from the scripts, tissue and retina from a made-up model ----

// What a TissueView points to, owned by the step (the World's views point into its tissues during the frame).
struct TissueData {
  std::vector<Eigen::Vector3d> positions, rest;
  std::vector<Eigen::Vector3d> tear_points;
};

struct Step {
  enum class Kind { kFrame, kPause, kResume };
  Kind kind = Kind::kFrame;
  double time = 0.0;
  std::int64_t stamp = 0;
  FrameView frame;
  std::vector<std::shared_ptr<TissueData>> data;  // shared: the views' pointers survive copies of the step
};

// The made-up tissue of one deformable object: nodes on a cap at the posterior pole that lift as the work goes on,
// adhesion points released one by one, springs torn late in the session, a needle's fluid, adhesion tears. Not
// physics; only plausible, monotone where the core's figures are, and driven by the scripted instruments where it can
// be (grasps, suction and cutting, injection), so the scenario's state changes the way it does in a real session.
class MadeUpTissue {
 public:
  MadeUpTissue(std::string object, scene::ObjectRole role, double eye_radius, double duration)
      : object_(std::move(object)), role_(role), eye_radius_(eye_radius), duration_(duration) {
    constexpr int kRings = 4, kPerRing = 10;
    for (int ring = 0; ring <= kRings; ++ring) {
      const int count = ring == 0 ? 1 : kPerRing;
      for (int k = 0; k < count; ++k) {
        const double polar = 1.6e-3 / eye_radius * ring / kRings;
        const double azimuth = 2.0 * M_PI * k / count + 0.3 * ring;
        const double r = eye_radius - 5e-5;
        rest_.emplace_back(r * std::sin(polar) * std::cos(azimuth), r * std::sin(polar) * std::sin(azimuth),
                           -r * std::cos(polar));
      }
    }
    initial_nodes_ = rest_.size();
  }

  scenario::TissueView next(double t, double dt, const std::vector<scenario::InstrumentView>& instruments,
                            const std::vector<world::InstrumentState>& states, TissueData& data) {
    const double progress = std::clamp(t / duration_, 0.0, 1.0);
    bool grasping = false, cutting = false;
    double flow = 0.0;
    const scenario::InstrumentView* needle = nullptr;
    for (std::size_t i = 0; i < instruments.size(); ++i) {
      const scenario::InstrumentView& tool = instruments[i];
      if (!tool.valid) continue;
      const bool near = eye_radius_ - tool.tip.norm() < 2.5e-3;
      if (tool.type == scene::InstrumentType::kForceps && tool.jaw_angle < 0.2 && near) grasping = true;
      if (tool.type == scene::InstrumentType::kVitrector && tool.suction > 0.0) {
        grasping = grasping || near;
        cutting = cutting || tool.cut_rate > 0.0;
      }
      if (tool.type == scene::InstrumentType::kNeedle) {
        needle = &tool;
        for (const world::InstrumentState& state : states) {
          if (state.slot == tool.slot) flow = state.injection_flow;
        }
      }
    }
    // Nodes born by cutting or tearing later in the session: no rest position (NaN), like the World's rest_by_slot.
    if (t > 0.7 * duration_ && rest_.size() < initial_nodes_ + 4 && static_cast<long>(t * kRate) % 25 == 0) {
      rest_.push_back(Eigen::Vector3d::Constant(std::nan("")));
    }
    // Work advances while the instrument works, but never ahead of the script's time: the session must not finish
    // long before its script ends, or the checkpoints after that would test a frozen scenario.
    if (grasping) lift_ = std::min(1.05 * progress, lift_ + 0.004);
    lift_ = std::max(lift_, 0.5 * progress);
    needle_inside_ = needle != nullptr && eye_radius_ - needle->tip.norm() < 4e-4;
    if (flow > 0.0) (needle_inside_ ? fluid_ : outside_) += flow * dt;
    if (cutting && static_cast<long>(t * kRate) % 4 == 0) {
      cut_ = std::min<std::uint64_t>(static_cast<std::uint64_t>(1.05 * progress * initial_nodes_), cut_ + 1);
    }
    if (t > 0.6 * duration_) torn_ = static_cast<std::uint64_t>((t - 0.6 * duration_) * 3.0);
    released_ = std::min<std::uint64_t>(kAdhesions, static_cast<std::uint64_t>(kAdhesions * 1.2 * progress));
    max_force_ = std::max(max_force_, 4e-3 * progress * (1.0 + 0.5 * std::sin(3.0 * t)));
    if (max_force_ > 3e-3 && static_cast<long>(t * kRate) % 40 == 7) {
      tear_points_.push_back(rest_[tear_points_.size() % initial_nodes_]);
    }

    data.rest = rest_;
    data.positions.resize(rest_.size());
    const double bleb = 3e-7 * std::cbrt(fluid_ * 1e9);  // m: a fluid volume's lift (made up)
    for (std::size_t i = 0; i < rest_.size(); ++i) {
      const Eigen::Vector3d base = rest_[i].allFinite() ? rest_[i] : rest_[i % initial_nodes_];
      const double share = std::clamp(1.5 * lift_ - static_cast<double>(i) / initial_nodes_, 0.0, 1.0);
      const double lift = 4e-4 * share + bleb * std::max(0.0, 1.0 - static_cast<double>(i) / 20.0);
      data.positions[i] = base * (1.0 - lift / base.norm());
    }
    data.tear_points = tear_points_;
    std::size_t lifted = 0;
    for (std::size_t i = 0; i < rest_.size(); ++i) lifted += (data.positions[i] - data.rest[i]).norm() > 1e-4;

    scenario::TissueView view;
    view.object = object_;
    view.role = role_;
    view.grasped_nodes = grasping ? 3 : 0;
    view.max_strain = 0.1 * lift_;
    view.max_lift = 4e-4 * lift_;
    view.lifted_fraction = static_cast<double>(lifted) / static_cast<double>(rest_.size());
    view.torn_springs = torn_;
    view.cut_nodes = cut_;
    view.released_adhesions = released_;
    view.adhesion_points = kAdhesions - released_;
    view.max_adhesion_force = max_force_;
    view.adhesion_tears = tear_points_.size();
    view.adhesion_tear_points = &data.tear_points;
    view.fluid_volume = fluid_;
    view.enclosed_volume = 1.1 * fluid_;
    view.fluid_pressure = 1e9 * fluid_;
    view.injected_outside = outside_;
    view.needle_inside = needle_inside_;
    view.initial_node_count = initial_nodes_;
    view.positions = data.positions.data();
    view.node_count = data.positions.size();
    view.rest_positions = &data.rest;
    return view;
  }

 private:
  static constexpr std::uint64_t kAdhesions = 12;
  std::string object_;
  scene::ObjectRole role_;
  double eye_radius_, duration_;
  std::vector<Eigen::Vector3d> rest_;
  std::size_t initial_nodes_ = 0;
  double lift_ = 0.0, fluid_ = 0.0, outside_ = 0.0, max_force_ = 0.0;
  bool needle_inside_ = false;
  std::uint64_t cut_ = 0, torn_ = 0, released_ = 0;
  std::vector<Eigen::Vector3d> tear_points_;
};

// The session of `script` in `scene`, as the World would show it to the scenario, plus a pause and a resume in the
// middle (the running time must carry across a checkpoint taken while paused, too). With `lost_tracking`, every
// instrument is untracked for 0.3 s after a quarter of the session: held objects fall, grasps end, work stops.
std::vector<Step> session(const scene::SceneDescription& scene, const std::string& script, bool lost_tracking) {
  const scene::SceneDescription scripted = scene::withScript(scene, script);
  const std::vector<scene::PedalWaypoint>& pedals = scene::findScript(scene, script).pedals;
  const double duration = std::max(scripted.scriptedDuration(), pedals.empty() ? 0.0 : pedals.back().t);
  const bool made_up_tissue = surgical(scene.scenario->type);
  std::vector<MadeUpTissue> tissues;
  if (made_up_tissue) {
    for (const scene::ObjectDescription& object : scene.objects) {
      if (object.isDeformable()) tissues.emplace_back(object.name, object.role, scene.eye.radius, duration);
    }
  }
  std::vector<Step> steps;
  const long ticks = std::lround((duration + kGrace) * kRate);
  const long pause_at = ticks * 2 / 5, resume_at = pause_at + static_cast<long>(kRate / 2);
  const long lost_from = ticks / 4, lost_until = lost_from + static_cast<long>(0.3 * kRate);
  std::size_t retina_events = 2;  // the core counted contacts before the session started: RetinaContacts' baseline
  double injury = 0.0, injured_area = 0.0;
  for (long tick = 0; tick <= ticks; ++tick) {
    const double t = static_cast<double>(tick) / kRate;
    const std::int64_t stamp = kEpochNs + world::fromSeconds(t);
    const double time = 1e-9 * static_cast<double>(stamp);
    if (tick == pause_at || tick == resume_at) {
      Step command;
      command.kind = tick == pause_at ? Step::Kind::kPause : Step::Kind::kResume;
      command.time = time;
      command.stamp = stamp;
      steps.push_back(command);
    }
    Step step;
    step.time = time;
    step.stamp = stamp;
    FrameView& frame = step.frame;
    frame.time = time;
    frame.stamp_ns = stamp;
    frame.dt = tick == 0 ? 0.0 : 1.0 / kRate;
    const std::vector<world::InstrumentState> states = world::scriptedInputsAt(scripted, t, stamp);
    for (const scene::InstrumentDescription& instrument : scene.instruments) {
      scenario::InstrumentView view;
      view.slot = scene::toString(instrument.slot);
      view.type = instrument.type;
      for (const world::InstrumentState& state : states) {
        if (state.slot != view.slot) continue;
        const Eigen::Isometry3d pose = state.pose();
        view.type = state.type.value_or(instrument.type);
        view.valid = state.valid && !(lost_tracking && tick >= lost_from && tick < lost_until);
        view.tip = pose.translation();
        view.axis = pose.linear().col(2);
        view.orientation = Eigen::Quaterniond(pose.linear());
        view.jaw_angle = state.jaw_angle;
        view.suction = state.suction;
        view.cut_rate = state.cut_rate;
      }
      if (view.type == scene::InstrumentType::kLaserProbe) {
        const auto* laser = std::get_if<scene::LaserProbeParams>(&instrument.params);
        view.laser = laser != nullptr ? *laser : scene::LaserProbeParams{};
      }
      frame.instruments.push_back(view);
    }
    if (!pedals.empty()) {
      const scene::PedalWaypoint pedal = scene::samplePedals(pedals, t);
      frame.pedals = {pedal.travel, pedal.reflux, pedal.instrument_switch};
    }
    if (made_up_tissue) {
      for (MadeUpTissue& tissue : tissues) {
        step.data.push_back(std::make_shared<TissueData>());
        frame.tissues.push_back(tissue.next(t, frame.dt, frame.instruments, states, *step.data.back()));
      }
      // A bleeding retina: a contact now and then, each spreading the injury over a few frames.
      const long phase = tick % 331;
      if (phase == 150) ++retina_events;
      frame.retina.simulated = true;
      frame.retina.contact_events = retina_events;
      frame.retina.in_contact = phase >= 150 && phase < 154;
      if (frame.retina.in_contact) {
        injury = std::min(1.0, injury + 0.03);
        injured_area += 2e-9;
      }
      frame.retina.max_injury = injury;
      frame.retina.injured_area = injured_area;
    }
    steps.push_back(std::move(step));
  }
  return steps;
}

void apply(ScenarioRunner& runner, const Step& step) {
  switch (step.kind) {
    case Step::Kind::kFrame:
      runner.frame(step.frame);
      break;
    case Step::Kind::kPause:
      runner.pause(step.time, step.stamp);
      break;
    case Step::Kind::kResume:
      runner.resume(step.time, step.stamp);
      break;
  }
}

// ---- saving, loading, comparing ----

std::string save(ScenarioRunner& runner) {
  StateArchive archive = StateArchive::saver();
  runner.transferState(archive);
  return archive.takeBytes();
}

void load(ScenarioRunner& runner, const std::string& bytes) {
  StateArchive archive = StateArchive::loader(bytes);
  runner.transferState(archive);
  if (!archive.atEnd()) throw StateError("checkpoint: " + std::to_string(archive.remaining()) + " bytes left over");
}

std::uint64_t hashOf(const ScenarioRunner& runner) {
  std::uint64_t hash = 1469598103934665603ull;
  runner.hash(hash);
  return hash;
}

bool same(double a, double b) { return std::memcmp(&a, &b, sizeof(double)) == 0; }  // bit for bit, NaN too
template <typename Matrix>
bool same(const Matrix& a, const Matrix& b) {
  return std::memcmp(a.data(), b.data(), sizeof(double) * a.size()) == 0;
}
bool same(const std::optional<double>& a, const std::optional<double>& b) {
  return a.has_value() == b.has_value() && (!a || same(*a, *b));
}

// The first field in which two statuses differ ("" when none), compared field by field and bit for bit — on its
// own, so a field that Status::transferState forgot is still compared.
std::string difference(const scenario::Status& a, const scenario::Status& b) {
  if (a.state != b.state) return std::string("state ") + toString(a.state) + " vs " + toString(b.state);
  if (!same(a.elapsed, b.elapsed)) return "elapsed " + std::to_string(a.elapsed) + " vs " + std::to_string(b.elapsed);
  if (a.timed_out != b.timed_out) return "timed_out";
  if (a.message != b.message) return "message '" + a.message + "' vs '" + b.message + "'";
  if (a.progress != b.progress) return "progress '" + a.progress + "' vs '" + b.progress + "'";
  if (!same(a.start_time, b.start_time) || !same(a.end_time, b.end_time)) return "start or end time";
  if (!same(a.score.total, b.score.total)) {
    return "score total " + std::to_string(a.score.total) + " vs " + std::to_string(b.score.total);
  }
  if (a.score.items.size() != b.score.items.size()) return "number of score items";
  for (std::size_t i = 0; i < a.score.items.size(); ++i) {
    const scenario::ScoreItem &x = a.score.items[i], &y = b.score.items[i];
    if (x.name != y.name || x.unit != y.unit || !same(x.value, y.value) || !same(x.weight, y.weight) ||
        !same(x.points, y.points)) {
      std::ostringstream out;
      out.precision(17);
      out << "score item " << x.name << " = " << x.value << " (" << x.points << " points) vs " << y.name << " = "
          << y.value << " (" << y.points << " points)";
      return out.str();
    }
  }
  if (a.score.groups.size() != b.score.groups.size()) return "number of factor groups";
  for (std::size_t i = 0; i < a.score.groups.size(); ++i) {
    const scenario::GroupScore &x = a.score.groups[i], &y = b.score.groups[i];
    if (x.name != y.name || !same(x.points, y.points) || !same(x.weight, y.weight)) return "factor group " + x.name;
  }
  if (a.events.size() != b.events.size()) {
    return "penalty events " + std::to_string(a.events.size()) + " vs " + std::to_string(b.events.size());
  }
  for (std::size_t i = 0; i < a.events.size(); ++i) {
    const scenario::PenaltyEvent &x = a.events[i], &y = b.events[i];
    if (!same(x.time, y.time) || x.kind != y.kind || x.item != y.item || x.slot != y.slot ||
        x.instrument != y.instrument || !same(x.position, y.position) || !same(x.points, y.points)) {
      return "penalty event " + std::to_string(i) + " (" + x.item + " vs " + y.item + ")";
    }
  }
  if (a.events_dropped != b.events_dropped) return "events_dropped";
  if (a.placements.size() != b.placements.size()) return "number of placements";
  for (std::size_t i = 0; i < a.placements.size(); ++i) {
    const scenario::ObjectPlacement &x = a.placements[i], &y = b.placements[i];
    if (x.name != y.name || x.frame_id != y.frame_id || !same(x.pose.matrix(), y.pose.matrix())) {
      return "placement of " + x.name;
    }
  }
  if (a.burns.size() != b.burns.size()) return "number of burns";
  for (std::size_t i = 0; i < a.burns.size(); ++i) {
    const scenario::LaserBurn &x = a.burns[i], &y = b.burns[i];
    if (!same(x.position, y.position) || !same(x.spot, y.spot) || !same(x.diameter, y.diameter) ||
        !same(x.grade, y.grade) || !same(x.whiteness, y.whiteness) || !same(x.power, y.power) ||
        !same(x.duration, y.duration) || !same(x.distance, y.distance) || !same(x.time, y.time)) {
      return "burn " + std::to_string(i);
    }
  }
  if (a.scenario != b.scenario || a.type != b.type || a.difficulty != b.difficulty) return "scene names";
  return "";
}

// A runner loaded from the checkpoint after step `from`, fed the same steps as the uninterrupted one until `until`.
struct Continuation {
  std::size_t from = 0, until = 0;
  std::unique_ptr<ScenarioRunner> runner;
};

struct Outcome {
  std::size_t steps = 0, active_steps = 0, checkpoints = 0, distinct_hashes = 0;
  std::string final_state, final_message;
  std::size_t events = 0;
  bool bytes_changed = false;
};

// Plays `steps` once uninterrupted; after every step saves it, loads the bytes into a fresh runner (which must save
// the very same bytes at once) and feeds both the following steps, requiring after each: the same hash and the same
// status; at the end of the continuation, the same saved bytes.
Outcome checkEveryCheckpoint(const scene::SceneDescription& scene, const std::vector<Step>& steps,
                             const std::string& what) {
  Outcome outcome;
  ScenarioRunner original(scene);
  EXPECT_EQ(original.start(steps.front().time, steps.front().stamp), "") << what;
  const std::string initial = save(original);
  std::list<Continuation> live;
  std::set<std::uint64_t> hashes;
  auto checkpoint = [&](std::size_t after, std::size_t until) {
    Continuation continuation{after, until, std::make_unique<ScenarioRunner>(scene)};
    const std::string bytes = save(original);
    load(*continuation.runner, bytes);
    EXPECT_EQ(save(*continuation.runner), bytes)
        << what << ": a loaded runner saves other bytes (step " << after << ")";
    EXPECT_EQ(hashOf(*continuation.runner), hashOf(original)) << what << ": step " << after;
    EXPECT_EQ(difference(original.status(), continuation.runner->status()), "") << what << ": step " << after;
    live.push_back(std::move(continuation));
    ++outcome.checkpoints;
  };
  const std::size_t full_every = std::max<std::size_t>(1, steps.size() / kFullCheckpoints);
  checkpoint(0, steps.size());  // started, before the first frame
  for (std::size_t i = 0; i < steps.size(); ++i) {
    apply(original, steps[i]);
    if (!original.ended()) ++outcome.active_steps;
    const std::uint64_t hash = hashOf(original);
    hashes.insert(hash);
    for (auto it = live.begin(); it != live.end();) {
      apply(*it->runner, steps[i]);
      const std::string diff = difference(original.status(), it->runner->status());
      const bool equal_hash = hashOf(*it->runner) == hash;
      const bool done = i + 1 >= it->until || !diff.empty() || !equal_hash;
      if (!diff.empty() || !equal_hash) {
        ADD_FAILURE() << what << ": loaded after step " << it->from << ", step " << i
                      << " differs: " << (equal_hash ? "" : "hash; ") << diff;
      } else if (done) {
        EXPECT_EQ(save(*it->runner), save(original))
            << what << ": loaded after step " << it->from << ", the bytes saved after step " << i << " differ";
      }
      it = done ? live.erase(it) : std::next(it);
    }
    // Stop testing a type after its first failing checkpoint: the rest would repeat it thousands of times.
    if (::testing::Test::HasFailure()) return outcome;
    if (i + 1 < steps.size()) {
      const bool full = (i + 1) % full_every == 0;
      checkpoint(i + 1, full ? steps.size() : std::min(steps.size(), i + 1 + kWindow));
    }
  }
  outcome.steps = steps.size();
  outcome.distinct_hashes = hashes.size();
  outcome.final_state = toString(original.status().state);
  outcome.final_message = original.status().message;
  outcome.events = original.status().events.size();
  outcome.bytes_changed = save(original) != initial;
  return outcome;
}

// ---- the tests ----

TEST(ScenarioState, TheTestCoversEveryRegisteredType) {
  std::vector<std::string> registered;
  for (const auto& entry : scenario::scenarioRegistry().entries()) registered.push_back(entry.name);
  std::vector<std::string> covered = scenarioTypes();
  std::sort(registered.begin(), registered.end());
  std::sort(covered.begin(), covered.end());
  EXPECT_EQ(registered, covered) << "a new scenario type needs a session here";
}

constexpr const char* kLostTracking = "novice_lost_tracking";

class EveryScenarioType : public ::testing::TestWithParam<std::tuple<std::string, std::string>> {};

TEST_P(EveryScenarioType, ContinuesBitForBitFromACheckpointAtEveryFrame) {
  const auto& [type, variant] = GetParam();
  scene::SceneDescription scene = scene::loadScene(scene::shippedScenePath(type));
  ASSERT_TRUE(scene.scenario);
  ASSERT_EQ(scene.scenario->type, type);
  const bool lost_tracking = variant == kLostTracking;
  const std::string script = lost_tracking ? "novice" : variant;
  // Dropped objects sink slowly through thick fluid here, so checkpoints fall between a release and its landing.
  if (lost_tracking && (type == "pick_and_place" || type == "object_manipulation" || type == "bimanual")) {
    scene.scenario->params["drag"].numbers = {1000.0};
  }
  // And a hand-over's drop counts as an impact only from above 1 cm, so the release height decides it.
  if (lost_tracking && type == "bimanual") scene.scenario->params["release_height"].numbers = {0.01};
  const std::vector<Step> steps = session(scene, script, lost_tracking);
  const Outcome outcome = checkEveryCheckpoint(scene, steps, type + " (" + variant + ")");
  if (HasFailure()) return;
  // The session must have moved the scenario, or the checkpoints proved nothing.
  EXPECT_TRUE(outcome.bytes_changed);
  EXPECT_GE(outcome.distinct_hashes, 10u) << type << " (" << variant << ")";
  std::printf(
      "  %s (%s): %zu steps (%zu before it ended), %zu checkpoints, %zu distinct hashes, %zu penalty events, "
      "ended %s: %s\n",
      type.c_str(), variant.c_str(), outcome.steps, outcome.active_steps, outcome.checkpoints, outcome.distinct_hashes,
      outcome.events, outcome.final_state.c_str(), outcome.final_message.c_str());
}

INSTANTIATE_TEST_SUITE_P(Scenarios, EveryScenarioType,
                         ::testing::Combine(::testing::ValuesIn(scenarioTypes()),
                                            ::testing::Values(std::string("expert"), std::string("novice"),
                                                              std::string(kLostTracking))),
                         [](const ::testing::TestParamInfo<std::tuple<std::string, std::string>>& info) {
                           return std::get<0>(info.param) + "_" + std::get<1>(info.param);
                         });

// A checkpoint in the middle of a novice's session, for the refusal tests.
std::string midSession(const scene::SceneDescription& scene) {
  const std::vector<Step> steps = session(scene, "novice", false);
  ScenarioRunner runner(scene);
  runner.start(steps.front().time, steps.front().stamp);
  for (std::size_t i = 0; i < steps.size() / 2; ++i) apply(runner, steps[i]);
  return save(runner);
}

TEST(ScenarioState, ATruncatedCheckpointIsRefused) {
  for (const std::string& type : scenarioTypes()) {
    const scene::SceneDescription scene = scene::loadScene(scene::shippedScenePath(type));
    const std::string bytes = midSession(scene);
    ASSERT_GT(bytes.size(), 100u) << type;
    std::vector<std::size_t> cuts = {0, 1, bytes.size() / 2, bytes.size() - 1};
    for (std::size_t cut = 7; cut < bytes.size(); cut += bytes.size() / 23 + 1) cuts.push_back(cut);
    for (std::size_t cut : cuts) {
      ScenarioRunner runner(scene);
      EXPECT_THROW(load(runner, bytes.substr(0, cut)), StateError) << type << " cut at " << cut;
    }
    ScenarioRunner whole(scene);
    EXPECT_NO_THROW(load(whole, bytes)) << type;
    EXPECT_THROW(load(whole, bytes + '\0'), StateError) << type << ": a byte too many";
  }
}

TEST(ScenarioState, ACheckpointOfAnotherSceneOrLevelIsRefused) {
  const scene::SceneDescription navigation = scene::loadScene(scene::shippedScenePath("navigation"));
  const scene::SceneDescription trajectory = scene::loadScene(scene::shippedScenePath("trajectory"));
  const std::string bytes = midSession(navigation);
  ScenarioRunner other(trajectory);
  try {
    load(other, bytes);
    ADD_FAILURE() << "a navigation checkpoint loaded into a trajectory runner";
  } catch (const StateError& error) {
    EXPECT_NE(std::string(error.what()).find("status"), std::string::npos) << error.what();
  }
  const scene::SceneDescription easy = scene::loadScene(scene::shippedScenePath("navigation"), "easy");
  ScenarioRunner easy_runner(easy);
  EXPECT_THROW(load(easy_runner, bytes), StateError);
}

}  // namespace
}  // namespace vrm_sim
