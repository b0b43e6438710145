// Settings of the pick job (python/scanalign/pick.py: scan, part poses, grasps and joint
// targets): how the scan is reconstructed in the robot's base frame (the eye-in-hand paper,
// Comput. Electron. Agric. 180 (2021) 105929, §3), how the parts are found in it (Kleppe, PhD
// thesis, NTNU 2018, ch. 7: part_identification.hpp), which model views are tried, and how a
// grasp is planned (grasp_planner.hpp). One struct, so that a pick run is described by one
// value (config files, the command line, batch jobs); its defaults are the pick pipeline's.
//
// Units: metres and radians.
#pragma once

#include "scanalign/grasp/grasp_planner.hpp"
#include "scanalign/pose/part_identification.hpp"
#include "scanalign/reconstruction/reconstruction_settings.hpp"

namespace scanalign {

/// Which model views of each part are matched.
enum class PickViews {
  /// The views from above the part's own xy plane (the tessellated sphere's vertices with
  /// z > 0): the part rests on its base, z up in the CAD frame, as parts on a table usually
  /// do; 2.5 times faster than all 42.
  Upper,
  /// Every view (any orientation).
  All,
};
/// "upper", "all".
const char* toString(PickViews views);

struct PickSettings {
  /// The scan, frame to model in the robot's base frame, every frame starting from the robot's
  /// pose T_base_camera = FK(q) T_flange_camera. That pose is within the robot's accuracy and
  /// the hand-eye error (about a millimetre) of the truth, so ICP needs only a short
  /// correspondence distance (3 mm): a long one lets the table plane's noise drag a frame
  /// sideways (the table dominates the points and constrains nothing in its own plane). Every
  /// second pixel (a quarter of them), depths up to 1 m, a 1 mm model grid, motion model
  /// Reference (the robot's motion since the last merged frame), model frame Base.
  ReconstructionSettings reconstruction = [] {
    ReconstructionSettings r;
    r.pixel_stride = 2;
    r.max_depth = 1.0;
    r.model_frame = ModelFrame::Base;
    r.frame_to_model.icp.max_correspondence_distance = 0.003;
    r.frame_to_model.model_voxel_size = 0.001;
    r.frame_to_model.motion_model = MotionModel::Reference;
    // The robot's pose and the 3 mm distance already hold each frame: the scan keeps the
    // paper's 5 mm normals, no depth filter and no box (the cell's parts span the table).
    r.filter_depth = false;
    r.frame_to_model.normal_radius = 0.005;
    r.frame_to_model.icp.box.reset();
    return r;
  }();
  /// The parts in the scan: table plane (4 mm), normal up (+z of the base frame), object
  /// clusters (10 mm, at least 300 points), at most 10 clusters, each reduced to 1 mm voxels.
  /// The CBD neighbourhood per part is max(6.3 mm, 0.15 x the part's size): merged scans with
  /// millimetre noise need a neighbourhood well above the noise on large parts (12.5 mm on the
  /// block) and a small one on small parts (6.3 mm on the standoff). The rest is
  /// FindPartsSettings' default (views rendered at 100 pixels, find_parts.pose.views).
  FindPartsSettings find_parts = [] {
    FindPartsSettings f;
    f.table.plane.threshold = 0.004;
    f.table.up = Eigen::Vector3d::UnitZ();
    f.table.cluster_tolerance = 0.01;
    f.table.min_cluster_size = 300;
    f.max_objects = 10;
    f.voxel_size = 0.001;
    f.cbd_radius_fraction = 0.15;
    return f;
  }();
  /// The model views matched (PickViews).
  PickViews views = PickViews::Upper;
  /// Grasp planning for every found part.
  GraspPlannerSettings planner;

  /// Throws std::invalid_argument naming the bad field with its path (e.g. "pick settings:
  /// find_parts: max_objects must be >= 1").
  void validate() const;
};

}  // namespace scanalign
