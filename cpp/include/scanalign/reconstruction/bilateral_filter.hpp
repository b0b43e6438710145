// Settings of the bilateral depth filter (bilateralFilterDepth, depth_image.hpp): edge-
// preserving smoothing of depth images before back-projection, as KinectFusion does before
// computing normals (Newcombe et al., "KinectFusion: Real-time dense surface mapping and
// tracking", ISMAR 2011, §3.2; Tomasi and Manduchi, "Bilateral filtering for gray and color
// images", ICCV 1998).
#pragma once

namespace scanalign {

struct BilateralFilterSettings {
  /// Window radius (pixels, in [0, 32]): each pixel becomes the weighted mean of the valid
  /// pixels within it (the window's (2 radius + 1)^2 taps per pixel bound the time).
  int radius = 2;
  /// Spatial standard deviation (pixels, >= 1e-3): weights exp(-d_pixels^2 / 2 sigma_space^2).
  double sigma_space = 1.5;
  /// Range standard deviation (m, >= 1e-9): weights exp(-dz^2 / 2 sigma_depth^2), so depth
  /// jumps much larger than it (edges) are kept.
  double sigma_depth = 0.003;

  /// Throws std::invalid_argument naming the field: a radius outside [0, 32] pixels, sigmas
  /// not finite or below sigma_space 1e-3 pixels, sigma_depth 1e-9 m (smaller ones smooth
  /// nothing, and their squares underflow so the weights become 0/0).
  void validate() const;
};

/// bilateralFilterDepth with the settings' window and sigmas (see depth_image.hpp).
void bilateralFilterDepth(const float* depth, int width, int height, float* out, const BilateralFilterSettings& settings,
                          int num_threads = 0);

}  // namespace scanalign
