#pragma once
// The command line every benchmark takes from scripts/bench.sh: [--quick] [--out FILE] (vrm_scene/cli/cli.h: --help,
// exit status 2 for a usage error).
#include <optional>
#include <string>

#include "vrm_scene/cli/cli.h"

namespace vrm_sim {
namespace bench {

struct BenchArgs {
  bool quick = false;
  std::string out_path;
};

// --quick and --out FILE, for a benchmark with options of its own.
inline void addBenchOptions(cli::CommandLine& command_line, BenchArgs* args) {
  command_line.add()("quick", cli::po::bool_switch(&args->quick), "a short smoke run (fewer sizes and repetitions)")(
      "out", cli::po::value(&args->out_path)->value_name("FILE"),
      args->out_path.empty() ? "write the results as JSON to FILE"
                             : ("the JSON results (default " + args->out_path + ")").c_str());
}

// Parses a benchmark's [--quick] [--out FILE] into *args (out_path starts as default_out). Returns the status to exit
// with at once (0 after --help, 2 after a usage error), or nullopt: run the benchmark.
inline std::optional<int> parseBenchArgs(int argc, char** argv, const std::string& name, const std::string& description,
                                         const std::string& default_out, BenchArgs* args) {
  args->out_path = default_out;
  cli::CommandLine command_line(name, "[--quick] [--out FILE]", description);
  addBenchOptions(command_line, args);
  return command_line.parse(argc, argv);
}

}  // namespace bench
}  // namespace vrm_sim
