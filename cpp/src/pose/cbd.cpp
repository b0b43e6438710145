// Curvature-based descriptor (thesis ch. 6, paper 5). See cbd.hpp.
#include "scanalign/pose/cbd.hpp"
#include "scanalign/common/threads.hpp"

#include <omp.h>

#include "scanalign/common/interrupt.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <numeric>
#include <queue>
#include <stdexcept>
#include <string>
#include <utility>

#include <Eigen/Eigenvalues>

#include "scanalign/fitting/detail/pencil.hpp"
#include "scanalign/fitting/sphere_fit.hpp"
#include "scanalign/registration/kdtree.hpp"

namespace scanalign {

namespace {

int threadsOf(int n) { return resolveThreads(n); }

void validate(const CbdSettings& s) {
  if (!(s.radius > 0) || !std::isfinite(s.radius))
    throw std::invalid_argument("CBD: radius must be a finite positive distance in metres");
  if (s.radius > kMaxCbdCoordinate) throw std::invalid_argument("CBD: radius beyond 1e100 m (overflow)");
  if (!(s.gamma >= 0) || !std::isfinite(s.gamma)) throw std::invalid_argument("CBD: gamma must be finite and >= 0 (1/m)");
  if (s.min_neighbors != 0 && s.min_neighbors < 5)
    throw std::invalid_argument("CBD: min_neighbors must be 0 (automatic) or >= 5 (a sphere fit needs 5 points)");
  if (s.keypoint_mode == CbdKeypointMode::Automatic && s.num_keypoints < 1)
    throw std::invalid_argument("CBD: num_keypoints must be >= 1");
  if (s.max_keypoints < 0) throw std::invalid_argument("CBD: max_keypoints must be >= 0 (0: no cap)");
  for (double d : {s.thresholds.linear, s.thresholds.planar, s.thresholds.spherical})
    if (!(d >= 0) || !std::isfinite(d)) throw std::invalid_argument("CBD: thresholds must be finite and >= 0");
  if (!(s.max_sphere_radius > 0) || !std::isfinite(s.max_sphere_radius))
    throw std::invalid_argument("CBD: max_sphere_radius must be a finite positive distance in metres");
  if (s.num_threads < 0) throw std::invalid_argument("CBD: num_threads must be >= 0");
}

/// Moments of the neighbours' offsets from the query q (offsets keep the sums well
/// conditioned far from the origin): count, Σd, Σddᵀ.
struct Moments {
  int count = 0;
  Eigen::Vector3d s1 = Eigen::Vector3d::Zero();
  Eigen::Matrix3d s2 = Eigen::Matrix3d::Zero();
  /// C = Σ (p − p̄)(p − p̄)ᵀ (P5 (11), no 1/n).
  Eigen::Matrix3d scatter() const {
    if (count == 0) return Eigen::Matrix3d::Zero();
    return s2 - s1 * s1.transpose() / count;
  }
};

template <typename Scalar>
Moments momentsAt(const LeftBalancedKdTree<Scalar>& tree, const Scalar* q, Scalar r2) {
  Moments m;
  tree.forEachInRadius(q, r2, [&](std::uint32_t node, Scalar) {
    const Scalar* p = tree.node(node).p;
    const Eigen::Vector3d d(double(p[0]) - q[0], double(p[1]) - q[1], double(p[2]) - q[2]);
    m.s1 += d;
    m.s2.noalias() += d * d.transpose();
    ++m.count;
  });
  return m;
}

/// Eigenvalues (descending, clamped at 0) and matching eigenvectors as columns v1, v2, v3.
void eigenDescending(const Eigen::Matrix3d& C, Eigen::Vector3d& values, Eigen::Matrix3d* vectors) {
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig;
  if (vectors)
    eig.compute(C);  // the iterative solver: accurate eigenvectors also for near-equal eigenvalues
  else
    eig.computeDirect(C, Eigen::EigenvaluesOnly);
  const Eigen::Vector3d ev = eig.eigenvalues();  // ascending
  values = Eigen::Vector3d(ev(2), ev(1), ev(0)).cwiseMax(0.0);
  if (vectors) {
    vectors->col(0) = eig.eigenvectors().col(2);
    vectors->col(1) = eig.eigenvectors().col(1);
    vectors->col(2) = eig.eigenvectors().col(0);
  }
}

struct ScoredIndex {
  double score;
  std::uint32_t index;
  bool operator<(const ScoredIndex& o) const { return score < o.score || (score == o.score && index < o.index); }
};

/// One weighted sphere fit in the keypoint's local frame x = (p − p_i)/r ((6.8)-(6.11)). The
/// fit is equivariant under this similarity, and the unit-scale coordinates keep
/// the 5x5 moment matrix well conditioned whatever the cloud's position.
CbdSphere fitLocalSphere(const Eigen::Matrix<double, 5, 5>& D, const Eigen::Vector3d& p_i, double scale,
                         double max_radius) {
  static const Matrix5d M = cga5::metric();
  const detail::PencilSolution<5> sol = detail::smallestPositive<5>(D, M);
  const Vector5d s = M * sol.a;  // [S*] (5.31)
  CbdSphere out;
  const double e_norm = s.head<3>().norm(), s0 = s(4);
  bool flat = !(std::abs(s0) > 1e-9 * e_norm) || !s.allFinite();
  double r = 0, d = 0;
  Eigen::Vector3d c = Eigen::Vector3d::Zero();
  if (!flat) {
    c = s.head<3>() / s0;                          // centre, local units
    const double r2 = c.squaredNorm() - 2.0 * s(3) / s0;  // (4.61)
    r = std::sqrt(std::max(r2, 0.0)) * scale;
    d = c.norm() * scale;
    flat = r2 <= 0 || r > max_radius;
  }
  if (flat) {
    out.flat = true;
    out.radius = out.distance = max_radius;
    if (e_norm > 0 && s.allFinite()) {
      const Eigen::Vector3d n = s.head<3>() / e_norm;
      out.dual << n, scale * s(3) / e_norm + n.dot(p_i), 0.0;  // n·p = δ in the cloud frame (4.66)
    }
    return out;
  }
  out.radius = r;
  out.distance = d;
  const Eigen::Vector3d cw = p_i + scale * c;
  out.dual << cw, 0.5 * (cw.squaredNorm() - r * r), 1.0;  // (4.60)
  return out;
}

/// Tiny exact k-nearest-neighbour tree over 4-D descriptors (median splits on the axis of
/// largest spread, stored implicitly in a permuted index array).
class DescriptorTree4 {
 public:
  explicit DescriptorTree4(const std::vector<Eigen::Vector4d>& pts) : pts_(pts), idx_(pts.size()), axis_(pts.size()) {
    std::iota(idx_.begin(), idx_.end(), 0u);
    build(0, idx_.size());
  }
  /// k nearest (squared distance, position) in ascending distance.
  void knn(const Eigen::Vector4d& q, int k, std::vector<std::pair<double, std::uint32_t>>& out) const {
    std::priority_queue<std::pair<double, std::uint32_t>> heap;  // max-heap of the best k
    search(q, 0, idx_.size(), k, heap);
    out.resize(heap.size());
    for (std::size_t i = out.size(); i-- > 0;) {
      out[i] = heap.top();
      heap.pop();
    }
  }

 private:
  void build(std::size_t lo, std::size_t hi) {
    if (hi - lo <= 1) return;
    Eigen::Vector4d mn = Eigen::Vector4d::Constant(std::numeric_limits<double>::infinity()), mx = -mn;
    for (std::size_t i = lo; i < hi; ++i) {
      mn = mn.cwiseMin(pts_[idx_[i]]);
      mx = mx.cwiseMax(pts_[idx_[i]]);
    }
    int axis;
    (mx - mn).maxCoeff(&axis);
    const std::size_t mid = lo + (hi - lo) / 2;
    std::nth_element(idx_.begin() + lo, idx_.begin() + mid, idx_.begin() + hi,
                     [&](std::uint32_t a, std::uint32_t b) { return pts_[a](axis) < pts_[b](axis); });
    axis_[mid] = static_cast<std::uint8_t>(axis);
    build(lo, mid);
    build(mid + 1, hi);
  }
  void search(const Eigen::Vector4d& q, std::size_t lo, std::size_t hi, int k,
              std::priority_queue<std::pair<double, std::uint32_t>>& heap) const {
    if (lo >= hi) return;
    const std::size_t mid = lo + (hi - lo) / 2;
    const std::uint32_t p = idx_[mid];
    const double d2 = (pts_[p] - q).squaredNorm();
    if (static_cast<int>(heap.size()) < k) {
      heap.emplace(d2, p);
    } else if (d2 < heap.top().first) {
      heap.pop();
      heap.emplace(d2, p);
    }
    if (hi - lo == 1) return;
    const int axis = axis_[mid];
    const double diff = q(axis) - pts_[p](axis);
    const bool left_first = diff < 0;
    if (left_first)
      search(q, lo, mid, k, heap);
    else
      search(q, mid + 1, hi, k, heap);
    if (static_cast<int>(heap.size()) < k || diff * diff < heap.top().first) {
      if (left_first)
        search(q, mid + 1, hi, k, heap);
      else
        search(q, lo, mid, k, heap);
    }
  }
  const std::vector<Eigen::Vector4d>& pts_;
  std::vector<std::uint32_t> idx_;
  std::vector<std::uint8_t> axis_;
};

/// Refuses a finite coordinate beyond kMaxCbdCoordinate: the neighbourhood scatter and the
/// conformal points square differences of coordinates, and beyond it they overflow to inf/NaN.
template <typename Scalar>
void requireCbdCoordinates(const CloudView<Scalar>& points, const char* what) {
  for (std::size_t i = 0; i < points.size; ++i)
    if (points.isFinite(i)) {
      const Scalar* p = points.ptr(i);
      if (std::max({std::abs(double(p[0])), std::abs(double(p[1])), std::abs(double(p[2]))}) > kMaxCbdCoordinate)
        throw std::invalid_argument(std::string(what) + ": points[" + std::to_string(i) +
                                    "]: overflow: coordinates beyond 1e100 m");
    }
}

/// PCA of every point over an existing tree of the same cloud (computeCbd reuses the tree
/// for the sphere fits instead of building a second one).
template <typename Scalar>
std::vector<NeighbourhoodPca> pcaOverTree(const CloudView<Scalar>& points, const LeftBalancedKdTree<Scalar>& tree,
                                          double radius, int num_threads) {
  std::vector<NeighbourhoodPca> out(points.size);
  const Scalar r2 = static_cast<Scalar>(radius * radius);
  // In chunks, with a Ctrl-C check between them: a radius as large as the cloud makes every
  // neighbourhood the whole cloud (quadratic; minutes at 200k points).
  constexpr std::ptrdiff_t kChunk = 512;  // about 0.25 s between checks in the worst case
  const auto n = static_cast<std::ptrdiff_t>(points.size);
  for (std::ptrdiff_t begin = 0; begin < n; begin += kChunk) {
    checkInterrupt();
#pragma omp parallel for schedule(dynamic, 64) num_threads(threadsOf(num_threads))
    for (std::ptrdiff_t ii = begin; ii < std::min(n, begin + kChunk); ++ii) {
      const std::size_t i = static_cast<std::size_t>(ii);
      if (!points.isFinite(i)) continue;
      const Moments m = momentsAt(tree, points.ptr(i), r2);
      out[i].count = static_cast<std::uint32_t>(m.count);
      eigenDescending(m.scatter(), out[i].eigenvalues, nullptr);
    }
  }
  return out;
}

}  // namespace

template <typename Scalar>
std::vector<NeighbourhoodPca> neighbourhoodPca(const CloudView<Scalar>& points, double radius, int num_threads) {
  if (!(radius > 0) || !std::isfinite(radius))
    throw std::invalid_argument("neighbourhoodPca: radius must be a finite positive distance in metres");
  if (num_threads < 0) throw std::invalid_argument("neighbourhoodPca: num_threads must be >= 0");
  if (radius > kMaxCbdCoordinate) throw std::invalid_argument("neighbourhoodPca: radius beyond 1e100 m (overflow)");
  requireCbdCoordinates(points, "neighbourhoodPca");
  if (points.size == 0) return {};
  return pcaOverTree(points, LeftBalancedKdTree<Scalar>(points), radius, num_threads);
}

ShapeFactors shapeFactorsOf(const NeighbourhoodPca& pca) {
  // A neighbourhood without spread (one point, or duplicates) has no shape: all zeros, so
  // it is never a keypoint. Everything else uses the one definition of (6.1)-(6.3).
  if (!(pca.eigenvalues.sum() > 0)) return {};
  return shapeFactors(pca.eigenvalues);
}

double keypointScore(const NeighbourhoodPca& pca, int min_neighbors) {
  if (pca.count < static_cast<std::uint32_t>(std::max(min_neighbors, 0)) || !(pca.eigenvalues.sum() > 0))
    return 1.0 / 3.0;
  const ShapeFactors f = shapeFactorsOf(pca);
  return f.linear * f.planar + f.planar * f.spherical + f.spherical * f.linear;
}

std::vector<std::uint32_t> selectKeypoints(const std::vector<NeighbourhoodPca>& pca, const ShapeThresholds& t,
                                           int min_neighbors, bool inclusive) {
  std::vector<std::uint32_t> out;
  // A factor never exceeds 1, so δ >= 1 disables its term with ">"; with ">="
  // (derived δ's) a δ of exactly 1 comes from a pure keypoint and must select it.
  const auto pass = [inclusive](double c, double delta) { return inclusive ? c >= delta : c > delta; };
  for (std::size_t i = 0; i < pca.size(); ++i) {
    if (pca[i].count < static_cast<std::uint32_t>(std::max(min_neighbors, 0)) || !(pca[i].eigenvalues.sum() > 0))
      continue;
    const ShapeFactors f = shapeFactorsOf(pca[i]);
    // (6.4)
    if (pass(f.linear, t.linear) || pass(f.planar, t.planar) || pass(f.spherical, t.spherical))
      out.push_back(static_cast<std::uint32_t>(i));
  }
  return out;
}

std::vector<std::uint32_t> automaticKeypoints(const std::vector<NeighbourhoodPca>& pca, int k, int min_neighbors,
                                              ShapeThresholds* thresholds) {
  if (k < 1) throw std::invalid_argument("automaticKeypoints: k must be >= 1");
  std::vector<ScoredIndex> scored;
  for (std::size_t i = 0; i < pca.size(); ++i)
    if (pca[i].count >= static_cast<std::uint32_t>(std::max(min_neighbors, 0)) && pca[i].eigenvalues.sum() > 0)
      scored.push_back({keypointScore(pca[i], min_neighbors), static_cast<std::uint32_t>(i)});
  const std::size_t n = std::min<std::size_t>(static_cast<std::size_t>(k), scored.size());
  std::partial_sort(scored.begin(), scored.begin() + n, scored.end());
  std::vector<std::uint32_t> out(n);
  // P5 starts from δ = 1; 2 marks a group no keypoint lowered, so that it stays disabled also
  // with the inclusive comparison.
  ShapeThresholds t{2.0, 2.0, 2.0};
  for (std::size_t j = 0; j < n; ++j) {
    out[j] = scored[j].index;
    const ShapeFactors f = shapeFactorsOf(pca[scored[j].index]);
    // The keypoint's dominant factor sets its group's δ (P5 §III-B4).
    if (f.linear >= f.planar && f.linear >= f.spherical)
      t.linear = std::min(t.linear, f.linear);
    else if (f.planar >= f.spherical)
      t.planar = std::min(t.planar, f.planar);
    else
      t.spherical = std::min(t.spherical, f.spherical);
  }
  std::sort(out.begin(), out.end());
  if (thresholds) *thresholds = t;
  return out;
}

template <typename Scalar>
CbdFeatures computeCbd(const CloudView<Scalar>& points, const CbdSettings& settings,
                       const ShapeThresholds* thresholds_override) {
  validate(settings);
  requireCbdCoordinates(points, "computeCbd");
  const auto t0 = std::chrono::steady_clock::now();
  CbdFeatures out;
  const int threads = threadsOf(settings.num_threads);
  const LeftBalancedKdTree<Scalar> tree(points);  // one tree for the PCA and the sphere fits
  const std::vector<NeighbourhoodPca> pca = pcaOverTree(points, tree, settings.radius, threads);
  CbdSettings s = settings;
  if (s.min_neighbors == 0) {
    std::vector<std::uint32_t> counts;
    for (const auto& p : pca)
      if (p.count > 0) counts.push_back(p.count);
    std::uint32_t median = 0;
    if (!counts.empty()) {
      std::nth_element(counts.begin(), counts.begin() + counts.size() / 2, counts.end());
      median = counts[counts.size() / 2];
    }
    s.min_neighbors = std::max(5, static_cast<int>(median / 2));
  }
  out.min_neighbors = s.min_neighbors;
  for (const auto& p : pca)
    if (p.count >= static_cast<std::uint32_t>(s.min_neighbors)) ++out.points_with_min_neighbors;

  // Keypoints ((6.4) or paper 5 §III-B4).
  std::vector<std::uint32_t> keys;
  bool capped_mode = true;
  if (thresholds_override) {
    out.thresholds = *thresholds_override;
    keys = selectKeypoints(pca, out.thresholds, s.min_neighbors, true);
  } else if (settings.keypoint_mode == CbdKeypointMode::Automatic) {
    keys = automaticKeypoints(pca, settings.num_keypoints, s.min_neighbors, &out.thresholds);
    capped_mode = false;
  } else {
    out.thresholds = settings.thresholds;
    keys = selectKeypoints(pca, out.thresholds, s.min_neighbors, false);
  }
  if (capped_mode && settings.max_keypoints > 0 && keys.size() > static_cast<std::size_t>(settings.max_keypoints)) {
    // Keep the purest (lowest-score) ones, as the automatic mode ranks them.
    std::vector<ScoredIndex> scored(keys.size());
    for (std::size_t j = 0; j < keys.size(); ++j) scored[j] = {keypointScore(pca[keys[j]], s.min_neighbors), keys[j]};
    const std::size_t n = static_cast<std::size_t>(settings.max_keypoints);
    std::partial_sort(scored.begin(), scored.begin() + n, scored.end());
    keys.resize(n);
    for (std::size_t j = 0; j < n; ++j) keys[j] = scored[j].index;
    std::sort(keys.begin(), keys.end());
  }

  // Two weighted spheres per keypoint ((6.8)-(6.11)), in parallel.
  const std::size_t nk = keys.size();
  out.keypoints = keys;
  out.descriptors.resize(nk);
  out.scalar.resize(nk);
  out.sphere1.resize(nk);
  out.sphere2.resize(nk);
  out.axes.resize(nk);
  if (nk > 0) {
    const Scalar r2 = static_cast<Scalar>(settings.radius * settings.radius);
    const double inv_r = 1.0 / settings.radius;
#pragma omp parallel for schedule(dynamic, 8) num_threads(threads)
    for (std::ptrdiff_t jj = 0; jj < static_cast<std::ptrdiff_t>(nk); ++jj) {
      const std::size_t j = static_cast<std::size_t>(jj);
      const Scalar* q = points.ptr(keys[j]);
      const Eigen::Vector3d p_i(q[0], q[1], q[2]);
      Eigen::Vector3d lambda;
      Eigen::Matrix3d V;
      eigenDescending(momentsAt(tree, q, r2).scatter(), lambda, &V);
      const Eigen::Vector3d v1 = V.col(0), v2 = V.col(1);
      // G_Pij = Σ_{l ∈ N_i} exp(−γ|P_l·Π̂_ij*|) [P_l][P_l]ᵀ (6.9–6.10): Π_i1 ⊥ v2, Π_i2 ⊥ v1.
      Eigen::Matrix<double, 5, 5> D1 = Eigen::Matrix<double, 5, 5>::Zero(), D2 = D1;
      double w1sum = 0, w2sum = 0;
      tree.forEachInRadius(q, r2, [&](std::uint32_t node, Scalar) {
        const Scalar* p = tree.node(node).p;
        const Eigen::Vector3d d(double(p[0]) - q[0], double(p[1]) - q[1], double(p[2]) - q[2]);
        const double w1 = std::exp(-settings.gamma * std::abs(v2.dot(d)));
        const double w2 = std::exp(-settings.gamma * std::abs(v1.dot(d)));
        const Eigen::Vector3d x = d * inv_r;
        Eigen::Matrix<double, 5, 1> P;
        P << x, 0.5 * x.squaredNorm(), 1.0;  // (4.55)
        const Eigen::Matrix<double, 5, 5> PP = P * P.transpose();
        D1.noalias() += w1 * PP;
        D2.noalias() += w2 * PP;
        w1sum += w1;
        w2sum += w2;
      });
      const CbdSphere s1 = fitLocalSphere(D1 / w1sum, p_i, settings.radius, settings.max_sphere_radius);
      const CbdSphere s2 = fitLocalSphere(D2 / w2sum, p_i, settings.radius, settings.max_sphere_radius);
      out.sphere1[j] = s1;
      out.sphere2[j] = s2;
      out.axes[j] = V;
      out.descriptors[j] = Eigen::Vector4d(s1.radius, s1.distance, s2.radius, s2.distance);
      // F = (S1 + S2)·P = ½(r1² − d1²) + ½(r2² − d2²) (6.14–6.16); a flat sphere adds 0.
      double F = 0;
      if (!s1.flat) F += 0.5 * (s1.radius * s1.radius - s1.distance * s1.distance);
      if (!s2.flat) F += 0.5 * (s2.radius * s2.radius - s2.distance * s2.distance);
      out.scalar[j] = F;
    }
  }
  // A descriptor is only handed out finite (coordinates and radius are bounded above, so this
  // is a guard, not an expected path).
  for (std::size_t j = 0; j < nk; ++j)
    if (!out.descriptors[j].allFinite() || !std::isfinite(out.scalar[j]))
      throw std::runtime_error("computeCbd: non-finite descriptor at keypoint " + std::to_string(out.keypoints[j]));
  out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return out;
}

bool sameDescriptors(const CbdSettings& a, const CbdSettings& b) {
  return a.radius == b.radius && a.gamma == b.gamma && a.min_neighbors == b.min_neighbors &&
         a.keypoint_mode == b.keypoint_mode && a.num_keypoints == b.num_keypoints &&
         a.thresholds.linear == b.thresholds.linear && a.thresholds.planar == b.thresholds.planar &&
         a.thresholds.spherical == b.thresholds.spherical && a.max_keypoints == b.max_keypoints &&
         a.max_sphere_radius == b.max_sphere_radius && a.variant == b.variant;
}

CbdMatches matchCbd(const CbdFeatures& source, const CbdFeatures& target, CbdDescriptorVariant variant, int k,
                    int num_threads) {
  if (k < 1) throw std::invalid_argument("matchCbd: k must be >= 1");
  if (num_threads < 0) throw std::invalid_argument("matchCbd: num_threads must be >= 0");
  CbdMatches out;
  const std::size_t ns = source.keypoints.size(), nt = target.keypoints.size();
  if (ns == 0 || nt == 0) return out;
  const int kk = static_cast<int>(std::min<std::size_t>(static_cast<std::size_t>(k), nt));
  std::vector<std::uint32_t> ts(ns * kk);
  std::vector<double> err(ns * kk);
  if (variant == CbdDescriptorVariant::RadiusDistance) {
    const DescriptorTree4 tree(target.descriptors);
#pragma omp parallel num_threads(threadsOf(num_threads))
    {
      std::vector<std::pair<double, std::uint32_t>> nn;
#pragma omp for schedule(static)
      for (std::ptrdiff_t ii = 0; ii < static_cast<std::ptrdiff_t>(ns); ++ii) {
        tree.knn(source.descriptors[ii], kk, nn);
        for (int m = 0; m < kk; ++m) {
          ts[ii * kk + m] = nn[m].second;
          err[ii * kk + m] = nn[m].first;  // e(k, l) of (32): the squared Euclidean distance
        }
      }
    }
  } else {
    // 1-D nearest neighbours of F (6.18) by binary search in the sorted target values.
    std::vector<std::pair<double, std::uint32_t>> sorted(nt);
    for (std::size_t l = 0; l < nt; ++l) sorted[l] = {target.scalar[l], static_cast<std::uint32_t>(l)};
    std::sort(sorted.begin(), sorted.end());
#pragma omp parallel for schedule(static) num_threads(threadsOf(num_threads))
    for (std::ptrdiff_t ii = 0; ii < static_cast<std::ptrdiff_t>(ns); ++ii) {
      const double f = source.scalar[ii];
      std::ptrdiff_t hi = std::lower_bound(sorted.begin(), sorted.end(), std::make_pair(f, std::uint32_t{0})) -
                          sorted.begin();
      std::ptrdiff_t lo = hi - 1;
      for (int m = 0; m < kk; ++m) {
        const bool take_hi = lo < 0 || (hi < static_cast<std::ptrdiff_t>(nt) &&
                                         std::abs(sorted[hi].first - f) <= std::abs(sorted[lo].first - f));
        const auto& pick = take_hi ? sorted[hi++] : sorted[lo--];
        ts[ii * kk + m] = pick.second;
        err[ii * kk + m] = (pick.first - f) * (pick.first - f);
      }
    }
  }
  out.source.resize(ns * kk);
  for (std::size_t i = 0; i < ns; ++i)
    for (int m = 0; m < kk; ++m) out.source[i * kk + m] = static_cast<std::uint32_t>(i);
  out.target = std::move(ts);
  out.error = std::move(err);
  return out;
}

#define SCANALIGN_INSTANTIATE(S)                                                                    \
  template std::vector<NeighbourhoodPca> neighbourhoodPca<S>(const CloudView<S>&, double, int);     \
  template CbdFeatures computeCbd<S>(const CloudView<S>&, const CbdSettings&, const ShapeThresholds*);
SCANALIGN_INSTANTIATE(float)
SCANALIGN_INSTANTIATE(double)
#undef SCANALIGN_INSTANTIATE

}  // namespace scanalign
