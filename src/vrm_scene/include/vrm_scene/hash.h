#pragma once
// The state hash every layer mixes into (world::World::stateHash, scenario::Scenario::hashState): 64-bit FNV-1a over
// bit patterns, so a replay that is bit-identical gives the same value and any difference changes it.

#include <cstddef>
#include <cstdint>

namespace vrm_sim {

constexpr std::uint64_t kHashSeed = 14695981039346656037ull;

// FNV-1a (64 bit) over `bytes` bytes, continuing from `hash`.
inline std::uint64_t hashBytes(std::uint64_t hash, const void* data, std::size_t bytes) {
  const auto* p = static_cast<const unsigned char*>(data);
  for (std::size_t i = 0; i < bytes; ++i) {
    hash ^= p[i];
    hash *= 1099511628211ull;
  }
  return hash;
}

}  // namespace vrm_sim
