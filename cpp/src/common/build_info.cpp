// What this build holds. SCANALIGN_VERSION and SCANALIGN_HAVE_PCL come from CMake (the project's
// VERSION and the SCANALIGN_WITH_PCL option), so the library cannot disagree with its build.
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
