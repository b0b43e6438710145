// CBD coarse alignment. See cbd_alignment.hpp.
#include "scanalign/pose/cbd_alignment.hpp"
#include "scanalign/registration/alignment_fitness.hpp"
#include "scanalign/common/threads.hpp"

#include <omp.h>

#include <chrono>
#include <cmath>
#include <stdexcept>
#include <utility>
#include <vector>

#include "scanalign/registration/kdtree.hpp"

namespace scanalign {

namespace {
double since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}
}  // namespace

template <typename Scalar>
CbdAlignmentResult alignCbd(const CloudView<Scalar>& source, const CbdFeatures& fs, const CloudView<Scalar>& target,
                            const CbdFeatures& ft, const CbdAlignmentSettings& s) {
  if (s.matches_per_keypoint < 1) throw std::invalid_argument("alignCbd: matches_per_keypoint must be >= 1");
  if (s.hypotheses < 1 || s.hypotheses > 1000)
    throw std::invalid_argument("alignCbd: hypotheses must be in [1, 1000], got " + std::to_string(s.hypotheses));
  const auto t0 = std::chrono::steady_clock::now();
  CbdAlignmentResult out;
  out.source_keypoints = fs.keypoints.size();
  out.target_keypoints = ft.keypoints.size();
  if (fs.keypoints.size() < 3 || ft.keypoints.size() < 3) {
    out.message = "too few CBD keypoints (source " + std::to_string(fs.keypoints.size()) + ", target " +
                  std::to_string(ft.keypoints.size()) + "; need 3): the cloud is too small or too sparse for radius " +
                  std::to_string(s.cbd.radius) + " m and min_neighbors " + std::to_string(s.cbd.min_neighbors);
    out.seconds = since(t0);
    return out;
  }
  const CbdMatches m = matchCbd(fs, ft, s.cbd.variant, s.matches_per_keypoint, s.cbd.num_threads);
  out.matches = m.source.size();
  out.match_seconds = since(t0);
  // Pairs as indices into keypoint coordinate arrays (double).
  std::vector<double> xs(3 * fs.keypoints.size()), ys(3 * ft.keypoints.size());
  for (std::size_t i = 0; i < fs.keypoints.size(); ++i)
    for (int k = 0; k < 3; ++k) xs[3 * i + k] = double(source.ptr(fs.keypoints[i])[k]);
  for (std::size_t i = 0; i < ft.keypoints.size(); ++i)
    for (int k = 0; k < 3; ++k) ys[3 * i + k] = double(target.ptr(ft.keypoints[i])[k]);
  std::vector<std::uint32_t> pairs(2 * m.source.size());
  for (std::size_t k = 0; k < m.source.size(); ++k) {
    pairs[2 * k] = m.source[k];
    pairs[2 * k + 1] = m.target[k];
  }
  const auto t2 = std::chrono::steady_clock::now();
  CorrespondenceRansacSettings rs = s.ransac;
  if (rs.num_threads == 0) rs.num_threads = s.cbd.num_threads;
  const CloudView<double> xv(xs.data(), fs.keypoints.size()), yv(ys.data(), ft.keypoints.size());
  // Sequential RANSAC: each hypothesis's inlier pairs leave the pool before the next run; the
  // hypotheses are compared on the whole source cloud, not on their consensus size.
  for (int h = 0; h < s.hypotheses && (h == 0 || pairs.size() >= 6); ++h) {
    const CorrespondenceRansacResult r = ransacRigidMotion(xv, yv, pairs.data(), pairs.size() / 2, rs);
    if (!r.found) {
      if (h == 0) out.message = r.message;
      break;
    }
    const auto f = alignmentFitness(source, target, r.T_target_source, rs.inlier_threshold, s.cbd.num_threads);
    if (!out.found || f.first > out.fitness || (f.first == out.fitness && f.second < out.inlier_rmse)) {
      out.found = true;
      out.T_target_source = r.T_target_source;
      out.match_inliers = r.inliers.size();
      out.fitness = f.first;
      out.inlier_rmse = f.second;
      out.message.clear();
    }
    std::vector<bool> used(pairs.size() / 2, false);
    for (const std::uint32_t i : r.inliers) used[i] = true;
    std::size_t kept = 0;
    for (std::size_t k = 0; k < used.size(); ++k)
      if (!used[k]) {
        pairs[2 * kept] = pairs[2 * k];
        pairs[2 * kept + 1] = pairs[2 * k + 1];
        ++kept;
      }
    pairs.resize(2 * kept);
  }
  out.ransac_seconds = since(t2);
  out.seconds = since(t0);
  return out;
}

template <typename Scalar>
CbdAlignmentResult alignCbd(const CloudView<Scalar>& source, const CloudView<Scalar>& target,
                            const CbdAlignmentSettings& s) {
  const auto t0 = std::chrono::steady_clock::now();
  const CbdFeatures fs = computeCbd(source, s.cbd);
  const CbdFeatures ft = s.target_thresholds_from_source ? computeCbd(target, s.cbd, &fs.thresholds)
                                                         : computeCbd(target, s.cbd);
  const double feature_seconds = since(t0);
  CbdAlignmentResult out = alignCbd(source, fs, target, ft, s);
  out.feature_seconds = feature_seconds;
  out.seconds = since(t0);
  return out;
}

#define SCANALIGN_INSTANTIATE(S)                                                                              \
  template CbdAlignmentResult alignCbd<S>(const CloudView<S>&, const CloudView<S>&, const CbdAlignmentSettings&); \
  template CbdAlignmentResult alignCbd<S>(const CloudView<S>&, const CbdFeatures&, const CloudView<S>&,         \
                                          const CbdFeatures&, const CbdAlignmentSettings&);
SCANALIGN_INSTANTIATE(float)
SCANALIGN_INSTANTIATE(double)
#undef SCANALIGN_INSTANTIATE

}  // namespace scanalign
