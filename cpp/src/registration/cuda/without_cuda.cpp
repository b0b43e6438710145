// The CUDA backend's entry points in a build without SCANALIGN_WITH_CUDA: no devices, and
// NotBuiltError naming the option for anything that would need one.
#include "scanalign/common/build_info.hpp"
#include "scanalign/registration/cuda/icp_device.hpp"

namespace scanalign::cuda {

namespace {
[[noreturn]] void notBuilt() {
  throw NotBuiltError("ICP backend 'cuda'", "SCANALIGN_WITH_CUDA=ON",
                      "install the CUDA toolkit (nvcc) and rebuild, or use backend 'cpu'");
}
}  // namespace

std::vector<std::string> deviceNames() { return {}; }

template <typename Scalar>
struct IcpDevice<Scalar>::Impl {};

template <typename Scalar>
IcpDevice<Scalar>::IcpDevice() {
  notBuilt();
}
template <typename Scalar>
IcpDevice<Scalar>::~IcpDevice() = default;
template <typename Scalar>
void IcpDevice<Scalar>::setTarget(const LeftBalancedNode<Scalar>*, const SubtreeBounds<Scalar>*, std::uint32_t,
                                  const Scalar*) {
  notBuilt();
}
template <typename Scalar>
void IcpDevice<Scalar>::setSource(const Scalar*, std::uint32_t, const std::uint32_t*) {
  notBuilt();
}
template <typename Scalar>
PassSums IcpDevice<Scalar>::pass(const IcpPassRules<Scalar>&, PassMode, std::uint32_t, std::uint32_t) {
  notBuilt();
}
template <typename Scalar>
double IcpDevice<Scalar>::lastPassSeconds() const {
  notBuilt();
}

template class IcpDevice<float>;
template class IcpDevice<double>;

}  // namespace scanalign::cuda
