#include "scanalign/reconstruction/depth_image.hpp"
#include "scanalign/reconstruction/bilateral_filter.hpp"
#include "scanalign/common/threads.hpp"

#include <omp.h>

#include <vector>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <list>
#include <mutex>
#include <stdexcept>
#include <string>
#include <type_traits>

namespace scanalign {

void checkImageSize(long long width, long long height, const char* what) {
  if (width <= 0 || height <= 0)
    throw std::invalid_argument(std::string(what) + ": width, height must be positive, got " +
                                std::to_string(width) + "x" + std::to_string(height));
  // Both below 2^31 here or the product test below fails: no overflow in the product.
  if (width > (1LL << 31) || height > (1LL << 31) ||
      static_cast<unsigned long long>(width) * static_cast<unsigned long long>(height) > kMaxImagePixels)
    throw std::invalid_argument(std::string(what) + ": width, height " + std::to_string(width) + "x" +
                                std::to_string(height) + " pixels is beyond the limit of " +
                                std::to_string(kMaxImagePixels) + " pixels (kMaxImagePixels)");
}

void PinholeIntrinsics::validate() const {
  checkImageSize(width, height, "intrinsics");
  if (!(std::isfinite(fx) && std::isfinite(fy) && std::isfinite(cx) && std::isfinite(cy)))
    throw std::invalid_argument("intrinsics: fx, fy, cx, cy must be finite");
  if (!(fx > 0.0 && fy > 0.0)) throw std::invalid_argument("intrinsics: focal lengths must be positive");
  // The steepest ray of the image, at its corners: beyond 1e6 (a field of view within 1e-4
  // degrees of 180) the intrinsics are garbage, and points would overflow.
  constexpr double kMaxSlope = 1e6;
  if (std::max(std::abs(cx), std::abs(width - 1 - cx)) > kMaxSlope * fx)
    throw std::invalid_argument("intrinsics: fx too small or cx too far off the image (ray slope |u - cx| / fx "
                                "above 1e6)");
  if (std::max(std::abs(cy), std::abs(height - 1 - cy)) > kMaxSlope * fy)
    throw std::invalid_argument("intrinsics: fy too small or cy too far off the image (ray slope |v - cy| / fy "
                                "above 1e6)");
  distortion.validate();
}

Eigen::Matrix3d PinholeIntrinsics::K() const {
  Eigen::Matrix3d k;
  k << fx, 0.0, cx, 0.0, fy, cy, 0.0, 0.0, 1.0;
  return k;
}

PinholeIntrinsics PinholeIntrinsics::scaled(double factor) const {
  if (!(factor > 0.0 && std::isfinite(factor))) throw std::invalid_argument("intrinsics: scale factor must be positive");
  PinholeIntrinsics s = *this;
  // Halves to even, as Python's round(); beyond int range the size check below refuses it.
  const double w = std::nearbyint(width * factor), h = std::nearbyint(height * factor);
  if (!(w >= 0.0 && w <= 2147483647.0 && h >= 0.0 && h <= 2147483647.0))
    throw std::invalid_argument("intrinsics: scaled size out of range");
  s.width = static_cast<int>(w);
  s.height = static_cast<int>(h);
  s.fx = fx * factor;
  s.fy = fy * factor;
  // Pixel centres sit at integer coordinates: the principal point maps as (c + 0.5) s - 0.5.
  s.cx = (cx + 0.5) * factor - 0.5;
  s.cy = (cy + 0.5) * factor - 0.5;
  s.validate();
  return s;
}

bool operator==(const LensDistortion& a, const LensDistortion& b) {
  return a.k1 == b.k1 && a.k2 == b.k2 && a.p1 == b.p1 && a.p2 == b.p2 && a.k3 == b.k3;
}

bool operator==(const PinholeIntrinsics& a, const PinholeIntrinsics& b) {
  return a.width == b.width && a.height == b.height && a.fx == b.fx && a.fy == b.fy && a.cx == b.cx &&
         a.cy == b.cy && a.distortion == b.distortion;
}

void LensDistortion::validate() const {
  if (!(std::isfinite(k1) && std::isfinite(k2) && std::isfinite(p1) && std::isfinite(p2) && std::isfinite(k3)))
    throw std::invalid_argument("intrinsics: distortion must be 5 finite numbers (k1, k2, p1, p2, k3)");
}

std::vector<double> undistortedRays(const PinholeIntrinsics& K, int max_iterations, double max_reprojection_error,
                                    int num_threads) {
  K.validate();
  const LensDistortion& d = K.distortion;
  if (max_iterations < 1) throw std::invalid_argument("undistorted rays: max_iterations must be >= 1");
  if (!(max_reprojection_error > 0.0))
    throw std::invalid_argument("undistorted rays: max_reprojection_error must be > 0 pixels");
  std::vector<double> rays(2 * static_cast<std::size_t>(K.width) * K.height);
  // OpenCV's cvUndistortPointsInternal, term for term (its rational and thin-prism terms
  // are zero here and add exact zeros there), so the rays equal undistortPointsIter's.
  const double ifx = 1.0 / K.fx, ify = 1.0 / K.fy;
  const double k1 = d.k1, k2 = d.k2, p1 = d.p1, p2 = d.p2, k3 = d.k3;
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const int threads = resolveThreads(num_threads);
#pragma omp parallel for num_threads(threads) schedule(static)
  for (int v = 0; v < K.height; ++v) {
    double* row = rays.data() + 2 * static_cast<std::size_t>(v) * K.width;
    for (int u = 0; u < K.width; ++u) {
      const double x0 = (u - K.cx) * ifx, y0 = (v - K.cy) * ify;
      double x = x0, y = y0;
      bool ok = true;
      for (int j = 0; j < max_iterations; ++j) {
        const double r2 = x * x + y * y;
        const double icdist = 1.0 / (1.0 + ((k3 * r2 + k2) * r2 + k1) * r2);
        if (!(icdist >= 0.0)) {  // OpenCV gives up here (and returns the pinhole ray)
          ok = false;
          break;
        }
        const double delta_x = 2 * p1 * x * y + p2 * (r2 + 2 * x * x);
        const double delta_y = p1 * (r2 + 2 * y * y) + 2 * p2 * x * y;
        const double nx = (x0 - delta_x) * icdist, ny = (y0 - delta_y) * icdist;
        const bool same = nx == x && ny == y;
        x = nx;
        y = ny;
        if (same) break;  // a fixed point: further steps change nothing
      }
      if (ok) {  // the ray must land back on its pixel
        const double r2 = x * x + y * y, radial = 1.0 + ((k3 * r2 + k2) * r2 + k1) * r2;
        const double xd = x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x);
        const double yd = y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y;
        const double ex = (xd - x0) * K.fx, ey = (yd - y0) * K.fy;
        ok = radial > 0.0 && std::isfinite(x) && std::isfinite(y) &&
             ex * ex + ey * ey <= max_reprojection_error * max_reprojection_error;
      }
      row[2 * u] = ok ? x : nan;
      row[2 * u + 1] = ok ? y : nan;
    }
  }
  return rays;
}

std::shared_ptr<const std::vector<double>> cachedUndistortedRays(const PinholeIntrinsics& intrinsics) {
  intrinsics.validate();
  using Entry = std::pair<PinholeIntrinsics, std::shared_ptr<const std::vector<double>>>;
  static std::mutex mutex;
  static std::list<Entry> cache;  // most recently used first
  {
    const std::lock_guard<std::mutex> lock(mutex);
    for (auto it = cache.begin(); it != cache.end(); ++it)
      if (it->first == intrinsics) {
        cache.splice(cache.begin(), cache, it);
        return cache.front().second;
      }
  }
  // Outside the lock: other threads keep back-projecting with their cameras meanwhile.
  auto table = std::make_shared<const std::vector<double>>(undistortedRays(intrinsics));
  const std::lock_guard<std::mutex> lock(mutex);
  for (const Entry& e : cache)
    if (e.first == intrinsics) return e.second;  // another thread was first: one copy kept
  cache.emplace_front(intrinsics, table);
  if (cache.size() > kRayTableCacheSize) cache.pop_back();
  return table;
}

namespace {

void validate(const DepthToCloudSettings& s) {
  if (!(s.depth_scale > 0.0 && s.depth_scale <= 1.0))
    throw std::invalid_argument("depth to cloud: depth_scale must be in (0, 1] metres per unit");
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
  // A distorted camera: each pixel's undistorted ray, from the cache (pinhole: the formula).
  const std::shared_ptr<const std::vector<double>> table = K.hasDistortion() ? cachedUndistortedRays(K) : nullptr;
  const double* rays = table ? table->data() : nullptr;
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
      float p[3];
      if (rays) {  // a distorted camera: the pixel's undistorted ray (NaN: none, an invalid pixel)
        p[0] = static_cast<float>(z * rays[2 * pixel]);
        p[1] = static_cast<float>(z * rays[2 * pixel + 1]);
      } else {
        p[0] = static_cast<float>(z * (u - K.cx) * inv_fx);
        p[1] = static_cast<float>(z * ry);
      }
      p[2] = static_cast<float>(z);
      // A depth beyond float range once multiplied by the ray (1e38 m with max_depth = inf)
      // is not a measurement: invalid, as a NaN pixel (never a non-finite point).
      if (!(std::isfinite(p[0]) && std::isfinite(p[1]) && std::isfinite(p[2]))) continue;
      out.points.insert(out.points.end(), p, p + 3);
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

namespace {

// The bilateral filter, vectorised across the pixels of a row: for each window offset
// (dy, dx), in the order of the straightforward per-pixel loop, every output pixel of the
// row adds that neighbour's term, so each pixel's sums run in the same order as before.
// Invalid pixels and a border of `radius` pixels hold 0 (valid depths are > 0) and get
// weight 0: no bounds checks in the loop, and a term of 0 changes no sum.

#if defined(__GNUC__)
/// One output row: num/den of every pixel over the (2 radius + 1)^2 window. `rows[j]` is
/// the padded input row v - radius + j, offset so that index u is pixel u; `padded_width`
/// is a whole number of vectors.
///
/// The range weight exp(x), x <= 0, is computed in the style of Cephes' expf: x = m ln 2 + r
/// with m = round(x / ln 2) and |r| <= ln(2) / 2, e^r by Cephes' polynomial, 2^m through
/// the exponent bits; relative error about 1e-7 (a float ulp or two) against libm's expf,
/// and exactly 0 below -87 (where expf is below 1.7e-38). Why: expf was the cost of the
/// filter (25 calls per pixel, 23 ms a 640x480 frame on two cores), and a libm call does
/// not vectorise. (Inline here: GCC drops the vector size of a vector type passed as a
/// template argument.)
template <std::size_t Bytes>
__attribute__((always_inline)) inline void filterRow(const float* const* rows, const float* centre, int radius,
                                                     const float* spatial, float inv2sd, int padded_width, float* num,
                                                     float* den) {
  typedef float V __attribute__((vector_size(Bytes)));
  typedef std::int32_t VI __attribute__((vector_size(Bytes)));
  constexpr int L = static_cast<int>(Bytes / sizeof(float));
  const int k = 2 * radius + 1;
  const V zero = {};
  for (int u = 0; u < padded_width; u += L) {
    V z, sum_wn = {}, sum_w = {};
    std::memcpy(&z, centre + u, sizeof(V));
    for (int j = 0; j < k; ++j)
      for (int dx = -radius; dx <= radius; ++dx) {
        V n;
        std::memcpy(&n, rows[j] + u + dx, sizeof(V));
        const V d = n - z;
        const V arg = -d * d * inv2sd;
        // exp(arg), as described above.
        const V x = arg < -87.0f ? zero - 87.0f : arg;
        // m = round(x / ln 2): adding 1.5 * 2^23 rounds to an integer, held in the low bits.
        const V shifted = x * 1.44269504088896341f + 12582912.0f;
        const V m = shifted - 12582912.0f;
        const V r = x - m * 0.693359375f - m * -2.12194440e-4f;  // x - m ln 2, in two parts
        V y = zero + 1.9875691500e-4f;
        y = y * r + 1.3981999507e-3f;
        y = y * r + 8.3334519073e-3f;
        y = y * r + 4.1665795894e-2f;
        y = y * r + 1.6666665459e-1f;
        y = y * r + 5.0000001201e-1f;
        y = y * (r * r) + r + 1.0f;
        const VI bits = ((VI)shifted - (VI)(zero + 12582912.0f) + 127) << 23;  // 2^m (vector casts keep bits)
        const V e = arg < -87.0f ? zero : y * (V)bits;
        const V w = n > 0.0f ? spatial[j * k + dx + radius] * e : zero;
        sum_wn += w * n;
        sum_w += w;
      }
    std::memcpy(num + u, &sum_wn, sizeof(V));
    std::memcpy(den + u, &sum_w, sizeof(V));
  }
}

#if defined(__x86_64__) || defined(__i386__)
__attribute__((target("avx2"))) void filterRowAvx2(const float* const* rows, const float* centre, int radius,
                                                   const float* spatial, float inv2sd, int padded_width, float* num,
                                                   float* den) {
  filterRow<32>(rows, centre, radius, spatial, inv2sd, padded_width, num, den);
}
#endif

void filterRowDispatch(const float* const* rows, const float* centre, int radius, const float* spatial, float inv2sd,
                       int padded_width, float* num, float* den) {
#if defined(__x86_64__) || defined(__i386__)
  static const bool avx2 = __builtin_cpu_supports("avx2");
  if (avx2) return filterRowAvx2(rows, centre, radius, spatial, inv2sd, padded_width, num, den);
#endif
  filterRow<16>(rows, centre, radius, spatial, inv2sd, padded_width, num, den);
}
constexpr int kRowLanes = 8;  // padded widths are whole AVX vectors
#else
void filterRowDispatch(const float* const* rows, const float* centre, int radius, const float* spatial, float inv2sd,
                       int padded_width, float* num, float* den) {
  const int k = 2 * radius + 1;
  for (int u = 0; u < padded_width; ++u) {
    float sum_wn = 0.0f, sum_w = 0.0f;
    for (int j = 0; j < k; ++j)
      for (int dx = -radius; dx <= radius; ++dx) {
        const float n = rows[j][u + dx], d = n - centre[u];
        const float w = n > 0.0f ? spatial[j * k + dx + radius] * std::exp(-d * d * inv2sd) : 0.0f;
        sum_wn += w * n;
        sum_w += w;
      }
    num[u] = sum_wn;
    den[u] = sum_w;
  }
}
constexpr int kRowLanes = 1;
#endif

}  // namespace

void BilateralFilterSettings::validate() const {
  if (radius < 0 || radius > 32) throw std::invalid_argument("bilateral filter: radius must be in [0, 32] pixels");
  if (!(sigma_space >= 1e-3 && std::isfinite(sigma_space)))
    throw std::invalid_argument("bilateral filter: sigma_space must be finite and >= 1e-3 pixels");
  if (!(sigma_depth >= 1e-9 && std::isfinite(sigma_depth)))
    throw std::invalid_argument("bilateral filter: sigma_depth must be finite and >= 1e-9 m");
}

void bilateralFilterDepth(const float* depth, int width, int height, float* out,
                          const BilateralFilterSettings& settings, int num_threads) {
  bilateralFilterDepth(depth, width, height, out, settings.radius, settings.sigma_space, settings.sigma_depth,
                       num_threads);
}

void bilateralFilterDepth(const float* depth, int width, int height, float* out, int radius, double sigma_space,
                          double sigma_depth, int num_threads) {
  if (width < 0 || height < 0) throw std::invalid_argument("bilateral filter: width and height must be >= 0");
  BilateralFilterSettings{radius, sigma_space, sigma_depth}.validate();
  if (width == 0 || height == 0) return;  // an empty image: nothing to filter
  checkImageSize(width, height, "bilateral filter");
  if (depth == nullptr || out == nullptr) throw std::invalid_argument("bilateral filter: null image");
  const int k = 2 * radius + 1;
  std::vector<float> spatial(static_cast<std::size_t>(k) * k);
  for (int dy = -radius; dy <= radius; ++dy)
    for (int dx = -radius; dx <= radius; ++dx)
      spatial[static_cast<std::size_t>(dy + radius) * k + dx + radius] =
          static_cast<float>(std::exp(-(dx * dx + dy * dy) / (2.0 * sigma_space * sigma_space)));
  const float inv2sd = static_cast<float>(1.0 / (2.0 * sigma_depth * sigma_depth));
  // Padded copy: `radius` pixels of 0 on every side, invalid pixels as 0, rows a whole
  // number of vectors long (plus the right border).
  const int padded_width = (width + kRowLanes - 1) / kRowLanes * kRowLanes;
  const std::size_t stride = static_cast<std::size_t>(padded_width) + 2 * radius;
  std::vector<float> padded(stride * (static_cast<std::size_t>(height) + 2 * radius), 0.0f);
  const int threads = resolveThreads(num_threads);
#pragma omp parallel num_threads(threads)
  {
#pragma omp for schedule(static)
    for (int v = 0; v < height; ++v) {
      const float* in = depth + static_cast<std::size_t>(v) * width;
      float* row = &padded[(static_cast<std::size_t>(v) + radius) * stride + radius];
      for (int u = 0; u < width; ++u) row[u] = in[u] > 0.0f && std::isfinite(in[u]) ? in[u] : 0.0f;
    }
    std::vector<float> num(padded_width), den(padded_width);
    std::vector<const float*> rows(k);
#pragma omp for schedule(static)
    for (int v = 0; v < height; ++v) {
      for (int j = 0; j < k; ++j) rows[j] = &padded[(static_cast<std::size_t>(v) + j) * stride + radius];
      filterRowDispatch(rows.data(), rows[radius], radius, spatial.data(), inv2sd, padded_width, num.data(),
                        den.data());
      const float* in = depth + static_cast<std::size_t>(v) * width;
      float* o = out + static_cast<std::size_t>(v) * width;
      for (int u = 0; u < width; ++u) {
        const float mean = num[u] / den[u];  // den >= 1 (the pixel itself)
        // Depths near float's maximum (3e38 m) can overflow the weighted sum: such a pixel
        // is invalid (NaN), never an infinite depth.
        o[u] = in[u] > 0.0f && std::isfinite(in[u]) && std::isfinite(mean) ? mean
                                                                           : std::numeric_limits<float>::quiet_NaN();
      }
    }
  }
}

}  // namespace scanalign
