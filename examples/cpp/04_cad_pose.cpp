// 04: pose of a part from its model cloud, in C++ only (no Python, no PCL): curvature-based
// descriptor + RANSAC with a Valkenburg–Dorst motor refit (thesis paper 5), then scanalign's
// point-to-plane ICP. Exits non-zero if the known pose is missed.
#include <cmath>
#include <cstdio>
#include <random>
#include <vector>

#include <Eigen/Geometry>

#include <scanalign/features/normals.hpp>
#include <scanalign/pose/cbd_alignment.hpp>
#include <scanalign/registration/icp.hpp>

int main() {
  // Model cloud (model frame, metres): the visible cap of a 100 x 60 x 40 mm ellipsoid with two
  // bumps of different sizes, as one camera view of a smooth cast part would see it.
  std::vector<double> model;
  for (int i = 0; i < 200; ++i)
    for (int j = 0; j < 400; ++j) {
      const double th = M_PI * (i + 0.5) / 200, ph = 2 * M_PI * j / 400;
      const double r = 1.0 + 0.3 * std::exp(-8 * ((th - 1.0) * (th - 1.0) + (ph - 1.0) * (ph - 1.0))) +
                       0.15 * std::exp(-30 * ((th - 1.2) * (th - 1.2) + (ph - 3.0) * (ph - 3.0)));
      const double z = 0.02 * r * std::cos(th);
      if (z < -0.004) continue;  // the underside is not seen
      model.insert(model.end(), {0.05 * r * std::sin(th) * std::cos(ph), 0.03 * r * std::sin(th) * std::sin(ph), z});
    }
  const scanalign::CloudView<double> model_view(model.data(), model.size() / 3);

  // The scan: the same surface at a known pose T_scene_model, with 0.02 mm noise.
  const Eigen::Affine3d T_true = Eigen::Translation3d(0.10, -0.05, 0.45) *
                                 Eigen::AngleAxisd(2.0, Eigen::Vector3d(1, -2, 0.5).normalized());
  std::mt19937 rng(1);
  std::normal_distribution<double> noise(0.0, 0.00002);
  std::vector<double> scene(model.size());
  for (std::size_t i = 0; i < model.size() / 3; ++i) {
    const Eigen::Vector3d p = T_true * Eigen::Vector3d(model[3 * i], model[3 * i + 1], model[3 * i + 2]);
    for (int k = 0; k < 3; ++k) scene[3 * i + k] = p[k] + noise(rng);
  }
  const scanalign::CloudView<double> scene_view(scene.data(), scene.size() / 3);

  // Coarse: CBD keypoints, descriptors, matches, RANSAC (thesis radius 6.3 mm, gamma 0.2/mm).
  scanalign::CbdAlignmentSettings cs;
  cs.cbd.min_neighbors = 0;  // automatic n_min for this density
  cs.cbd.keypoint_mode = scanalign::CbdKeypointMode::Automatic;  // a smooth part: no edge passes (6.4)
  cs.cbd.num_keypoints = 1000;
  const scanalign::CbdAlignmentResult coarse = scanalign::alignCbd(model_view, scene_view, cs);
  std::printf("CBD: %s, %zu/%zu keypoints, %zu of %zu matches consistent, fitness %.3f, %.0f ms\n",
              coarse.found ? "found" : coarse.message.c_str(), coarse.source_keypoints, coarse.target_keypoints,
              coarse.match_inliers, coarse.matches, coarse.fitness, 1000 * coarse.seconds);
  if (!coarse.found) return 1;

  // Fine: point-to-plane ICP against the scan (normals towards the camera at the origin).
  std::vector<double> normals(scene.size());
  scanalign::estimateNormals(scene_view, scanalign::NormalEstimationSettings{}, normals.data());
  scanalign::IcpSettings is;
  is.max_correspondence_distance = 0.005;
  scanalign::Icp<double> icp(is);
  icp.setTarget(scene_view, scanalign::CloudView<double>(normals.data(), normals.size() / 3));
  const scanalign::IcpResult fine = icp.align(model_view, coarse.T_target_source);
  const Eigen::Matrix4d T = fine.T_target_source;
  const double angle = Eigen::AngleAxisd(Eigen::Matrix3d(T.topLeftCorner<3, 3>().transpose() *
                                                         T_true.linear())).angle();
  const double dist = (T.topRightCorner<3, 1>() - T_true.translation()).norm();
  std::printf("ICP: %s, fitness %.3f, inlier RMSE %.3f mm; pose error %.4f deg, %.4f mm\n",
              scanalign::toString(fine.status), fine.fitness, 1000 * fine.inlier_rmse, angle * 180 / M_PI,
              1000 * dist);
  return angle < 0.2 * M_PI / 180 && dist < 0.0005 ? 0 : 1;
}
