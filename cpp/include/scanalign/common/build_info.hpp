// What this build of scanalign holds: its version and its optional parts.
#pragma once

#include <stdexcept>
#include <string>

namespace scanalign {

/// The library's version, "MAJOR.MINOR.PATCH": the one in the top-level CMakeLists.txt, which
/// the Python package reports too (one version source).
const char* version();

/// Whether the PCL plug-ins and baselines (scanalign::pcl: PCL ICP variants, BoxRejector and
/// PointToPlaneLLS inside PCL, FPFH/SHOT/3DSC/PPF alignment) were built: CMake option
/// SCANALIGN_WITH_PCL (AUTO: when PCL is found).
bool builtWithPcl();

/// Whether the CUDA ICP backend (IcpBackend::Cuda, registration/cuda/icp_device.hpp) was
/// built: CMake option SCANALIGN_WITH_CUDA (AUTO: when nvcc is found). Whether a GPU is
/// present is a separate question: cuda::deviceNames().
bool builtWithCuda();

/// Thrown by a call that needs a part this build was configured without. Its message names
/// the call and the CMake option that builds the part.
class NotBuiltError : public std::runtime_error {
 public:
  NotBuiltError(const std::string& what, const std::string& option, const std::string& needs)
      : std::runtime_error(what + " needs scanalign built with " + option + " (this build has it off; " + needs +
                           ")") {}
};

}  // namespace scanalign
