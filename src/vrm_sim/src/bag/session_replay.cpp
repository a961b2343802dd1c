#include "vrm_sim/bag/session_replay.h"

#include <rosbag/bag.h>
#include <rosbag/view.h>

#include <algorithm>
#include <boost/make_shared.hpp>
#include <chrono>
#include <filesystem>
#include <iomanip>
#include <sstream>

#include "vrm_msgs/EyeState.h"
#include "vrm_msgs/InputFrame.h"
#include "vrm_msgs/InputFrames.h"
#include "vrm_msgs/InstrumentState.h"
#include "vrm_msgs/PedalState.h"
#include "vrm_msgs/ScenarioCommand.h"
#include "vrm_scene/scene_loader.h"
#include "vrm_sim/conversions.h"
#include "vrm_sim/world/offline.h"
#include "vrm_sim/world/session.h"
#include "vrm_sim/world/session_result.h"

namespace vrm_sim {
namespace bag {

namespace {

// Reads every message of `view` with `read`. A message whose bytes do not hold its type throws from deserialization
// (ros::serialization::StreamOverrunException, std::bad_alloc): a corrupt record that prepareSessionBag's check let
// through (a wildcard md5sum, a later part of a session) becomes a BagError naming it, not an abort.
template <typename Read>
void readEach(rosbag::View& view, const std::string& path, Read&& read) {
  for (const rosbag::MessageInstance& message : view) {
    try {
      read(message);
    } catch (const BagError&) {
      throw;
    } catch (const std::exception& error) {
      std::ostringstream what;
      what << path << ": corrupt message on " << message.getTopic() << " at bag time " << std::fixed
           << std::setprecision(3) << message.getTime().toSec() << " s (" << error.what()
           << "); the bag cannot be replayed";
      throw BagError(what.str());
    }
  }
}

// "0.1.0" of "vrm_sim 0.1.0": what a version comparison looks at.
std::string versionNumber(const std::string& version) {
  const auto space = version.rfind(' ');
  return space == std::string::npos ? version : version.substr(space + 1);
}

// The later parts of a session recorded across a recorder crash (<stem>.part<k>.bag, k = 2, 3, ...; a part whose
// recorder was killed too is recovered into a copy): their frames belong to the session as well (issue 39).
std::vector<std::string> laterParts(const std::string& original) {
  std::vector<std::string> parts;
  const bool has_suffix = original.size() > 4 && original.compare(original.size() - 4, 4, ".bag") == 0;
  if (!has_suffix || original.find(".part") != std::string::npos) return parts;
  const std::string stem = original.substr(0, original.size() - 4);
  for (int part = 2;; ++part) {
    const std::string path = stem + ".part" + std::to_string(part) + ".bag";
    if (std::filesystem::exists(path)) {
      parts.push_back(prepareSessionBag(path).usable);
    } else if (std::filesystem::exists(path + ".active")) {
      parts.push_back(prepareSessionBag(path + ".active").usable);
    } else {
      break;
    }
  }
  return parts;
}

}  // namespace

SessionSetup resolveSession(const PreparedBag& bag, const std::string& scene_override) {
  SessionSetup setup;
  if (!bag.session_info) {
    if (scene_override.empty()) {
      throw BagError(bag.original + ": no /session_info (which scene was this?); give the scene (--scene / scene:=)");
    }
    setup.warnings.push_back("no /session_info in the bag: scene '" + scene_override +
                             "' as given, default difficulty, the scenario starting with the first input");
    setup.scene = setup.scene_name = scene_override;
    return setup;
  }
  const vrm_msgs::SessionInfo& info = *bag.session_info;
  setup.scene_name = info.scene;
  setup.difficulty = info.difficulty;
  setup.collision_detector = info.collision_detector;
  setup.auto_start = info.auto_start;
  setup.seed = info.seed;
  std::error_code error;
  setup.scene = !info.scene_file.empty() && std::filesystem::is_regular_file(info.scene_file, error) ? info.scene_file
                                                                                                     : info.scene;
  if (!scene_override.empty() && scene_override != info.scene && scene_override != info.scene_file) {
    setup.warnings.push_back("the bag was recorded with scene '" + info.scene + "'; replaying it with scene '" +
                             scene_override + "' as asked (the state will differ from the recording)");
    setup.scene = setup.scene_name = scene_override;
  }
  if (versionNumber(info.software_version) != versionNumber(softwareVersion())) {
    setup.warnings.push_back(
        "the bag was recorded by " +
        (info.software_version.empty() ? std::string("an unknown version") : "'" + info.software_version + "'") +
        ", this is '" + softwareVersion() + "': the replay may not reproduce its state");
  }
  return setup;
}

ReplayResult replaySession(const PreparedBag& prepared, const SessionSetup& setup, ReplayInput input_choice) {
  const auto wall_start = std::chrono::steady_clock::now();
  world::WorldOptions options;
  options.detector_override = setup.collision_detector;
  options.auto_start = setup.auto_start;
  options.log = [](world::Severity, const std::string&) {};  // the counts are in the result
  world::Session session(world::Session::loadByName(setup.scene, setup.difficulty), options);

  ReplayResult result;
  result.setup = setup;
  rosbag::Bag bag(prepared.usable, rosbag::bagmode::Read);
  std::optional<world::Stamp> first, last;
  auto note = [&](world::Stamp stamp) {
    if (!first || stamp < *first) first = stamp;
    if (!last || stamp > *last) last = stamp;
  };
  const bool has_frames = recordsInputFrames(prepared);
  if (has_frames && input_choice == ReplayInput::kAsRecorded) {
    // The frames the live session's mediator closed, in their sequence: every decision that depended on arrival
    // order or on a silent source is in them, so the replay repeats the session whatever the load was.
    result.input = "input_frame";
    std::vector<vrm_msgs::InputFrame::ConstPtr> recorded;
    std::size_t resent = 0;
    const auto read_frames = [&](rosbag::Bag& part, const std::string& path) {
      rosbag::View view(part, rosbag::TopicQuery(std::vector<std::string>{inputFrameTopic(), resentFramesTopic()}));
      readEach(view, path, [&](const rosbag::MessageInstance& message) {
        if (auto frame = message.instantiate<vrm_msgs::InputFrame>()) recorded.push_back(frame);
        // Frames a simulation node resent (issue 39): after resuming from its journal, those the dead process may
        // still have had queued for the recorder; to a respawned recorder, those published while it was down. They
        // fill the record's holes; the ones it has are skipped below.
        if (auto frames = message.instantiate<vrm_msgs::InputFrames>()) {
          for (const vrm_msgs::InputFrame& frame : frames->frames) {
            recorded.push_back(boost::make_shared<vrm_msgs::InputFrame>(frame));
            ++resent;
          }
        }
      });
    };
    read_frames(bag, prepared.usable);
    const std::vector<std::string> later_parts = laterParts(prepared.original);
    for (const std::string& path : later_parts) {
      rosbag::Bag part;
      try {
        part.open(path, rosbag::bagmode::Read);
      } catch (const rosbag::BagException& error) {
        // prepareSessionBag() checked it; it changed since (a recorder still writing it, a disk error).
        throw BagError(path + ": cannot open this later part of the session: " + error.what());
      }
      read_frames(part, path);
    }
    if (!later_parts.empty()) {
      result.setup.warnings.push_back("the session was recorded in " + std::to_string(later_parts.size() + 1) +
                                      " parts (its recorder restarted); replayed from all of them");
    }
    // A simulation node restarted after a crash numbers its frames from 1 again under a new run: the runs in the
    // order the recorder saw them, each in its sequence.
    std::vector<std::uint64_t> runs;
    for (const auto& frame : recorded) {
      if (std::find(runs.begin(), runs.end(), frame->run) == runs.end()) runs.push_back(frame->run);
    }
    std::vector<vrm_msgs::InputFrame::ConstPtr> frames;
    for (std::size_t run = 0; run < runs.size(); ++run) {
      std::vector<vrm_msgs::InputFrame::ConstPtr> of_run;
      for (const auto& frame : recorded) {
        if (frame->run == runs[run]) of_run.push_back(frame);
      }
      std::stable_sort(of_run.begin(), of_run.end(),
                       [](const auto& a, const auto& b) { return a->sequence < b->sequence; });
      if (resent > 0) {
        // A frame both recorded and resent is one frame (the same sequence, stamp and kind).
        of_run.erase(std::unique(of_run.begin(), of_run.end(),
                                 [](const auto& a, const auto& b) {
                                   return a->sequence == b->sequence && a->header.stamp == b->header.stamp &&
                                          a->kind == b->kind;
                                 }),
                     of_run.end());
      }
      for (std::size_t i = 1; i < of_run.size(); ++i) {
        if (of_run[i]->sequence == of_run[i - 1]->sequence + 1) continue;
        std::ostringstream what;
        what << prepared.original << ": the recorded input frames jump from sequence " << of_run[i - 1]->sequence
             << " to " << of_run[i]->sequence << " (frame " << frames.size() + i + 1 << " of " << recorded.size()
             << ", input time " << std::fixed << std::setprecision(3) << of_run[i]->header.stamp.toSec() << " s"
             << (runs.size() > 1 ? ", run " + std::to_string(run + 1) + " of " + std::to_string(runs.size()) : "")
             << "): "
             << (of_run[i]->sequence == of_run[i - 1]->sequence
                     ? std::string("a frame recorded twice")
                     : std::to_string(of_run[i]->sequence - of_run[i - 1]->sequence - 1) + " frames lost")
             << "; the bag cannot reproduce its session";
        throw BagError(what.str());
      }
      if (run > 0) {
        result.setup.warnings.push_back("the simulation node restarted during the recording (run " +
                                        std::to_string(run + 1) + " from frame " +
                                        std::to_string(of_run.front()->sequence) + ")");
      }
      frames.insert(frames.end(), of_run.begin(), of_run.end());
    }
    for (const auto& message : frames) {
      ++result.inputs;
      if (message->kind == vrm_msgs::InputFrame::KIND_FRAME) note(toStamp(message->header.stamp));
      session.handle(toWorld(*message));
    }
  } else {
    result.input = "devices";
    if (!has_frames) {
      result.setup.warnings.push_back(
          "the bag predates input frames (no " + inputFrameTopic() +
          "): replayed from the device topics through the mediator, which may decide a frame differently than the "
          "live session did when the recording machine was loaded");
    }
    rosbag::View view(bag, rosbag::TopicQuery(deviceTopics()));
    // The inputs in the order of their stamps (stable: equal stamps keep the recorded order). The simulation node
    // receives them in-process in the order the devices published them; the recorder, a process of its own, may
    // fall behind on one topic under load (instrument states were seen 188 ms behind the eye states), and replayed
    // in the recorded order those inputs would arrive late to a mediator that closes frames by stamp.
    struct Input {
      ros::Time stamp;
      vrm_msgs::EyeState::ConstPtr eye;
      vrm_msgs::InstrumentState::ConstPtr instrument;
      vrm_msgs::PedalState::ConstPtr pedals;
      vrm_msgs::ScenarioCommand::ConstPtr command;
    };
    std::vector<Input> inputs;
    readEach(view, prepared.usable, [&](const rosbag::MessageInstance& message) {
      Input input;
      input.stamp = message.getTime();
      if ((input.eye = message.instantiate<vrm_msgs::EyeState>())) {
        input.stamp = input.eye->header.stamp;
      } else if ((input.instrument = message.instantiate<vrm_msgs::InstrumentState>())) {
        input.stamp = input.instrument->header.stamp;
      } else if ((input.pedals = message.instantiate<vrm_msgs::PedalState>())) {
        input.stamp = input.pedals->header.stamp;
      } else if ((input.command = message.instantiate<vrm_msgs::ScenarioCommand>())) {
        input.stamp = input.command->header.stamp;
      }
      inputs.push_back(std::move(input));
    });
    std::stable_sort(inputs.begin(), inputs.end(), [](const Input& a, const Input& b) { return a.stamp < b.stamp; });
    for (const Input& input : inputs) {
      ++result.inputs;
      if (input.eye) {
        note(toStamp(input.eye->header.stamp));
        session.handle(toWorld(*input.eye));
      } else if (input.instrument) {
        note(toStamp(input.instrument->header.stamp));
        session.handle(toWorld(*input.instrument));
      } else if (input.pedals) {
        session.handle(toWorld(*input.pedals));
      } else if (input.command) {
        if (auto converted = toWorld(*input.command)) session.handle(*converted);
      }
    }
  }
  session.flush();
  const world::World& world = session.world();
  result.frames = world.statistics().frames;
  result.simulated_frames = world.statistics().simulated_frames;
  result.late_inputs = world.statistics().late_inputs;
  result.rejected_inputs = world.statistics().rejected_inputs;
  result.frames_without_source = world.statistics().frames_without_source;
  result.final_state_hash = world.stateHash();
  if (const scenario::Status* status = world.scenarioStatus()) {
    result.score_total = status->score.total;
    result.scenario_state = scenario::toString(status->state);
    result.setup.difficulty = status->difficulty;  // the level in effect (the recorded "" is the default)
  }
  result.input_seconds = first ? world::toSeconds(*last - *first) : 0.0;
  result.wall_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - wall_start).count();
  result.speedup = result.wall_seconds > 0.0 ? result.input_seconds / result.wall_seconds : 0.0;
  world::ResultContext context;
  context.seed = session.loads() > 0 ? session.seed() : setup.seed;
  context.bag = prepared.original;
  result.session_result = world::sessionResult(world, context);
  return result;
}

std::string ReplayResult::json(const PreparedBag& bag) const {
  std::ostringstream out;
  out.precision(15);
  const auto quoted = world::jsonString;
  out << "{\"bag\": " << quoted(bag.original) << ", \"replayed\": " << quoted(bag.usable)
      << ", \"scene\": " << quoted(setup.scene_name) << ", \"difficulty\": " << quoted(setup.difficulty)
      << ", \"seed\": " << setup.seed << ", \"frames\": " << frames << ", \"simulated_frames\": " << simulated_frames
      << ", \"final_state_hash\": \"" << world::hashString(final_state_hash) << "\", \"score_total\": ";
  if (score_total) {
    out << *score_total;
  } else {
    out << "null";
  }
  out << ", \"state\": " << (scenario_state.empty() ? "null" : quoted(scenario_state)) << ", \"inputs\": " << inputs
      << ", \"late_inputs\": " << late_inputs << ", \"rejected_inputs\": " << rejected_inputs
      << ", \"frames_without_source\": " << frames_without_source << ", \"input\": " << quoted(input)
      << ", \"input_seconds\": " << input_seconds << ", \"wall_seconds\": " << wall_seconds
      << ", \"speedup\": " << speedup << ", \"recovered_messages\": " << (bag.recovery ? bag.recovery->messages : 0)
      << ", \"recovered_seconds\": " << (bag.recovery ? bag.recovery->seconds : 0.0) << ", \"warnings\": [";
  for (std::size_t i = 0; i < setup.warnings.size(); ++i) out << (i ? ", " : "") << quoted(setup.warnings[i]);
  out << "]";
  if (session_result) {
    std::string text = result::toJson(*session_result);
    while (!text.empty() && text.back() == '\n') text.pop_back();
    out << ", \"result\": " << text;
  }
  out << "}";
  return out.str();
}

}  // namespace bag
}  // namespace vrm_sim
