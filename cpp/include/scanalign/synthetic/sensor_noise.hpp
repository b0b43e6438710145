// Depth sensor error model of the synthetic scans: axial noise growing with a power of the
// depth (the square for triangulation sensors, less for time of flight), dropouts at grazing
// incidence, around depth edges and at random, time-of-flight mixed ("flying") pixels at depth
// edges, a measurable range and quantisation.
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
  /// Exponent p of the axial noise law sigma(z) = axial_sigma_ref (z / z_ref)^p, in [0, 4]: 2 for
  /// triangulation (structured light, stereo), about 1-1.5 for time of flight.
  double axial_exponent = 2.0;
  /// Time of flight: probability, in [0, 1], that a pixel on a depth edge (edge_threshold,
  /// edge_width) returns a mixed ("flying") depth between the two surfaces it straddles, drawn
  /// uniformly between the nearest and farthest depth of its 3x3 neighbourhood, instead of being
  /// dropped. 0: every edge pixel is dropped.
  double flying_pixels = 0.0;

  /// Throws std::invalid_argument naming the first bad field ("SensorNoise.<field> ...").
  void validate() const;
  /// Axial standard deviation (m) at depth z (m): axial_sigma_ref (z / z_ref)^axial_exponent.
  double sigma(double z) const;
};

/// Noisy depth (m, NaN = missing) of a row-major width x height image from noise-free
/// `depth` (m, NaN = nothing hit) and the rendered `cos_incidence`. In order: pixels are
/// dropped at grazing incidence (|cos| < grazing_cos), on both sides of depth discontinuities
/// (a 4-neighbour more than edge_threshold times the nearer depth away, or missing) dilated
/// to edge_width pixels (or, with probability flying_pixels, given a mixed depth between the
/// nearest and farthest of their 3x3 neighbourhood), and at random with probability dropout;
/// the rest get Gaussian noise
/// of standard deviation sigma(z); values outside [min_range, max_range] are dropped; the
/// rest are rounded to multiples of depth_unit; a result that is not a positive float32
/// depth (an absurd model) is missing. All randomness comes from `seed`. An empty image is
/// left as it is; throws std::invalid_argument for an invalid model or negative sizes.
void applySensorNoise(const SensorNoise& noise, const float* depth, const float* cos_incidence, int width, int height,
                      std::uint64_t seed, float* out);

}  // namespace scanalign
