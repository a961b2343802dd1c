// Replays every seed (corpus/<target>/) and every input that once crashed a fuzz target (regressions/<target>/)
// through the target's entry point, built without libFuzzer (plain gcc build, run by scripts/test.sh). One test per
// target for its corpus and one per regression input. An input listed in regressions/KNOWN_BUGS.txt
// ("<target>/<file> <bug>") is skipped with that bug as the message: it still crashes code this package may not
// change, and the skip names what is to be fixed.
#include <gtest/gtest.h>
#include <sys/resource.h>

#include <algorithm>
#include <cctype>
#include <exception>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>
#include <sstream>

#include "fuzz_target.h"
#include "vrm_tracking/calibration.h"

namespace fs = std::filesystem;

namespace {

const fs::path kPackage = VRM_FUZZ_SOURCE_DIR;

std::vector<std::uint8_t> readFile(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  return std::vector<std::uint8_t>(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

std::vector<fs::path> inputsIn(const fs::path& folder) {
  std::vector<fs::path> files;
  if (!fs::is_directory(folder)) return files;
  for (const auto& entry : fs::directory_iterator(folder)) {
    if (entry.is_regular_file() && entry.path().filename().string()[0] != '.') files.push_back(entry.path());
  }
  std::sort(files.begin(), files.end());
  return files;
}

std::map<std::string, std::string> knownBugs() {
  std::map<std::string, std::string> bugs;
  std::ifstream in(kPackage / "regressions" / "KNOWN_BUGS.txt");
  std::string line;
  while (std::getline(in, line)) {
    if (line.empty() || line[0] == '#') continue;
    const auto space = line.find(' ');
    if (space != std::string::npos) bugs[line.substr(0, space)] = line.substr(space + 1);
  }
  return bugs;
}

// Runs one input; an exception escaping the entry point is what libFuzzer reports as a crash (abort).
void replay(vrm_fuzz::EntryPoint entry, const fs::path& file) {
  const std::vector<std::uint8_t> bytes = readFile(file);
  vrm_fuzz::resetPersistentState();
  try {
    entry(bytes.data(), bytes.size());
  } catch (const std::exception& e) {
    ADD_FAILURE() << file << ": uncaught exception: " << e.what();
  } catch (...) {
    ADD_FAILURE() << file << ": uncaught non-standard exception";
  }
}

class CorpusTest : public testing::Test {
 public:
  CorpusTest(vrm_fuzz::EntryPoint entry, fs::path folder) : entry_(entry), folder_(std::move(folder)) {}
  void TestBody() override {
    const auto files = inputsIn(folder_);
    if (files.empty()) GTEST_SKIP() << "no seeds in " << folder_;
    for (const fs::path& file : files) replay(entry_, file);
    RecordProperty("inputs", static_cast<int>(files.size()));
  }

 private:
  vrm_fuzz::EntryPoint entry_;
  fs::path folder_;
};

class RegressionTest : public testing::Test {
 public:
  RegressionTest(vrm_fuzz::EntryPoint entry, fs::path file, std::string known_bug)
      : entry_(entry), file_(std::move(file)), known_bug_(std::move(known_bug)) {}
  void TestBody() override {
    if (!known_bug_.empty()) GTEST_SKIP() << "known bug, not fixed yet: " << known_bug_;
    replay(entry_, file_);
  }

 private:
  vrm_fuzz::EntryPoint entry_;
  fs::path file_;
  std::string known_bug_;
};

std::string testName(std::string name) {
  for (char& c : name) {
    if (!std::isalnum(static_cast<unsigned char>(c))) c = '_';
  }
  return name;
}

}  // namespace

namespace vrm_fuzz {  // fuzz/calibrator_images.cpp
vrm_tracking::ChessboardTarget seedBoard();
bool calibrateFromImages(const std::uint8_t* data, std::size_t size);
}  // namespace vrm_fuzz

// A seed that stops short of its path leaves the fuzzer to find it: the calibrator's seed once lost its third view to
// the same-pose test, and the fuzzer's coverage fell by 30 % (557 edges against 789).
TEST(Seeds, CalibratorImagesSeedCalibrates) {
  const std::vector<std::uint8_t> seed =
      readFile(kPackage / "corpus" / "calibrator_images" / "chessboard_three_views_and_fixture");
  ASSERT_FALSE(seed.empty());
  EXPECT_TRUE(vrm_fuzz::calibrateFromImages(seed.data(), seed.size()));
}

// The seed for detectTarget's last check: OpenCV finds the board's corners, but the squares sampled at both ends of
// their order are white (a spot on each), so there is no dark first square and the view is refused.
TEST(Seeds, CalibratorLightEndSquaresSeedReachesTheDarkSquareCheck) {
  const std::vector<std::uint8_t> seed = readFile(kPackage / "corpus" / "calibrator_images" / "light_end_squares");
  ASSERT_EQ(seed.size(), 7u + 96 * 80);  // [role][encoding mono8][flags][u16 96][u16 80], then the pixels
  cv::Mat grey(80, 96, CV_8UC1, const_cast<std::uint8_t*>(seed.data() + 7));
  std::vector<cv::Point2f> corners;
  const vrm_tracking::ChessboardTarget target = vrm_fuzz::seedBoard();
  ASSERT_TRUE(cv::findChessboardCorners(grey, cv::Size(target.cols, target.rows), corners,
                                        cv::CALIB_CB_ADAPTIVE_THRESH | cv::CALIB_CB_NORMALIZE_IMAGE));
  cv::Mat bgr;
  cv::cvtColor(grey, bgr, cv::COLOR_GRAY2BGR);
  EXPECT_FALSE(vrm_tracking::detectTarget(bgr, target, &corners));
}

int main(int argc, char** argv) {
  // A fuzzed array length may ask for gigabytes; fail that allocation (std::bad_alloc, which the entry points treat
  // like roscpp's failure to read the message) instead of swapping. The libFuzzer build does the same through
  // ASan's max_allocation_size_mb (scripts/fuzz.sh), and so does this test in the ASan build (scripts/test.sh
  // --sanitize; fuzz_support.cpp's default options): there the limit would fail ASan's own mappings, since its shadow
  // memory alone reserves terabytes of address space.
#ifndef __SANITIZE_ADDRESS__
  rlimit limit{rlim_t(8) << 30, rlim_t(8) << 30};
  setrlimit(RLIMIT_AS, &limit);
#endif
  testing::InitGoogleTest(&argc, argv);
  const auto bugs = knownBugs();
  for (const auto& [target, entry] : vrm_fuzz::registeredTargets()) {
    const fs::path corpus = kPackage / "corpus" / target;
    testing::RegisterTest("Corpus", target.c_str(), nullptr, nullptr, __FILE__, __LINE__,
                          [entry = entry, corpus]() -> testing::Test* { return new CorpusTest(entry, corpus); });
    for (const fs::path& file : inputsIn(kPackage / "regressions" / target)) {
      const std::string key = target + "/" + file.filename().string();
      const auto bug = bugs.find(key);
      const std::string known = bug == bugs.end() ? "" : bug->second;
      testing::RegisterTest(("Regression_" + target).c_str(), testName(file.filename().string()).c_str(), nullptr,
                            nullptr, __FILE__, __LINE__, [entry = entry, file, known]() -> testing::Test* {
                              return new RegressionTest(entry, file, known);
                            });
    }
  }
  return RUN_ALL_TESTS();
}
