#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <stdexcept>

#include "fuzz_target.h"
#include "vrm_scene/scene_loader.h"

namespace vrm_fuzz {

namespace {
// The fuzz build runs in a checkout: vrm_sim's shipped scenes (sim_messages.h) from its source package.
const bool kShippedScenes = (vrm_sim::scene::setPackageDirectory(VRM_FUZZ_SOURCE_DIR "/../vrm_sim"), true);
}  // namespace

std::vector<std::pair<std::string, EntryPoint>>& registeredTargets() {
  static std::vector<std::pair<std::string, EntryPoint>> targets;
  return targets;
}

bool registerTarget(const char* name, EntryPoint entry) {
  registeredTargets().emplace_back(name, entry);
  return true;
}

namespace {
std::vector<void (*)()>& resets() {
  static std::vector<void (*)()> hooks;
  return hooks;
}
}  // namespace

void registerReset(void (*reset)()) {
  for (auto hook : resets()) {
    if (hook == reset) return;
  }
  resets().push_back(reset);
}

void resetPersistentState() {
  for (auto hook : resets()) hook();
}

namespace {
struct ScratchDirectory {
  std::string path;
  ScratchDirectory() {
    const char* base = std::filesystem::is_directory("/dev/shm") ? "/dev/shm" : "/tmp";
    std::string pattern = std::string(base) + "/vrm_fuzz_XXXXXX";
    if (!mkdtemp(pattern.data())) throw std::runtime_error("vrm_fuzz: cannot create a scratch directory");
    path = pattern;
  }
  ~ScratchDirectory() {
    std::error_code ignored;
    std::filesystem::remove_all(path, ignored);
  }
};
}  // namespace

const std::string& scratchDirectory() {
  static ScratchDirectory directory;
  return directory.path;
}

std::string writeScratchFile(const std::string& name, const std::uint8_t* data, std::size_t size) {
  const std::string path = scratchDirectory() + "/" + name;
  std::FILE* file = std::fopen(path.c_str(), "wb");
  if (!file) throw std::runtime_error("vrm_fuzz: cannot write " + path);
  if (size) std::fwrite(data, 1, size, file);
  std::fclose(file);
  return path;
}

std::string packageDirectory(const std::string& package) { return std::string(VRM_FUZZ_SOURCE_DIR) + "/../" + package; }

}  // namespace vrm_fuzz

#if defined(VRM_FUZZ_LIBFUZZER) || defined(__SANITIZE_ADDRESS__)
// The same holds for test_fuzz_regressions in scripts/test.sh --sanitize (gcc's ASan build), which replays those
// inputs: without this, a regression input's gigabyte array length ends it with ASan's "Failed to mmap" instead of the
// std::bad_alloc the entry point is tested to survive.
#ifndef VRM_FUZZ_LIBFUZZER
// scripts/fuzz.sh sets these for the fuzz executables; the sanitizer test run's env.sh does not (ASAN_OPTIONS, when
// set, overrides each option it names).
extern "C" const char* __asan_default_options() { return "allocator_may_return_null=1:max_allocation_size_mb=128"; }
#endif
// ASan's operator new reports an allocation it cannot serve (max_allocation_size_mb, scripts/fuzz.sh) as a fatal
// out-of-memory instead of throwing std::bad_alloc. A fuzzed array length prefix asks for gigabytes in roscpp's
// deserializer; what the simulator must survive is the std::bad_alloc a normal build throws there, so the fuzz
// executables get the standard behaviour back: operator new on top of (ASan-intercepted) malloc, which returns null
// for such a size, and throws. Heap errors are still found (malloc/free are ASan's); only new/delete mismatches are
// not.
#include <cstdlib>
#include <new>

namespace {
void* allocateOrThrow(std::size_t size) {
  if (void* p = std::malloc(size ? size : 1)) return p;
  throw std::bad_alloc();
}
void* allocateAlignedOrThrow(std::size_t size, std::align_val_t alignment) {
  void* p = nullptr;
  const std::size_t a = std::max(static_cast<std::size_t>(alignment), sizeof(void*));
  if (posix_memalign(&p, a, size ? size : 1) == 0 && p) return p;
  throw std::bad_alloc();
}
}  // namespace

void* operator new(std::size_t size) { return allocateOrThrow(size); }
void* operator new[](std::size_t size) { return allocateOrThrow(size); }
void* operator new(std::size_t size, const std::nothrow_t&) noexcept { return std::malloc(size ? size : 1); }
void* operator new[](std::size_t size, const std::nothrow_t&) noexcept { return std::malloc(size ? size : 1); }
void* operator new(std::size_t size, std::align_val_t alignment) { return allocateAlignedOrThrow(size, alignment); }
void* operator new[](std::size_t size, std::align_val_t alignment) { return allocateAlignedOrThrow(size, alignment); }
void* operator new(std::size_t size, std::align_val_t alignment, const std::nothrow_t&) noexcept {
  try {
    return allocateAlignedOrThrow(size, alignment);
  } catch (const std::bad_alloc&) {
    return nullptr;
  }
}
void* operator new[](std::size_t size, std::align_val_t alignment, const std::nothrow_t&) noexcept {
  return operator new(size, alignment, std::nothrow);
}
void operator delete(void* p) noexcept { std::free(p); }
void operator delete[](void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t) noexcept { std::free(p); }
void operator delete(void* p, const std::nothrow_t&) noexcept { std::free(p); }
void operator delete[](void* p, const std::nothrow_t&) noexcept { std::free(p); }
void operator delete(void* p, std::align_val_t) noexcept { std::free(p); }
void operator delete[](void* p, std::align_val_t) noexcept { std::free(p); }
void operator delete(void* p, std::size_t, std::align_val_t) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t, std::align_val_t) noexcept { std::free(p); }
void operator delete(void* p, std::align_val_t, const std::nothrow_t&) noexcept { std::free(p); }
void operator delete[](void* p, std::align_val_t, const std::nothrow_t&) noexcept { std::free(p); }
#endif
