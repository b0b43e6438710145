// What this build holds. SCANALIGN_VERSION, SCANALIGN_HAVE_PCL and SCANALIGN_HAVE_CUDA come from
// CMake (the project's VERSION and the SCANALIGN_WITH_PCL / SCANALIGN_WITH_CUDA options), so the
// library cannot disagree with its build.
#include "scanalign/common/build_info.hpp"

namespace scanalign {

const char* version() { return SCANALIGN_VERSION; }

bool builtWithPcl() {
#if SCANALIGN_HAVE_PCL
  return true;
#else
  return false;
#endif
}

}  // namespace scanalign

namespace scanalign {

bool builtWithCuda() {
#if SCANALIGN_HAVE_CUDA
  return true;
#else
  return false;
#endif
}

}  // namespace scanalign
