// The strict YAML reader every project file format goes through (scenes, marker layouts, camera rigs): locations,
// typo hints, unknown and duplicate keys, numbers that are not finite, syntax errors and unreadable files.
#include <gtest/gtest.h>

#include <functional>
#include <string>

#include "vrm_scene/yaml/strict_reader.h"

namespace vrm_sim {
namespace yaml {
namespace {

std::string failure(const std::function<void()>& read) {
  try {
    read();
  } catch (const YamlError& error) {
    return error.what();
  }
  return "no error";
}

TEST(StrictReader, ReadsKnownKeysAndRejectsTheRestWithAHint) {
  const Field root = parseText("speed: 2.5\nname: probe\nlimit: 3\n", "f.yaml");
  MapFields fields(root);
  EXPECT_DOUBLE_EQ(fields.required("speed").positive(), 2.5);
  EXPECT_EQ(fields.required("name").text(), "probe");
  EXPECT_EQ(failure([&] { fields.finish(); }), "f.yaml:3:1: limit: unknown key; allowed keys: speed, name");
  MapFields again(root);
  again.optional("speed");
  again.optional("name");
  again.optional("limits");
  EXPECT_EQ(failure([&] { again.finish(); }),
            "f.yaml:3:1: limit: unknown key (did you mean 'limits'?); allowed keys: speed, name, limits");
}

TEST(StrictReader, LocatesEveryProblem) {
  const Field root = parseText("a:\n  b: [1, .inf, 3]\n  c: -2\n  d: maybe\n", "g.yaml");
  MapFields top(root);
  MapFields a(top.required("a"));
  EXPECT_EQ(failure([&] { a.required("b").numbers(3, "a finite number", -1e9, 1e9); }),
            "g.yaml:2:10: a.b[1]: expected a finite number, got '.inf'");
  EXPECT_EQ(failure([&] { a.required("c").nonNegative(); }),
            "g.yaml:3:6: a.c: expected a non-negative number, got '-2'");
  EXPECT_EQ(failure([&] { a.required("d").boolean(); }), "g.yaml:4:6: a.d: expected true or false, got 'maybe'");
  EXPECT_EQ(failure([&] { a.required("e"); }), "g.yaml:2:3: a: missing required key 'e'");
  EXPECT_EQ(failure([&] {
              a.required("d").name({"mayby", "never"});
            }),
            "g.yaml:4:6: a.d: expected one of mayby, never, got 'maybe' (did you mean 'mayby'?)");
  EXPECT_EQ(failure([&] { a.required("c").integer(0, 10); }),
            "g.yaml:3:6: a.c: expected an integer in [0, 10], got '-2'");
}

TEST(StrictReader, SyntaxErrorsDuplicatesAndFiles) {
  EXPECT_EQ(failure([] { parseText("a: [1, 2\n", "h.yaml"); }).rfind("h.yaml:2:1: YAML syntax error: ", 0), 0u);
  EXPECT_EQ(failure([] { MapFields fields(parseText("a: 1\na: 2\n", "h.yaml")); }), "h.yaml:2:1: a: duplicate key");
  EXPECT_EQ(failure([] { MapFields fields(parseText("- 1\n", "h.yaml")); }), "h.yaml:1:1: expected a map, got a list");
  EXPECT_EQ(failure([] { readFile("/nonexistent/x.yaml", "marker layout"); }),
            "/nonexistent/x.yaml: marker layout not found");
  EXPECT_EQ(failure([] { readFile("/", "rig calibration"); }), "/: cannot read the rig calibration");
}

}  // namespace
}  // namespace yaml
}  // namespace vrm_sim
