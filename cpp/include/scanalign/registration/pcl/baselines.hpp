// Stock PCL 1.13 ICP variants, run on the same inputs and criteria as scanalign's engine,
// for evaluation (the eye-in-hand paper, Comput. Electron. Agric. 180 (2021) 105929, §4: PCL SVD and dual quaternion; PCL's point-to-plane LLS).
// The declarations here are PCL-free; the implementations live in pcl_baselines.cpp.
#pragma once

#include <string>
#include <vector>

#include <Eigen/Core>

#include "scanalign/common/cloud_view.hpp"
#include "scanalign/registration/icp.hpp"
#include "scanalign/registration/point_to_plane_lls.hpp"

namespace scanalign {

enum class PclIcpVariant {
  Svd,                      ///< pcl::IterativeClosestPoint, TransformationEstimationSVD
  DualQuaternion,           ///< pcl::IterativeClosestPoint, TransformationEstimationDualQuaternion
  PointToPlaneLLS,          ///< pcl::IterativeClosestPointWithNormals (PCL's own point-to-plane LLS)
  ScanalignPointToPlaneLLS, ///< pcl::IterativeClosestPointWithNormals with scanalign::PointToPlaneLLS
};

const char* toString(PclIcpVariant variant);

/// Runs a stock PCL ICP. Uses settings.max_correspondence_distance, max_iterations,
/// transformation_epsilon, transformation_rotation_epsilon, fitness_epsilon and box
/// (through scanalign::BoxRejector). The result's fitness, inlier_rmse and
/// correspondence_count are evaluated at the final transform exactly as the engine does,
/// so the two are comparable; `seconds` times PCL's setInputSource/Target + align (its
/// k-d tree build included); `converged` follows scanalign: a criterion was met (PCL also
/// counts reaching max_iterations as converged; status tells them apart), and never without a
/// correspondence at the final transform (status NotEnoughCorrespondences). Normals are needed
/// for the point-to-plane variants. Throws std::invalid_argument on bad input (empty clouds, a
/// target without a finite point (with a valid normal), as Icp::setTarget).
IcpResult pclIcp(const CloudView<float>& source, const CloudView<float>& target, const CloudView<float>& target_normals,
                 const Eigen::Matrix4d& T_target_source_init, const IcpSettings& settings, PclIcpVariant variant);

/// One estimate of PCL's TransformationEstimationPointToPlaneLLS (double precision) on
/// paired points: source[i] <-> target[i] with target_normals[i]. `seconds` (may be null)
/// receives the time of the estimate alone, without the cloud conversion. Pairs with a
/// non-finite point or a non-finite or zero normal are left out; std::invalid_argument when
/// the input is empty or no pair is left.
Eigen::Matrix4d pclPointToPlaneLLS(const CloudView<float>& source, const CloudView<float>& target,
                                   const CloudView<float>& target_normals, double* seconds = nullptr);

/// The same correspondences through scanalign::PointToPlaneLLS (double precision);
/// `solve` receives the rank / conditioning of the system.
Eigen::Matrix4d scanalignPointToPlaneLLS(const CloudView<float>& source, const CloudView<float>& target,
                                         const CloudView<float>& target_normals, PointToPlaneSolve* solve = nullptr,
                                         double degeneracy_threshold = 1e-10, double* seconds = nullptr);

/// Runs scanalign::BoxRejector (the PCL plug-in) on correspondences whose source indices
/// are `query_indices` into `source`; returns the source indices it keeps, in order.
std::vector<int> boxRejectorKeep(const CloudView<float>& source, const std::vector<int>& query_indices,
                                 const Box& box);

}  // namespace scanalign
