// A non-owning view of 3-D points stored with a fixed stride.
//
// The same view reads a NumPy (N,3) array (stride 3), a PCL pcl::PointXYZ cloud
// (stride 4 floats) or a pcl::PointNormal cloud (stride 8 floats) without copying.
#pragma once

#include <cmath>
#include <cstddef>
#include <stdexcept>

#include <Eigen/Core>

namespace scanalign {

template <typename Scalar>
struct CloudView {
  using Vector3 = Eigen::Matrix<Scalar, 3, 1>;

  const Scalar* data = nullptr;  ///< first coordinate of the first point
  std::size_t size = 0;          ///< number of points
  std::size_t stride = 3;        ///< elements (not bytes) between consecutive points

  CloudView() = default;
  CloudView(const Scalar* data_, std::size_t size_, std::size_t stride_ = 3)
      : data(data_), size(size_), stride(stride_) {
    if (size_ > 0 && data_ == nullptr) throw std::invalid_argument("CloudView: null data with non-zero size");
    if (stride_ < 3) throw std::invalid_argument("CloudView: stride must be at least 3 elements");
  }

  bool empty() const { return size == 0; }
  const Scalar* ptr(std::size_t i) const { return data + i * stride; }
  Eigen::Map<const Vector3> operator[](std::size_t i) const { return Eigen::Map<const Vector3>(ptr(i)); }
  bool isFinite(std::size_t i) const {
    const Scalar* p = ptr(i);
    return std::isfinite(p[0]) && std::isfinite(p[1]) && std::isfinite(p[2]);
  }
};

}  // namespace scanalign
