// Depth image -> point cloud in the camera frame (the first step of Algorithm 1 of the eye-in-hand paper
// (Comput. Electron. Agric. 180 (2021) 105929):
// every RGB-D capture becomes a coloured cloud S).
#pragma once

#include <cstdint>
#include <vector>

namespace scanalign {

/// Pinhole intrinsics of a rectified depth image, OpenCV convention: the camera frame has
/// x right, y down, z along the optical axis; the centre of pixel (u, v) = (column, row)
/// sits at image coordinates (u, v); a camera point projects to u = fx x/z + cx,
/// v = fy y/z + cy. Focal lengths and principal point in pixels.
struct PinholeIntrinsics {
  int width = 0;
  int height = 0;
  double fx = 0.0;
  double fy = 0.0;
  double cx = 0.0;
  double cy = 0.0;

  /// Throws std::invalid_argument unless the size is positive and fx, fy > 0, all finite.
  void validate() const;
};

struct DepthToCloudSettings {
  /// Metres per unit of an integer (uint16) depth image: 1e-3 for millimetres, 1/5000 for
  /// the TUM RGB-D benchmark. Float images are in metres and ignore this.
  double depth_scale = 0.001;
  /// Pixels nearer than this (m, along z) are dropped: sensors report garbage below their
  /// minimum range.
  double min_depth = 0.1;
  /// Pixels farther than this (m) are dropped.
  double max_depth = 2.0;
  /// Use every `stride`-th pixel in both directions (1 = full resolution).
  int stride = 1;
};

/// A cloud from one depth image; only valid pixels (finite, in range) are kept.
struct DepthCloud {
  std::vector<float> points;         ///< 3 per point, metres, camera frame
  std::vector<std::uint8_t> colors;  ///< 3 per point (RGB) when an image was given, else empty
  std::vector<std::int32_t> pixels;  ///< the pixel each point came from: row * width + column
  std::size_t size() const { return pixels.size(); }
};

/// Back-projects a row-major depth image of intrinsics.height x intrinsics.width pixels:
/// p = (z (u - cx) / fx, z (v - cy) / fy, z). A zero, non-finite or out-of-range depth is
/// an invalid pixel. `rgb` (may be null) holds 3 uint8 per pixel, row-major, registered to
/// the depth image. Throws std::invalid_argument on bad intrinsics or settings.
DepthCloud depthToCloud(const std::uint16_t* depth, const PinholeIntrinsics& intrinsics,
                        const DepthToCloudSettings& settings, const std::uint8_t* rgb = nullptr);
DepthCloud depthToCloud(const float* depth, const PinholeIntrinsics& intrinsics,
                        const DepthToCloudSettings& settings, const std::uint8_t* rgb = nullptr);

/// Edge-preserving smoothing of a depth image before back-projection (as KinectFusion does
/// before computing normals). Why: axial sensor noise (about 1 mm at 0.4 m for an SR300)
/// tilts 5 mm PCA normals by several degrees, and because each normal's error is
/// correlated with the noise of the very points it is fitted to, point-to-plane ICP is
/// pulled off the true pose (measured on the synthetic SR300 scan: 24 mm from the true
/// pose in one frame). Each valid pixel becomes the weighted mean of the valid pixels within
/// `radius` pixels, weights exp(-d_pixels^2 / 2 sigma_space^2) exp(-dz^2 / 2 sigma_depth^2),
/// so depth edges (jumps much larger than sigma_depth) are kept. Invalid pixels (NaN, <= 0)
/// stay invalid and are never used. `depth` and `out` are row-major width x height, metres,
/// and must not overlap. Throws std::invalid_argument on bad sizes or parameters.
/// Computed in float, vectorised across each row with a polynomial exp (about 1e-7
/// relative to libm's): within 3e-6 of the depth from a float64 evaluation, as the float
/// sums alone allow (5 ms a 640x480 frame on two cores, 28 ms with libm's expf per weight).
void bilateralFilterDepth(const float* depth, int width, int height, float* out, int radius = 2,
                          double sigma_space = 1.5, double sigma_depth = 0.003, int num_threads = 0);

}  // namespace scanalign
