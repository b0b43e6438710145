// RANSAC models (CGA plane and sphere) and their least-squares refits. See ransac.hpp for
// the equations.
#include "scanalign/segmentation/ransac.hpp"
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
    const SphereFitResult f = fitSphere(CloudView<Scalar>(xyz.data(), indices.size()));
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

#define SCANALIGN_INSTANTIATE(S)                                                                                   \
  template bool fitPlaneLeastSquares<S>(const CloudView<S>&, const std::vector<std::uint32_t>&, PlaneModel&);      \
  template bool fitSphereLeastSquares<S>(const CloudView<S>&, const std::vector<std::uint32_t>&, SphereModel&);    \
  template RansacResult<PlaneModel> ransacPlane<S>(const CloudView<S>&, const RansacSettings&);                    \
  template RansacResult<SphereModel> ransacSphere<S>(const CloudView<S>&, const RansacSettings&,                   \
                                                     const SphereLimits&);
SCANALIGN_INSTANTIATE(float)
SCANALIGN_INSTANTIATE(double)
#undef SCANALIGN_INSTANTIATE

}  // namespace scanalign
