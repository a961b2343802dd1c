// session_trajectory: the per-frame eye and instrument trajectories of a session bag, as the JSON file the records
// store imports with the session's result (records/trajectory.h). The bag stays on the station; these samples go to
// the records server and into `records export`. `rosrun eyesi_gui session_trajectory BAG [--out FILE]`.
//
// From the recorded input frames (/input_frame, KIND_FRAME): the eye's pose and every slot's applied pose as the
// World used them, one sample per source and frame. A bag recorded before input frames existed (issue 31) has only
// the device topics: then one sample per /eye_state and /instrument_state message, numbered per source.
#include <rosbag/bag.h>
#include <rosbag/view.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>

#include "eyesi_gui/records/trajectory.h"
#include "vrm_msgs/EyeState.h"
#include "vrm_msgs/InputFrame.h"
#include "vrm_msgs/InstrumentState.h"
#include "vrm_scene/cli/cli.h"

namespace {

namespace records = eyesi_gui::records;

void setPose(records::TrajectorySample* s, const geometry_msgs::Point& p, const geometry_msgs::Quaternion& q) {
  s->position[0] = p.x;
  s->position[1] = p.y;
  s->position[2] = p.z;
  s->orientation[0] = q.x;
  s->orientation[1] = q.y;
  s->orientation[2] = q.z;
  s->orientation[3] = q.w;
}

std::vector<records::TrajectorySample> fromInputFrames(rosbag::Bag& bag) {
  std::vector<records::TrajectorySample> samples;
  rosbag::View view(bag, rosbag::TopicQuery(std::vector<std::string>{"/input_frame"}));
  double first = -1.0;
  for (const rosbag::MessageInstance& message : view) {
    const auto frame = message.instantiate<vrm_msgs::InputFrame>();
    if (!frame || frame->kind != vrm_msgs::InputFrame::KIND_FRAME) continue;
    const double stamp = frame->header.stamp.toSec();
    if (first < 0.0) first = stamp;
    records::TrajectorySample eye;
    eye.frame = frame->sequence;
    eye.time = stamp - first;
    eye.source = "eye";
    eye.frame_id = frame->header.frame_id.empty() ? "world" : frame->header.frame_id;
    setPose(&eye, frame->eye_pose.position, frame->eye_pose.orientation);
    eye.valid = frame->eye_valid;
    samples.push_back(eye);
    for (const vrm_msgs::AppliedInstrument& instrument : frame->instruments) {
      records::TrajectorySample s;
      s.frame = frame->sequence;
      s.time = eye.time;
      s.source = "instrument:" + instrument.slot;
      s.frame_id = instrument.header.frame_id;
      setPose(&s, instrument.pose.position, instrument.pose.orientation);
      s.valid = instrument.valid;
      samples.push_back(std::move(s));
    }
  }
  return samples;
}

std::vector<records::TrajectorySample> fromDeviceTopics(rosbag::Bag& bag) {
  std::vector<records::TrajectorySample> samples;
  rosbag::View view(bag, rosbag::TopicQuery(std::vector<std::string>{"/eye_state", "/instrument_state"}));
  std::map<std::string, std::uint64_t> counts;
  double first = -1.0;
  for (const rosbag::MessageInstance& message : view) {
    records::TrajectorySample s;
    double stamp = 0.0;
    if (const auto eye = message.instantiate<vrm_msgs::EyeState>()) {
      stamp = eye->header.stamp.toSec();
      s.source = "eye";
      s.frame_id = eye->header.frame_id;
      setPose(&s, eye->rotation_center, eye->rotation);
      s.valid = eye->valid;
    } else if (const auto instrument = message.instantiate<vrm_msgs::InstrumentState>()) {
      stamp = instrument->header.stamp.toSec();
      s.source = "instrument:" + instrument->instrument_id;
      s.frame_id = instrument->header.frame_id;
      setPose(&s, instrument->tip_pose.position, instrument->tip_pose.orientation);
      s.valid = instrument->valid;
    } else {
      continue;
    }
    if (first < 0.0) first = stamp;
    s.time = stamp - first;
    s.frame = ++counts[s.source];
    samples.push_back(std::move(s));
  }
  return samples;
}

// Writes the trajectory file of one bag; returns a line for the log. Throws on a bag without frames or states.
std::string writeTrajectory(const std::string& bag_path, const std::string& out_path) {
  rosbag::Bag bag(bag_path, rosbag::bagmode::Read);
  std::vector<records::TrajectorySample> samples = fromInputFrames(bag);
  const bool frames = !samples.empty();
  if (!frames) samples = fromDeviceTopics(bag);
  if (samples.empty()) throw std::runtime_error(bag_path + ": no input frames and no eye or instrument states");
  // Written under a temporary name and renamed: a reader (records sync) never sees half a file.
  const std::string partial = out_path + ".partial";
  std::ofstream out(partial, std::ios::binary);
  out << records::trajectoryJson(samples, bag_path) << '\n';
  out.close();
  if (!out || std::rename(partial.c_str(), out_path.c_str()) != 0) {
    std::remove(partial.c_str());
    throw std::runtime_error(out_path + ": cannot write the trajectory file");
  }
  return std::to_string(samples.size()) + " samples (" + (frames ? "input frames" : "device topics") + ") -> " +
         out_path;
}

std::string besideTheBag(const std::filesystem::path& bag) {
  return (bag.parent_path() / (bag.stem().string() + ".trajectory.json")).string();
}

}  // namespace

int main(int argc, char** argv) {
  namespace po = vrm_sim::cli::po;
  vrm_sim::cli::CommandLine cli("session_trajectory", "BAG [--out FILE] | --missing FOLDER",
                                "The per-frame eye and instrument trajectories of a session bag, as the JSON file "
                                "`records import` and `records sync` read next to it (<stem>.trajectory.json).",
                                "");
  cli.add()("out", po::value<std::string>()->value_name("FILE"), "where to write (default: next to the bag)")(
      "missing", po::value<std::string>()->value_name("FOLDER"),
      "every closed *.bag under FOLDER without its trajectory file (a station's sessions folder, before a sync)");
  cli.hidden()("bag", po::value<std::string>());
  cli.positional("bag", 1);
  if (const auto status = cli.parse(argc, argv)) return *status;
  if (cli.values().count("missing")) {
    const std::string folder = cli.values()["missing"].as<std::string>();
    int failed = 0, written = 0;
    std::error_code ec;
    for (std::filesystem::recursive_directory_iterator it(folder, ec), end; !ec && it != end; it.increment(ec)) {
      // A bag being recorded is <name>.bag.active: only closed bags are read.
      if (!it->is_regular_file() || it->path().extension() != ".bag") continue;
      const std::string out = besideTheBag(it->path());
      if (std::filesystem::exists(out)) continue;
      try {
        std::cout << writeTrajectory(it->path().string(), out) << '\n';
        ++written;
      } catch (const std::exception& e) {
        std::cerr << "session_trajectory: " << e.what() << '\n';
        ++failed;
      }
    }
    if (ec) {
      std::cerr << "session_trajectory: " << folder << ": " << ec.message() << '\n';
      return 1;
    }
    std::cout << written << " written, " << failed << " failed\n";
    return failed == 0 ? 0 : 1;
  }
  if (cli.values().count("bag") == 0) return cli.fail("no BAG (or --missing FOLDER)");
  const std::string bag_path = cli.values()["bag"].as<std::string>();
  const std::string out_path =
      cli.values().count("out") ? cli.values()["out"].as<std::string>() : besideTheBag(bag_path);
  try {
    std::cout << writeTrajectory(bag_path, out_path) << '\n';
    return 0;
  } catch (const std::exception& e) {
    std::cerr << "session_trajectory: " << e.what() << '\n';
    return 1;
  }
}
