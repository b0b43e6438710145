// The fine planar pose from a reference-to-image homography (Kleppe et al., Robotics 6 (2017)
// 14, eqs. (5)-(6)) against homographies written out by hand for a camera looking straight down,
// against the geometry of tilted cameras, its statuses, and the hand camera's view plan.
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <stdexcept>

#include "scanalign/grasp/view_planner.hpp"
#include "scanalign/pose/homography_pose.hpp"

using namespace scanalign;

namespace {

PinholeIntrinsics webcam() {  // a 1280x720 webcam (Logitech C930e-like), f = 900 px
  PinholeIntrinsics k;
  k.width = 1280;
  k.height = 720;
  k.fx = k.fy = 900.0;
  k.cx = 639.5;
  k.cy = 359.5;
  return k;
}

ReferenceImageGeometry label() {  // 60 x 40 mm top face at 0.2 mm per pixel, 25 mm above the origin
  ReferenceImageGeometry r;
  r.width = 300;
  r.height = 200;
  r.pixels_per_metre = 5000.0;
  r.origin_pixel = {149.5, 99.5};
  r.top_height = 0.025;
  return r;
}

Eigen::Isometry3d uprightPart(double x, double y, double z, double theta) {
  return Eigen::Translation3d(x, y, z) * Eigen::AngleAxisd(theta, Eigen::Vector3d::UnitZ());
}

/// Camera at (cx_w, cy_w, zc) looking straight down: camera x = base x, y = -base y, z = -base z.
Eigen::Isometry3d downCamera(double cx_w, double cy_w, double zc) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::Vector3d(1, -1, -1).asDiagonal();
  T.translation() = Eigen::Vector3d(cx_w, cy_w, zc);
  return T;
}

}  // namespace

TEST(HomographyPose, HandWrittenHomographiesGiveThePoseTo1e9) {
  // For the straight-down camera, reference pixel (u, v) lands at
  //   U = cx + (f/d) (x - cx_w) + a (cos t (u - ou) + sin t (v - ov)),
  //   V = cy - (f/d) (y - cy_w) - a (sin t (u - ou) - cos t (v - ov)),   a = f / (d s),
  // with d the camera's height above the top face: an affine H, written out here.
  const PinholeIntrinsics k = webcam();
  const ReferenceImageGeometry r = label();
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> off(-0.03, 0.03), ang(-3.1, 3.1);
  for (int trial = 0; trial < 200; ++trial) {
    const double x = 0.5 + off(rng), y = -0.2 + off(rng), z0 = 0.01, t = ang(rng);
    const double cxw = 0.5 + off(rng), cyw = -0.2 + off(rng), zc = 0.3;
    const double d = zc - (z0 + r.top_height), f = k.fx, s = r.pixels_per_metre, a = f / (d * s);
    const double ou = r.origin_pixel.x(), ov = r.origin_pixel.y();
    Eigen::Matrix3d H;
    H << a * std::cos(t), a * std::sin(t), k.cx + f / d * (x - cxw) - a * (std::cos(t) * ou + std::sin(t) * ov),
        -a * std::sin(t), a * std::cos(t), k.cy - f / d * (y - cyw) + a * (std::sin(t) * ou - std::cos(t) * ov), 0, 0,
        1;
    H *= -2.5;  // a homography is defined up to scale, sign included
    const Eigen::Isometry3d rough = uprightPart(x + 0.015, y - 0.012, z0, t + 0.1);
    const HomographyPose p = planarPoseFromHomography(H, r, k, downCamera(cxw, cyw, zc), rough);
    ASSERT_EQ(p.status, HomographyPoseStatus::Ok) << p.reason;
    EXPECT_NEAR(p.x, x, 1e-9);
    EXPECT_NEAR(p.y, y, 1e-9);
    EXPECT_NEAR(std::remainder(p.theta - t, 2 * M_PI), 0.0, 1e-9);
    EXPECT_LE((p.T_base_part.matrix() - uprightPart(x, y, z0, t).matrix()).cwiseAbs().maxCoeff(), 1e-9);
    EXPECT_NEAR(p.singular_values(0), 1.0, 1e-9);
    EXPECT_NEAR(p.singular_values(1), 1.0, 1e-9);
  }
}

TEST(HomographyPose, TiltedCamerasRoundTripThroughTheirGeometry) {
  // homographyOfPart against the projection of reference points through the camera model, then
  // planarPoseFromHomography recovers the part.
  const PinholeIntrinsics k = webcam();
  const ReferenceImageGeometry r = label();
  std::mt19937 rng(12);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (int trial = 0; trial < 200; ++trial) {
    const Eigen::Isometry3d part = uprightPart(0.4 + 0.05 * u(rng), 0.1 * u(rng), 0.02 * u(rng), 3.0 * u(rng));
    Eigen::Isometry3d cam = downCamera(part.translation().x() + 0.02 * u(rng), part.translation().y() + 0.02 * u(rng),
                                       0.35 + 0.05 * u(rng));
    cam.linear() = cam.linear() * Eigen::AngleAxisd(0.3 * u(rng), Eigen::Vector3d(u(rng), u(rng), 0.3).normalized())
                                      .toRotationMatrix();  // tilted up to 17 degrees
    const Eigen::Matrix3d H = homographyOfPart(r, k, cam, part);
    for (double pu : {0.0, 150.0, 299.0})
      for (double pv : {0.0, 77.0, 199.0}) {
        const Eigen::Vector3d X = cam.inverse() * (part * r.partPoint(pu, pv));
        const Eigen::Vector2d expect(k.cx + k.fx * X.x() / X.z(), k.cy + k.fy * X.y() / X.z());
        const Eigen::Vector3d h = H * Eigen::Vector3d(pu, pv, 1.0);
        ASSERT_LE((h.head<2>() / h.z() - expect).norm(), 1e-7);
      }
    const HomographyPose p = planarPoseFromHomography(H, r, k, cam, uprightPart(0.41, 0.01, part.translation().z(), 0));
    ASSERT_EQ(p.status, HomographyPoseStatus::Ok) << p.reason;
    EXPECT_LE((p.T_base_part.matrix() - part.matrix()).cwiseAbs().maxCoeff(), 1e-9);
  }
}

TEST(HomographyPose, StatusesSayWhatIsWrong) {
  const PinholeIntrinsics k = webcam();
  const ReferenceImageGeometry r = label();
  const Eigen::Isometry3d part = uprightPart(0.5, 0.0, 0.0, 0.4);
  const Eigen::Isometry3d cam = downCamera(0.5, 0.0, 0.3);
  const Eigen::Matrix3d H = homographyOfPart(r, k, cam, part);
  // A fit that stretched the reference by 30 %: not a rigid placement of the part.
  Eigen::Matrix3d stretched = H * Eigen::Vector3d(1.3, 1.0, 1.0).asDiagonal();
  auto p = planarPoseFromHomography(stretched, r, k, cam, part);
  EXPECT_EQ(p.status, HomographyPoseStatus::NonRigid);
  EXPECT_NE(p.reason.find("singular values"), std::string::npos) << p.reason;
  // Mirrored.
  p = planarPoseFromHomography(H * Eigen::Vector3d(-1.0, 1.0, 1.0).asDiagonal(), r, k, cam, part);
  EXPECT_EQ(p.status, HomographyPoseStatus::NonRigid);
  // A 14 % scale error passes the default tolerance (15 %), 16 % does not.
  EXPECT_EQ(planarPoseFromHomography(H * Eigen::Vector3d(1.14, 1.14, 1.0).asDiagonal(), r, k, cam, part).status,
            HomographyPoseStatus::Ok);
  EXPECT_EQ(planarPoseFromHomography(H * Eigen::Vector3d(1.16, 1.16, 1.0).asDiagonal(), r, k, cam, part).status,
            HomographyPoseStatus::NonRigid);
  // The part 40 cm to the side of a camera 30 cm up: its origin falls outside the image.
  p = planarPoseFromHomography(homographyOfPart(r, k, cam, uprightPart(0.9, 0.0, 0.0, 0.0)), r, k, cam, part);
  EXPECT_EQ(p.status, HomographyPoseStatus::PartOutsideImage);
  // A camera below the top plane, looking down: the plane is behind it.
  const Eigen::Isometry3d low = downCamera(0.5, 0.0, 0.01);
  p = planarPoseFromHomography(H, r, k, low, part);
  EXPECT_EQ(p.status, HomographyPoseStatus::NotInView);
  // Singular and non-finite.
  EXPECT_EQ(planarPoseFromHomography(Eigen::Matrix3d::Zero(), r, k, cam, part).status, HomographyPoseStatus::NotFinite);
  Eigen::Matrix3d nan = H;
  nan(0, 1) = NAN;
  EXPECT_EQ(planarPoseFromHomography(nan, r, k, cam, part).status, HomographyPoseStatus::NotFinite);
  // Bad arguments throw, naming them.
  PinholeIntrinsics distorted = k;
  distorted.distortion.k1 = 0.1;
  EXPECT_THROW(planarPoseFromHomography(H, r, distorted, cam, part), std::invalid_argument);
  ReferenceImageGeometry bad = r;
  bad.pixels_per_metre = 0;
  EXPECT_THROW(planarPoseFromHomography(H, bad, k, cam, part), std::invalid_argument);
  Eigen::Isometry3d skew = cam;
  skew.matrix()(0, 1) += 0.1;
  EXPECT_THROW(planarPoseFromHomography(H, r, k, skew, part), std::invalid_argument);
}

TEST(ViewPlanner, TheCameraLooksStraightDownFromTheChosenJoints) {
  Robot robot = Robot::ur5();
  Gripper mount;  // a camera 5 cm below the flange, looking along the tool axis, in a 6 x 6 x 6 cm box
  mount.T_flange_tcp = Eigen::Translation3d(0.0, 0.03, 0.05) * Eigen::Isometry3d::Identity();
  mount.box_centre = {0.0, 0.03, 0.03};
  mount.box_half_extents = {0.03, 0.03, 0.03};
  const Vector6d q0 = (Vector6d() << 0, -M_PI / 2, M_PI / 2, -M_PI / 2, -M_PI / 2, 0).finished();
  const Eigen::Isometry3d part = uprightPart(0.45, 0.15, 0.0, 0.7);
  ViewPlannerSettings settings;
  const ViewPlan plan = planCameraView(robot, part, 0.025, mount, Eigen::Vector4d(0, 0, 1, 0), q0, settings);
  ASSERT_TRUE(plan.found) << plan.message;
  EXPECT_EQ(plan.plan.candidates.size(), 4u * 8u);
  const Eigen::Isometry3d T = robot.forwardFlange(plan.q) * mount.T_flange_tcp;
  EXPECT_LE((T.matrix() - plan.T_base_camera.matrix()).cwiseAbs().maxCoeff(), 1e-9);
  EXPECT_NEAR(plan.T_base_camera.linear().col(2).z(), -1.0, 1e-12);  // optical axis straight down
  EXPECT_NEAR(plan.T_base_camera.translation().x(), 0.45, 1e-12);
  EXPECT_NEAR(plan.T_base_camera.translation().y(), 0.15, 1e-12);
  EXPECT_NEAR(plan.T_base_camera.translation().z(), 0.025 + settings.height, 1e-12);
  // Out of reach: no view, with the planner's reasons.
  const ViewPlan far = planCameraView(robot, uprightPart(3.0, 0.0, 0.0, 0.0), 0.025, mount,
                                      Eigen::Vector4d(0, 0, 1, 0), q0, settings);
  EXPECT_FALSE(far.found);
  EXPECT_NE(far.message.find("unreachable"), std::string::npos) << far.message;
  settings.height = -1;
  EXPECT_THROW(planCameraView(robot, part, 0.025, mount, Eigen::Vector4d(0, 0, 1, 0), q0, settings),
               std::invalid_argument);
}
