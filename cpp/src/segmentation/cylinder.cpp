// RANSAC cylinders and their least-squares refit. See cylinder.hpp.
#include "scanalign/segmentation/cylinder.hpp"

#include <cmath>
#include <stdexcept>
#include <string>

#include <Eigen/Dense>

#include "scanalign/features/normals.hpp"

namespace scanalign {

void validate(const CylinderSettings& s) {
  validate(s.ransac);
  auto fail = [](const std::string& what) { throw std::invalid_argument("cylinder settings: " + what); };
  if (!(s.min_radius >= 0) || !(s.max_radius > s.min_radius)) fail("need 0 <= min_radius < max_radius (metres)");
  if (!(s.max_normal_angle > 0) || !(s.max_normal_angle <= M_PI / 2))
    fail("max_normal_angle must lie in (0, pi/2] radians");
  if (!(s.normal_radius > 0) || !std::isfinite(s.normal_radius))
    fail("normal_radius must be a finite positive distance in metres");
}

bool cylinderFromOrientedPoints(const Eigen::Vector3d& p1, const Eigen::Vector3d& n1, const Eigen::Vector3d& p2,
                                const Eigen::Vector3d& n2, double tolerance, CylinderModel& out) {
  const double l1 = n1.norm(), l2 = n2.norm();
  if (!(l1 > 0) || !(l2 > 0)) return false;
  const Eigen::Vector3d u1 = n1 / l1, u2 = n2 / l2;
  const Eigen::Vector3d axis = u1.cross(u2);
  const double s = axis.norm();
  if (!(s > 0.0175)) return false;  // normals within ~1 degree of parallel: a plane or a sphere's cap
  // Closest points p1 + t u1 and p2 + v u2 of the normal lines (both meet the true axis).
  const Eigen::Vector3d w = p1 - p2;
  const double b = u1.dot(u2), d = u1.dot(w), e = u2.dot(w), den = 1.0 - b * b;
  const double t = (b * e - d) / den, v = (e - b * d) / den;
  CylinderModel m;
  m.axis = axis / s;
  m.point = 0.5 * ((p1 + t * u1) + (p2 + v * u2));
  const double r1 = m.axisDistance(p1), r2 = m.axisDistance(p2);
  if (!(std::abs(r1 - r2) <= tolerance) || !std::isfinite(r1 + r2)) return false;
  m.radius = 0.5 * (r1 + r2);
  if (!(m.radius > 0)) return false;
  out = m;
  return true;
}

namespace {

/// Two unit vectors completing `a` to an orthonormal basis.
void basisOf(const Eigen::Vector3d& a, Eigen::Vector3d& e1, Eigen::Vector3d& e2) {
  e1 = (std::abs(a.x()) < 0.9 ? Eigen::Vector3d::UnitX() : Eigen::Vector3d::UnitY()).cross(a).normalized();
  e2 = a.cross(e1);
}

double cylinderCost(const std::vector<Eigen::Vector3d>& p, const CylinderModel& m) {
  double c = 0;
  for (const auto& q : p) c += std::pow(m.axisDistance(q) - m.radius, 2);
  return c;
}

}  // namespace

template <typename Scalar>
bool fitCylinderLeastSquares(const CloudView<Scalar>& points, const std::vector<std::uint32_t>& indices,
                             CylinderModel& model, int max_iterations) {
  if (indices.size() < 5 || !model.point.allFinite() || !model.axis.allFinite() || !(model.axis.norm() > 0))
    return false;
  std::vector<Eigen::Vector3d> p;
  p.reserve(indices.size());
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
  for (std::uint32_t i : indices) {
    p.push_back(points[i].template cast<double>());
    centroid += p.back();
  }
  centroid /= double(p.size());
  CylinderModel m = model;
  m.axis.normalize();
  double cost = cylinderCost(p, m);
  const double initial = cost;
  double lambda = 1e-3;
  for (int it = 0; it < max_iterations; ++it) {
    Eigen::Vector3d e1, e2;
    basisOf(m.axis, e1, e2);
    Eigen::Matrix<double, 5, 5> JtJ = Eigen::Matrix<double, 5, 5>::Zero();
    Eigen::Matrix<double, 5, 1> Jtf = Eigen::Matrix<double, 5, 1>::Zero();
    for (const auto& q : p) {
      const Eigen::Vector3d d = q - m.point;
      const double along = d.dot(m.axis);
      const Eigen::Vector3d radial = d - along * m.axis;
      const double rho = radial.norm();
      if (!(rho > 0)) continue;  // on the axis: no gradient
      const Eigen::Vector3d u = radial / rho;
      // d rho / d(theta1, theta2, u1, u2, r) for axis a + theta e, point c + u e.
      Eigen::Matrix<double, 5, 1> J;
      J << -along * u.dot(e1), -along * u.dot(e2), -u.dot(e1), -u.dot(e2), -1.0;
      JtJ.noalias() += J * J.transpose();
      Jtf.noalias() += J * (rho - m.radius);
    }
    bool improved = false;
    for (int tries = 0; tries < 10 && !improved; ++tries) {
      Eigen::Matrix<double, 5, 5> A = JtJ;
      A.diagonal() += lambda * JtJ.diagonal().cwiseMax(1e-12);
      const Eigen::Matrix<double, 5, 1> step = A.ldlt().solve(-Jtf);
      if (!step.allFinite()) break;
      CylinderModel next = m;
      next.axis = (m.axis + step[0] * e1 + step[1] * e2).normalized();
      next.point = m.point + step[2] * e1 + step[3] * e2;
      next.radius = m.radius + step[4];
      const double c = next.radius > 0 ? cylinderCost(p, next) : std::numeric_limits<double>::infinity();
      if (c < cost) {
        const bool converged = cost - c <= 1e-12 * cost;
        m = next;
        cost = c;
        lambda = std::max(lambda / 3, 1e-12);
        improved = true;
        if (converged) it = max_iterations;
      } else {
        lambda *= 4;
      }
    }
    if (!improved) break;
  }
  if (!(cost <= initial) || !m.point.allFinite() || !m.axis.allFinite() || !std::isfinite(m.radius)) return false;
  m.point += (centroid - m.point).dot(m.axis) * m.axis;  // the foot of the centroid: a readable axis point
  model = m;
  return true;
}

template <typename Scalar>
RansacResult<CylinderModel> ransacCylinder(const CloudView<Scalar>& points, const CloudView<Scalar>& normals,
                                           const CylinderSettings& settings) {
  validate(settings);
  if (normals.size != points.size) throw std::invalid_argument("ransacCylinder: need one normal per point");
  RansacResult<CylinderModel> r;
  std::vector<Eigen::Vector3d> xyz, nrm;
  std::vector<std::uint32_t> idx;
  for (std::size_t i = 0; i < points.size; ++i) {
    if (!points.isFinite(i) || !normals.isFinite(i)) continue;
    const Eigen::Vector3d n = normals[i].template cast<double>();
    if (!(n.norm() > 0)) continue;
    idx.push_back(static_cast<std::uint32_t>(i));
    xyz.push_back(points[i].template cast<double>());
    nrm.push_back(n.normalized());
  }
  const double thr = settings.ransac.threshold, cos_max = std::cos(settings.max_normal_angle);
  auto inLimits = [&](const CylinderModel& m) {
    return m.radius >= settings.min_radius && m.radius <= settings.max_radius;
  };
  auto build = [&](const std::uint32_t* s, CylinderModel& m) {
    return cylinderFromOrientedPoints(xyz[s[0]], nrm[s[0]], xyz[s[1]], nrm[s[1]], thr, m) && inLimits(m);
  };
  // The surface distance; a point whose normal is not radial is no inlier whatever its distance.
  auto error = [&](const CylinderModel& m, std::size_t i) {
    const Eigen::Vector3d d = xyz[i] - m.point;
    const Eigen::Vector3d radial = d - d.dot(m.axis) * m.axis;
    const double rho = radial.norm();
    const double e = std::abs(rho - m.radius);
    if (e >= thr) return e;
    return std::abs(nrm[i].dot(radial)) >= cos_max * rho ? e : std::numeric_limits<double>::infinity();
  };
  auto inliersOf = [&](const CylinderModel& m) {
    std::vector<std::uint32_t> out;
    for (std::size_t i = 0; i < xyz.size(); ++i)
      if (error(m, i) < thr) out.push_back(idx[i]);
    return out;
  };
  const RansacLoopStats st = ransacLoop(xyz.size(), 2, build, error, settings.ransac, r.hypothesis);
  r.status = st.status;
  r.iterations = st.iterations;
  r.degenerate_samples = st.degenerate_samples;
  r.hypothesis_inliers = st.best_inliers;
  if (!r.success()) return r;
  r.model = r.hypothesis;
  r.inliers = inliersOf(r.model);
  // Refit and re-select until the inliers settle (at most 3 rounds): a two-point hypothesis
  // on noisy data is far from the optimum, and its inlier set is not the refit's.
  for (int round = 0; settings.ransac.refine && round < 3; ++round) {
    CylinderModel refit = r.model;
    if (!fitCylinderLeastSquares(points, r.inliers, refit) || !inLimits(refit)) break;
    std::vector<std::uint32_t> inliers = inliersOf(refit);
    if (inliers.size() < r.inliers.size() && r.refined) break;  // the previous round was better
    r.model = refit;
    r.refined = true;
    const bool settled = inliers == r.inliers;
    r.inliers = std::move(inliers);
    if (settled) break;
  }
  return r;
}

template <typename Scalar>
RansacResult<CylinderModel> ransacCylinder(const CloudView<Scalar>& points, const CylinderSettings& settings) {
  validate(settings);
  NormalEstimationSettings ns;
  ns.radius = settings.normal_radius;
  ns.num_threads = settings.ransac.num_threads;
  std::vector<Scalar> normals(3 * points.size);
  if (!points.empty()) estimateNormals(points, ns, normals.data());
  return ransacCylinder(points, CloudView<Scalar>(normals.empty() ? nullptr : normals.data(), points.size), settings);
}

#define SCANALIGN_INSTANTIATE(S)                                                                                  \
  template bool fitCylinderLeastSquares<S>(const CloudView<S>&, const std::vector<std::uint32_t>&, CylinderModel&, \
                                           int);                                                                  \
  template RansacResult<CylinderModel> ransacCylinder<S>(const CloudView<S>&, const CloudView<S>&,               \
                                                         const CylinderSettings&);                                \
  template RansacResult<CylinderModel> ransacCylinder<S>(const CloudView<S>&, const CylinderSettings&);
SCANALIGN_INSTANTIATE(float)
SCANALIGN_INSTANTIATE(double)
#undef SCANALIGN_INSTANTIATE

}  // namespace scanalign
