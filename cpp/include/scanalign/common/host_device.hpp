// Functions the CPU engine and the CUDA kernels share.
//
// SCANALIGN_HOST_DEVICE marks an inline function that nvcc compiles for both the host and the
// device; a C++ compiler sees a plain inline function. Such functions are written in plain
// C++ (no Eigen, no std containers, no exceptions), so that the CPU tests exercise the very
// arithmetic the GPU kernels run.
#pragma once

#include <cmath>

#if defined(__CUDACC__)
#define SCANALIGN_HOST_DEVICE __host__ __device__
#else
#define SCANALIGN_HOST_DEVICE
#endif

namespace scanalign::detail {

/// std::isfinite on the host, CUDA's isfinite on the device.
template <typename T>
SCANALIGN_HOST_DEVICE inline bool finite(T x) {
#if defined(__CUDA_ARCH__)
  return isfinite(x);
#else
  return std::isfinite(x);
#endif
}

template <typename Scalar>
SCANALIGN_HOST_DEVICE inline bool finite3(const Scalar* p) {
  return finite(p[0]) && finite(p[1]) && finite(p[2]);
}

}  // namespace scanalign::detail
