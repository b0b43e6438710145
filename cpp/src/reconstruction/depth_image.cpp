#include "scanalign/reconstruction/depth_image.hpp"

#include <omp.h>

#include <vector>

#include <algorithm>
#include <cmath>
#include <limits>
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

void bilateralFilterDepth(const float* depth, int width, int height, float* out, int radius, double sigma_space,
                          double sigma_depth, int num_threads) {
  if (width <= 0 || height <= 0) throw std::invalid_argument("bilateral filter: width and height must be positive");
  if (depth == nullptr || out == nullptr) throw std::invalid_argument("bilateral filter: null image");
  if (radius < 0 || radius > 32) throw std::invalid_argument("bilateral filter: radius must be in [0, 32] pixels");
  if (!(sigma_space > 0.0 && std::isfinite(sigma_space)) || !(sigma_depth > 0.0 && std::isfinite(sigma_depth)))
    throw std::invalid_argument("bilateral filter: sigma_space (pixels) and sigma_depth (m) must be positive");
  const int k = 2 * radius + 1;
  std::vector<float> spatial(static_cast<std::size_t>(k) * k);
  for (int dy = -radius; dy <= radius; ++dy)
    for (int dx = -radius; dx <= radius; ++dx)
      spatial[static_cast<std::size_t>(dy + radius) * k + dx + radius] =
          static_cast<float>(std::exp(-(dx * dx + dy * dy) / (2.0 * sigma_space * sigma_space)));
  const float inv2sd = static_cast<float>(1.0 / (2.0 * sigma_depth * sigma_depth));
  const int threads = num_threads > 0 ? num_threads : omp_get_max_threads();
#pragma omp parallel for schedule(static) num_threads(threads)
  for (int v = 0; v < height; ++v) {
    for (int u = 0; u < width; ++u) {
      const float z = depth[static_cast<std::size_t>(v) * width + u];
      float& o = out[static_cast<std::size_t>(v) * width + u];
      if (!(z > 0.0f) || !std::isfinite(z)) {
        o = std::numeric_limits<float>::quiet_NaN();
        continue;
      }
      float num = 0.0f, den = 0.0f;
      for (int dy = std::max(-radius, -v); dy <= std::min(radius, height - 1 - v); ++dy) {
        const float* row = depth + static_cast<std::size_t>(v + dy) * width;
        const float* w_row = &spatial[static_cast<std::size_t>(dy + radius) * k + radius];
        for (int dx = std::max(-radius, -u); dx <= std::min(radius, width - 1 - u); ++dx) {
          const float n = row[u + dx];
          if (!(n > 0.0f) || !std::isfinite(n)) continue;
          const float d = n - z;
          const float w = w_row[dx] * std::exp(-d * d * inv2sd);
          num += w * n;
          den += w;
        }
      }
      o = num / den;  // den >= 1 (the pixel itself)
    }
  }
}

}  // namespace scanalign
