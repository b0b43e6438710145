// Depth sensor error model of the synthetic scans: axial noise growing with the square of the
// depth (triangulation sensors), dropouts at grazing incidence, around depth edges and at
// random, a measurable range and quantisation.
#pragma once

#include <cstdint>
#include <limits>
#include <string>

namespace scanalign {

/// A depth sensor's error model, applied to noise-free depth (applySensorNoise).
struct SensorNoise {
  std::string name = "custom";  ///< label
  double axial_sigma_ref = 0.0;  ///< standard deviation of the depth error at z_ref (m, >= 0)
  double z_ref = 1.0;            ///< reference depth of axial_sigma_ref (m, > 0)
  double depth_unit = 0.0;       ///< quantisation step of the reported depth (m); 0 for none
  double min_range = 0.0;        ///< nearest measurable depth (m)
  double max_range = std::numeric_limits<double>::infinity();  ///< farthest measurable depth (m, > min_range)
  double grazing_cos = 0.0;      ///< minimum |cosine of incidence| for a measurement, in [0, 1)
  double edge_threshold = 0.0;   ///< relative depth jump marking a discontinuity; 0 disables edge dropout
  int edge_width = 0;            ///< pixels dropped on each side of a discontinuity (>= 0)
  double dropout = 0.0;          ///< probability that any other pixel is missing, in [0, 1)

  /// Throws std::invalid_argument naming the first bad field ("SensorNoise.<field> ...").
  void validate() const;
  /// Axial standard deviation (m) at depth z (m): axial_sigma_ref (z / z_ref)^2.
  double sigma(double z) const { return axial_sigma_ref * (z / z_ref) * (z / z_ref); }
};

/// Noisy depth (m, NaN = missing) of a row-major width x height image from noise-free
/// `depth` (m, NaN = nothing hit) and the rendered `cos_incidence`. In order: pixels are
/// dropped at grazing incidence (|cos| < grazing_cos), on both sides of depth discontinuities
/// (a 4-neighbour more than edge_threshold times the nearer depth away, or missing) dilated
/// to edge_width pixels, and at random with probability dropout; the rest get Gaussian noise
/// of standard deviation sigma(z); values outside [min_range, max_range] are dropped; the
/// rest are rounded to multiples of depth_unit; a result that is not a positive float32
/// depth (an absurd model) is missing. All randomness comes from `seed`. An empty image is
/// left as it is; throws std::invalid_argument for an invalid model or negative sizes.
void applySensorNoise(const SensorNoise& noise, const float* depth, const float* cos_incidence, int width, int height,
                      std::uint64_t seed, float* out);

}  // namespace scanalign
