// RANSAC (thesis §5.2) with conformal (CGA) plane and sphere models. Euclidean clustering
// and the table segmentation of paper 3 build on it (euclidean_clusters.hpp,
// table_segmentation.hpp).
//
// Generic RANSAC, thesis (5.2): for k = 1..n draw a minimal sample xi_k, build the model
// M_k(xi_k), count the points with error f(M_k, x_i) < E_T, keep the best. The four
// parameters are the model builder, n (max_iterations), f (the error function) and E_T
// (threshold). On top of that:
//  - the iteration count adapts to the best inlier ratio w found so far: the run stops
//    after k >= log(1 - confidence) / log(1 - w^s) hypotheses (s = sample size);
//  - sample k is drawn from its own generator seeded by (seed, k), and hypotheses are
//    scored in parallel in batches but accepted strictly in the order k = 0, 1, 2, ...,
//    so the result is that of the sequential algorithm for any number of threads;
//  - degenerate samples (the builder returns false) produce no hypothesis; they count as
//    iterations (so a cloud with only degenerate samples ends after max_iterations).
//
// CGA models use 5-vectors in the basis (e1, e2, e3, e_inf, e0) (Kleppe, PhD thesis, NTNU 2018, (4.54)-(4.66)):
//   point  P  = [p; p^2/2; 1]                (4.54-4.55)
//   plane  Pi* = [n; delta; 0], |n| = 1       (4.65-4.66), P . Pi* = n.p - delta  (4.67)
//   sphere S* = [c; (c^2 - r^2)/2; 1]        (4.59-4.60), S* . P = (r^2 - |p-c|^2)/2
// and the inner product X . Y = [X]^T M [Y] with the metric M of (5.32).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "scanalign/cga/vector5.hpp"
#include "scanalign/common/interrupt.hpp"
#include "scanalign/common/threads.hpp"
#include "scanalign/common/cloud_view.hpp"

#ifdef _OPENMP
#include <omp.h>
#endif

namespace scanalign {

// The small 5-vector algebra the models need: scanalign/cga/vector5.hpp (cga5::).

// ---------------------------------------------------------------------------
// Models
// ---------------------------------------------------------------------------

/// Plane n . p = distance with |n| = 1 (dual plane Pi* = n + distance e_inf, (4.65)).
struct PlaneModel {
  Eigen::Vector3d normal = Eigen::Vector3d::Zero();
  double distance = 0.0;  ///< metres: signed distance of the plane from the origin along n
  /// Signed distance of p, P . Pi* = n.p - delta (4.67); positive on the normal's side.
  double signedDistance(const Eigen::Vector3d& p) const { return normal.dot(p) - distance; }
  cga5::Vec5 dual() const {
    cga5::Vec5 v;
    v << normal, distance, 0.0;
    return v;
  }
};

/// Sphere |p - c| = radius (dual sphere S* = up(c) - r^2/2 e_inf, (4.59)).
struct SphereModel {
  Eigen::Vector3d center = Eigen::Vector3d::Zero();
  double radius = 0.0;  ///< metres
  /// Distance of p from the surface, |d - r| with d^2 = r^2 - 2 P . S* = |p - c|^2
  /// (the natural CGA sphere residual, from S*.P = 1/2 (r^2 - d^2), Paper 5 eq. (10)).
  double surfaceDistance(const Eigen::Vector3d& p) const { return std::abs((p - center).norm() - radius); }
  cga5::Vec5 dual() const {
    cga5::Vec5 v;
    v << center, 0.5 * (center.squaredNorm() - radius * radius), 1.0;
    return v;
  }
};

/// Plane through three points: Pi = P_A ^ P_B ^ P_C ^ e_inf (5.35), dualised and
/// normalised so that |n| = 1 (Pi* / sqrt(Pi*^2): (5.36) read with a normalised dual plane). Returns
/// false for a degenerate (collinear or repeated) sample, where Pi = 0: |n| below
/// 1e-12 times the squared largest side. The normal's sign is that of the CGA dual.
bool planeFromPoints(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c, PlaneModel& out);

/// Sphere through four points: S = P_A ^ P_B ^ P_C ^ P_D (4.58), dualised and
/// rescaled so that its e0 coefficient is 1 (4.60): centre = S*[e1..e3],
/// r^2 = c^2 - 2 S*[e_inf]. Returns false when the points are coplanar (S*'s e0
/// coefficient, which is the tetrahedron's volume up to a constant, vanishes; the
/// blade is then a plane) or when r^2 <= 0.
bool sphereFromPoints(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c,
                      const Eigen::Vector3d& d, SphereModel& out);

/// Least-squares plane (PCA): the centroid and the eigenvector of the smallest
/// eigenvalue of the covariance of `points[indices]`. Returns false for < 3 points.
template <typename Scalar>
bool fitPlaneLeastSquares(const CloudView<Scalar>& points, const std::vector<std::uint32_t>& indices,
                          PlaneModel& out);

/// Algebraic least-squares sphere: the CGA sphere fit (thesis 5.26-5.34, Dorst): minimise
/// sum (S*.P_i)^2 / S*^2, i.e. Q [S*] = lambda [S*] with Q = (1/n) sum [P_i][P_i]^T M
/// (5.31), taking the eigenvector of the smallest positive eigenvalue (Q has exactly one
/// negative one) and rescaling it to e0 coefficient 1. The points are centred and scaled
/// first (the fit is equivariant under similarity transforms). Returns false for < 4
/// points, or when the solution is a plane (e0 coefficient ~ 0, thesis (5.26)-(5.34)).
template <typename Scalar>
bool fitSphereLeastSquares(const CloudView<Scalar>& points, const std::vector<std::uint32_t>& indices,
                           SphereModel& out);

// ---------------------------------------------------------------------------
// Generic RANSAC
// ---------------------------------------------------------------------------

enum class RansacStatus {
  kSuccess,       ///< a model was found (and refined when asked)
  kTooFewPoints,  ///< fewer finite points than the minimal sample size
  kDegenerate,    ///< every sample drawn was degenerate: no hypothesis could be built
};
const char* toString(RansacStatus s);

struct RansacSettings {
  double threshold = 0.01;       ///< E_T, metres: inlier if error < threshold
  int max_iterations = 1000;     ///< n: most hypotheses (samples) drawn
  double confidence = 0.99;      ///< adaptive stop, in [0, 1]; 0 or 1 disables it (always max_iterations)
  std::uint64_t seed = 0;        ///< sample k is drawn from a generator seeded by (seed, k)
  int num_threads = 0;           ///< OpenMP threads for scoring, 0 = all; never changes the result
  bool refine = true;            ///< least-squares refit of the winner over its inliers
  /// Rank hypotheses by the MSAC cost sum min(e^2, threshold^2) (Torr and Zisserman 2000)
  /// instead of the inlier count: among hypotheses with about as many inliers it prefers the
  /// one that fits them closely (near-symmetric shapes, inexact correspondences).
  bool msac = false;
};

/// Throws std::invalid_argument naming the field: threshold must be finite and > 0,
/// max_iterations >= 1, confidence in [0, 1].
void validate(const RansacSettings& settings);

/// Outcome of the generic loop: the index of the winning hypothesis' model in the
/// caller's terms is returned through `best`.
struct RansacLoopStats {
  RansacStatus status = RansacStatus::kDegenerate;
  int iterations = 0;            ///< samples drawn
  int degenerate_samples = 0;    ///< of which degenerate
  std::size_t best_inliers = 0;  ///< inliers of the winning hypothesis
  int best_iteration = -1;       ///< k of the winning hypothesis
};

/// Deterministic sample of `s` distinct integers in [0, n) for iteration k.
void ransacSample(std::uint64_t seed, std::uint64_t k, std::uint32_t n, int s, std::uint32_t* out);

/// Iterations needed to draw one all-inlier sample of size s with probability
/// `confidence` when the inlier ratio is w: log(1 - confidence) / log(1 - w^s).
double ransacRequiredIterations(double w, int s, double confidence);

/// The generic RANSAC of thesis (5.2) over points 0..n-1.
///   build(const std::uint32_t* sample, Model& m) -> bool   (false: degenerate sample)
///   error(const Model& m, std::size_t i) -> double          (f; inlier if < threshold)
/// Writes the winning hypothesis to `best` (unchanged if none). Hypotheses are scored in
/// parallel; ties go to the earlier hypothesis, so the result is thread-count independent.
/// Throws Interrupted (common/interrupt.hpp) when the interrupt hook asks to stop, checked
/// before each batch of hypotheses.
template <typename Model, typename Build, typename Error>
RansacLoopStats ransacLoop(std::size_t n, int sample_size, Build&& build, Error&& error,
                           const RansacSettings& settings, Model& best);

/// Result of a plane / sphere RANSAC.
template <typename Model>
struct RansacResult {
  RansacStatus status = RansacStatus::kTooFewPoints;
  Model model;       ///< the returned model: the refit when refined, else the winning hypothesis
  Model hypothesis;  ///< the winning minimal-sample hypothesis
  /// Input indices i (ascending) of the finite points with error(model, i) < threshold,
  /// for the returned `model` (so after a refit they are re-selected against the refit).
  std::vector<std::uint32_t> inliers;
  std::size_t hypothesis_inliers = 0;  ///< inlier count of the winning hypothesis
  int iterations = 0;
  int degenerate_samples = 0;
  bool refined = false;  ///< the least-squares refit succeeded and was used
  bool success() const { return status == RansacStatus::kSuccess; }
};

/// RANSAC plane, CGA model (5.35) and inlier test |P . Pi*| < E_T (5.36, normalised).
/// Fewer than 3 finite points: status kTooFewPoints. Throws for invalid settings (validate).
template <typename Scalar>
RansacResult<PlaneModel> ransacPlane(const CloudView<Scalar>& points, const RansacSettings& settings);

struct SphereLimits {
  double min_radius = 0.0;                                       ///< metres
  double max_radius = std::numeric_limits<double>::infinity();  ///< metres
};

/// RANSAC sphere from four points (4.58); residual ||p - c| - r|. A sample is degenerate
/// when its four points lie within `threshold` of one plane (a plane explains them as
/// well as any sphere: on planar data no sphere is reported) or the sphere's radius is
/// outside the limits. The refit is rejected when its radius leaves the limits. Throws for
/// invalid settings (validate) or limits (not 0 <= min_radius < max_radius).
template <typename Scalar>
RansacResult<SphereModel> ransacSphere(const CloudView<Scalar>& points, const RansacSettings& settings,
                                       const SphereLimits& limits = {});

// ---------------------------------------------------------------------------
// ransacLoop implementation
// ---------------------------------------------------------------------------

template <typename Model, typename Build, typename Error>
RansacLoopStats ransacLoop(std::size_t n, int sample_size, Build&& build, Error&& error,
                           const RansacSettings& settings, Model& best) {
  RansacLoopStats st;
  if (sample_size <= 0 || n < static_cast<std::size_t>(sample_size)) {
    st.status = RansacStatus::kTooFewPoints;
    return st;
  }
  if (n >= (std::size_t{1} << 32)) n = (std::size_t{1} << 32) - 1;
  const int max_it = std::max(0, settings.max_iterations);
  const double threshold = settings.threshold;
  int threads = settings.num_threads;
#ifdef _OPENMP
  threads = resolveThreads(threads);
#else
  threads = 1;
#endif
  // The batch size only changes how much work past the adaptive stop is wasted, never
  // the result: hypotheses are accepted in order below.
  const int batch = std::max(16, 8 * threads);  // few parallel regions: cheap on busy machines
  std::vector<Model> models(batch);
  std::vector<char> valid(batch);
  std::vector<std::size_t> counts(batch);
  std::vector<double> costs(batch);
  const double t2 = threshold * threshold;
  double best_cost = std::numeric_limits<double>::infinity();
  std::vector<std::uint32_t> samples(static_cast<std::size_t>(batch) * sample_size);
  double required = max_it;
  int k0 = 0;
  bool have = false;
  while (k0 < max_it && k0 < required) {
    checkInterrupt();  // once per batch, outside the parallel region (common/interrupt.hpp)
    const int m = std::min(batch, max_it - k0);
#pragma omp parallel for schedule(dynamic, 1) num_threads(threads)
    for (int j = 0; j < m; ++j) {
      std::uint32_t* s = samples.data() + static_cast<std::size_t>(j) * sample_size;
      ransacSample(settings.seed, static_cast<std::uint64_t>(k0 + j), static_cast<std::uint32_t>(n), sample_size, s);
      valid[j] = build(static_cast<const std::uint32_t*>(s), models[j]) ? 1 : 0;
      std::size_t c = 0;
      double cost = 0;
      if (valid[j])
        for (std::size_t i = 0; i < n; ++i) {
          const double e = error(models[j], i);
          c += e < threshold ? 1 : 0;
          if (settings.msac) cost += std::min(e * e, t2);
        }
      counts[j] = c;
      costs[j] = cost;
    }
    for (int j = 0; j < m; ++j) {
      if (k0 + j >= required) break;  // the sequential algorithm would have stopped here
      ++st.iterations;
      if (!valid[j]) {
        ++st.degenerate_samples;
        continue;
      }
      const bool better = settings.msac ? costs[j] < best_cost : counts[j] > st.best_inliers;
      if (!have || better) {
        have = true;
        best_cost = costs[j];
        best = models[j];
        st.best_inliers = counts[j];
        st.best_iteration = k0 + j;
        if (settings.confidence > 0 && settings.confidence < 1)
          required = std::min<double>(max_it, ransacRequiredIterations(double(counts[j]) / double(n), sample_size,
                                                                       settings.confidence));
      }
    }
    k0 += m;
  }
  st.status = have ? RansacStatus::kSuccess : RansacStatus::kDegenerate;
  return st;
}

}  // namespace scanalign
