// The fine planar pose of a part from the homography between its top-face reference image and
// a hand camera's image: the second step of the two-step pose of Kleppe et al., "Automated
// assembly using 3D and 2D cameras", Robotics 6 (2017) 14 (the thesis's Paper 3), §3.3.
//
// A rough 3D detection (about 1-2 cm) places the part; a camera on the robot's hand looks down
// at it, SIFT keypoints of a reference image of the part's top face are matched in the camera
// image and a homography H (reference pixels -> camera pixels) is fitted. The paper reads the
// fine pose off H through two points, its eqs. (5)-(6):
//     p0 = H(reference centre),  p1 = H(reference centre + a step along the reference x axis),
//     v = p1 - p0,  theta = atan2(v_y, v_x).
// The paper's camera looks straight down, so image and table axes are parallel up to scale.
// Here p0 and p1 are back-projected onto the part's top plane through the camera's intrinsics
// and pose first, which keeps the equations exact for a tilted camera as well.
//
// Frames (T_a_b maps b into a; metres, radians): base (z up, the table's normal), camera
// (x right, y down, z forward), part (upright on the table: its z along base z). The
// reference image is an orthographic view from above: pixel u along part +x, pixel v along
// part -y, `pixels_per_metre` pixels per metre, the part origin's vertical at origin_pixel.
#pragma once

#include <string>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "scanalign/reconstruction/depth_image.hpp"

namespace scanalign {

/// Where a part's top-face reference image lies on the part.
struct ReferenceImageGeometry {
  int width = 0;                      ///< px
  int height = 0;                     ///< px
  double pixels_per_metre = 5000.0;   ///< px/m (5000: 0.2 mm per pixel)
  Eigen::Vector2d origin_pixel = Eigen::Vector2d::Zero();  ///< (u, v) px above the part origin
  double top_height = 0.0;            ///< m, height of the top face above the part origin (part z)

  /// Throws std::invalid_argument naming the field: a non-positive size or scale, non-finite values.
  void validate() const;
  /// The part-frame point (x, y, top_height) under reference pixel (u, v), m.
  Eigen::Vector3d partPoint(double u, double v) const;
};

struct HomographyPoseSettings {
  /// Largest |singular value - 1| of the map from the part's top plane to the table plane that
  /// H implies (1, 1 for a rigid motion): beyond it the homography is not rigid (a wrong match
  /// set, a flipped or sheared fit) and the status is NonRigid. Fits from AKAZE or ORB keypoints
  /// on a 60 mm label seen from 25 cm stray by up to about 12 % while their p0 and p1 stay within
  /// 0.1 mm; a wrong match set strays far more.
  double max_scale_error = 0.15;
  /// m, the step along the reference x axis to p1 (eqs. (5)-(6)); any positive length gives the
  /// same angle for an exact H, a part-sized one averages a fitted H over the part.
  double axis_length = 0.02;

  void validate() const;
};

enum class HomographyPoseStatus {
  Ok = 0,
  NonRigid = 1,          ///< H implies a scaled, sheared or mirrored top plane (see max_scale_error)
  PartOutsideImage = 2,  ///< p0, the image of the part origin, lies outside the camera image
  NotInView = 3,         ///< p0 or p1 back-projects behind the camera, or the ray is parallel to the plane
  NotFinite = 4,         ///< H is singular or not finite
};
const char* toString(HomographyPoseStatus status);

struct HomographyPose {
  HomographyPoseStatus status = HomographyPoseStatus::NotFinite;
  std::string reason;  ///< why not Ok, with the measured value
  /// The refined pose: x, y and the yaw from the image, z from the rough pose, upright.
  Eigen::Isometry3d T_base_part = Eigen::Isometry3d::Identity();
  double x = 0.0, y = 0.0;     ///< m, the part origin in the base frame
  double theta = 0.0;          ///< rad, yaw of part x about base z, in (-pi, pi]
  Eigen::Vector2d p0 = Eigen::Vector2d::Zero();  ///< px, the part origin in the camera image (eq. (5))
  Eigen::Vector2d p1 = Eigen::Vector2d::Zero();  ///< px, the reference x-axis point in the camera image
  Eigen::Vector2d singular_values = Eigen::Vector2d::Zero();  ///< of the top-plane map (1, 1: rigid)
};

/// The part's planar pose from H_image_reference (3x3, reference pixels -> undistorted camera
/// pixels, any scale), the reference image's geometry, the camera's intrinsics (no distortion:
/// undistort the image first) and pose T_base_camera, and the rough pose T_base_part_rough,
/// which gives the height of the top plane. Throws std::invalid_argument naming the argument
/// for bad intrinsics, geometry or settings, distorted intrinsics or non-rigid poses.
HomographyPose planarPoseFromHomography(const Eigen::Matrix3d& H_image_reference, const ReferenceImageGeometry& reference,
                                        const PinholeIntrinsics& intrinsics, const Eigen::Isometry3d& T_base_camera,
                                        const Eigen::Isometry3d& T_base_part_rough,
                                        const HomographyPoseSettings& settings = {});

/// The homography a part at T_base_part induces between its reference image and the camera
/// image (reference pixels -> camera pixels, H(2,2) = 1): K [r1 r2 h r3 + t] M_ref with
/// T_camera_part = (r1 r2 r3 | t), h the top height and M_ref the reference pixel -> part-plane
/// map. For rendering the top face and for tests. Throws as planarPoseFromHomography.
Eigen::Matrix3d homographyOfPart(const ReferenceImageGeometry& reference, const PinholeIntrinsics& intrinsics,
                                 const Eigen::Isometry3d& T_base_camera, const Eigen::Isometry3d& T_base_part);

}  // namespace scanalign
