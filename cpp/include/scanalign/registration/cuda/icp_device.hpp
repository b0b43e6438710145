// The ICP pass on an NVIDIA GPU: Algorithm 1 of the eye-in-hand paper (Comput. Electron.
// Agric. 180 (2021) 105929).
//
// The model's left-balanced k-d tree (built on the CPU, left_balanced_search.hpp) and its
// normals stay on the device between passes and frames; the source and its processing order
// are uploaded once per alignment. One kernel launch per pass gives each source point a thread
// that moves it, applies the box and distance rejection, searches the tree with a fixed stack
// and adds its terms (correspondence_terms.hpp, the same functions the CPU engine runs); a
// block reduction and a final fixed-order reduction leave the estimator's sums, the only
// numbers copied back. The 6x6 solve stays on the CPU (icp.cpp), as in the paper.
//
// The reductions add in a fixed order (no atomics), so a pass is deterministic: the same
// input gives the same bits, run after run. Icp<Scalar> (icp.hpp) drives this class when
// IcpSettings::backend is IcpBackend::Cuda; most users never touch it.
//
// Plain C++ (no Eigen, no CUDA headers), so the core builds without the CUDA toolkit: a build
// without SCANALIGN_WITH_CUDA defines these functions to throw NotBuiltError.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "scanalign/registration/correspondence_terms.hpp"
#include "scanalign/registration/left_balanced_search.hpp"

namespace scanalign::cuda {

/// The CUDA devices this process sees (empty without a driver or a device, or in a build
/// without CUDA): "index: name (compute capability, memory)".
std::vector<std::string> deviceNames();

/// What a pass accumulates besides the correspondence statistics.
enum class PassMode : int {
  Evaluate = 0,      ///< statistics only (the final fitness pass)
  PointToPlane = 1,  ///< Low's normal equations (ata, atb, btb)
  PointToPoint = 2,  ///< the point-to-point sums (sum_s, sum_d, sum_sd, sum_ss, sum_dd)
};

/// The sums of one pass over the source, reduced on the device in a fixed order.
struct PassSums {
  double used = 0;      ///< finite source points inside the box
  double inliers = 0;   ///< of those, with a model point within range
  double sum_d2 = 0;    ///< sum of squared correspondence distances (m^2)
  double inexact = 0;   ///< searches that dropped a branch that could have held a closer point
  double ata[21] = {};  ///< PointToPlane: upper triangle of A^T A, row-major
  double atb[6] = {};   ///< PointToPlane: A^T b
  double btb = 0;       ///< PointToPlane: sum of b^2 (m^2)
  double sum_s[3] = {}, sum_d[3] = {}, sum_sd[9] = {}, sum_ss = 0, sum_dd = 0;  ///< PointToPoint
};

/// A device-resident ICP target and source. Not copyable; one per Icp object.
template <typename Scalar>
class IcpDevice {
 public:
  /// Selects the current CUDA device. Throws NotBuiltError in a build without CUDA and
  /// std::runtime_error when no CUDA device is usable (the message says why).
  IcpDevice();
  ~IcpDevice();
  IcpDevice(const IcpDevice&) = delete;
  IcpDevice& operator=(const IcpDevice&) = delete;

  /// Uploads the model: n tree nodes, their subtree bounds and (optional, 3 per node in
  /// tree order) unit normals. Keeps the device buffers when they are large enough.
  void setTarget(const LeftBalancedNode<Scalar>* nodes, const SubtreeBounds<Scalar>* bounds, std::uint32_t n,
                 const Scalar* normals);
  /// Uploads n source points (x, y, z packed) and the order the passes visit them in (a
  /// permutation of [0, n): neighbouring threads then query neighbouring points), and
  /// forgets the last neighbours (the warm-start hints).
  void setSource(const Scalar* xyz, std::uint32_t n, const std::uint32_t* order);
  /// One pass over the source points order[k * stride] for k in [0, count).
  PassSums pass(const IcpPassRules<Scalar>& rules, PassMode mode, std::uint32_t stride, std::uint32_t count);
  /// Seconds the last pass spent on the device (kernels and the copy back).
  double lastPassSeconds() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

extern template class IcpDevice<float>;
extern template class IcpDevice<double>;

}  // namespace scanalign::cuda
