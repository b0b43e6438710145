// Kleppe et al., Robotics 6 (2017) 14 (the thesis's Paper 3), §3.3, eqs. (5)-(6); see
// pose/homography_pose.hpp.
#include "scanalign/pose/homography_pose.hpp"

#include <cmath>
#include <stdexcept>

#include <Eigen/LU>
#include <Eigen/SVD>

#include "scanalign/common/rigid.hpp"

namespace scanalign {

namespace {

void fail(const std::string& what) { throw std::invalid_argument(what); }

/// Reference pixel (u, v, 1) -> part top-plane coordinates (x, y, 1).
Eigen::Matrix3d referenceToPlane(const ReferenceImageGeometry& r) {
  const double s = 1.0 / r.pixels_per_metre;
  Eigen::Matrix3d M;
  M << s, 0, -s * r.origin_pixel.x(), 0, -s, s * r.origin_pixel.y(), 0, 0, 1;
  return M;
}

/// Plane point (x, y, 1) of the horizontal plane z = z0 (base frame) -> camera pixel.
Eigen::Matrix3d planeToImage(const PinholeIntrinsics& k, const Eigen::Isometry3d& T_camera_plane, double z0) {
  const Eigen::Matrix3d R = T_camera_plane.linear();
  Eigen::Matrix3d P;
  P.col(0) = R.col(0);
  P.col(1) = R.col(1);
  P.col(2) = z0 * R.col(2) + T_camera_plane.translation();
  return k.K() * P;
}

void checkInputs(const ReferenceImageGeometry& reference, const PinholeIntrinsics& intrinsics,
                 const Eigen::Isometry3d& T_base_camera, const Eigen::Isometry3d& T_base_part) {
  reference.validate();
  intrinsics.validate();
  if (intrinsics.hasDistortion())
    fail("intrinsics: the homography relates undistorted images; undistort the camera image first "
         "(distortion coefficients must be zero)");
  requireRigid(T_base_camera.matrix(), "T_base_camera");
  requireRigid(T_base_part.matrix(), "T_base_part");
}

/// The point where the ray through pixel p meets the plane z = z0 (base frame); false when it
/// runs parallel to it or meets it behind the camera.
bool backProject(const PinholeIntrinsics& k, const Eigen::Isometry3d& T_base_camera, const Eigen::Vector2d& p,
                 double z0, Eigen::Vector3d& out) {
  const Eigen::Vector3d ray_cam((p.x() - k.cx) / k.fx, (p.y() - k.cy) / k.fy, 1.0);
  const Eigen::Vector3d d = T_base_camera.linear() * ray_cam;
  const Eigen::Vector3d c = T_base_camera.translation();
  if (!(std::abs(d.z()) > 1e-12)) return false;
  const double t = (z0 - c.z()) / d.z();
  if (!(t > 0.0)) return false;
  out = c + t * d;
  return out.allFinite();
}

Eigen::Vector2d apply(const Eigen::Matrix3d& H, const Eigen::Vector2d& p) {
  const Eigen::Vector3d q = H * p.homogeneous();
  return q.head<2>() / q.z();
}

}  // namespace

const char* toString(HomographyPoseStatus status) {
  switch (status) {
    case HomographyPoseStatus::Ok: return "ok";
    case HomographyPoseStatus::NonRigid: return "non_rigid";
    case HomographyPoseStatus::PartOutsideImage: return "part_outside_image";
    case HomographyPoseStatus::NotInView: return "not_in_view";
    case HomographyPoseStatus::NotFinite: return "not_finite";
  }
  return "unknown";
}

void ReferenceImageGeometry::validate() const {
  if (width <= 0 || height <= 0) fail("ReferenceImageGeometry: width and height must be positive pixels");
  if (!(pixels_per_metre > 0.0) || !std::isfinite(pixels_per_metre))
    fail("ReferenceImageGeometry.pixels_per_metre must be a finite positive scale (px/m)");
  if (!origin_pixel.allFinite()) fail("ReferenceImageGeometry.origin_pixel must be finite (px)");
  if (!std::isfinite(top_height)) fail("ReferenceImageGeometry.top_height must be finite (m)");
}

Eigen::Vector3d ReferenceImageGeometry::partPoint(double u, double v) const {
  return {(u - origin_pixel.x()) / pixels_per_metre, -(v - origin_pixel.y()) / pixels_per_metre, top_height};
}

void HomographyPoseSettings::validate() const {
  if (!(max_scale_error > 0.0) || !std::isfinite(max_scale_error))
    fail("HomographyPoseSettings.max_scale_error must be a finite positive fraction");
  if (!(axis_length > 0.0) || !std::isfinite(axis_length))
    fail("HomographyPoseSettings.axis_length must be a finite positive length (m)");
}

Eigen::Matrix3d homographyOfPart(const ReferenceImageGeometry& reference, const PinholeIntrinsics& intrinsics,
                                 const Eigen::Isometry3d& T_base_camera, const Eigen::Isometry3d& T_base_part) {
  checkInputs(reference, intrinsics, T_base_camera, T_base_part);
  const Eigen::Isometry3d T_camera_part = T_base_camera.inverse() * T_base_part;
  Eigen::Matrix3d H = planeToImage(intrinsics, T_camera_part, reference.top_height) * referenceToPlane(reference);
  return H / H(2, 2);
}

HomographyPose planarPoseFromHomography(const Eigen::Matrix3d& H_in, const ReferenceImageGeometry& reference,
                                        const PinholeIntrinsics& intrinsics, const Eigen::Isometry3d& T_base_camera,
                                        const Eigen::Isometry3d& T_base_part_rough,
                                        const HomographyPoseSettings& settings) {
  checkInputs(reference, intrinsics, T_base_camera, T_base_part_rough);
  settings.validate();
  HomographyPose out;
  const double det = H_in.allFinite() ? H_in.determinant() : 0.0;
  if (!(std::abs(det) > 0.0) || !std::isfinite(det)) {
    out.reason = "the homography is singular or not finite";
    return out;
  }
  const Eigen::Matrix3d H = H_in / H_in.norm();
  // The top plane: the rough pose's top-face height, horizontal (the part is upright).
  const double z_top = (T_base_part_rough * Eigen::Vector3d(0.0, 0.0, reference.top_height)).z();
  // Eqs. (5)-(6): the reference centre and a point on the reference x axis, in the image.
  const Eigen::Vector2d c = reference.origin_pixel;
  const Eigen::Vector2d c1 = c + Eigen::Vector2d(settings.axis_length * reference.pixels_per_metre, 0.0);
  const Eigen::Vector3d h0 = H * c.homogeneous(), h1 = H * c1.homogeneous();
  out.p0 = h0.head<2>() / h0.z();
  out.p1 = h1.head<2>() / h1.z();
  if (!out.p0.allFinite() || !out.p1.allFinite()) {
    out.reason = "the part origin maps to infinity";
    return out;
  }
  if (!(out.p0.x() >= -0.5 && out.p0.x() < intrinsics.width - 0.5 && out.p0.y() >= -0.5 &&
        out.p0.y() < intrinsics.height - 0.5)) {
    out.status = HomographyPoseStatus::PartOutsideImage;
    out.reason = "the part origin maps to pixel (" + std::to_string(out.p0.x()) + ", " + std::to_string(out.p0.y()) +
                 "), outside the " + std::to_string(intrinsics.width) + "x" + std::to_string(intrinsics.height) +
                 " image";
    return out;
  }
  Eigen::Vector3d P0, P1;
  if (!backProject(intrinsics, T_base_camera, out.p0, z_top, P0) ||
      !backProject(intrinsics, T_base_camera, out.p1, z_top, P1)) {
    out.status = HomographyPoseStatus::NotInView;
    out.reason = "the part's top plane is not in front of the camera along the rays of p0 and p1";
    return out;
  }
  // Rigidity: the map from the part's top plane to the table's that H implies.
  Eigen::Isometry3d T_camera_base = T_base_camera.inverse();
  Eigen::Matrix3d G = planeToImage(intrinsics, T_camera_base, z_top).inverse() * H * referenceToPlane(reference).inverse();
  G /= G(2, 2);
  const Eigen::Matrix2d A = G.topLeftCorner<2, 2>();
  out.singular_values = Eigen::JacobiSVD<Eigen::Matrix2d>(A).singularValues();
  const double scale_error =
      std::max(std::abs(out.singular_values(0) - 1.0), std::abs(out.singular_values(1) - 1.0));
  // Perspective terms over the reference image's extent act like a scale change there.
  const double extent = std::max(reference.width, reference.height) / reference.pixels_per_metre;
  const double perspective = G.bottomLeftCorner<1, 2>().norm() * extent;
  if (!(A.determinant() > 0.0) || !(scale_error <= settings.max_scale_error) ||
      !(perspective <= settings.max_scale_error)) {
    out.status = HomographyPoseStatus::NonRigid;
    out.reason = A.determinant() > 0.0 ? "the homography scales or shears the top plane: singular values " +
                                             std::to_string(out.singular_values(0)) + ", " +
                                             std::to_string(out.singular_values(1)) + ", perspective " +
                                             std::to_string(perspective) + " (max_scale_error " +
                                             std::to_string(settings.max_scale_error) + ")"
                                       : std::string("the homography mirrors the top plane");
    return out;
  }
  out.x = P0.x();
  out.y = P0.y();
  out.theta = std::atan2(P1.y() - P0.y(), P1.x() - P0.x());  // eq. (6) on the table plane
  out.T_base_part = Eigen::Translation3d(out.x, out.y, T_base_part_rough.translation().z()) *
                    Eigen::AngleAxisd(out.theta, Eigen::Vector3d::UnitZ());
  out.status = HomographyPoseStatus::Ok;
  return out;
}

}  // namespace scanalign
