#include "scanalign/synthetic/scan_paths.hpp"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <stdexcept>
#include <string>

#include "scanalign/common/look_at.hpp"

namespace scanalign {

namespace {

constexpr double kPi = 3.14159265358979323846;

void require(bool ok, const std::string& message) {
  if (!ok) throw std::invalid_argument(message);
}

/// Bounds of a planned path, checked before anything is allocated: n_frames in [1,
/// kMaxPathFrames] (a pose is 128 bytes), lengths within kMaxPathLength metres.
void requireFrames(int n_frames, int at_least) {
  require(n_frames >= at_least && n_frames <= kMaxPathFrames,
          "n_frames must be an integer in [" + std::to_string(at_least) + ", " + std::to_string(kMaxPathFrames) +
              "], got " + std::to_string(n_frames));
}
bool length(double v) { return std::isfinite(v) && std::abs(v) <= kMaxPathLength; }
bool point(const Eigen::Vector3d& p) { return length(p.x()) && length(p.y()) && length(p.z()); }

}  // namespace

Poses loopCameraPoses(int n_frames, const Eigen::Vector3d& center, double height, double radius, double start_angle,
                      double sweep, const Eigen::Vector3d& target) {
  requireFrames(n_frames, 1);
  require(point(center), "center: expected (x, y, z) in metres, finite, within 1e6");
  require(point(target), "target: expected (x, y, z) in metres, finite, within 1e6");
  require(length(height) && height > 0, "height must be a positive distance in metres, at most 1e6");
  require(length(radius) && radius >= 0, "radius must be a non-negative distance in metres, at most 1e6");
  require(std::isfinite(start_angle) && std::isfinite(sweep), "start_angle and sweep must be finite (radians)");
  Poses poses;
  poses.reserve(static_cast<std::size_t>(n_frames));
  for (int k = 0; k < n_frames; ++k) {
    const double a = start_angle + sweep * k / n_frames;
    const Eigen::Vector3d radial(std::cos(a), std::sin(a), 0.0);
    // Straight down (radius 0): keep the image up pointing outwards along the azimuth.
    const Eigen::Vector3d up = radius > 1e-9 * height ? Eigen::Vector3d::UnitZ() : radial;
    poses.push_back(lookAt(center + radius * radial + Eigen::Vector3d(0, 0, height), target, up));
  }
  return poses;
}

Poses hemisphereCameraPoses(int n_frames, const Eigen::Vector3d& target, double distance,
                            const std::vector<double>& elevations, double start_angle) {
  const auto rings = static_cast<int>(elevations.size());
  require(rings > 0 && std::all_of(elevations.begin(), elevations.end(),
                                   [](double e) { return e > 0 && e <= kPi / 2 + 1e-12; }),
          "elevations must be non-empty and in (0, pi/2] radians");
  require(rings <= kMaxPathFrames, "elevations: at most " + std::to_string(kMaxPathFrames) + " rings");
  requireFrames(n_frames, rings);  // at least one frame per ring
  require(length(distance) && distance > 0, "distance must be a positive length in metres, at most 1e6");
  require(point(target), "target: expected (x, y, z) in metres, finite, within 1e6");
  require(std::isfinite(start_angle), "start_angle must be finite (radians)");
  // Largest-remainder apportionment of the frames to the rings.
  std::vector<double> share(elevations.size());
  for (std::size_t r = 0; r < share.size(); ++r) share[r] = std::max(std::cos(elevations[r]), 1e-3);
  const double total = std::accumulate(share.begin(), share.end(), 0.0);
  std::vector<int> counts(share.size());
  int assigned = 0;
  for (std::size_t r = 0; r < share.size(); ++r) {
    share[r] *= (n_frames - rings) / total;
    counts[r] = 1 + static_cast<int>(std::floor(share[r]));
    assigned += counts[r];
  }
  std::vector<std::size_t> by_remainder(share.size());
  std::iota(by_remainder.begin(), by_remainder.end(), std::size_t{0});
  std::stable_sort(by_remainder.begin(), by_remainder.end(), [&](std::size_t a, std::size_t b) {
    return share[a] - std::floor(share[a]) > share[b] - std::floor(share[b]);
  });
  for (int i = 0; i < n_frames - assigned; ++i) ++counts[by_remainder[static_cast<std::size_t>(i)]];
  Poses poses;
  double azimuth = start_angle;
  for (std::size_t r = 0; r < counts.size(); ++r) {
    const double e = elevations[r], step = (r % 2 == 0 ? 1.0 : -1.0) * 2 * kPi / counts[r];
    for (int k = 0; k < counts[r]; ++k) {
      const Eigen::Vector3d radial(std::cos(azimuth + step * k), std::sin(azimuth + step * k), 0.0);
      const Eigen::Vector3d eye = target + distance * (std::cos(e) * radial + Eigen::Vector3d(0, 0, std::sin(e)));
      poses.push_back(lookAt(eye, target, std::cos(e) > 1e-6 ? Eigen::Vector3d::UnitZ() : radial));
    }
    azimuth += step * (counts[r] - 1);
  }
  return poses;
}

}  // namespace scanalign
