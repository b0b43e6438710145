// Settings of the reconstruction job: depth images of an RGB-D sequence to a model, frame to
// model (the eye-in-hand paper (Comput. Electron. Agric. 180 (2021) 105929), §3 and
// Algorithm 1): which pixels become points, the optional depth filter, the registration and
// its checks, the model frame, and the registration method (scanalign's engine or a stock PCL
// ICP baseline, §3.7). One struct, so that a run is described by one value (config files,
// the command line, batch jobs).
#pragma once

#include "scanalign/reconstruction/bilateral_filter.hpp"
#include "scanalign/reconstruction/frame_to_model.hpp"

namespace scanalign {

/// The frame the model is built in.
enum class ModelFrame {
  /// Base when the first frame has a reference pose (T_base_camera), else camera.
  Auto,
  /// The first camera's frame.
  Camera,
  /// The robot base frame: the first frame is placed at its reference pose (required).
  Base,
};
const char* toString(ModelFrame frame);

/// How frames are registered to the model.
enum class RegistrationMethod {
  Scanalign,             ///< scanalign's ICP engine (FrameToModel::integrate; estimator in icp.estimator)
  PclSvd,                ///< stock pcl::IterativeClosestPoint (SVD point-to-point), for comparison
  PclDualQuaternion,     ///< PCL's dual-quaternion point-to-point estimator
  PclPointToPlaneLls,    ///< PCL's linear least-squares point-to-plane estimator
};
/// "scanalign", "pcl_svd", "pcl_dual_quaternion", "pcl_point_to_plane_lls".
const char* toString(RegistrationMethod method);

struct ReconstructionSettings {
  /// Pixels nearer than this (m, along z) are dropped: sensors report garbage below their
  /// minimum range.
  double min_depth = 0.1;
  /// Pixels farther than this (m) are dropped.
  double max_depth = 2.0;
  /// Use every pixel_stride-th pixel of the depth images in both directions (1 = all).
  int pixel_stride = 1;
  /// Bilateral-filter every depth image before back-projection (depth_filter): for noisy
  /// consumer sensors, whose axial noise tilts PCA normals; off as in the eye-in-hand paper.
  bool filter_depth = false;
  BilateralFilterSettings depth_filter;
  /// The frame-to-model pipeline: normals, grids, ICP, checks, motion model. Its motion
  /// model defaults to ConstantVelocity here (the reconstruct command's default), not the
  /// eye-in-hand paper's Previous.
  FrameToModelSettings frame_to_model = [] {
    FrameToModelSettings s;
    s.motion_model = MotionModel::ConstantVelocity;
    return s;
  }();
  ModelFrame model_frame = ModelFrame::Auto;
  RegistrationMethod registration = RegistrationMethod::Scanalign;
};

/// Throws std::invalid_argument naming the field: min_depth < 0 or not below max_depth (NaN
/// included), pixel_stride < 1, a bad depth_filter (even when off) or frame_to_model, or an
/// enum value out of range.
void validate(const ReconstructionSettings& settings);

}  // namespace scanalign
