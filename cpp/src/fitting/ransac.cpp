// RANSAC models (CGA plane and sphere), least-squares refits, Euclidean clustering and
// the table segmentation pipeline. See ransac.hpp for the equations.
#include "scanalign/fitting/ransac.hpp"
#include "scanalign/fitting/sphere_fit.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numeric>
#include <stdexcept>

#include <Eigen/Dense>

#include "scanalign/registration/kdtree.hpp"

namespace scanalign {

const char* toString(RansacStatus s) {
  switch (s) {
    case RansacStatus::kSuccess: return "success";
    case RansacStatus::kTooFewPoints: return "too_few_points";
    case RansacStatus::kDegenerate: return "degenerate";
  }
  return "unknown";
}

// ---------------------------------------------------------------------------
// Minimal-sample models
// ---------------------------------------------------------------------------

bool planeFromPoints(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c, PlaneModel& out) {
  // Built relative to a (translation covariance of the construction) so that ½p² stays
  // small: the plane through a+x_i is the plane through x_i shifted by a.
  const Eigen::Vector3d o = Eigen::Vector3d::Zero(), bb = b - a, cc = c - a;
  const cga5::Vec5 pi = cga5::dualOfOuter4(cga5::up(o), cga5::up(bb), cga5::up(cc), cga5::eInf());  // (5.35)
  // Pi* = n + delta e_inf with no e0 part; Pi*^2 = |n|^2 (normalisation of (5.36)).
  const double n2 = cga5::inner(pi, pi);
  const double scale = std::max({bb.squaredNorm(), cc.squaredNorm(), (cc - bb).squaredNorm()});
  if (!(scale > 0) || !(n2 > 1e-24 * scale * scale) || !std::isfinite(n2)) return false;  // collinear: Pi = 0
  const double inv = 1.0 / std::sqrt(n2);
  out.normal = pi.head<3>() * inv;
  out.distance = pi[3] * inv + out.normal.dot(a);  // shift back by a: n.(p - a) = delta'
  return true;
}

bool sphereFromPoints(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c,
                      const Eigen::Vector3d& d, SphereModel& out) {
  const Eigen::Vector3d bb = b - a, cc = c - a, dd = d - a;
  const cga5::Vec5 s =
      cga5::dualOfOuter4(cga5::up(Eigen::Vector3d::Zero()), cga5::up(bb), cga5::up(cc), cga5::up(dd));  // (4.58)
  // The e0 coefficient is -det[bb; cc; dd] (the 4x4 minor of the rows [x, 1]).
  const double L = std::max({bb.norm(), cc.norm(), dd.norm()});
  if (!(L > 0) || !(std::abs(s[4]) > 1e-12 * L * L * L) || !std::isfinite(s[4])) return false;  // coplanar
  const cga5::Vec5 v = s / s[4];  // (4.60): e0 coefficient 1
  const double r2 = v.head<3>().squaredNorm() - 2.0 * v[3];
  if (!(r2 > 0) || !std::isfinite(r2)) return false;
  out.center = v.head<3>() + a;
  out.radius = std::sqrt(r2);
  return true;
}

// ---------------------------------------------------------------------------
// Least-squares refits
// ---------------------------------------------------------------------------

template <typename Scalar>
bool fitPlaneLeastSquares(const CloudView<Scalar>& points, const std::vector<std::uint32_t>& indices,
                          PlaneModel& out) {
  if (indices.size() < 3) return false;
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (std::uint32_t i : indices) mean += points[i].template cast<double>();
  mean /= double(indices.size());
  Eigen::Matrix3d C = Eigen::Matrix3d::Zero();
  for (std::uint32_t i : indices) {
    const Eigen::Vector3d d = points[i].template cast<double>() - mean;
    C.noalias() += d * d.transpose();
  }
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(C);
  if (es.info() != Eigen::Success) return false;
  const Eigen::Vector3d ev = es.eigenvalues();
  if (!(ev[1] > 1e-12 * ev[2])) return false;  // collinear inliers: no unique plane
  out.normal = es.eigenvectors().col(0).normalized();
  out.distance = out.normal.dot(mean);
  return true;
}

template <typename Scalar>
bool fitSphereLeastSquares(const CloudView<Scalar>& points, const std::vector<std::uint32_t>& indices,
                           SphereModel& out) {
  // The CGA least-squares sphere of thesis (5.26)-(5.34), as fitSphere() computes it, over
  // the inliers; a plane, an imaginary sphere or degenerate data is a failed refit.
  if (indices.size() < 5) return false;
  std::vector<Scalar> xyz;
  xyz.reserve(3 * indices.size());
  for (std::uint32_t i : indices) xyz.insert(xyz.end(), points.ptr(i), points.ptr(i) + 3);
  try {
    const SphereFit f = fitSphere(CloudView<Scalar>(xyz.data(), indices.size()));
    if (f.is_plane || f.imaginary || !(f.radius > 0.0) || !std::isfinite(f.radius)) return false;
    out.center = f.center;
    out.radius = f.radius;
    return true;
  } catch (const std::invalid_argument&) {
    return false;
  }
}

// ---------------------------------------------------------------------------
// Generic RANSAC helpers
// ---------------------------------------------------------------------------

namespace {
inline std::uint64_t splitmix64(std::uint64_t& x) {
  std::uint64_t z = (x += 0x9E3779B97F4A7C15ull);
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  return z ^ (z >> 31);
}
}  // namespace

void ransacSample(std::uint64_t seed, std::uint64_t k, std::uint32_t n, int s, std::uint32_t* out) {
  std::uint64_t state = seed * 0xD1B54A32D192ED03ull ^ (k + 1) * 0x9E3779B97F4A7C15ull;
  splitmix64(state);
  for (int j = 0; j < s; ++j) {
    for (;;) {
      // Multiply-shift maps 32 random bits to [0, n) (bias < n / 2^32, irrelevant here).
      const std::uint32_t r = static_cast<std::uint32_t>(splitmix64(state) >> 32);
      const std::uint32_t v = static_cast<std::uint32_t>((std::uint64_t(r) * n) >> 32);
      bool dup = false;
      for (int q = 0; q < j; ++q) dup |= out[q] == v;
      if (!dup) {
        out[j] = v;
        break;
      }
    }
  }
}

double ransacRequiredIterations(double w, int s, double confidence) {
  if (!(confidence > 0 && confidence < 1)) return std::numeric_limits<double>::infinity();
  const double ws = std::pow(std::clamp(w, 0.0, 1.0), s);
  if (ws >= 1.0) return 1.0;
  if (ws <= 0.0) return std::numeric_limits<double>::infinity();
  const double denom = std::log1p(-ws);
  if (!(denom < 0)) return std::numeric_limits<double>::infinity();
  return std::ceil(std::log(1.0 - confidence) / denom);
}

// ---------------------------------------------------------------------------
// Plane and sphere RANSAC
// ---------------------------------------------------------------------------

namespace {

/// Finite points copied to double (RANSAC touches every point once per hypothesis; a
/// packed double array keeps that loop simple and exact).
template <typename Scalar>
std::vector<std::uint32_t> finiteIndices(const CloudView<Scalar>& points, std::vector<Eigen::Vector3d>& xyz) {
  std::vector<std::uint32_t> idx;
  idx.reserve(points.size);
  xyz.clear();
  xyz.reserve(points.size);
  for (std::size_t i = 0; i < points.size; ++i)
    if (points.isFinite(i)) {
      idx.push_back(static_cast<std::uint32_t>(i));
      xyz.push_back(points[i].template cast<double>());
    }
  return idx;
}

template <typename Model, typename Err>
std::vector<std::uint32_t> selectInliers(const std::vector<Eigen::Vector3d>& xyz, const std::vector<std::uint32_t>& idx,
                                         const Model& m, double threshold, Err&& err) {
  std::vector<std::uint32_t> out;
  for (std::size_t i = 0; i < xyz.size(); ++i)
    if (err(m, xyz[i]) < threshold) out.push_back(idx[i]);
  return out;
}

}  // namespace

namespace {
/// The loop's outcome into a model's result (shared by every model).
template <typename Model>
void copyLoopStats(const RansacLoopStats& st, RansacResult<Model>& r) {
  r.status = st.status;
  r.iterations = st.iterations;
  r.degenerate_samples = st.degenerate_samples;
  r.hypothesis_inliers = st.best_inliers;
}
}  // namespace

void validate(const RansacSettings& s) {
  if (!(s.threshold > 0) || !std::isfinite(s.threshold))
    throw std::invalid_argument("RANSAC settings: threshold must be a finite positive distance in metres");
  if (s.max_iterations < 1) throw std::invalid_argument("RANSAC settings: max_iterations must be at least 1");
  if (!(s.confidence >= 0 && s.confidence <= 1))
    throw std::invalid_argument("RANSAC settings: confidence must lie in [0, 1] (0 or 1: no adaptive stop)");
}

void validate(const TableSegmentationSettings& s) {
  validate(s.plane);
  auto fail = [](const std::string& what) { throw std::invalid_argument("table segmentation settings: " + what); };
  if (s.crop_min.hasNaN() || s.crop_max.hasNaN()) fail("crop_min and crop_max must not be NaN");
  if (!s.viewpoint.allFinite()) fail("viewpoint must be 3 finite coordinates");
  if (!s.up.allFinite()) fail("up must be 3 finite coordinates");
  if (!(s.cluster_tolerance > 0) || !std::isfinite(s.cluster_tolerance))
    fail("cluster_tolerance must be a finite positive distance in metres");
  if (s.min_cluster_size < 1 || s.max_cluster_size < s.min_cluster_size)
    fail("need 1 <= min_cluster_size <= max_cluster_size");
}

template <typename Scalar>
RansacResult<PlaneModel> ransacPlane(const CloudView<Scalar>& points, const RansacSettings& settings) {
  validate(settings);
  RansacResult<PlaneModel> r;
  std::vector<Eigen::Vector3d> xyz;
  const std::vector<std::uint32_t> idx = finiteIndices(points, xyz);
  auto build = [&](const std::uint32_t* s, PlaneModel& m) { return planeFromPoints(xyz[s[0]], xyz[s[1]], xyz[s[2]], m); };
  // (5.36): |P . Pi*| with |n| = 1 is the Euclidean distance to the plane.
  auto err = [](const PlaneModel& m, const Eigen::Vector3d& p) { return std::abs(m.signedDistance(p)); };
  auto error = [&](const PlaneModel& m, std::size_t i) { return err(m, xyz[i]); };
  const RansacLoopStats st = ransacLoop(xyz.size(), 3, build, error, settings, r.hypothesis);
  copyLoopStats(st, r);
  if (!r.success()) return r;
  r.model = r.hypothesis;
  r.inliers = selectInliers(xyz, idx, r.model, settings.threshold, err);
  if (settings.refine) {
    PlaneModel refit;
    if (fitPlaneLeastSquares(points, r.inliers, refit)) {
      if (refit.normal.dot(r.hypothesis.normal) < 0) {  // keep the hypothesis' orientation
        refit.normal = -refit.normal;
        refit.distance = -refit.distance;
      }
      r.model = refit;
      r.refined = true;
      r.inliers = selectInliers(xyz, idx, r.model, settings.threshold, err);
    }
  }
  return r;
}

template <typename Scalar>
RansacResult<SphereModel> ransacSphere(const CloudView<Scalar>& points, const RansacSettings& settings,
                                       const SphereLimits& limits) {
  validate(settings);
  if (!(limits.min_radius >= 0) || !(limits.max_radius > limits.min_radius))
    throw std::invalid_argument("ransacSphere: need 0 <= min_radius < max_radius (metres)");
  RansacResult<SphereModel> r;
  std::vector<Eigen::Vector3d> xyz;
  const std::vector<std::uint32_t> idx = finiteIndices(points, xyz);
  const double thr = settings.threshold;
  auto inLimits = [&](const SphereModel& m) { return m.radius >= limits.min_radius && m.radius <= limits.max_radius; };
  auto build = [&](const std::uint32_t* s, SphereModel& m) {
    const Eigen::Vector3d p[4] = {xyz[s[0]], xyz[s[1]], xyz[s[2]], xyz[s[3]]};
    // Degenerate when the four points lie within the threshold of one plane (their
    // least-squares plane): such a sample cannot tell a sphere from a plane.
    const Eigen::Vector3d mean = 0.25 * (p[0] + p[1] + p[2] + p[3]);
    Eigen::Matrix3d C = Eigen::Matrix3d::Zero();
    for (const auto& q : p) C.noalias() += (q - mean) * (q - mean).transpose();
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(C);
    const Eigen::Vector3d nrm = es.eigenvectors().col(0);
    double off = 0;
    for (const auto& q : p) off = std::max(off, std::abs(nrm.dot(q - mean)));
    if (off < thr) return false;
    return sphereFromPoints(p[0], p[1], p[2], p[3], m) && inLimits(m);
  };
  auto err = [](const SphereModel& m, const Eigen::Vector3d& p) { return m.surfaceDistance(p); };
  auto error = [&](const SphereModel& m, std::size_t i) { return err(m, xyz[i]); };
  const RansacLoopStats st = ransacLoop(xyz.size(), 4, build, error, settings, r.hypothesis);
  copyLoopStats(st, r);
  if (!r.success()) return r;
  r.model = r.hypothesis;
  r.inliers = selectInliers(xyz, idx, r.model, thr, err);
  if (settings.refine) {
    SphereModel refit;
    if (fitSphereLeastSquares(points, r.inliers, refit) && inLimits(refit)) {
      r.model = refit;
      r.refined = true;
      r.inliers = selectInliers(xyz, idx, r.model, thr, err);
    }
  }
  return r;
}

// ---------------------------------------------------------------------------
// Euclidean clustering and table segmentation
// ---------------------------------------------------------------------------

namespace {

/// Clusters of input indices in the documented order: ascending indices within a cluster;
/// clusters by decreasing size, ties by smallest first index; sizes within [min, max].
std::vector<std::vector<std::uint32_t>> orderClusters(std::vector<std::vector<std::uint32_t>> all,
                                                      std::size_t min_size, std::size_t max_size) {
  std::vector<std::vector<std::uint32_t>> clusters;
  for (auto& c : all)
    if (c.size() >= min_size && c.size() <= max_size) {
      std::sort(c.begin(), c.end());
      clusters.push_back(std::move(c));
    }
  std::sort(clusters.begin(), clusters.end(), [](const auto& a, const auto& b) {
    return a.size() != b.size() ? a.size() > b.size() : a.front() < b.front();
  });
  return clusters;
}

/// Region growing on the k-d tree (PCL's EuclideanClusterExtraction): every point's whole
/// radius neighbourhood is visited, so a tolerance that links most points to most others
/// costs O(N^2). Kept only for clouds whose extent is beyond 2^52 tolerance-sized cells,
/// where the cell grid below cannot index cells.
template <typename Scalar>
std::vector<std::vector<std::uint32_t>> regionGrowing(const CloudView<Scalar>& points,
                                                      const std::vector<std::uint32_t>& sel, Scalar r2) {
  LeftBalancedKdTree<Scalar> tree;
  std::vector<char> selected(points.size, 0);
  for (std::uint32_t i : sel) selected[i] = 1;
  tree.build(points, [&](std::size_t i) { return selected[i] != 0; });
  std::vector<char> visited(points.size, 0);
  std::vector<std::vector<std::uint32_t>> all;
  for (std::uint32_t seed : sel) {
    if (visited[seed]) continue;
    checkInterrupt();
    std::vector<std::uint32_t> cluster{seed};
    visited[seed] = 1;
    for (std::size_t head = 0; head < cluster.size(); ++head)
      tree.forEachInRadius(points.ptr(cluster[head]), r2, [&](std::uint32_t node, Scalar) {
        const std::uint32_t j = tree.node(node).index();
        if (!visited[j]) {
          visited[j] = 1;
          cluster.push_back(j);
        }
      });
    all.push_back(std::move(cluster));
  }
  return all;
}

}  // namespace

// Connected components of the graph "|p - q| <= tolerance" (the links PCL's region growing
// follows) by union-find over a grid of cells of edge a bit under tolerance / sqrt(3):
// any two points of one cell are closer than tolerance, so each cell is one node, and only
// cells within 2 cells of each other along every axis can hold linked points. A pair of cells
// already in one component is never tested; otherwise the first linked pair ends the test.
// So the cost is O(N log N) in the number of points whatever the tolerance -- region
// growing visits every neighbour of every point, O(N^2) once the tolerance spans the scene
// (200k points: minutes). Pairs of large cells are tested through a k-d tree over the
// larger one, so no pair costs more than (smaller cell) x log(larger cell). The links are
// decided by the same test in the cloud's precision as the k-d tree's radius search, so
// the clusters are those of region growing.
template <typename Scalar>
std::vector<std::vector<std::uint32_t>> euclideanClusters(const CloudView<Scalar>& points,
                                                          const std::vector<std::uint32_t>& indices,
                                                          double tolerance, std::size_t min_size,
                                                          std::size_t max_size) {
  if (indices.empty()) return {};
  if (!(tolerance > 0) || !std::isfinite(tolerance))
    throw std::invalid_argument("euclideanClusters: tolerance must be a finite positive distance in metres");
  std::vector<std::uint32_t> sel;
  sel.reserve(indices.size());
  for (std::uint32_t i : indices) {
    if (i >= points.size) throw std::invalid_argument("euclideanClusters: index out of range");
    if (points.isFinite(i)) sel.push_back(i);
  }
  std::sort(sel.begin(), sel.end());
  sel.erase(std::unique(sel.begin(), sel.end()), sel.end());
  if (sel.empty()) return {};
  const Scalar r2 = static_cast<Scalar>(tolerance * tolerance);
  // Cell edge: the cell's diagonal is tolerance (1 - 1e-6), a margin far above the rounding
  // of the squared-distance test, so points of one cell are always linked.
  const double edge = tolerance / std::sqrt(3.0) * (1.0 - 1e-6);
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity());
  for (std::uint32_t i : sel) lo = lo.cwiseMin(points[i].template cast<double>());
  struct Keyed {
    std::int64_t z, y, x;
    std::uint32_t i;
  };
  std::vector<Keyed> keyed(sel.size());
  for (std::size_t j = 0; j < sel.size(); ++j) {
    const Eigen::Vector3d c = ((points[sel[j]].template cast<double>() - lo) / edge).array().floor();
    if (!(c.maxCoeff() < 4503599627370496.0))  // 2^52: cells no longer indexable
      return orderClusters(regionGrowing(points, sel, r2), min_size, max_size);
    keyed[j] = {static_cast<std::int64_t>(c.z()), static_cast<std::int64_t>(c.y()), static_cast<std::int64_t>(c.x()),
                sel[j]};
  }
  auto before = [](const Keyed& a, const Keyed& b) {
    return a.z != b.z ? a.z < b.z : (a.y != b.y ? a.y < b.y : a.x < b.x);
  };
  std::sort(keyed.begin(), keyed.end(), [&](const Keyed& a, const Keyed& b) {
    return before(a, b) || (!before(b, a) && a.i < b.i);
  });
  // Cells (contiguous runs of keyed) and their points, packed in the cloud's precision.
  std::vector<std::uint32_t> cell_start;
  for (std::size_t j = 0; j < keyed.size(); ++j)
    if (j == 0 || before(keyed[j - 1], keyed[j])) cell_start.push_back(static_cast<std::uint32_t>(j));
  const std::size_t nc = cell_start.size();
  cell_start.push_back(static_cast<std::uint32_t>(keyed.size()));
  std::vector<Scalar> packed(3 * keyed.size());
  for (std::size_t j = 0; j < keyed.size(); ++j)
    for (int k = 0; k < 3; ++k) packed[3 * j + k] = points.ptr(keyed[j].i)[k];
  std::vector<std::uint32_t> parent(nc);
  std::iota(parent.begin(), parent.end(), 0u);
  auto find = [&](std::uint32_t c) {
    while (parent[c] != c) c = parent[c] = parent[parent[c]];
    return c;
  };
  std::vector<LeftBalancedKdTree<Scalar>> trees(nc);  // built on demand, for large cells
  const Scalar below_r2 = std::nextafter(r2, std::numeric_limits<Scalar>::infinity());  // nearest() is strict
  auto linked = [&](std::size_t a, std::size_t b) {
    std::size_t na = cell_start[a + 1] - cell_start[a], nb = cell_start[b + 1] - cell_start[b];
    if (na > nb) {
      std::swap(a, b);
      std::swap(na, nb);
    }
    const Scalar* pa = &packed[3 * std::size_t{cell_start[a]}];
    const Scalar* pb = &packed[3 * std::size_t{cell_start[b]}];
    if (na * nb <= 4096) {
      for (std::size_t u = 0; u < na; ++u)
        for (std::size_t v = 0; v < nb; ++v)
          if (detail::squaredDistance(pa + 3 * u, pb + 3 * v) <= r2) return true;
      return false;
    }
    if (trees[b].empty()) trees[b].build(CloudView<Scalar>(pb, nb, 3));
    for (std::size_t u = 0; u < na; ++u)
      if (trees[b].nearest(pa + 3 * u, below_r2, LeftBalancedKdTree<Scalar>::kMaxStack).found()) return true;
    return false;
  };
  // Each pair of cells once: cell b after cell a in (z, y, x) order, in the 13 rows
  // (dz, dy) at or after a's own. For a fixed row offset, the first candidate (z + dz,
  // y + dy, x - 2) grows with a, so one pointer per row walks the cells once. Near pairs
  // (within one cell along every axis) first: on dense data they join almost every
  // component, so the farther pairs, which are the expensive ones to refute, are mostly
  // skipped as already joined.
  for (const std::int64_t reach : {1, 2}) {
    for (std::int64_t dz = 0; dz <= reach; ++dz)
      for (std::int64_t dy = dz == 0 ? 0 : -reach; dy <= reach; ++dy) {
        std::size_t next = 0;  // first cell not before the current row window
        for (std::size_t a = 0; a < nc; ++a) {
          if (a % 4096 == 0) checkInterrupt();
          const Keyed& ka = keyed[cell_start[a]];
          const std::int64_t x0 = dz == 0 && dy == 0 ? ka.x + 1 : ka.x - reach;
          const Keyed first{ka.z + dz, ka.y + dy, x0, 0};
          while (next < nc && before(keyed[cell_start[next]], first)) ++next;
          for (std::size_t b = next; b < nc; ++b) {
            const Keyed& kb = keyed[cell_start[b]];
            if (kb.z != first.z || kb.y != first.y || kb.x > ka.x + reach) break;
            // Pairs within one cell along every axis belong to the first pass only.
            if (reach == 2 && std::abs(dz) < 2 && std::abs(dy) < 2 && std::abs(kb.x - ka.x) < 2) continue;
            const std::uint32_t ra = find(static_cast<std::uint32_t>(a)), rb = find(static_cast<std::uint32_t>(b));
            if (ra != rb && linked(a, b)) parent[std::max(ra, rb)] = std::min(ra, rb);
          }
        }
      }
  }
  std::vector<std::vector<std::uint32_t>> all;
  std::vector<std::int64_t> slot(nc, -1);
  for (std::size_t c = 0; c < nc; ++c) {
    const std::uint32_t r = find(static_cast<std::uint32_t>(c));
    if (slot[r] < 0) {
      slot[r] = static_cast<std::int64_t>(all.size());
      all.emplace_back();
    }
    auto& cluster = all[static_cast<std::size_t>(slot[r])];
    for (std::uint32_t j = cell_start[c]; j < cell_start[c + 1]; ++j) cluster.push_back(keyed[j].i);
  }
  return orderClusters(std::move(all), min_size, max_size);
}

template <typename Scalar>
TableSegmentation segmentTable(const CloudView<Scalar>& points, const TableSegmentationSettings& s) {
  validate(s);
  TableSegmentation out;
  // (1) pass-through crop.
  std::vector<std::uint32_t> kept;
  std::vector<Scalar> packed;
  for (std::size_t i = 0; i < points.size; ++i) {
    if (!points.isFinite(i)) continue;
    const Eigen::Vector3d p = points[i].template cast<double>();
    if (s.crop && ((p.array() < s.crop_min.array()).any() || (p.array() > s.crop_max.array()).any())) continue;
    kept.push_back(static_cast<std::uint32_t>(i));
    packed.insert(packed.end(), {points.ptr(i)[0], points.ptr(i)[1], points.ptr(i)[2]});
  }
  out.cropped_points = kept.size();
  const CloudView<Scalar> view(packed.empty() ? nullptr : packed.data(), kept.size(), 3);
  // (2) dominant plane.
  out.plane = ransacPlane(view, s.plane);
  out.status = out.plane.status;
  if (!out.success()) return out;
  PlaneModel& pl = out.plane.model;
  // Orient the normal up, or towards the viewpoint (P3: "orient v toward the camera").
  const bool flip = s.up.squaredNorm() > 0 ? pl.normal.dot(s.up) < 0 : pl.signedDistance(s.viewpoint) < 0;
  if (flip) {
    pl.normal = -pl.normal;
    pl.distance = -pl.distance;
    out.plane.hypothesis.normal = -out.plane.hypothesis.normal;
    out.plane.hypothesis.distance = -out.plane.hypothesis.distance;
  }
  // (3) remove the inliers and everything below: keep signed distance >= threshold.
  std::vector<std::uint32_t> above;
  for (std::size_t i = 0; i < kept.size(); ++i)
    if (pl.signedDistance(view[i].template cast<double>()) >= s.plane.threshold)
      above.push_back(static_cast<std::uint32_t>(i));
  out.above_points = above.size();
  // (4)-(5) Euclidean clustering, small/large clusters dropped.
  out.objects = euclideanClusters(view, above, s.cluster_tolerance, s.min_cluster_size, s.max_cluster_size);
  for (auto& c : out.objects)
    for (auto& i : c) i = kept[i];  // back to input indices (kept is ascending: order preserved)
  for (auto& i : out.plane.inliers) i = kept[i];
  return out;
}

#define SCANALIGN_INSTANTIATE(S)                                                                                   \
  template bool fitPlaneLeastSquares<S>(const CloudView<S>&, const std::vector<std::uint32_t>&, PlaneModel&);      \
  template bool fitSphereLeastSquares<S>(const CloudView<S>&, const std::vector<std::uint32_t>&, SphereModel&);    \
  template RansacResult<PlaneModel> ransacPlane<S>(const CloudView<S>&, const RansacSettings&);                    \
  template RansacResult<SphereModel> ransacSphere<S>(const CloudView<S>&, const RansacSettings&,                   \
                                                     const SphereLimits&);                                         \
  template std::vector<std::vector<std::uint32_t>> euclideanClusters<S>(                                           \
      const CloudView<S>&, const std::vector<std::uint32_t>&, double, std::size_t, std::size_t);                   \
  template TableSegmentation segmentTable<S>(const CloudView<S>&, const TableSegmentationSettings&);
SCANALIGN_INSTANTIATE(float)
SCANALIGN_INSTANTIATE(double)
#undef SCANALIGN_INSTANTIATE

}  // namespace scanalign
