#pragma once
// Loading scene files (config/scenes/*.yaml; the schema is documented in scene_description.h) and turning their
// object descriptions into meshes.

#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

#include "vrm_scene/scene_description.h"

namespace vrm_sim {
namespace scene {

// Any problem with a scene file: the strict reader's error (yaml/yaml_error.h). what() reads
// "<file>:<line>:<column>: <field>: <problem>", e.g.
// "membrane_peeling.yaml:14:5: objects[1].tissue.stiffness: expected a positive number, got 'abc'"
// (line and column are omitted when unknown, e.g. for a missing file).
using SceneError = vrm_sim::YamlError;

// The scene a node, tool or launch file runs when it is not told one: defined here once.
extern const char* const kDefaultSceneName;

// What identifies a scene's content: FNV-1a 64 of the scene file's bytes and the difficulty level (a scene edited on
// disk under the same name is another scene). 0 when the file cannot be read. The one scene owner announces it
// (vrm_msgs/RunningScene); a follower compares it with what it runs.
std::uint64_t sceneContentHash(const std::string& file, const std::string& difficulty);

// Loads a scene by name or path (resolveScenePath: an existing file, else the shipped scene of that name), the one
// entry point every package uses. Parses and validates the scene file: unknown keys, wrong types, out-of-range values,
// inconsistent simulations, unknown trocars and missing mesh files are all SceneErrors. Relative mesh paths are
// resolved against the scene file's directory, then against the vrm_sim package directory (packageDirectory(), when
// set). `difficulty`: the scenario's difficulty level whose overrides to apply (empty: its default level); a level the
// scenario does not have, or any level for a scene without levels, is a SceneError.
SceneDescription loadScene(const std::string& name_or_path, const std::string& difficulty = "");
// Same, from text; `virtual_path` names the document in messages and anchors relative mesh paths.
SceneDescription loadSceneFromString(const std::string& yaml_text, const std::string& virtual_path,
                                     const std::string& difficulty = "");

// A scripted session in its own file (scenario_offline --script FILE, the device twins' ~script): the full form of a
// scenario's scripts at the top level (scene_description.h), plus an optional `name` (default: the file's stem) and
// `format_version: 1`. SceneError with file:line:col as for scenes.
// `name_or_path` as resolveScriptPath reads it.
ScriptedSession loadScript(const std::string& name_or_path);
// An existing file; else, for a bare name, the shipped script <package>/config/scripts/NAME.yaml (e.g. "demo", what
// the device twins play without a ~script); else the path as written.
std::string resolveScriptPath(const std::string& name_or_path);
// Names of the shipped scripts (config/scripts/*.yaml), sorted; none when the package directory was not set.
std::vector<std::string> shippedScripts();
// Same, from text; `virtual_path` names the document in messages.
ScriptedSession loadScriptFromString(const std::string& yaml_text, const std::string& virtual_path);

// Where the shipped data is found: the vrm_sim package directory (config/scenes/, shared mesh assets), found at run
// time, never compiled in: a source package in a devel space, <prefix>/share/vrm_sim in an install space. The core
// does not look for it; whoever knows sets it once per process: the ROS layer with vrm_sim::usePackageData()
// (vrm_scene/package_data.h: ros::package::getPath), tests with their source package. Empty until set.
void setPackageDirectory(const std::string& directory);
std::string packageDirectory();

// Path of a shipped scene, e.g. shippedScenePath("navigation") -> <package>/config/scenes/navigation.yaml. A
// SceneError when the package directory was not set.
std::string shippedScenePath(const std::string& scene_name);
// What loadScene's and the nodes' and tools' `scene` arguments mean: an existing file; else, for a bare name (no '/',
// no '.'), the shipped scene of that name; else the path as written (loadScene then reports it missing).
std::string resolveScenePath(const std::string& name_or_path);
// Names of the shipped scenes (config/scenes/*.yaml), sorted; none when the package directory was not set.
std::vector<std::string> shippedScenes();

enum class MeshFrame {
  kLocal,   // vertices in the object's own frame
  kParent,  // the object's pose applied: vertices in the frame the object names (eye or world)
};

// Generates or imports the object's mesh (named after the object). Import and generator failures are rethrown as
// SceneError carrying the object's location in the scene file.
TriangleMesh buildMesh(const ObjectDescription& object, MeshFrame frame = MeshFrame::kParent);
// One mesh per scene object, in the order of scene.objects, in the objects' parent frames.
std::vector<TriangleMesh> resolveMeshes(const SceneDescription& scene);
// The instrument's mesh in its instrument frame (see instrument_meshes.h).
TriangleMesh buildInstrumentMesh(const InstrumentDescription& instrument);

}  // namespace scene
}  // namespace vrm_sim
