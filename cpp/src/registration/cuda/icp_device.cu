// The ICP pass on an NVIDIA GPU (registration/cuda/icp_device.hpp): Algorithm 1 of the
// eye-in-hand paper (Comput. Electron. Agric. 180 (2021) 105929). Only the launch, the device
// memory and the reductions are here; the per-point work is the CPU engine's own code
// (correspondence_terms.hpp, left_balanced_search.hpp).
#include "scanalign/registration/cuda/icp_device.hpp"

#include <cuda_runtime.h>

#include <chrono>
#include <cstddef>
#include <stdexcept>
#include <string>

namespace scanalign::cuda {

namespace {

/// Threads per block: a multiple of the warp size; 256 keeps the per-thread sums (up to 32
/// doubles) in registers.
constexpr int kThreads = 256;
constexpr int kWarps = kThreads / 32;
/// The device search stack. A left-balanced tree of at most 2^30 points is at most 30
/// levels high, so 32 entries hold every pending branch: the device search is exact whenever
/// the requested stack_depth makes the CPU's exact, and approximates the same way otherwise.
constexpr int kStackCapacity = 32;

/// Sums per thread: 4 statistics (used, inliers, sum_d2, inexact), then the estimator's.
__host__ __device__ constexpr int components(PassMode mode) {
  return mode == PassMode::PointToPlane ? 4 + 21 + 6 + 1 : (mode == PassMode::PointToPoint ? 4 + 3 + 3 + 9 + 2 : 4);
}
constexpr int kMaxComponents = components(PassMode::PointToPlane);

void check(cudaError_t e, const char* what) {
  if (e != cudaSuccess) throw std::runtime_error(std::string("CUDA ") + what + ": " + cudaGetErrorString(e));
}

/// An owning device array that only grows.
template <typename T>
class DeviceArray {
 public:
  DeviceArray() = default;
  DeviceArray(const DeviceArray&) = delete;
  DeviceArray& operator=(const DeviceArray&) = delete;
  ~DeviceArray() {
    if (ptr_) cudaFree(ptr_);
  }
  void reserve(std::size_t n, const char* what) {
    if (n <= capacity_) return;
    if (ptr_) cudaFree(ptr_);
    ptr_ = nullptr;
    capacity_ = 0;
    check(cudaMalloc(reinterpret_cast<void**>(&ptr_), n * sizeof(T)), what);
    capacity_ = n;
  }
  void upload(const T* host, std::size_t n, const char* what) {
    reserve(n, what);
    if (n) check(cudaMemcpy(ptr_, host, n * sizeof(T), cudaMemcpyHostToDevice), what);
  }
  T* get() const { return ptr_; }

 private:
  T* ptr_ = nullptr;
  std::size_t capacity_ = 0;
};

__device__ inline double warpSum(double v) {
  for (int offset = 16; offset > 0; offset >>= 1) v += __shfl_down_sync(0xffffffffu, v, offset);
  return v;
}

/// Sums v over the block in a fixed order (shuffles within each warp, then the warps in
/// turn) and writes the K totals to out: the same bits for the same input on every run.
template <int K>
__device__ inline void blockSum(const double (&v)[K], double* out) {
  __shared__ double warp_sums[kWarps][K];
  const int lane = threadIdx.x & 31, warp = threadIdx.x >> 5;
#pragma unroll
  for (int c = 0; c < K; ++c) {
    const double s = warpSum(v[c]);
    if (lane == 0) warp_sums[warp][c] = s;
  }
  __syncthreads();
  if (threadIdx.x < K) {
    double s = 0;
    for (int w = 0; w < kWarps; ++w) s += warp_sums[w][threadIdx.x];
    out[threadIdx.x] = s;
  }
}

/// One thread per visited source point: Algorithm 1's body. Each block writes its K sums.
template <typename Scalar, PassMode Mode>
__global__ void __launch_bounds__(kThreads)
    passKernel(const IcpPassRules<Scalar> rules, const Scalar* __restrict__ source,
               const std::uint32_t* __restrict__ order, std::uint32_t stride, std::uint32_t count,
               const LeftBalancedNode<Scalar>* __restrict__ nodes, const SubtreeBounds<Scalar>* __restrict__ bounds,
               std::uint32_t n, const Scalar* __restrict__ normals, std::uint32_t* __restrict__ neighbor,
               double* __restrict__ block_sums) {
  constexpr int K = components(Mode);
  double v[K];
#pragma unroll
  for (int c = 0; c < K; ++c) v[c] = 0.0;
  const std::uint32_t k = blockIdx.x * blockDim.x + threadIdx.x;
  if (k < count) {
    const std::uint32_t i = order[static_cast<std::size_t>(k) * stride];
    const Scalar* s = source + 3 * static_cast<std::size_t>(i);
    if (detail::sourcePointUsed(rules, s)) {
      v[0] = 1.0;
      Scalar q[3];
      detail::transformPoint(rules, s, q);
      const std::uint32_t hint = rules.warm_start ? neighbor[i] : NearestNeighbor<Scalar>::kNone;
      const NearestNeighbor<Scalar> nn = leftBalancedNearest<Scalar, kStackCapacity>(
          nodes, bounds, n, q, rules.max_squared_distance, rules.stack_depth, hint);
      if (!nn.exact) v[3] = 1.0;
      if (nn.found()) {
        neighbor[i] = nn.node;
        v[1] = 1.0;
        v[2] = static_cast<double>(nn.squared_distance);
        if constexpr (Mode != PassMode::Evaluate) {
          const Scalar* p = nodes[nn.node].p;
          const double sq[3] = {double(q[0]), double(q[1]), double(q[2])};
          const double dq[3] = {double(p[0]), double(p[1]), double(p[2])};
          if constexpr (Mode == PassMode::PointToPlane) {
            const Scalar* np = normals + 3 * static_cast<std::size_t>(nn.node);
            const double nq[3] = {double(np[0]), double(np[1]), double(np[2])};
            const double w = detail::robustWeight(rules.kernel, rules.robust_scale, sq, dq, nq);
            detail::addPointToPlaneTerms(v + 4, v + 25, v[31], sq, dq, nq, w);
          } else {
            detail::addPointPairTerms(v + 4, v + 7, v + 10, v[19], v[20], sq, dq);
          }
        }
      }
    }
  }
  blockSum<K>(v, block_sums + static_cast<std::size_t>(blockIdx.x) * K);
}

/// The block sums added in a fixed order by one block: thread t takes blocks t, t + 256, ...
template <int K>
__global__ void __launch_bounds__(kThreads) finalSumKernel(const double* __restrict__ block_sums,
                                                           std::uint32_t nblocks, double* __restrict__ out) {
  double v[K];
#pragma unroll
  for (int c = 0; c < K; ++c) v[c] = 0.0;
  for (std::uint32_t b = threadIdx.x; b < nblocks; b += blockDim.x)
#pragma unroll
    for (int c = 0; c < K; ++c) v[c] += block_sums[static_cast<std::size_t>(b) * K + c];
  blockSum<K>(v, out);
}

}  // namespace

std::vector<std::string> deviceNames() {
  std::vector<std::string> names;
  int count = 0;
  if (cudaGetDeviceCount(&count) != cudaSuccess) {
    cudaGetLastError();  // clear the sticky "no driver" error
    return names;
  }
  for (int d = 0; d < count; ++d) {
    cudaDeviceProp prop{};
    if (cudaGetDeviceProperties(&prop, d) != cudaSuccess) continue;
    names.push_back(std::to_string(d) + ": " + prop.name + " (compute capability " + std::to_string(prop.major) + "." +
                    std::to_string(prop.minor) + ", " +
                    std::to_string(static_cast<long long>(prop.totalGlobalMem >> 20)) + " MiB)");
  }
  return names;
}

template <typename Scalar>
struct IcpDevice<Scalar>::Impl {
  DeviceArray<LeftBalancedNode<Scalar>> nodes;
  DeviceArray<SubtreeBounds<Scalar>> bounds;
  DeviceArray<Scalar> normals;
  DeviceArray<Scalar> source;
  DeviceArray<std::uint32_t> order;
  DeviceArray<std::uint32_t> neighbor;
  DeviceArray<double> block_sums;
  DeviceArray<double> totals;
  std::uint32_t target_size = 0;
  std::uint32_t source_size = 0;
  bool has_normals = false;
  double last_pass_seconds = 0.0;
};

template <typename Scalar>
IcpDevice<Scalar>::IcpDevice() {
  int count = 0;
  const cudaError_t e = cudaGetDeviceCount(&count);
  if (e != cudaSuccess || count == 0) {
    const std::string why = e != cudaSuccess ? cudaGetErrorString(e) : "the driver reports 0 devices";
    cudaGetLastError();
    throw std::runtime_error("ICP backend 'cuda': no usable CUDA device (" + why +
                             "); use backend 'cpu' on this machine");
  }
  check(cudaFree(nullptr), "context creation");  // creates the context now, not in the first pass
  impl_ = std::make_unique<Impl>();
}

template <typename Scalar>
IcpDevice<Scalar>::~IcpDevice() = default;

template <typename Scalar>
void IcpDevice<Scalar>::setTarget(const LeftBalancedNode<Scalar>* nodes, const SubtreeBounds<Scalar>* bounds,
                                  std::uint32_t n, const Scalar* normals) {
  Impl& d = *impl_;
  d.nodes.upload(nodes, n, "upload of the model's k-d tree");
  d.bounds.upload(bounds, n, "upload of the model's subtree bounds");
  d.has_normals = normals != nullptr;
  if (d.has_normals) d.normals.upload(normals, 3 * static_cast<std::size_t>(n), "upload of the model's normals");
  d.target_size = n;
}

template <typename Scalar>
void IcpDevice<Scalar>::setSource(const Scalar* xyz, std::uint32_t n, const std::uint32_t* order) {
  Impl& d = *impl_;
  d.source.upload(xyz, 3 * static_cast<std::size_t>(n), "upload of the source");
  d.order.upload(order, n, "upload of the source order");
  d.neighbor.reserve(n, "allocation of the warm-start hints");
  if (n) check(cudaMemset(d.neighbor.get(), 0xFF, n * sizeof(std::uint32_t)), "reset of the warm-start hints");
  d.source_size = n;
}

template <typename Scalar>
PassSums IcpDevice<Scalar>::pass(const IcpPassRules<Scalar>& rules, PassMode mode, std::uint32_t stride,
                                 std::uint32_t count) {
  Impl& d = *impl_;
  PassSums out;
  if (count == 0) return out;
  if (stride == 0 || static_cast<std::size_t>(count - 1) * stride >= d.source_size)
    throw std::invalid_argument("IcpDevice::pass: the visited points exceed the uploaded source");
  if (mode == PassMode::PointToPlane && !d.has_normals)
    throw std::invalid_argument("IcpDevice::pass: point-to-plane needs the model's normals");
  const auto t0 = std::chrono::steady_clock::now();
  const std::uint32_t nblocks = (count + kThreads - 1) / kThreads;
  d.block_sums.reserve(static_cast<std::size_t>(nblocks) * kMaxComponents, "allocation of the block sums");
  d.totals.reserve(kMaxComponents, "allocation of the totals");
  const int K = components(mode);
  auto launch = [&](auto mode_tag) {
    constexpr PassMode M = decltype(mode_tag)::value;
    passKernel<Scalar, M><<<nblocks, kThreads>>>(rules, d.source.get(), d.order.get(), stride, count, d.nodes.get(),
                                                 d.bounds.get(), d.target_size, d.normals.get(), d.neighbor.get(),
                                                 d.block_sums.get());
    check(cudaGetLastError(), "launch of the ICP pass");
    finalSumKernel<components(M)><<<1, kThreads>>>(d.block_sums.get(), nblocks, d.totals.get());
    check(cudaGetLastError(), "launch of the final reduction");
  };
  switch (mode) {
    case PassMode::Evaluate: launch(std::integral_constant<PassMode, PassMode::Evaluate>{}); break;
    case PassMode::PointToPlane: launch(std::integral_constant<PassMode, PassMode::PointToPlane>{}); break;
    case PassMode::PointToPoint: launch(std::integral_constant<PassMode, PassMode::PointToPoint>{}); break;
  }
  double v[kMaxComponents] = {};
  check(cudaMemcpy(v, d.totals.get(), K * sizeof(double), cudaMemcpyDeviceToHost), "copy of the pass sums");
  out.used = v[0];
  out.inliers = v[1];
  out.sum_d2 = v[2];
  out.inexact = v[3];
  if (mode == PassMode::PointToPlane) {
    for (int c = 0; c < 21; ++c) out.ata[c] = v[4 + c];
    for (int c = 0; c < 6; ++c) out.atb[c] = v[25 + c];
    out.btb = v[31];
  } else if (mode == PassMode::PointToPoint) {
    for (int c = 0; c < 3; ++c) {
      out.sum_s[c] = v[4 + c];
      out.sum_d[c] = v[7 + c];
    }
    for (int c = 0; c < 9; ++c) out.sum_sd[c] = v[10 + c];
    out.sum_ss = v[19];
    out.sum_dd = v[20];
  }
  d.last_pass_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return out;
}

template <typename Scalar>
double IcpDevice<Scalar>::lastPassSeconds() const {
  return impl_->last_pass_seconds;
}

template class IcpDevice<float>;
template class IcpDevice<double>;

}  // namespace scanalign::cuda
