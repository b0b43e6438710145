#include "scanalign/synthetic/sensor_noise.hpp"

#include <algorithm>
#include <cmath>
#include <random>
#include <stdexcept>
#include <vector>

namespace scanalign {

namespace {

void require(bool ok, const char* field, const char* what) {
  if (!ok) throw std::invalid_argument(std::string("SensorNoise.") + field + " must be " + what);
}

/// Pixels within `width` pixels of a depth discontinuity: a 4-neighbour pair whose depths
/// differ by more than `threshold` times the nearer one, or where exactly one of the two sees
/// a surface (a silhouette against the void). Both sides are marked; only valid pixels.
std::vector<char> depthEdges(const float* z, int w, int h, double threshold, int width) {
  const std::size_t n = static_cast<std::size_t>(w) * static_cast<std::size_t>(h);
  std::vector<char> edge(n, 0);
  auto pair = [&](std::size_t a, std::size_t b) {
    const bool va = std::isfinite(z[a]), vb = std::isfinite(z[b]);
    if (va != vb || (va && vb && std::abs(double(z[a]) - z[b]) > threshold * std::min<double>(z[a], z[b])))
      edge[a] = edge[b] = 1;
  };
  for (int r = 0; r < h; ++r)
    for (int c = 0; c < w; ++c) {
      const std::size_t i = static_cast<std::size_t>(r) * w + c;
      if (c + 1 < w) pair(i, i + 1);
      if (r + 1 < h) pair(i, i + w);
    }
  // Dilate by one pixel per step (4-neighbourhood). After w + h steps every pixel connected
  // to an edge pixel is marked, so more steps change nothing: a huge edge_width (1e9) costs
  // no more than that instead of hanging.
  const int steps = static_cast<int>(std::min<long long>(width, static_cast<long long>(w) + h + 1));
  for (int step = 1; step < steps; ++step) {
    std::vector<char> grown = edge;
    for (int r = 0; r < h; ++r)
      for (int c = 0; c < w; ++c) {
        const std::size_t i = static_cast<std::size_t>(r) * w + c;
        if (!edge[i]) continue;
        if (c > 0) grown[i - 1] = 1;
        if (c + 1 < w) grown[i + 1] = 1;
        if (r > 0) grown[i - w] = 1;
        if (r + 1 < h) grown[i + w] = 1;
      }
    edge.swap(grown);
  }
  return edge;
}

/// A depth between the nearest and farthest finite depth of pixel i's 3x3 neighbourhood, at
/// fraction `where` in [0, 1): the mixed return of a time-of-flight pixel straddling an edge.
/// NaN when the neighbourhood holds a single depth (a silhouette against the void: no second
/// surface to mix with).
double mixedDepth(const float* z, int w, int h, std::size_t i, double where) {
  const int r0 = static_cast<int>(i / static_cast<std::size_t>(w)), c0 = static_cast<int>(i % static_cast<std::size_t>(w));
  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  for (int r = std::max(0, r0 - 1); r <= std::min(h - 1, r0 + 1); ++r)
    for (int c = std::max(0, c0 - 1); c <= std::min(w - 1, c0 + 1); ++c) {
      const float v = z[static_cast<std::size_t>(r) * w + c];
      if (!std::isfinite(v)) continue;
      lo = std::min(lo, double(v));
      hi = std::max(hi, double(v));
    }
  if (!(hi > lo)) return std::numeric_limits<double>::quiet_NaN();
  return lo + where * (hi - lo);
}

}  // namespace

void SensorNoise::validate() const {
  for (auto [v, field] : {std::pair{axial_sigma_ref, "axial_sigma_ref"}, {depth_unit, "depth_unit"},
                          {min_range, "min_range"}, {grazing_cos, "grazing_cos"}, {edge_threshold, "edge_threshold"},
                          {dropout, "dropout"}})
    require(std::isfinite(v) && v >= 0, field, "finite and >= 0");
  require(std::isfinite(z_ref) && z_ref > 0, "z_ref", "a positive depth (m)");
  require(max_range > min_range, "max_range", "greater than min_range");
  require(grazing_cos < 1, "grazing_cos", "< 1");
  require(dropout < 1, "dropout", "< 1");
  require(edge_width >= 0, "edge_width", "a non-negative integer");
  require(std::isfinite(axial_exponent) && axial_exponent >= 0 && axial_exponent <= 4, "axial_exponent",
          "in [0, 4]");
  require(std::isfinite(flying_pixels) && flying_pixels >= 0 && flying_pixels <= 1, "flying_pixels", "in [0, 1]");
}

double SensorNoise::sigma(double z) const {
  const double r = z / z_ref;
  // The square exactly as before the exponent existed, so triangulation presets keep their images.
  return axial_exponent == 2.0 ? axial_sigma_ref * r * r : axial_sigma_ref * std::pow(r, axial_exponent);
}

void applySensorNoise(const SensorNoise& noise, const float* depth, const float* cos_incidence, int width, int height,
                      std::uint64_t seed, float* out) {
  noise.validate();
  if (width < 0 || height < 0) throw std::invalid_argument("apply sensor noise: width and height must be >= 0");
  if (width == 0 || height == 0) return;
  if (depth == nullptr || cos_incidence == nullptr || out == nullptr)
    throw std::invalid_argument("apply sensor noise: null image");
  const std::size_t n = static_cast<std::size_t>(width) * static_cast<std::size_t>(height);
  std::vector<char> edge;
  if (noise.edge_threshold > 0 && noise.edge_width > 0)
    edge = depthEdges(depth, width, height, noise.edge_threshold, noise.edge_width);
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  std::normal_distribution<double> normal(0.0, 1.0);
  for (std::size_t i = 0; i < n; ++i) {
    out[i] = std::numeric_limits<float>::quiet_NaN();
    bool valid = std::isfinite(depth[i]);
    if (noise.grazing_cos > 0) valid = valid && std::abs(cos_incidence[i]) >= noise.grazing_cos;
    // Time of flight: an edge pixel may return a mixed depth instead of nothing. Its draws come
    // only with flying_pixels > 0, so the other models' random streams are unchanged.
    double mixed = std::numeric_limits<double>::quiet_NaN();
    if (!edge.empty() && edge[i] && noise.flying_pixels > 0) {
      const double pick = uniform(rng), where = uniform(rng);
      if (valid && pick < noise.flying_pixels) mixed = mixedDepth(depth, width, height, i, where);
    }
    if (!edge.empty()) valid = valid && (!edge[i] || std::isfinite(mixed));
    // The dropout draw comes first and for every pixel, so one pixel's fate does not shift
    // the random stream of the others.
    if (noise.dropout > 0 && uniform(rng) < noise.dropout) valid = false;
    if (!valid) continue;
    double z = std::isfinite(mixed) ? mixed : double(depth[i]);
    if (noise.axial_sigma_ref > 0) z += noise.sigma(z) * normal(rng);
    if (z < noise.min_range || z > noise.max_range) continue;
    if (noise.depth_unit > 0) z = std::round(z / noise.depth_unit) * noise.depth_unit;
    // An absurd model (axial_sigma_ref 1e300, a depth unit coarser than the depth) cannot
    // give an infinite or non-positive depth: such a reading is missing (NaN).
    if (!(z > 0 && std::isfinite(static_cast<float>(z)))) continue;
    out[i] = static_cast<float>(z);
  }
}

}  // namespace scanalign
