// Settings of the 2D refinement step of the two-step pose (Kleppe et al., "Automated assembly
// using 3D and 2D cameras", Robotics 6 (2017) 14, the thesis's Paper 3, §3.3): keypoint
// matching between a part's reference image and the hand camera's image (run by OpenCV in
// scanalign.pose.image_matching), the homography's robust fit, the planar pose read off it
// (homography_pose.hpp) and the repetition of the step until the correction is small.
#pragma once

#include <string>

#include "scanalign/pose/homography_pose.hpp"

namespace scanalign {

struct ImageMatchSettings {
  /// Keypoints and descriptors: "sift" (the paper's), "akaze" or "orb" (free substitutes for
  /// its SIFT/SURF hybrid; SURF is patented and not in OpenCV's free build).
  std::string detector = "sift";
  int max_features = 4000;            ///< keypoints kept per image (strongest first), 100..100000
  double ratio = 0.75;                ///< Lowe's ratio test: best / second-best descriptor distance below this, (0, 1]
  double ransac_threshold = 2.0;      ///< px, reprojection error of a RANSAC inlier of the homography
  int ransac_iterations = 5000;       ///< RANSAC's cap, 10..1000000
  int min_matches = 12;               ///< fewer matches after the ratio test: status too_few_matches (>= 4)
  int min_inliers = 10;               ///< fewer RANSAC inliers: status too_few_inliers (>= 4)

  /// Throws std::invalid_argument naming the field.
  void validate() const;
};

struct Refine2dSettings {
  ImageMatchSettings matching;
  HomographyPoseSettings homography;
  int max_steps = 4;  ///< views taken at most (the paper repeats the step to converge or to verify), 1..100
  /// Converged when a step moves the estimate by less than this (m) ...
  double converged_translation = 0.0003;
  /// ... and turns it by less than this (rad; 0.003 rad = 0.17 deg).
  double converged_angle = 0.003;

  void validate() const;
};

}  // namespace scanalign
