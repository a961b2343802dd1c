// Linked into the tests and benchmarks (vrm_sim's, and vrm_tracking's tests of scene trocars), which run in a
// checkout: vrm_sim's shipped scenes come from its source package (VRM_SIM_PACKAGE_DIR, set by each CMakeLists).
// Installed code finds the package at run time instead (package_data.h).
#include "vrm_scene/scene_loader.h"

namespace {
const bool kSourcePackage = (vrm_sim::scene::setPackageDirectory(VRM_SIM_PACKAGE_DIR), true);
}  // namespace
