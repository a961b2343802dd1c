#pragma once
// One fuzz entry point per file (fuzz/<target>.cpp), compiled two ways:
//   * with VRM_FUZZ_LIBFUZZER (scripts/fuzz.sh, clang): VRM_FUZZ_TARGET is libFuzzer's LLVMFuzzerTestOneInput, one
//     executable fuzz_<target> per file;
//   * without (the plain gcc build): a function registered under the target's name, so every target coexists in the
//     regression test that replays corpus/<target>/ and regressions/<target>/ (test/test_fuzz_regressions.cpp).
// The body is the same in both: exactly the code that libFuzzer ran is what the replay runs.

#include <cstddef>
#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

namespace vrm_fuzz {

using EntryPoint = int (*)(const std::uint8_t* data, std::size_t size);

// Registered entry points by target name (replay build only; empty under libFuzzer).
std::vector<std::pair<std::string, EntryPoint>>& registeredTargets();
bool registerTarget(const char* name, EntryPoint entry);

// A cursor over the fuzz bytes: fixed-size reads return 0 (or the fallback) once the input is exhausted, so every
// input is a valid program for the target (the FuzzedDataProvider idea, minus its reverse-order integer reads, which
// make seeds harder to write by hand).
class Bytes {
 public:
  Bytes(const std::uint8_t* data, std::size_t size) : data_(data), size_(size) {}
  std::size_t remaining() const { return size_ - pos_; }
  bool empty() const { return pos_ >= size_; }
  template <typename T>
  T take(T fallback = T()) {
    if (remaining() < sizeof(T)) {
      pos_ = size_;
      return fallback;
    }
    T value;
    std::memcpy(&value, data_ + pos_, sizeof(T));
    pos_ += sizeof(T);
    return value;
  }
  // Up to n bytes (fewer at the end of the input).
  std::vector<std::uint8_t> takeBytes(std::size_t n) {
    n = n < remaining() ? n : remaining();
    std::vector<std::uint8_t> out(data_ + pos_, data_ + pos_ + n);
    pos_ += n;
    return out;
  }
  std::string rest() {
    std::string out(reinterpret_cast<const char*>(data_ + pos_), remaining());
    pos_ = size_;
    return out;
  }
  const std::uint8_t* cursor() const { return data_ + pos_; }
  void skip(std::size_t n) { pos_ += n < remaining() ? n : remaining(); }

 private:
  const std::uint8_t* data_;
  std::size_t size_;
  std::size_t pos_ = 0;
};

// State a target keeps across inputs (sim_messages' persistent World) registers how to drop it; the regression replay
// drops it before every file, so a file replays against the state a fresh fuzzer process starts from.
void registerReset(void (*reset)());
void resetPersistentState();

// A private temporary directory for targets that must hand a *file* to the code under test (mesh import by
// extension, bags); in /dev/shm when available. Created once per process, removed at exit.
const std::string& scratchDirectory();
// Writes `size` bytes to scratchDirectory()/name and returns the path.
std::string writeScratchFile(const std::string& name, const std::uint8_t* data, std::size_t size);

// The workspace's source folder of a package (for seeds and shipped configuration): VRM_FUZZ_SOURCE_DIR/../<pkg>.
std::string packageDirectory(const std::string& package);

}  // namespace vrm_fuzz

#define VRM_FUZZ_CONCAT_(a, b) a##b
#define VRM_FUZZ_CONCAT(a, b) VRM_FUZZ_CONCAT_(a, b)

#ifdef VRM_FUZZ_LIBFUZZER
#define VRM_FUZZ_TARGET(name) extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size)
#else
#define VRM_FUZZ_TARGET(name)                                                             \
  static int VRM_FUZZ_CONCAT(vrmFuzz_, name)(const std::uint8_t* data, std::size_t size); \
  [[maybe_unused]] static const bool VRM_FUZZ_CONCAT(vrmFuzzRegistered_, name) =          \
      ::vrm_fuzz::registerTarget(#name, &VRM_FUZZ_CONCAT(vrmFuzz_, name));                \
  static int VRM_FUZZ_CONCAT(vrmFuzz_, name)(const std::uint8_t* data, std::size_t size)
#endif
