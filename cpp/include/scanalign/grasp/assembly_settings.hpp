// Settings of the assembly job (python/scanalign/pipelines/assemble.py): the two-step pose of
// Kleppe et al., "Automated assembly using 3D and 2D cameras", Robotics 6 (2017) 14 (the
// thesis's Paper 3) -- a rough pose of each part from one fixed 3D camera's depth image, refined
// by a hand camera's 2D step -- then the pick of part A and its place onto part B. One struct,
// so that an assembly run is one value (config files, the command line, batch jobs).
//
// Units: metres and radians.
#pragma once

#include "scanalign/grasp/grasp_planner.hpp"
#include "scanalign/grasp/pick_settings.hpp"
#include "scanalign/grasp/view_planner.hpp"
#include "scanalign/pose/part_identification.hpp"
#include "scanalign/pose/refine_2d_settings.hpp"

namespace scanalign {

struct AssemblySettings {
  /// The parts in one time-of-flight depth image (Kinect One-like, 0.75 m away: about 1 mm
  /// noise, 2 mm between points, flying pixels at the parts' edges). Tighter table plane
  /// (2.5 mm: the bracket's 6 mm base plate would go with the table at 4 mm), clusters joined
  /// within 20 mm (the bracket's plates seen edge-on part by more than 10 mm), clusters from 50
  /// points (a 30 mm standoff gives about 200), a CBD neighbourhood of 0.25 x the part's size
  /// (single-view noise needs more support than a merged scan), the size gate at 3 x (flying
  /// pixels stretch a cluster along the rays) and 90 % of a cluster on the part's surface (the
  /// flying pixels lie off it). On the synthetic cell, seeds 0-11: both parts found in 23 of
  /// 24 (one ambiguous), within 0.1-6.7 mm; with the pick job's settings 5 of 24.
  FindPartsSettings find_parts = [] {
    FindPartsSettings f;
    f.table.plane.threshold = 0.0025;
    f.table.up = Eigen::Vector3d::UnitZ();
    f.table.cluster_tolerance = 0.02;
    f.table.min_cluster_size = 50;
    f.max_objects = 10;
    f.cbd_radius_fraction = 0.25;
    f.max_size_ratio = 3.0;
    f.min_surface_coverage = 0.9;
    return f;
  }();
  /// The model views matched (the parts rest on their bases).
  PickViews views = PickViews::Upper;
  /// The hand camera's 2D step: matching, homography, iterations and convergence.
  Refine2dSettings refine_2d;
  /// Where the camera arm looks from: 12 cm above each part's top face, not the planner's 18 cm.
  /// The standoff's 22 mm label fills fewer pixels than the 60 mm labels the 18 cm were chosen
  /// for: over 40 SIFT views each (webcam, 0.8 px blur, 2 grey levels noise) the median error
  /// of p0 is 0.094 mm at 18 cm and 0.060 mm at 12 cm, the homography's worst scale error 0.153
  /// (one view refused as non-rigid) and 0.101 (none refused).
  ViewPlannerSettings view = [] {
    ViewPlannerSettings v;
    v.height = 0.12;
    return v;
  }();
  /// The gripper arm's pick and place: every grasp, symmetric copy and IK branch judged.
  GraspPlannerSettings planner;

  /// Throws std::invalid_argument naming the bad field with its path.
  void validate() const;
};

}  // namespace scanalign
