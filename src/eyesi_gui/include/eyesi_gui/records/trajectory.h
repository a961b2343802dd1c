// Per-frame trajectories of a session (issue 41, "data a researcher can use"): the eye's and every instrument's pose
// as the World applied them in each simulation frame, taken from the session's recorded input frames (the bag stays
// on the station; these samples go to the records server). ROS-free: the bag is read by the session_trajectory tool,
// which writes the samples as a JSON file next to the result (<stem>.trajectory.json), and the records store reads
// that file with the result.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace eyesi_gui::records {

struct TrajectorySample {
  std::uint64_t frame = 0;  // the input frame's sequence number (1, 2, ...; per source for a bag without frames)
  double time = 0.0;        // s since the session's first frame (input time)
  std::string source;       // "eye" or "instrument:<slot>"
  std::string frame_id;     // the frame the pose is in ("world" for the eye, normally "eye" for instruments)
  double position[3] = {0.0, 0.0, 0.0};          // m; eye: its rotation centre; instrument: its tip
  double orientation[4] = {0.0, 0.0, 0.0, 1.0};  // quaternion x, y, z, w
  bool valid = false;                            // tracked (eye) / tracked and interacting (instrument)
};

// The sidecar file's format (a JSON object: {"format": kTrajectoryFormat, "source_bag": ..., "samples": [[frame,
// time, source, frame_id, x, y, z, qx, qy, qz, qw, valid], ...]}).
constexpr const char* kTrajectoryFormat = "eyesi_trajectory/1";

std::string trajectoryJson(const std::vector<TrajectorySample>& samples, const std::string& source_bag);
// Throws StoreError naming `origin` and what is wrong when the text is not such a file.
std::vector<TrajectorySample> parseTrajectoryJson(const std::string& text, const std::string& origin);
// "<stem>.trajectory.json" for "<stem>.result.json" (or "<path>.trajectory.json" for any other name).
std::string trajectoryPathFor(const std::string& result_path);

}  // namespace eyesi_gui::records
