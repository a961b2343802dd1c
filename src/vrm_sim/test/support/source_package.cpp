// Linked into the tests and benchmarks, which run in a checkout: shipped scenes come from the source package
// (VRM_SIM_PACKAGE_DIR, set by CMake). Installed code finds the package at run time instead (package_data.h).
#include "vrm_sim/scene/scene_loader.h"

namespace {
const bool kSourcePackage = (vrm_sim::scene::setPackageDirectory(VRM_SIM_PACKAGE_DIR), true);
}  // namespace
