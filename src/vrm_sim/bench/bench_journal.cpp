// Crash = pause (issue 39): what the session journal costs on the frame thread and how long a restore takes, against
// its error (the restored state's hash against the live one's: equal, or the restore is wrong). Each case plays a
// shipped scene's scripted session through a world::Session, as the simulation node does, appending every input frame
// to a journal (bag/session_journal.h) and timing each append (serialisation and the write(2); the frame's message
// is filled for publishing anyway); then reads the journal back and restores a fresh Session from it, timed. Cases:
// the default session (membrane peeling), vitrectomy, navigation (rigid only), retina relocation, and the hard ones:
// a long session (the restore grows with it) and the appends with busy loops on both cores.
// Checkpoints (issue 39 §1): every 10 s of session (from 0.02 s on) the live Session is also checkpointed
// (Session::checkpoint on the frame thread, timed: what the simulation node pays), and the restore is done a second
// way, from the last checkpoint and the journal's frames after it, timed against the same hash. That restore's time is
// bounded by the checkpoint interval, not the session's length.
//
// Usage: bench_journal [--quick] [--out FILE]
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <thread>
#include <vector>

#include "bench_cli.h"
#include "vrm_scene/scene_loader.h"
#include "vrm_sim/bag/session_journal.h"
#include "vrm_sim/conversions.h"
#include "vrm_sim/world/offline.h"
#include "vrm_sim/world/session.h"

using namespace vrm_sim;
using Clock = std::chrono::steady_clock;

namespace {

struct Case {
  std::string name, scene, script, kind;
  double seconds = 0.0;  // of session (the script, then its instruments held still)
  bool load = false;     // busy loops on both cores while the session runs
};

struct Row {
  Case c;
  std::uint64_t frames = 0, bytes = 0;
  double append_us_mean = 0, append_us_p50 = 0, append_us_p99 = 0, append_us_max = 0;
  double frame_ms_mean = 0;
  double read_ms = 0, restore_s = 0;
  bool hash_equal = false;
  // Checkpoints.
  std::size_t checkpoints = 0, checkpoint_bytes = 0;
  double checkpoint_ms_mean = 0, checkpoint_ms_max = 0, checkpoint_ms_cold = 0;
  std::uint64_t tail_frames = 0;  // journal frames after the last checkpoint
  double checkpoint_restore_s = 0;
  bool checkpoint_hash_equal = false;
};

constexpr double kCheckpointInterval = 10.0;  // s of session

double percentile(std::vector<double> values, double q) {
  if (values.empty()) return 0.0;
  std::sort(values.begin(), values.end());
  return values[std::min(values.size() - 1, static_cast<std::size_t>(q * static_cast<double>(values.size())))];
}

Row run(const Case& c, const std::string& folder) {
  Row row;
  row.c = c;
  const scene::SceneDescription base = scene::loadScene(scene::shippedScenePath(c.scene));
  const scene::SceneDescription scene = scene::withScript(base, c.script);
  const std::vector<scene::PedalWaypoint> pedals = scene::findScript(base, c.script).pedals;
  world::WorldOptions options;
  options.log = [](world::Severity, const std::string&) {};
  const std::string path = folder + "/" + c.name + ".journal";
  bag::JournalWriter journal;
  journal.create(path, bag::JournalHeader{c.scene, "", 0, 1});
  std::vector<double> append_us;
  world::Session live(scene, options);
  std::vector<double> checkpoint_ms;
  std::string last_checkpoint, buffer;
  // As the node does at its start: one checkpoint not written, which touches the memory the periodic ones reuse (the
  // first touch of fresh pages is what a cold checkpoint costs in a VM); timed apart.
  {
    const auto start = Clock::now();
    live.checkpoint(buffer);
    row.checkpoint_ms_cold = std::chrono::duration<double, std::milli>(Clock::now() - start).count();
  }
  std::uint64_t checkpoint_sequence = 0;
  // At 0.02 s + k intervals: the restore at the session's end is then the worst case, a whole interval of frames
  // after the last checkpoint (a crash just before the next one).
  double next_checkpoint = 0.02;
  live.setInputObserver([&](const world::InputFrame& frame) {
    vrm_msgs::InputFrame message;
    fillInputFrame(frame, "world", "eye", message);
    message.run = 1;
    const auto start = Clock::now();
    journal.append(message);
    append_us.push_back(std::chrono::duration<double, std::micro>(Clock::now() - start).count());
  });
  std::atomic<bool> busy{c.load};
  std::vector<std::thread> loops;
  if (c.load) {
    for (int i = 0; i < 2; ++i) {
      loops.emplace_back([&busy] {
        volatile std::uint64_t sink = 0;
        while (busy.load(std::memory_order_relaxed)) sink = sink + 1;
      });
    }
  }
  const long ticks = std::lround(c.seconds * 50.0);
  for (long tick = 0; tick <= ticks; ++tick) {
    const double t = static_cast<double>(tick) / 50.0;
    const world::Stamp stamp = world::fromSeconds(1000.0 + t);
    for (const world::InstrumentState& input : world::scriptedInputsAt(scene, t, stamp)) live.handle(input);
    if (!pedals.empty()) {
      const scene::PedalWaypoint sample = scene::samplePedals(pedals, t);
      world::PedalState pedal;
      pedal.stamp = stamp;
      pedal.travel = sample.travel;
      pedal.reflux = sample.reflux;
      live.handle(pedal);
    }
    if (t >= next_checkpoint) {
      // Between frames, as the node's frame observer would: the frames up to this tick are closed.
      live.flush();
      const auto start = Clock::now();
      live.checkpoint(buffer);
      checkpoint_ms.push_back(std::chrono::duration<double, std::milli>(Clock::now() - start).count());
      last_checkpoint = buffer;  // the node hands it to its writer thread instead
      checkpoint_sequence = live.nextSequence() - 1;
      next_checkpoint += kCheckpointInterval;
    }
  }
  live.flush();
  busy = false;
  for (std::thread& loop : loops) loop.join();
  journal.close();
  row.frames = append_us.size();
  row.bytes = std::filesystem::file_size(path);
  double sum = 0.0;
  for (double us : append_us) sum += us;
  row.append_us_mean = append_us.empty() ? 0.0 : sum / static_cast<double>(append_us.size());
  row.append_us_p50 = percentile(append_us, 0.5);
  row.append_us_p99 = percentile(append_us, 0.99);
  row.append_us_max = percentile(append_us, 1.0);
  const world::WorldStatistics statistics = live.world().statistics();
  row.frame_ms_mean = 1e3 * statistics.total_frame_wall_time / std::max<std::uint64_t>(statistics.frames, 1);

  const auto read_start = Clock::now();
  const bag::JournalContents contents = bag::readJournal(path);
  row.read_ms = std::chrono::duration<double, std::milli>(Clock::now() - read_start).count();
  const auto restore_start = Clock::now();
  world::Session restored(scene, options);
  for (const vrm_msgs::InputFrame::Ptr& frame : contents.frames) restored.handle(toWorld(*frame));
  row.restore_s = std::chrono::duration<double>(Clock::now() - restore_start).count();
  row.hash_equal = restored.world().stateHash() == live.world().stateHash();

  row.checkpoints = checkpoint_ms.size();
  row.checkpoint_bytes = last_checkpoint.size();
  for (double ms : checkpoint_ms) row.checkpoint_ms_mean += ms / static_cast<double>(checkpoint_ms.size());
  row.checkpoint_ms_max = percentile(checkpoint_ms, 1.0);
  if (!last_checkpoint.empty()) {
    const auto start = Clock::now();
    world::Session from_checkpoint(scene, options);
    from_checkpoint.restoreCheckpoint(last_checkpoint);
    for (const vrm_msgs::InputFrame::Ptr& frame : contents.frames) {
      if (frame->sequence <= checkpoint_sequence) continue;
      from_checkpoint.handle(toWorld(*frame));
      ++row.tail_frames;
    }
    row.checkpoint_restore_s = std::chrono::duration<double>(Clock::now() - start).count();
    row.checkpoint_hash_equal = from_checkpoint.world().stateHash() == live.world().stateHash();
  }
  std::filesystem::remove(path);
  return row;
}

}  // namespace

int main(int argc, char** argv) {
  bench::BenchArgs args;
  if (const auto status = bench::parseBenchArgs(
          argc, argv, "bench_journal",
          "Crash = pause: the journal's cost per frame and the restore's time, against the restored state's error.",
          "bench/results/journal.json", &args)) {
    return *status;
  }
  std::vector<Case> cases;
  if (args.quick) {
    cases = {{"membrane_peeling", "membrane_peeling", "expert", "kind: the default session", 12.0}};
  } else {
    cases = {
        {"membrane_peeling", "membrane_peeling", "expert", "kind: the default session", 30.0},
        {"vitrectomy", "vitrectomy", "expert", "kind", 30.0},
        {"navigation", "navigation", "expert", "kind: rigid only", 30.0},
        {"retina_relocation", "retina_relocation", "expert", "kind", 30.0},
        {"membrane_peeling_loaded", "membrane_peeling", "expert", "hard: busy loops on both cores", 30.0, true},
        {"membrane_peeling_long", "membrane_peeling", "expert", "hard: a 5-minute session", 300.0},
    };
  }
  const std::string folder = std::filesystem::temp_directory_path().string() + "/bench_journal_" +
                             std::to_string(static_cast<long>(::getpid()));
  std::filesystem::create_directories(folder);
  std::printf("bench_journal (%s): the journal's append on the frame thread, and a restore of the whole session\n",
              args.quick ? "quick" : "full");
  std::printf("%-24s %7s %8s %7s %8s %8s %8s %9s %8s %9s %10s %6s | %5s %8s %8s %8s %7s %9s %6s\n", "case", "seconds",
              "frames", "B/frm", "app_us", "p99_us", "max_us", "frame_ms", "read_ms", "restore_s", "restore/s", "equal",
              "ckpts", "ckpt_KB", "ckpt_ms", "ckpt_max", "tail", "restore_s", "equal");
  std::string rows;
  double worst_append_us = 0.0, worst_restore_per_second = 0.0, worst_checkpoint_ms = 0.0;
  double worst_checkpoint_restore_s = 0.0;
  bool all_equal = true;
  for (const Case& c : cases) {
    const Row row = run(c, folder);
    const double per_second = row.restore_s / c.seconds;
    worst_append_us = std::max(worst_append_us, row.append_us_max);
    worst_restore_per_second = std::max(worst_restore_per_second, per_second);
    all_equal = all_equal && row.hash_equal && (row.checkpoints == 0 || row.checkpoint_hash_equal);
    worst_checkpoint_ms = std::max(worst_checkpoint_ms, row.checkpoint_ms_max);
    worst_checkpoint_restore_s = std::max(worst_checkpoint_restore_s, row.checkpoint_restore_s);
    std::printf(
        "%-24s %7.0f %8lu %7.0f %8.1f %8.1f %8.1f %9.3f %8.1f %9.2f %10.4f %6s | %5zu %8.1f %8.3f %8.3f %7lu %9.3f "
        "%6s\n",
        c.name.c_str(), c.seconds, static_cast<unsigned long>(row.frames),
        static_cast<double>(row.bytes) / static_cast<double>(std::max<std::uint64_t>(row.frames, 1)),
        row.append_us_mean, row.append_us_p99, row.append_us_max, row.frame_ms_mean, row.read_ms, row.restore_s,
        per_second, row.hash_equal ? "yes" : "NO", row.checkpoints, static_cast<double>(row.checkpoint_bytes) / 1024.0,
        row.checkpoint_ms_mean, row.checkpoint_ms_max, static_cast<unsigned long>(row.tail_frames),
        row.checkpoint_restore_s, row.checkpoints == 0 ? "-" : (row.checkpoint_hash_equal ? "yes" : "NO"));
    char line[2000];
    std::snprintf(line, sizeof(line),
                  "{\"suite\":\"journal\",\"case\":\"%s\",\"scene\":\"%s\",\"script\":\"%s\",\"kind\":\"%s\","
                  "\"load\":%s,\"session_seconds\":%.1f,\"frames\":%lu,\"journal_bytes\":%lu,\"bytes_per_frame\":%.1f,"
                  "\"append_us_mean\":%.3f,\"append_us_p50\":%.3f,\"append_us_p99\":%.3f,\"append_us_max\":%.3f,"
                  "\"frame_ms_mean\":%.4f,\"read_ms\":%.3f,\"restore_s\":%.4f,\"restore_s_per_session_s\":%.5f,"
                  "\"restored_hash_equal\":%s,\"checkpoint_interval_s\":%.1f,\"checkpoints\":%zu,"
                  "\"checkpoint_bytes\":%zu,\"checkpoint_ms_mean\":%.4f,\"checkpoint_ms_max\":%.4f,"
                  "\"checkpoint_ms_cold\":%.4f,"
                  "\"checkpoint_tail_frames\":%lu,\"checkpoint_restore_s\":%.4f,\"checkpoint_restored_hash_equal\":%s}",
                  c.name.c_str(), c.scene.c_str(), c.script.c_str(), c.kind.c_str(), c.load ? "true" : "false",
                  c.seconds, static_cast<unsigned long>(row.frames), static_cast<unsigned long>(row.bytes),
                  static_cast<double>(row.bytes) / static_cast<double>(std::max<std::uint64_t>(row.frames, 1)),
                  row.append_us_mean, row.append_us_p50, row.append_us_p99, row.append_us_max, row.frame_ms_mean,
                  row.read_ms, row.restore_s, per_second, row.hash_equal ? "true" : "false", kCheckpointInterval,
                  row.checkpoints, row.checkpoint_bytes, row.checkpoint_ms_mean, row.checkpoint_ms_max,
                  row.checkpoint_ms_cold, static_cast<unsigned long>(row.tail_frames), row.checkpoint_restore_s,
                  row.checkpoints == 0 ? "null" : (row.checkpoint_hash_equal ? "true" : "false"));
    rows += (rows.empty() ? "\n  " : ",\n  ") + std::string(line);
  }
  std::filesystem::remove_all(folder);
  std::printf(
      "worst append %.1f us; worst restore %.3f s per session second; worst checkpoint %.3f ms; worst restore from a "
      "checkpoint %.3f s; every restore equal: %s\n",
      worst_append_us, worst_restore_per_second, worst_checkpoint_ms, worst_checkpoint_restore_s,
      all_equal ? "yes" : "NO");
  std::ofstream out(args.out_path);
  out << "{\"suite\":\"journal\",\"command\":\"rosrun vrm_sim bench_journal" << (args.quick ? " --quick" : "")
      << "\",\"quick\":" << (args.quick ? "true" : "false") << ",\"worst_append_us\":" << worst_append_us
      << ",\"worst_restore_s_per_session_s\":" << worst_restore_per_second
      << ",\"worst_checkpoint_ms\":" << worst_checkpoint_ms
      << ",\"worst_checkpoint_restore_s\":" << worst_checkpoint_restore_s
      << ",\"all_restores_equal\":" << (all_equal ? "true" : "false") << ",\"rows\":[" << rows << "\n]}\n";
  if (!out) {
    std::fprintf(stderr, "bench_journal: cannot write %s\n", args.out_path.c_str());
    return 1;
  }
  std::printf("wrote %s\n", args.out_path.c_str());
  return all_equal ? 0 : 1;
}
