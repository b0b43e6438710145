// Summaries of per-pose errors (ATE, RPE) and of cloud-to-mesh distances, with the
// definitions the TUM RGB-D benchmark tools and evo use (Sturm et al., "A Benchmark for the
// Evaluation of RGB-D SLAM Systems", IROS 2012). Header-only: two short functions.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <stdexcept>
#include <vector>

namespace scanalign {

/// Statistics of errors in one unit (metres or degrees).
struct ErrorStats {
  double rmse = 0, mean = 0, median = 0, std = 0, min = 0, max = 0, sse = 0;
  std::int64_t count = 0;
  std::vector<double> errors;
};

/// Cloud-to-mesh distance statistics (metres) over the finite distances.
struct MeshDistanceStats {
  double mean = 0, median = 0, p95 = 0, max = 0, rmse = 0;
  std::int64_t count = 0, dropped = 0;
};

/// The q-th percentile (0..100) of sorted values, interpolated linearly between the two
/// nearest ranks (numpy.percentile's default).
inline double percentileOfSorted(const std::vector<double>& sorted, double q) {
  const double rank = q / 100.0 * static_cast<double>(sorted.size() - 1);
  const auto lo = static_cast<std::size_t>(std::floor(rank));
  const std::size_t hi = std::min(lo + 1, sorted.size() - 1);
  return sorted[lo] + (sorted[hi] - sorted[lo]) * (rank - static_cast<double>(lo));
}

/// rmse = sqrt(sse / count), std with ddof = 0 (as numpy.std, evo and the TUM scripts).
/// Throws std::invalid_argument for no errors.
inline ErrorStats summarizeErrors(std::vector<double> errors) {
  if (errors.empty()) throw std::invalid_argument("errors: no errors to summarise");
  ErrorStats s;
  s.count = static_cast<std::int64_t>(errors.size());
  const double n = static_cast<double>(errors.size());
  for (double e : errors) s.sse += e * e, s.mean += e;
  s.mean /= n;
  for (double e : errors) s.std += (e - s.mean) * (e - s.mean);
  s.std = std::sqrt(s.std / n);
  s.rmse = std::sqrt(s.sse / n);
  std::vector<double> sorted = errors;
  std::sort(sorted.begin(), sorted.end());
  s.min = sorted.front();
  s.max = sorted.back();
  s.median = percentileOfSorted(sorted, 50);
  s.errors = std::move(errors);
  return s;
}

/// Non-finite distances (points with NaN/Inf coordinates) are counted as dropped.
/// Throws std::invalid_argument when no distance is finite.
inline MeshDistanceStats summarizeDistances(const double* d, std::size_t n) {
  std::vector<double> e;
  for (std::size_t i = 0; i < n; ++i)
    if (std::isfinite(d[i])) e.push_back(d[i]);
  if (e.empty()) throw std::invalid_argument("mesh_distance_stats: no finite point to measure");
  std::sort(e.begin(), e.end());
  MeshDistanceStats s;
  s.count = static_cast<std::int64_t>(e.size());
  s.dropped = static_cast<std::int64_t>(n - e.size());
  for (double v : e) s.mean += v, s.rmse += v * v;
  s.mean /= static_cast<double>(e.size());
  s.rmse = std::sqrt(s.rmse / static_cast<double>(e.size()));
  s.median = percentileOfSorted(e, 50);
  s.p95 = percentileOfSorted(e, 95);
  s.max = e.back();
  return s;
}

}  // namespace scanalign
