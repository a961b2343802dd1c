#pragma once
// Where a value of a project file came from, and the error every strict reader throws (yaml/strict_reader.h). Apart
// from the reader so that descriptions can carry locations without including yaml-cpp.

#include <stdexcept>
#include <string>

namespace vrm_sim {

// Where a value came from, for error messages during and after loading (e.g. a mesh file that fails to import).
struct SourceLocation {
  std::string file;
  int line = 0;  // 1-based; 0 = unknown
  int column = 0;
  std::string field;  // e.g. "objects[1].mesh"
};

// Any problem with a file read through this reader. what() reads "<file>:<line>:<column>: <field>: <problem>", e.g.
// "membrane_peeling.yaml:14:5: objects[1].tissue.stiffness: expected a positive number, got 'abc'" (line and column
// are omitted when unknown, e.g. for a missing file).
class YamlError : public std::runtime_error {
 public:
  YamlError(const SourceLocation& location, const std::string& problem);
  const SourceLocation& location() const { return location_; }
  const std::string& problem() const { return problem_; }

 private:
  SourceLocation location_;
  std::string problem_;
};

}  // namespace vrm_sim
