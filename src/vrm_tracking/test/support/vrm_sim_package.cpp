// Linked into the unit tests, which run in a checkout: vrm_sim's shipped scenes come from its source package
// (VRM_SIM_PACKAGE_DIR, set by CMake). The nodelets find the package at run time (vrm_sim/package_data.h).
#include "vrm_sim/scene/scene_loader.h"

namespace {
const bool kSourcePackage = (vrm_sim::scene::setPackageDirectory(VRM_SIM_PACKAGE_DIR), true);
}  // namespace
