#include "scanalign/reconstruction/depth_image.hpp"

#include <cmath>
#include <stdexcept>
#include <string>
#include <type_traits>

namespace scanalign {

void PinholeIntrinsics::validate() const {
  if (width <= 0 || height <= 0)
    throw std::invalid_argument("intrinsics: width and height must be positive, got " + std::to_string(width) + "x" +
                                std::to_string(height));
  if (!(std::isfinite(fx) && std::isfinite(fy) && std::isfinite(cx) && std::isfinite(cy)))
    throw std::invalid_argument("intrinsics: fx, fy, cx, cy must be finite");
  if (!(fx > 0.0 && fy > 0.0)) throw std::invalid_argument("intrinsics: focal lengths must be positive");
}

namespace {

void validate(const DepthToCloudSettings& s) {
  if (!(std::isfinite(s.depth_scale) && s.depth_scale > 0.0))
    throw std::invalid_argument("depth to cloud: depth_scale must be a positive number of metres per unit");
  if (!(s.min_depth >= 0.0 && s.max_depth > s.min_depth) || std::isnan(s.max_depth))
    throw std::invalid_argument("depth to cloud: need 0 <= min_depth < max_depth (metres)");
  if (s.stride < 1) throw std::invalid_argument("depth to cloud: stride must be >= 1");
}

template <typename DepthT>
DepthCloud backProject(const DepthT* depth, const PinholeIntrinsics& K, const DepthToCloudSettings& s,
                       const std::uint8_t* rgb) {
  K.validate();
  validate(s);
  if (depth == nullptr) throw std::invalid_argument("depth to cloud: null depth image");
  DepthCloud out;
  const std::size_t expected = (static_cast<std::size_t>(K.width) / s.stride + 1) *
                               (static_cast<std::size_t>(K.height) / s.stride + 1);
  out.points.reserve(3 * expected);
  out.pixels.reserve(expected);
  if (rgb) out.colors.reserve(3 * expected);
  const double inv_fx = 1.0 / K.fx, inv_fy = 1.0 / K.fy;
  for (int v = 0; v < K.height; v += s.stride) {
    const double ry = (v - K.cy) * inv_fy;
    for (int u = 0; u < K.width; u += s.stride) {
      const std::size_t pixel = static_cast<std::size_t>(v) * K.width + u;
      double z;
      if constexpr (std::is_integral_v<DepthT>) {
        if (depth[pixel] == 0) continue;
        z = depth[pixel] * s.depth_scale;
      } else {
        z = depth[pixel];
        if (!std::isfinite(z)) continue;
      }
      if (!(z >= s.min_depth && z <= s.max_depth) || z <= 0.0) continue;
      out.points.push_back(static_cast<float>(z * (u - K.cx) * inv_fx));
      out.points.push_back(static_cast<float>(z * ry));
      out.points.push_back(static_cast<float>(z));
      out.pixels.push_back(static_cast<std::int32_t>(pixel));
      if (rgb) out.colors.insert(out.colors.end(), rgb + 3 * pixel, rgb + 3 * pixel + 3);
    }
  }
  return out;
}

}  // namespace

DepthCloud depthToCloud(const std::uint16_t* depth, const PinholeIntrinsics& intrinsics,
                        const DepthToCloudSettings& settings, const std::uint8_t* rgb) {
  return backProject(depth, intrinsics, settings, rgb);
}

DepthCloud depthToCloud(const float* depth, const PinholeIntrinsics& intrinsics, const DepthToCloudSettings& settings,
                        const std::uint8_t* rgb) {
  return backProject(depth, intrinsics, settings, rgb);
}

}  // namespace scanalign
