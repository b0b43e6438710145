// Depth image -> point cloud in the camera frame (the first step of Algorithm 1 of the eye-in-hand paper
// (Comput. Electron. Agric. 180 (2021) 105929):
// every RGB-D capture becomes a coloured cloud S).
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <vector>

#include <Eigen/Core>

namespace scanalign {

/// The largest depth image (width x height pixels) the depth-image functions and the
/// renderer accept: 2^27 = 134 M pixels (e.g. 16384 x 8192; the largest RGB-D sensors give
/// about 5 M). The check comes before any allocation, so a size that is only claimed (a
/// broadcast NumPy view of no memory, a lying header) is refused with std::invalid_argument
/// rather than allocating gigabytes: the bilateral filter needs about 12 bytes a pixel.
constexpr std::size_t kMaxImagePixels = std::size_t{1} << 27;

/// Throws std::invalid_argument naming `what` (and "width, height") unless 1 <= width, height and
/// width * height <= kMaxImagePixels.
void checkImageSize(long long width, long long height, const char* what);

/// Brown–Conrady lens distortion (OpenCV's and ROS's "plumb_bob" model, coefficients in
/// OpenCV's order k1 k2 p1 p2 k3) of normalised image coordinates (x, y) = (X/Z, Y/Z):
/// with r^2 = x^2 + y^2, the distorted point is
///   x_d = x (1 + k1 r^2 + k2 r^4 + k3 r^6) + 2 p1 x y + p2 (r^2 + 2 x^2),
///   y_d = y (1 + k1 r^2 + k2 r^4 + k3 r^6) + p1 (r^2 + 2 y^2) + 2 p2 x y,
/// and the pixel is u = fx x_d + cx, v = fy y_d + cy. All zero: a pinhole camera.
struct LensDistortion {
  double k1 = 0.0;
  double k2 = 0.0;
  double p1 = 0.0;
  double p2 = 0.0;
  double k3 = 0.0;

  bool isZero() const { return k1 == 0.0 && k2 == 0.0 && p1 == 0.0 && p2 == 0.0 && k3 == 0.0; }
  /// Throws std::invalid_argument unless all five coefficients are finite.
  void validate() const;
};

/// Intrinsics of a depth image, OpenCV convention: the camera frame has x right, y down, z
/// along the optical axis; the centre of pixel (u, v) = (column, row) sits at image
/// coordinates (u, v); a camera point projects to u = fx x_d + cx, v = fy y_d + cy with
/// (x_d, y_d) the lens distortion of (x/z, y/z) (a pinhole camera, the default: x_d = x/z,
/// y_d = y/z). Focal lengths and principal point in pixels. The one intrinsics type of the
/// library: depth images back-project with it, the renderer draws with it (pinhole only),
/// camera files are read into it.
struct PinholeIntrinsics {
  int width = 0;
  int height = 0;
  double fx = 0.0;
  double fy = 0.0;
  double cx = 0.0;
  double cy = 0.0;
  /// Brown-Conrady distortion of the lens; zero (the default): a pinhole camera, or
  /// rectified images.
  LensDistortion distortion = {};

  /// Throws std::invalid_argument (naming the field) unless the size is positive and at
  /// most kMaxImagePixels, fx, fy > 0 and all are finite, every pixel's ray has finite
  /// slopes |u - cx| / fx, |v - cy| / fy <= 1e6 (a focal length of 1e-300 pixels or a
  /// principal point at 1e300 would turn every depth into an infinite point), and the
  /// distortion coefficients are finite.
  void validate() const;
  bool hasDistortion() const { return !distortion.isZero(); }
  /// The 3x3 camera matrix [[fx, 0, cx], [0, fy, cy], [0, 0, 1]].
  Eigen::Matrix3d K() const;
  /// The intrinsics of the image resized by `factor` (> 0, finite; 0.5: half resolution):
  /// size rounded to the nearest integer (halves to even), focal lengths times factor, the
  /// principal point mapped as (c + 0.5) factor - 0.5 (pixel centres sit at integer
  /// coordinates); the distortion, which acts on normalised coordinates, unchanged.
  /// Throws std::invalid_argument for a bad factor or a result validate() refuses.
  PinholeIntrinsics scaled(double factor) const;
};

bool operator==(const LensDistortion& a, const LensDistortion& b);
bool operator==(const PinholeIntrinsics& a, const PinholeIntrinsics& b);
inline bool operator!=(const PinholeIntrinsics& a, const PinholeIntrinsics& b) { return !(a == b); }

/// The undistorted normalised coordinates (x, y) = (X/Z, Y/Z) of the ray through every
/// pixel centre (u, v) of a camera with intrinsics.distortion: 2 doubles a pixel, row-major
/// (index 2 (v width + u)), the table depthToCloud back-projects a distorted camera's pixels
/// with (cachedUndistortedRays). Each pixel is undistorted as OpenCV's undistortPoints
/// does it (the same fixed-point iteration x <- (x0 - delta(x)) / radial(x), from the
/// pinhole coordinates x0 = (u - cx) / fx), for up to `max_iterations` steps or until a
/// step changes nothing (so the result equals OpenCV's undistortPointsIter with that many
/// COUNT iterations). A pixel whose ray does not re-project onto the pixel within
/// `max_reprojection_error` pixels (the iteration diverged or the model folds over there:
/// radial factor <= 0, beyond the calibrated field of view) gets NaN and back-projects to
/// no point. Zero distortion gives the pinhole rays ((u - cx) / fx, (v - cy) / fy).
/// Throws std::invalid_argument on bad intrinsics or coefficients, max_iterations < 1 or
/// a max_reprojection_error that is not positive.
std::vector<double> undistortedRays(const PinholeIntrinsics& intrinsics, int max_iterations = 100,
                                    double max_reprojection_error = 1e-3, int num_threads = 0);

/// undistortedRays(intrinsics) with its defaults, computed once per intrinsics (size, K and
/// coefficients) and kept for the next frames: the last kRayTableCacheSize tables are cached
/// (least recently used dropped first), shared read-only, safe to call from any thread (a
/// table is computed outside the lock; two threads asking for a new camera at once may both
/// compute it, and one copy is kept). So a distorted camera's frame costs what a pinhole
/// frame costs.
std::shared_ptr<const std::vector<double>> cachedUndistortedRays(const PinholeIntrinsics& intrinsics);
constexpr std::size_t kRayTableCacheSize = 8;

struct DepthToCloudSettings {
  /// Metres per unit of an integer (uint16) depth image, in (0, 1]: 1e-3 for millimetres,
  /// 1/5000 for the TUM RGB-D benchmark (1: whole metres, the coarsest a sensor could
  /// mean). Float images are in metres and ignore this.
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
/// p = (z (u - cx) / fx, z (v - cy) / fy, z) for a pinhole camera. A zero, non-finite or out-of-range depth is
/// an invalid pixel, and so is a pixel whose point is not finite in float32 (a float depth
/// of 1e38 with max_depth = inf): every returned point is finite. `rgb` (may be null) holds
/// 3 uint8 per pixel, row-major, registered to the depth image. Throws
/// std::invalid_argument on bad intrinsics (see PinholeIntrinsics::validate) or settings
/// (depth_scale outside (0, 1] m, min_depth < 0, max_depth <= min_depth, stride < 1).
/// With lens distortion (intrinsics.distortion not zero), p = (z x, z y, z) with the
/// pixel's undistorted ray (x, y) from cachedUndistortedRays (a NaN ray: an invalid pixel);
/// zero distortion takes the pinhole formula above, bit for bit.
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
/// stay invalid and are never used; a pixel whose weighted mean overflows float (depths
/// near 3e38 m) becomes invalid, so no output is infinite. `depth` and `out` are row-major width x height, metres,
/// and must not overlap. An empty image (width or height 0) is returned as it is (nothing
/// to do). Throws std::invalid_argument on a negative size or one beyond kMaxImagePixels,
/// null images, a radius outside [0, 32] pixels (the window's 1089 taps per pixel bound the
/// time), or sigmas not finite or below sigma_space 1e-3 pixels, sigma_depth 1e-9 m
/// (smaller ones smooth nothing, and their squares underflow so the weights become 0/0).
/// Computed in float, vectorised across each row with a polynomial exp (about 1e-7
/// relative to libm's): within 3e-6 of the depth from a float64 evaluation, as the float
/// sums alone allow (5 ms a 640x480 frame on two cores, 28 ms with libm's expf per weight).
void bilateralFilterDepth(const float* depth, int width, int height, float* out, int radius = 2,
                          double sigma_space = 1.5, double sigma_depth = 0.003, int num_threads = 0);

}  // namespace scanalign
