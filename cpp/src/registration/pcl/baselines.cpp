// Stock PCL ICP baselines (the eye-in-hand paper (Comput. Electron. Agric. 180 (2021) 105929),
// §3.7, §4): the only other file that pays for PCL's
// registration templates.
#include "scanalign/registration/pcl/baselines.hpp"

#include <chrono>
#include <stdexcept>
#include <type_traits>
#include <vector>

#include <Eigen/Eigenvalues>

#include <pcl/point_types.h>
#include <pcl/registration/icp.h>
#include <pcl/registration/transformation_estimation_dual_quaternion.h>
#include <pcl/registration/transformation_estimation_point_to_plane_lls.h>
#include <pcl/registration/transformation_estimation_svd.h>

#include "scanalign/common/interrupt.hpp"
#include "scanalign/common/rigid.hpp"
#include "scanalign/registration/pcl/box_rejector.hpp"
#include "scanalign/registration/pcl/point_to_plane_lls.hpp"

namespace scanalign {

namespace {

/// Gives read access to the iteration count PCL keeps protected.
template <class Registration>
struct WithIterations : Registration {
  int iterations() const { return this->nr_iterations_; }
};

/// Wraps a PCL estimator so a non-finite step (an undetermined LLS system on unrelated or
/// degenerate correspondences) becomes no step: PCL would apply it, move the source to NaN
/// and assert in its k-d tree on the next iteration. The run is then reported degenerate.
template <typename PointT>
class FiniteStep : public pcl::registration::TransformationEstimation<PointT, PointT, float> {
 public:
  using Base = pcl::registration::TransformationEstimation<PointT, PointT, float>;
  using Cloud = pcl::PointCloud<PointT>;
  using Matrix4 = typename Base::Matrix4;
  explicit FiniteStep(typename Base::Ptr inner) : inner_(std::move(inner)) {}
  bool failed() const { return failed_; }

  void estimateRigidTransformation(const Cloud& s, const Cloud& t, Matrix4& T) const override {
    inner_->estimateRigidTransformation(s, t, T);
    guard(T);
  }
  void estimateRigidTransformation(const Cloud& s, const pcl::Indices& is, const Cloud& t, Matrix4& T) const override {
    inner_->estimateRigidTransformation(s, is, t, T);
    guard(T);
  }
  void estimateRigidTransformation(const Cloud& s, const pcl::Indices& is, const Cloud& t, const pcl::Indices& it,
                                   Matrix4& T) const override {
    inner_->estimateRigidTransformation(s, is, t, it, T);
    guard(T);
  }
  void estimateRigidTransformation(const Cloud& s, const Cloud& t, const pcl::Correspondences& c, Matrix4& T) const override {
    inner_->estimateRigidTransformation(s, t, c, T);
    guard(T);
  }

 private:
  void guard(Matrix4& T) const {
    checkInterrupt();  // once per PCL iteration: Ctrl-C stops a long baseline run
    if (T.allFinite()) return;
    T.setIdentity();
    failed_ = true;
  }
  typename Base::Ptr inner_;
  mutable bool failed_ = false;
};

template <typename PointT, class Registration, class Estimator>
std::shared_ptr<FiniteStep<PointT>> guardSteps(Registration& icp, pcl::shared_ptr<Estimator> inner) {
  auto guard = pcl::make_shared<FiniteStep<PointT>>(std::move(inner));
  icp.setTransformationEstimation(guard);
  return guard;
}

template <typename PointT>
typename pcl::PointCloud<PointT>::Ptr toCloud(const CloudView<float>& points, const CloudView<float>& normals) {
  auto cloud = pcl::make_shared<pcl::PointCloud<PointT>>();
  cloud->resize(points.size);
  for (std::size_t i = 0; i < points.size; ++i) {
    PointT& p = (*cloud)[i];
    p.x = points.ptr(i)[0];
    p.y = points.ptr(i)[1];
    p.z = points.ptr(i)[2];
    if constexpr (std::is_same_v<PointT, pcl::PointNormal>) {
      p.normal_x = normals.empty() ? 0.f : normals.ptr(i)[0];
      p.normal_y = normals.empty() ? 0.f : normals.ptr(i)[1];
      p.normal_z = normals.empty() ? 0.f : normals.ptr(i)[2];
      p.curvature = 0.f;
    }
  }
  cloud->is_dense = false;
  return cloud;
}

IcpStatus fromPcl(pcl::registration::DefaultConvergenceCriteria<float>::ConvergenceState state) {
  using CC = pcl::registration::DefaultConvergenceCriteria<float>;
  switch (state) {
    case CC::CONVERGENCE_CRITERIA_TRANSFORM: return IcpStatus::ConvergedTransform;
    case CC::CONVERGENCE_CRITERIA_ABS_MSE: return IcpStatus::ConvergedAbsoluteMse;
    case CC::CONVERGENCE_CRITERIA_REL_MSE: return IcpStatus::ConvergedRelativeMse;
    case CC::CONVERGENCE_CRITERIA_NO_CORRESPONDENCES: return IcpStatus::NotEnoughCorrespondences;
    default: return IcpStatus::MaxIterations;
  }
}

/// The usable part of a cloud for PCL: finite points (with, for point-to-plane targets, a
/// finite non-zero normal). PCL asserts on a non-finite point, so none may reach it.
struct Usable {
  std::vector<float> points, normals;
  std::size_t size() const { return points.size() / 3; }
  CloudView<float> view() const { return {points.data(), size()}; }
  CloudView<float> normalView() const { return normals.empty() ? CloudView<float>() : CloudView<float>(normals.data(), size()); }
};

Usable usable(const CloudView<float>& points, const CloudView<float>& normals, bool need_normals) {
  Usable u;
  for (std::size_t i = 0; i < points.size; ++i) {
    if (!points.isFinite(i)) continue;
    if (need_normals && (!normals.isFinite(i) || normals[i].squaredNorm() == 0.f)) continue;
    u.points.insert(u.points.end(), points.ptr(i), points.ptr(i) + 3);
    if (need_normals) u.normals.insert(u.normals.end(), normals.ptr(i), normals.ptr(i) + 3);
  }
  return u;
}

/// A rigid motion is determined only by points spanning a plane: identical or collinear
/// points leave a rotation free (the second eigenvalue of their scatter vanishes).
bool spansAPlane(const CloudView<float>& c) {
  if (c.size < 3) return false;
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (std::size_t i = 0; i < c.size; ++i) mean += c[i].cast<double>();
  mean /= double(c.size);
  Eigen::Matrix3d S = Eigen::Matrix3d::Zero();
  for (std::size_t i = 0; i < c.size; ++i) {
    const Eigen::Vector3d d = c[i].cast<double>() - mean;
    S += d * d.transpose();
  }
  const Eigen::Vector3d ev = Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(S).eigenvalues();  // ascending
  return ev(2) > 0 && ev(1) > 1e-10 * ev(2);
}

/// The engine's quality figures at T (the same measure for PCL and scanalign runs).
IcpResult evaluateAt(const CloudView<float>& source, const CloudView<float>& target, Eigen::Matrix4d T,
                     const IcpSettings& settings) {
  Icp<float> evaluator(settings);
  evaluator.settings().estimator = IcpEstimator::PointToPoint;
  evaluator.settings().max_iterations = 0;
  evaluator.setTarget(target);
  // PCL composes in float; re-orthonormalise so the evaluator accepts it as rigid.
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(T.topLeftCorner<3, 3>(), Eigen::ComputeFullU | Eigen::ComputeFullV);
  T.topLeftCorner<3, 3>() = svd.matrixU() * svd.matrixV().transpose();
  return evaluator.align(source, T);
}

template <typename PointT, class Registration, class Estimator>
IcpResult runPcl(Registration& icp, pcl::shared_ptr<Estimator> estimator, const CloudView<float>& source_in,
                 const CloudView<float>& target_in, const CloudView<float>& target_normals, const Eigen::Matrix4d& init,
                 const IcpSettings& settings) {
  constexpr bool plane = std::is_same_v<PointT, pcl::PointNormal>;
  const Usable source = usable(source_in, {}, false), target = usable(target_in, target_normals, plane);
  // As Icp::setTarget: a target with nothing usable is bad input, not a status.
  if (target.size() == 0)
    throw std::invalid_argument(plane ? "PCL ICP target: no point with finite coordinates and a valid normal"
                                      : "PCL ICP target: no point with finite coordinates");
  // An undetermined problem is a status, not a run: too few points (3 pairs fix a rigid
  // motion; point-to-plane constrains one direction per pair, so 6), or points that do not
  // span a plane, on either side.
  const std::size_t needed = plane ? 6 : 3;
  if (source.size() < needed || target.size() < needed || !spansAPlane(source.view()) || !spansAPlane(target.view())) {
    IcpResult result = target.size() ? evaluateAt(source.view(), target.view(), init, settings) : IcpResult{};
    result.T_target_source = init;
    result.status = IcpStatus::NotEnoughCorrespondences;
    result.converged = false;
    result.iterations = 0;
    result.degenerate = source.size() >= needed && target.size() >= needed;
    result.min_rank = 0;
    return result;
  }
  const auto src = toCloud<PointT>(source.view(), {});
  const auto tgt = toCloud<PointT>(target.view(), target.normalView());
  const auto steps = guardSteps<PointT>(icp, std::move(estimator));
  icp.setMaxCorrespondenceDistance(settings.max_correspondence_distance);
  icp.setMaximumIterations(settings.max_iterations);
  icp.setTransformationEpsilon(settings.transformation_epsilon);
  if (settings.transformation_rotation_epsilon > 0.0)
    icp.setTransformationRotationEpsilon(settings.transformation_rotation_epsilon);
  icp.setEuclideanFitnessEpsilon(settings.fitness_epsilon);
  icp.getConvergeCriteria()->setAbsoluteMSE(settings.absolute_mse_epsilon);
  if (settings.box) {
    auto rejector = pcl::make_shared<BoxRejector>(*settings.box);
    rejector->setInputSource<PointT>(src);
    icp.addCorrespondenceRejector(rejector);
  }
  pcl::PointCloud<PointT> aligned;
  const auto t0 = std::chrono::steady_clock::now();
  icp.setInputSource(src);
  icp.setInputTarget(tgt);
  icp.align(aligned, init.cast<float>());
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();

  const Eigen::Matrix4d T = icp.getFinalTransformation().template cast<double>();
  const bool finite = T.allFinite() && !steps->failed();
  IcpResult result = evaluateAt(source.view(), target.view(), finite ? T : init, settings);
  result.iterations = icp.iterations();
  // No correspondence at the final transform (e.g. coordinates of 1e30 m, whose squared
  // distances overflow float: PCL then meets its MSE criterion on nothing) is no convergence.
  const bool matched = result.correspondence_count > 0 && result.T_target_source.allFinite();
  result.status = finite && matched ? fromPcl(icp.getConvergeCriteria()->getConvergenceState())
                                    : IcpStatus::NotEnoughCorrespondences;
  result.converged = finite && matched && icp.hasConverged() && result.status != IcpStatus::MaxIterations &&
                     result.status != IcpStatus::NotEnoughCorrespondences;
  result.mse = 0.0;
  result.degenerate = !finite;
  result.min_rank = finite ? 6 : 0;
  result.seconds = seconds;
  return result;
}

void checkInputs(const CloudView<float>& source, const CloudView<float>& target, const CloudView<float>& normals,
                 bool need_normals) {
  if (source.empty()) throw std::invalid_argument("PCL ICP: empty source cloud");
  if (target.empty()) throw std::invalid_argument("PCL ICP: empty target cloud");
  if (need_normals && normals.size != target.size)
    throw std::invalid_argument("PCL ICP: point-to-plane needs one normal per target point");
}

}  // namespace

IcpResult pclIcp(const CloudView<float>& source, const CloudView<float>& target, const CloudView<float>& target_normals,
                 const Eigen::Matrix4d& T_target_source_init, const IcpSettings& settings, PclIcpVariant variant) {
  validate(settings);
  const bool plane = variant == PclIcpVariant::PointToPlaneLLS || variant == PclIcpVariant::ScanalignPointToPlaneLLS;
  checkInputs(source, target, target_normals, plane);
  requireRigid(T_target_source_init, "PCL ICP: the initial transform");
  // PCL works in float: beyond ~1e6 m a millimetre is below float resolution.
  if (T_target_source_init.topRightCorner<3, 1>().norm() > 1e6)
    throw std::invalid_argument("PCL ICP: the initial transform's translation is beyond 1e6 m");
  using pcl::PointNormal, pcl::PointXYZ;
  namespace reg = pcl::registration;
  switch (variant) {
    case PclIcpVariant::Svd: {
      WithIterations<pcl::IterativeClosestPoint<PointXYZ, PointXYZ>> icp;
      return runPcl<PointXYZ>(icp, pcl::make_shared<reg::TransformationEstimationSVD<PointXYZ, PointXYZ>>(), source,
                              target, target_normals, T_target_source_init, settings);
    }
    case PclIcpVariant::DualQuaternion: {
      WithIterations<pcl::IterativeClosestPoint<PointXYZ, PointXYZ>> icp;
      return runPcl<PointXYZ>(icp, pcl::make_shared<reg::TransformationEstimationDualQuaternion<PointXYZ, PointXYZ>>(),
                              source, target, target_normals, T_target_source_init, settings);
    }
    case PclIcpVariant::PointToPlaneLLS: {
      WithIterations<pcl::IterativeClosestPointWithNormals<PointNormal, PointNormal>> icp;
      return runPcl<PointNormal>(icp, pcl::make_shared<reg::TransformationEstimationPointToPlaneLLS<PointNormal, PointNormal>>(),
                                 source, target, target_normals, T_target_source_init, settings);
    }
    case PclIcpVariant::ScanalignPointToPlaneLLS: {
      WithIterations<pcl::IterativeClosestPointWithNormals<PointNormal, PointNormal>> icp;
      auto lls = pcl::make_shared<PointToPlaneLLS<PointNormal, PointNormal>>(settings.degeneracy_threshold, settings.num_threads);
      return runPcl<PointNormal>(icp, lls, source, target, target_normals, T_target_source_init, settings);
    }
  }
  throw std::invalid_argument("PCL ICP: unknown variant");
}

namespace {
void checkPaired(const CloudView<float>& source, const CloudView<float>& target, const CloudView<float>& normals) {
  if (source.size != target.size || normals.size != target.size)
    throw std::invalid_argument("point-to-plane LLS: source, target and normals must have the same number of rows");
}

/// The pairs PCL's LLS can use: finite source and target points with a finite, non-zero
/// normal (a non-finite one would make the whole transform NaN). std::invalid_argument for
/// none, as Icp::setTarget / pclIcp refuse an empty or all-non-finite cloud.
struct UsablePairs {
  std::vector<float> source, target, normals;
  std::size_t size() const { return source.size() / 3; }
};
UsablePairs usablePairs(const CloudView<float>& source, const CloudView<float>& target,
                        const CloudView<float>& normals) {
  if (source.empty()) throw std::invalid_argument("point-to-plane LLS: no correspondences (empty input)");
  UsablePairs u;
  for (std::size_t i = 0; i < source.size; ++i) {
    if (!source.isFinite(i) || !target.isFinite(i) || !normals.isFinite(i) || normals[i].squaredNorm() == 0.f) continue;
    u.source.insert(u.source.end(), source.ptr(i), source.ptr(i) + 3);
    u.target.insert(u.target.end(), target.ptr(i), target.ptr(i) + 3);
    u.normals.insert(u.normals.end(), normals.ptr(i), normals.ptr(i) + 3);
  }
  if (u.size() == 0)
    throw std::invalid_argument(
        "point-to-plane LLS: no pair with finite coordinates and a valid (finite, non-zero) normal");
  return u;
}
}  // namespace

Eigen::Matrix4d pclPointToPlaneLLS(const CloudView<float>& source_in, const CloudView<float>& target_in,
                                   const CloudView<float>& normals_in, double* seconds) {
  checkPaired(source_in, target_in, normals_in);
  const UsablePairs pairs = usablePairs(source_in, target_in, normals_in);
  const CloudView<float> source(pairs.source.data(), pairs.size()), target(pairs.target.data(), pairs.size()),
      target_normals(pairs.normals.data(), pairs.size());
  const auto src = toCloud<pcl::PointNormal>(source, {});
  const auto tgt = toCloud<pcl::PointNormal>(target, target_normals);
  pcl::registration::TransformationEstimationPointToPlaneLLS<pcl::PointNormal, pcl::PointNormal, double> est;
  Eigen::Matrix4d T = Eigen::Matrix4d::Identity();
  const auto t0 = std::chrono::steady_clock::now();
  est.estimateRigidTransformation(*src, *tgt, T);
  if (seconds) *seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return T;
}

Eigen::Matrix4d scanalignPointToPlaneLLS(const CloudView<float>& source, const CloudView<float>& target,
                                         const CloudView<float>& target_normals, PointToPlaneSolve* solve,
                                         double degeneracy_threshold, double* seconds) {
  checkPaired(source, target, target_normals);
  const auto src = toCloud<pcl::PointNormal>(source, {});
  const auto tgt = toCloud<pcl::PointNormal>(target, target_normals);
  PointToPlaneLLS<pcl::PointNormal, pcl::PointNormal, double> est(degeneracy_threshold);
  Eigen::Matrix4d T = Eigen::Matrix4d::Identity();
  const auto t0 = std::chrono::steady_clock::now();
  est.estimateRigidTransformation(*src, *tgt, T);
  if (seconds) *seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  if (solve) *solve = est.lastSolve();
  return T;
}

std::vector<int> boxRejectorKeep(const CloudView<float>& source, const std::vector<int>& query_indices,
                                 const Box& box) {
  const auto cloud = toCloud<pcl::PointXYZ>(source, {});
  BoxRejector rejector(box);
  rejector.setInputSource<pcl::PointXYZ>(cloud);
  auto input = pcl::make_shared<pcl::Correspondences>();
  for (std::size_t k = 0; k < query_indices.size(); ++k)
    input->emplace_back(query_indices[k], static_cast<int>(k), 0.f);
  rejector.setInputCorrespondences(input);
  pcl::Correspondences kept;
  rejector.getCorrespondences(kept);
  std::vector<int> out;
  out.reserve(kept.size());
  for (const auto& c : kept) out.push_back(c.index_query);
  return out;
}

}  // namespace scanalign
