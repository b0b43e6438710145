// Frame-to-model reconstruction (the eye-in-hand paper
// (Comput. Electron. Agric. 180 (2021) 105929), §3 and Algorithm 1).
//
// The model is one accumulated cloud with normals and colours, kept in a fixed model
// frame (the first camera's frame, or a base frame given at reset). Each new frame is
//   1. cropped (optional box in its camera frame) and voxel-downsampled;
//   2. given normals by PCA over 5 mm, oriented towards the camera (§3.5);
//   3. registered to the model by the point-to-plane LLS ICP engine, starting from the
//      previous registration (§3.2) or a constant-velocity prediction (MotionModel);
//      optional box rejector, §3.4;
//   4. checked (convergence, fitness, motion since the guess): a frame that fails is
//      reported and skipped and leaves the model untouched;
//   5. transformed into the model frame, merged, and the model voxel-gridded at 1 mm so
//      its size, and the per-frame cost, stay bounded (§3.6). The merge folds each new
//      point into its model voxel through a hash index (O(frame points)), with the result
//      of re-gridding the whole model (see merge()).
//
// No lost data: a frame that fails a check, and a call that throws anywhere (bad input, a
// failed allocation, Interrupted from a Ctrl-C during the registration), leaves the model,
// the poses and the frame counts exactly as they were. Every step that can fail runs
// before the first change; the merge reserves its memory, then commits without throwing.
//
// Range: voxel coordinates must stay within the grids' 2^21 voxels per axis. A frame point
// farther than kFrameRangeVoxels frame voxels from its camera along an axis (524 m at
// 1 mm: no depth sensor measures that far; a stray 1e30 reading) is dropped in prepare(),
// and a point landing farther than kModelRangeVoxels model voxels (1048 m at 1 mm) from
// the model's anchor (the first merged camera's position) is dropped in merge(); both are
// counted (far_points), never a refused frame.
#pragma once

#include <cstdint>
#include <limits>
#include <optional>
#include <vector>

#include <Eigen/Core>

#include "scanalign/common/cloud_view.hpp"
#include "scanalign/reconstruction/voxel_index.hpp"
#include "scanalign/registration/box.hpp"
#include "scanalign/registration/icp.hpp"

namespace scanalign {

/// Where a frame's registration starts when the caller gives no initial guess.
enum class MotionModel {
  /// Eye-in-hand paper §3.2: the previous registration (the camera is assumed not to move).
  Previous,
  /// The motion between the last two merged frames, applied once more:
  /// T_k = T_{k-1} (T_{k-2}^-1 T_{k-1}), as a constant-velocity tracker (e.g. KISS-ICP,
  /// Vizzo et al. 2023). For frames at a constant rate along a smooth path (a robot's
  /// scan), it starts ICP much closer to the answer, so fewer iterations run. Falls back
  /// to Previous until two frames are merged; after a skipped frame the prediction lags
  /// by that frame's motion.
  ConstantVelocity,
  /// Odometry-aided: each frame's guess is the robot's reference motion since the last
  /// merged frame applied to that frame's estimate, T_k = T_m (R_m^-1 R_k) with R the
  /// reference poses (forward kinematics and the hand-eye calibration) and m the last merged
  /// frame, as in the eye-in-hand paper's robot scans. The caller computes it from the
  /// reference poses and passes it as the guess; a frame integrated without a guess falls
  /// back to ConstantVelocity.
  Reference,
};

const char* toString(MotionModel model);

struct FrameToModelSettings {
  /// Registration settings (eye-in-hand paper §3.3 convergence defaults). The correspondence distance
  /// default is tighter than IcpSettings' because consecutive eye-in-hand frames move
  /// little (the eye-in-hand paper's robot moves at most 0.1 m/s at 10 Hz).
  IcpSettings icp = [] {
    IcpSettings s;
    s.max_correspondence_distance = 0.02;
    return s;
  }();
  /// PCA normal radius (m). Eye-in-hand paper §3.5: 5 mm.
  double normal_radius = 0.005;
  /// Voxel edge of the model grid applied after each merge (m). Eye-in-hand paper §3.6: 1 mm.
  double model_voxel_size = 0.001;
  /// Voxel edge applied to each incoming frame before normals and registration (m);
  /// 0 keeps the frame at full resolution. At the eye-in-hand paper's 40 cm range a depth pixel covers
  /// about 0.7 mm, so a 1 mm frame grid loses little and halves the work.
  double frame_voxel_size = 0.001;
  /// Optional box in the frame's camera coordinates; points outside are dropped before
  /// anything else (bounds the model to the workspace). Unlike icp.box it also limits
  /// what is merged.
  std::optional<Box> crop_box;
  /// Frames with fewer points than this after cropping and downsampling are skipped.
  int min_frame_points = 200;
  /// A registration with fitness (inlier fraction) below this is rejected.
  double min_fitness = 0.3;
  /// Reject a registration that did not meet a convergence criterion (hit
  /// icp.max_iterations). Set false for fixed iteration budgets (eye-in-hand paper Figs. 6 and 9).
  bool require_convergence = true;
  /// Largest accepted change from the initial guess: translation (m) and rotation (rad).
  /// A registration that jumps further is taken to have failed.
  double max_translation_change = 0.10;
  double max_rotation_change = 0.5;
  /// Initial guess of a frame given none (see MotionModel; Reference without a guess acts as
  /// ConstantVelocity). Default: the eye-in-hand paper's.
  MotionModel motion_model = MotionModel::Previous;
  /// OpenMP threads for normals and ICP (overrides icp.num_threads when > 0); 0 = all cores.
  int num_threads = 0;
};

/// Throws std::invalid_argument when the settings cannot be used.
void validate(const FrameToModelSettings& settings);

enum class FrameStatus {
  Initialized,           ///< first accepted frame: defines the model at the given pose
  Registered,            ///< registered and merged
  SkippedEmpty,          ///< no valid point in the frame (after cropping)
  SkippedTooFewPoints,   ///< fewer than min_frame_points
  SkippedNoConvergence,  ///< ICP hit its iteration cap with require_convergence
  SkippedTooFewCorrespondences,  ///< ICP stopped: not enough correspondences
  SkippedLowFitness,     ///< fitness below min_fitness
  SkippedMotion,         ///< the result moved too far from the initial guess
};

const char* toString(FrameStatus status);
inline bool accepted(FrameStatus s) { return s == FrameStatus::Initialized || s == FrameStatus::Registered; }

/// A frame ready to register: camera-frame points with unit normals (towards the camera)
/// and optional colours, after cropping and downsampling. Points whose normal could not
/// be estimated are removed.
struct PreparedFrame {
  std::vector<float> points;         ///< 3 per point (m), camera frame
  std::vector<float> normals;        ///< 3 per point, unit
  std::vector<std::uint8_t> colors;  ///< 3 per point or empty
  std::size_t input_points = 0;      ///< points given to prepare()
  std::size_t far_points = 0;        ///< finite points dropped as beyond the frame grid's range
  double seconds = 0.0;              ///< time to crop, downsample and estimate normals
  std::size_t size() const { return points.size() / 3; }
  CloudView<float> view() const { return CloudView<float>(points.data(), size()); }
};

struct FrameResult {
  int index = -1;                    ///< 0-based count of frames given to the pipeline
  double timestamp = 0.0;            ///< s; the frame's time stamp, as the caller gives it
  std::size_t input_points = 0;      ///< points given (before crop and downsampling)
  FrameStatus status = FrameStatus::SkippedEmpty;
  /// Estimated camera pose in the model frame (camera -> model). For a skipped frame:
  /// the initial guess it was tried from.
  Eigen::Matrix4d T_model_camera = Eigen::Matrix4d::Identity();
  IcpResult icp;                     ///< registration details (default for the first frame)
  std::size_t frame_points = 0;      ///< points after crop, downsampling and normals
  std::size_t model_points = 0;      ///< model size after this frame
  /// Finite points dropped as beyond the voxel grids' range: farther than
  /// kFrameRangeVoxels frame voxels from the camera, or (merged frames) kModelRangeVoxels
  /// model voxels from the model's anchor.
  std::size_t far_points = 0;
  double prepare_seconds = 0.0;      ///< crop + downsample + normals
  double register_seconds = 0.0;     ///< tree build + ICP
  double merge_seconds = 0.0;        ///< transform + merge + voxel grid
  double total_seconds = 0.0;
  bool merged() const { return accepted(status); }
};

/// The accumulated model: points in the model frame (m), unit normals, colours (uint8 RGB
/// or empty when the frames had none). One point per occupied voxel of the model grid, in
/// the order the voxels were first occupied (not PCL's z-y-x order).
struct Model {
  std::vector<float> points;
  std::vector<float> normals;
  std::vector<std::uint8_t> colors;
  std::size_t size() const { return points.size() / 3; }
};

/// Frame points farther than this many frame voxels (frame_voxel_size, else
/// model_voxel_size) from the camera along an axis are dropped: 2^19, 524 m at 1 mm.
constexpr std::int64_t kFrameRangeVoxels = std::int64_t{1} << 19;
/// Model points farther than this many model voxels from the anchor (the first merged
/// camera's position) along an axis are dropped: 2^20, 1048 m at 1 mm, so the model spans
/// fewer than voxelGrid's 2^21 voxels per axis.
constexpr std::int64_t kModelRangeVoxels = std::int64_t{1} << 20;

class FrameToModel {
 public:
  explicit FrameToModel(FrameToModelSettings settings = {});

  /// Empties the model. The next accepted frame defines it, at pose T_model_camera0
  /// (identity: the model frame is the first camera's frame; T_base_camera of the first
  /// frame: the model lives in the robot's base frame).
  void reset(const Eigen::Matrix4d& T_model_camera0 = Eigen::Matrix4d::Identity());

  /// Crop, downsample and estimate normals of a camera-frame cloud (non-finite points
  /// are dropped, and so are points beyond kFrameRangeVoxels, counted in far_points).
  /// `colors` (may be null) holds 3 uint8 per point.
  PreparedFrame prepare(const CloudView<float>& points_camera, const std::uint8_t* colors = nullptr) const;

  /// The whole step for one frame. The initial guess is `T_model_camera_guess` when given
  /// (e.g. from the robot's kinematics), else predictedPose() (settings.motion_model).
  /// Never throws on bad frames: they come back with a Skipped status and the model is
  /// unchanged. Throws std::invalid_argument for invalid settings or a non-rigid or
  /// non-finite guess, and passes on std::bad_alloc and Interrupted; whatever it throws, the
  /// model, poses and counts are unchanged (the frame did not happen).
  FrameResult integrate(const CloudView<float>& points_camera, const std::uint8_t* colors = nullptr,
                        const Eigen::Matrix4d* T_model_camera_guess = nullptr);

  /// As integrate(), for a frame already prepared.
  FrameResult integratePrepared(const PreparedFrame& frame, const Eigen::Matrix4d* T_model_camera_guess = nullptr);

  /// Merges a prepared frame at a pose found elsewhere (e.g. another registration
  /// method), then voxel-grids the model; the pose becomes lastPose(). Returns the new
  /// model size. The result is voxelGrid(model points + frame points) at
  /// model_voxel_size, each model point counting as one point, normals averaged and
  /// re-normalised (NaN where they cancel), colours averaged (grey for frames without):
  /// the same points, normals and colours as that re-grid up to the order of the points
  /// (see the .cpp for the exactness statement), computed in O(frame points). Frame points
  /// beyond kModelRangeVoxels from the anchor are dropped, their count added to
  /// `*far_points` when given. Strong guarantee: when it throws (a bad frame or pose:
  /// std::invalid_argument; std::bad_alloc) nothing has changed.
  std::size_t merge(const PreparedFrame& frame, const Eigen::Matrix4d& T_model_camera,
                    std::size_t* far_points = nullptr);

  /// Applies the acceptance checks of integrate() to an external registration result.
  FrameStatus check(const IcpResult& result, const Eigen::Matrix4d& T_model_camera_guess) const;

  const Model& model() const { return model_; }
  /// The last accepted pose (camera -> model); the initial pose before the first frame.
  const Eigen::Matrix4d& lastPose() const { return last_pose_; }
  /// The initial guess (camera -> model) of the next frame when none is given, from
  /// settings().motion_model and the last two accepted poses.
  Eigen::Matrix4d predictedPose() const;
  bool hasModel() const { return model_.size() > 0; }
  int framesSeen() const { return frames_seen_; }
  /// Counts a frame registered outside integrate() (e.g. by a PCL baseline); returns its index.
  int countFrame() { return frames_seen_++; }
  int framesMerged() const { return frames_merged_; }
  const FrameToModelSettings& settings() const { return settings_; }
  FrameToModelSettings& settings() { return settings_; }

 private:
  FrameToModelSettings settings_;
  Model model_;
  Eigen::Matrix4d last_pose_ = Eigen::Matrix4d::Identity();
  Eigen::Matrix4d previous_pose_ = Eigen::Matrix4d::Identity();  ///< the accepted pose before last_pose_
  int frames_seen_ = 0;
  int frames_merged_ = 0;
  Icp<float> icp_;
  bool tree_current_ = false;  ///< icp_ holds a tree of the current model
  /// Model voxel -> index of its model point, for the incremental merge; built for the
  /// leaf index_leaf_ (0: not built, e.g. after the leaf setting changed).
  VoxelIndex voxels_;
  double index_leaf_ = 0.0;
  Eigen::Vector3d anchor_ = Eigen::Vector3d::Zero();  ///< first merged camera position, model frame (m)

  void regridMerge(const std::vector<float>& points, const std::vector<double>& normals,
                   const std::vector<std::uint8_t>& colors, bool colored);
  bool buildIndex() noexcept;  ///< false (and no index) when it cannot be built
};

}  // namespace scanalign
