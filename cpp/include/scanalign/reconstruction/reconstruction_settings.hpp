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
  /// Bilateral-filter every depth image before back-projection (depth_filter). On by default
  /// (the eye-in-hand paper had none): the axial noise of consumer RGB-D sensors (SR300, D435)
  /// tilts PCA normals, and point-to-plane ICP then slides; on the built-in SR300-like scan the
  /// filter takes the ATE from 12 mm to 4 mm and costs little on low-noise sensors.
  bool filter_depth = true;
  BilateralFilterSettings depth_filter;
  /// The frame-to-model pipeline: normals, grids, ICP, checks, motion model. Four fields
  /// differ from FrameToModelSettings' (the eye-in-hand paper's, kept there for its
  /// experiments), so that the defaults track a hand-held or robot scan of a tabletop part
  /// with a consumer sensor (built-in SR300-like scan: ATE 159 mm with the paper's values,
  /// 25 of 36 frames not converged; about 3 mm with these):
  /// - motion_model ConstantVelocity, not Previous: fewer iterations on a smooth scan path;
  /// - normal_radius 10 mm, not 5 mm: a 5 mm PCA neighbourhood holds too few points above
  ///   consumer-sensor noise (ATE 12 mm against 3-4 mm, both with the filter);
  /// - icp.box (-0.1, 0.1, -0.1, 0.1, 0.0001, 10) m, the paper's box rejector (§3.4) sized to a
  ///   part's workspace (between its banana and free-hand boxes): correspondences on the
  ///   table around the part constrain nothing in the table's plane, and their noise drags a
  ///   frame sideways (ATE 20 mm without the box, 6 mm with the free-hand box). Widen or
  ///   remove it (icp.box = None) for room-scale scans.
  FrameToModelSettings frame_to_model = [] {
    FrameToModelSettings s;
    s.motion_model = MotionModel::ConstantVelocity;
    s.normal_radius = 0.01;
    s.icp.box = Box(-0.1, 0.1, -0.1, 0.1, 0.0001, 10.0);
    return s;
  }();
  ModelFrame model_frame = ModelFrame::Auto;
  RegistrationMethod registration = RegistrationMethod::Scanalign;
  /// A run that merges fewer than this fraction of its frames has failed (its result's
  /// status says so, the command line exits 1): a model built from a minority of frames
  /// after the rest did not converge is not a reconstruction to trust. In [0, 1].
  double min_merged_fraction = 0.5;
};

/// Throws std::invalid_argument naming the field: min_depth < 0 or not below max_depth (NaN
/// included), pixel_stride < 1, a bad depth_filter (even when off) or frame_to_model,
/// min_merged_fraction outside [0, 1], or an enum value out of range.
void validate(const ReconstructionSettings& settings);

}  // namespace scanalign
