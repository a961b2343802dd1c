#pragma once
// The hard cases of bench_tissue (issues 15, 40): grasp-and-pull, yank and push-through scenes on the bench membrane
// with the stiffness, mass, resolution, dt and driver speed pushed to where integrators break. Issue 40 §2 asks that
// `auto` choose well on scenes it has not seen: randomHardCase() draws such scenes from a seed, outside the hand-made
// list, from a generator of its own (SplitMix64 and explicit transforms, not <random>'s distributions, whose output
// differs between standard libraries), so a seed names the same scene on every machine.
#include <cmath>
#include <cstdint>
#include <sstream>
#include <string>

namespace vrm_sim {
namespace bench {

struct HardCase {
  std::string name;
  int cells;
  double dt;               // s; < 0: −dt × the explicit bound
  double stiffness_ratio;  // the x > 0 half
  double mass_ratio;       // the x > 0 half
  double pull_speed;       // m/s, grasp and pull
  double push_speed;       // m/s, sphere pushed through
  double stiffness_scale = 1.0, mass_scale = 1.0, damping = 2e-3;
  bool yank = false;        // grasp, lift at pull_speed for 20 frames, then yank_speed sideways and up for 5, hold
  double yank_speed = 0.6;  // m/s
  std::uint64_t seed = 0;   // randomHardCase(): the seed it was drawn from (0: hand-made)
  std::string description;  // randomHardCase(): the drawn parameters
};

// SplitMix64 (Steele, Lea & Flood 2014): the next 64-bit value of `state`.
inline std::uint64_t splitMix64(std::uint64_t& state) {
  std::uint64_t z = (state += 0x9e3779b97f4a7c15ULL);
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
  return z ^ (z >> 31);
}

// Uniform in [0, 1) from the top 53 bits.
inline double unitUniform(std::uint64_t& state) { return static_cast<double>(splitMix64(state) >> 11) * 0x1.0p-53; }

// 10^(log10(low) + u·(log10(high) − log10(low))): each decade equally likely.
inline double logUniform(std::uint64_t& state, double low, double high) {
  return low * std::pow(high / low, unitUniform(state));
}

// A hard scene nobody tuned `auto` on (issue 40 §2), drawn from `seed`:
//  - resolution 12–40 cells per side;
//  - stiffness 1–1000× the thesis' 2 N/m, the x > 0 half another 1–100× stiffer (a stiffness ratio);
//  - mass ratio 1–10⁴ (the x > 0 half heavier);
//  - dt 0.25–5 ms (up to ~50× the explicit bound of the stiffest draw);
//  - driver speed 3 mm/s – 0.6 m/s: a pull at that speed up to 50 mm/s, above it a slow lift (10 mm/s) and a 5 ms yank
//    at that speed, as a trainee's jerk.
inline HardCase randomHardCase(std::uint64_t seed) {
  std::uint64_t state = seed;
  HardCase hard{"random_" + std::to_string(seed), 0, 0.0, 1.0, 1.0, 0.0, 0.0};
  hard.seed = seed;
  hard.cells = 12 + static_cast<int>(unitUniform(state) * 29.0);
  hard.stiffness_scale = logUniform(state, 1.0, 1e3);
  hard.stiffness_ratio = logUniform(state, 1.0, 1e2);
  hard.mass_ratio = logUniform(state, 1.0, 1e4);
  hard.dt = logUniform(state, 2.5e-4, 5e-3);
  const double driver_speed = logUniform(state, 3e-3, 0.6);
  if (driver_speed <= 0.05) {
    hard.pull_speed = driver_speed;
  } else {
    hard.pull_speed = 0.01;
    hard.yank = true;
    hard.yank_speed = driver_speed;
  }
  std::ostringstream text;
  text.precision(3);
  text << hard.cells << "x" << hard.cells << ", k x" << hard.stiffness_scale << " (ratio " << hard.stiffness_ratio
       << "), mass ratio " << hard.mass_ratio << ", dt " << hard.dt * 1e3 << " ms, " << (hard.yank ? "yank " : "pull ")
       << driver_speed << " m/s";
  hard.description = text.str();
  return hard;
}

}  // namespace bench
}  // namespace vrm_sim
