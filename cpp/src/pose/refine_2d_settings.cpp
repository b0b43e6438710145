// Validation of the 2D refinement's settings (pose/refine_2d_settings.hpp).
#include "scanalign/pose/refine_2d_settings.hpp"

#include <cmath>
#include <stdexcept>

namespace scanalign {

namespace {
void check(bool ok, const std::string& what) {
  if (!ok) throw std::invalid_argument(what);
}
}  // namespace

void ImageMatchSettings::validate() const {
  check(detector == "sift" || detector == "akaze" || detector == "orb",
        "ImageMatchSettings.detector must be 'sift', 'akaze' or 'orb', got '" + detector + "'");
  check(max_features >= 100 && max_features <= 100000, "ImageMatchSettings.max_features must be in 100..100000");
  check(ratio > 0.0 && ratio <= 1.0, "ImageMatchSettings.ratio must be in (0, 1]");
  check(ransac_threshold > 0.0 && std::isfinite(ransac_threshold),
        "ImageMatchSettings.ransac_threshold must be a finite positive distance (px)");
  check(ransac_iterations >= 10 && ransac_iterations <= 1000000,
        "ImageMatchSettings.ransac_iterations must be in 10..1000000");
  check(min_matches >= 4, "ImageMatchSettings.min_matches must be >= 4 (a homography needs 4 pairs)");
  check(min_inliers >= 4, "ImageMatchSettings.min_inliers must be >= 4 (a homography needs 4 pairs)");
}

void Refine2dSettings::validate() const {
  matching.validate();
  homography.validate();
  check(max_steps >= 1 && max_steps <= 100, "Refine2dSettings.max_steps must be in 1..100");
  check(converged_translation > 0.0 && std::isfinite(converged_translation),
        "Refine2dSettings.converged_translation must be a finite positive distance (m)");
  check(converged_angle > 0.0 && std::isfinite(converged_angle),
        "Refine2dSettings.converged_angle must be a finite positive angle (rad)");
}

}  // namespace scanalign
