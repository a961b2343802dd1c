// StateArchive (issue 39 §1): one transferState() saves and loads a class's state; values come back bit for bit, and
// a truncated, oversized or misplaced stream is refused with an error naming where.

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <deque>
#include <limits>
#include <map>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "vrm_sim/state/state_archive.h"

namespace vrm_sim {
namespace {

enum class Phase : std::uint8_t { kIdle, kRunning };

struct Inner {
  std::optional<Eigen::Vector3d> tip;
  std::vector<bool> flags;
  void transferState(StateArchive& archive) { archive(tip)(flags); }
};

struct Everything {
  double number = 0.0;
  std::int64_t count = 0;
  Phase phase = Phase::kIdle;
  std::string name;
  std::vector<Eigen::Vector3d> points;
  std::vector<std::array<std::uint32_t, 2>> pairs;
  std::map<std::string, Inner> inners;
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  Eigen::Quaterniond rotation = Eigen::Quaterniond::Identity();
  std::deque<double> window;
  std::set<std::uint64_t> ids;
  void transferState(StateArchive& archive) {
    archive.section("everything");
    archive(number)(count)(phase)(name)(points)(pairs)(inners)(pose)(rotation)(window)(ids);
  }
};

Everything sample() {
  Everything e;
  e.number = std::nextafter(0.1, 1.0);  // a value a decimal round trip would change
  e.count = -42;
  e.phase = Phase::kRunning;
  e.name = std::string("membrane\0peeling", 16);
  e.points = {{1e-300, -0.0, 3.0}, {std::numeric_limits<double>::denorm_min(), 2.0, -1.0}};
  e.pairs = {{1, 2}, {7, 9}};
  e.inners["left"].tip = Eigen::Vector3d(0.1, 0.2, 0.3);
  e.inners["left"].flags = {true, false, true};
  e.inners["right"];
  e.pose.translate(Eigen::Vector3d(1, 2, 3));
  e.pose.rotate(Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitY()));
  e.rotation = Eigen::Quaterniond(Eigen::AngleAxisd(1.1, Eigen::Vector3d::UnitX()));
  e.window = {0.5, 0.25};
  e.ids = {5, 3, 99};
  return e;
}

std::string save(Everything& e) {
  StateArchive archive = StateArchive::saver();
  archive(e);
  return archive.takeBytes();
}

TEST(StateArchive, RoundTripIsBitForBit) {
  Everything original = sample();
  const std::string bytes = save(original);
  Everything loaded;
  StateArchive archive = StateArchive::loader(bytes);
  archive(loaded);
  EXPECT_TRUE(archive.atEnd());
  EXPECT_EQ(std::memcmp(&loaded.number, &original.number, sizeof(double)), 0);
  EXPECT_EQ(loaded.count, original.count);
  EXPECT_EQ(loaded.phase, Phase::kRunning);
  EXPECT_EQ(loaded.name, original.name);
  ASSERT_EQ(loaded.points.size(), 2u);
  EXPECT_TRUE(std::signbit(loaded.points[0].y()));  // -0.0 kept
  EXPECT_EQ(loaded.points[1].x(), std::numeric_limits<double>::denorm_min());
  EXPECT_EQ(loaded.pairs, original.pairs);
  ASSERT_EQ(loaded.inners.size(), 2u);
  EXPECT_EQ(*loaded.inners["left"].tip, *original.inners["left"].tip);
  EXPECT_EQ(loaded.inners["left"].flags, original.inners["left"].flags);
  EXPECT_FALSE(loaded.inners["right"].tip.has_value());
  EXPECT_TRUE(loaded.pose.matrix() == original.pose.matrix());
  EXPECT_TRUE(loaded.rotation.coeffs() == original.rotation.coeffs());
  EXPECT_EQ(loaded.window, original.window);
  EXPECT_EQ(loaded.ids, original.ids);
  // Saving the loaded object gives the same bytes.
  EXPECT_EQ(save(loaded), bytes);
}

TEST(StateArchive, LoadingReplacesWhatWasThere) {
  Everything original = sample();
  const std::string bytes = save(original);
  Everything target = sample();
  target.points.resize(10);
  target.inners["extra"];
  target.ids.insert(1000);
  StateArchive archive = StateArchive::loader(bytes);
  archive(target);
  EXPECT_EQ(target.points.size(), 2u);
  EXPECT_EQ(target.inners.count("extra"), 0u);
  EXPECT_EQ(target.ids.count(1000), 0u);
}

TEST(StateArchive, BadStreamsAreRefusedWithWhere) {
  Everything original = sample();
  const std::string bytes = save(original);
  // Every truncation fails (never reads past the end, never succeeds short).
  for (std::size_t cut = 0; cut < bytes.size(); ++cut) {
    Everything target;
    StateArchive archive = StateArchive::loader(bytes.substr(0, cut));
    EXPECT_THROW(archive(target), StateError) << "cut at " << cut;
  }
  // A wrong section tag names both.
  std::string renamed = bytes;
  renamed[0] = 'E';
  try {
    Everything target;
    StateArchive archive = StateArchive::loader(renamed);
    archive(target);
    ADD_FAILURE() << "accepted";
  } catch (const StateError& error) {
    EXPECT_NE(std::string(error.what()).find("section 'everything' expected, found 'Everything'"), std::string::npos)
        << error.what();
  }
  // A length far beyond the data is refused before anything is allocated.
  std::string bomb = "everything";
  bomb.append(sizeof(double) + sizeof(std::int64_t) + 1, '\0');
  const std::uint64_t huge = std::uint64_t{1} << 60;
  bomb.append(reinterpret_cast<const char*>(&huge), sizeof huge);
  try {
    Everything target;
    StateArchive archive = StateArchive::loader(bomb);
    archive(target);
    ADD_FAILURE() << "accepted";
  } catch (const StateError& error) {
    EXPECT_NE(std::string(error.what()).find("beyond the"), std::string::npos) << error.what();
    EXPECT_NE(std::string(error.what()).find("(in everything)"), std::string::npos) << error.what();
  }
}

TEST(StateArchive, ExpectChecksConfiguration) {
  StateArchive saver = StateArchive::saver();
  saver.expect(std::size_t{100}, "node count");
  const std::string bytes = saver.takeBytes();
  StateArchive same = StateArchive::loader(bytes);
  EXPECT_NO_THROW(same.expect(std::size_t{100}, "node count"));
  StateArchive other = StateArchive::loader(bytes);
  EXPECT_THROW(other.expect(std::size_t{101}, "node count"), StateError);
}

}  // namespace
}  // namespace vrm_sim
