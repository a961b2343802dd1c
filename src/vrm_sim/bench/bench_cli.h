#pragma once
// The command line every benchmark takes from scripts/bench.sh: [--quick] [--out FILE].
#include <cstdio>
#include <optional>
#include <string>

namespace vrm_sim {
namespace bench {

struct BenchArgs {
  bool quick = false;
  std::string out_path;
};

// nullopt after printing the usage (exit status 2) for anything else.
inline std::optional<BenchArgs> parseBenchArgs(int argc, char** argv, const std::string& default_out) {
  BenchArgs args;
  args.out_path = default_out;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    if (arg == "--quick") {
      args.quick = true;
    } else if (arg == "--out" && i + 1 < argc) {
      args.out_path = argv[++i];
    } else {
      std::fprintf(stderr, "usage: %s [--quick] [--out FILE]\n", argv[0]);
      return std::nullopt;
    }
  }
  return args;
}

}  // namespace bench
}  // namespace vrm_sim
