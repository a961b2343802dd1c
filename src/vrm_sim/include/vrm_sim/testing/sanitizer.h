#pragma once
// Whether this test binary is built with AddressSanitizer (scripts/test.sh --sanitize). Header-only, no ROS.
//
// Under ASan the instrumented nodelets run several times slower than in Release: a test that also checks a rate or a
// wall-clock bound relaxes or reports that one check there (saying why where it does), and checks everything else
// alike. One constant, so that `if (kUnderSanitizer)` reads the same in every test and no test spells its own #ifdef.

namespace vrm_sim::testing {

#ifdef __SANITIZE_ADDRESS__
inline constexpr bool kUnderSanitizer = true;
#else
inline constexpr bool kUnderSanitizer = false;
#endif

}  // namespace vrm_sim::testing
