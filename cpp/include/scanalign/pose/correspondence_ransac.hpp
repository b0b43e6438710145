// Robust rigid motion from putative point correspondences (e.g. descriptor matches): RANSAC
// with a prerejection test on the sample's edge lengths (after Buch et al. 2013, the idea of
// PCL's SampleConsensusPrerejective), minimal 3-point Kabsch hypotheses, and a final
// least-squares refit on the inliers with the Valkenburg–Dorst motor estimator (Kleppe, PhD
// thesis, NTNU 2018, paper 5 (36)-(44)). The thesis's own method puts all matches into the
// least squares without outlier rejection; descriptor matches always contain outliers,
// hence this wrapper. The loop is the generic ransacLoop of fitting/ransac.hpp.
//
// Hypotheses are ranked by the MSAC cost (Torr and Zisserman 2000), not the bare inlier count:
// on near-symmetric parts a slightly wrong pose can collect as many matches within the
// threshold as the true one, but fits them less closely.
//
// Deterministic: samples are drawn from (seed, iteration) and the best hypothesis is chosen
// by (inlier count, lowest iteration), so the answer does not depend on the thread count.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "scanalign/common/cloud_view.hpp"

namespace scanalign {

struct CorrespondenceRansacSettings {
  int max_iterations = 1000;       ///< hypotheses (thesis baselines: 1000)
  double inlier_threshold = 0.005; ///< m; a pair is an inlier if |y − (R x + t)| < this (thesis: 5 mm)
  /// Prerejection: a sample is skipped unless every edge-length ratio between its source and
  /// target triangles is at least this (0 disables; PCL's prerejective default 0.9).
  double edge_similarity = 0.9;
  double min_edge = 0.0;           ///< m; samples with an edge shorter than this are skipped (0: any)
  double confidence = 0.999;       ///< stop early once this confidence of an all-inlier sample is reached
  int refine_iterations = 3;       ///< inlier refits with the motor estimator (recollecting inliers each time)
  std::uint64_t seed = 0;
  int num_threads = 0;             ///< OpenMP threads; 0 = all cores
};

struct CorrespondenceRansacResult {
  Eigen::Matrix4d T_target_source = Eigen::Matrix4d::Identity();
  bool found = false;                   ///< a hypothesis with at least 3 inliers was found
  std::vector<std::uint32_t> inliers;   ///< indices into the pair list
  double inlier_rmse = 0.0;             ///< m, over the inlier pairs
  int iterations = 0;                   ///< hypotheses drawn (early stop included)
  std::string message;                  ///< why nothing was found
};

/// `pairs` holds n_pairs (source index, target index) pairs, row-major (2 per pair), into
/// `source` and `target`. Throws std::invalid_argument for bad settings or out-of-range indices.
CorrespondenceRansacResult ransacRigidMotion(const CloudView<double>& source, const CloudView<double>& target,
                                             const std::uint32_t* pairs, std::size_t n_pairs,
                                             const CorrespondenceRansacSettings& settings = {});

}  // namespace scanalign
