// 05: find a CAD part on a table, in C++ only (no Python, no PCL): the part's mesh is rendered
// from the 42 viewpoints of a tessellated sphere (Kleppe, PhD thesis, NTNU 2018, §7.3), the
// scan's table plane and object clusters are found with CGA RANSAC (paper 3), and each cluster
// is matched against every view with the curvature-based descriptor, RANSAC with a motor refit
// (paper 5) and point-to-plane ICP. Exits non-zero if the known pose is missed.
#include <cmath>
#include <cstdio>
#include <random>
#include <vector>

#include <Eigen/Geometry>

#include <scanalign/pose/find_objects.hpp>

namespace {

// Adds an axis-aligned box (corners lo, hi; metres) as 12 outward-wound triangles.
void addBox(std::vector<double>& V, std::vector<std::int32_t>& F, const Eigen::Vector3d& lo, const Eigen::Vector3d& hi) {
  const auto base = static_cast<std::int32_t>(V.size() / 3);
  for (int k = 0; k < 8; ++k) V.insert(V.end(), {k & 1 ? hi.x() : lo.x(), k & 2 ? hi.y() : lo.y(), k & 4 ? hi.z() : lo.z()});
  const int quads[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4}, {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
  for (const auto& q : quads) F.insert(F.end(), {base + q[0], base + q[1], base + q[2], base + q[0], base + q[2], base + q[3]});
}

}  // namespace

int main() {
  // The CAD part (model frame, metres): a 80 x 50 x 20 mm plate carrying an off-centre
  // 30 x 20 x 25 mm block and a 10 mm pin, so that no rotation maps it onto itself.
  std::vector<double> V;
  std::vector<std::int32_t> F;
  addBox(V, F, {-0.040, -0.025, 0.000}, {0.040, 0.025, 0.020});
  addBox(V, F, {0.000, -0.025, 0.020}, {0.030, -0.005, 0.045});
  addBox(V, F, {-0.030, 0.010, 0.020}, {-0.020, 0.020, 0.030});
  scanalign::FindObjectsSettings fs;
  fs.pose.views.resolution = 120;       // pixels: how the views below are rendered
  const std::vector<scanalign::ModelView> views = scanalign::renderModelViews(
      scanalign::CloudView<double>(V.data(), V.size() / 3), F.data(), F.size() / 3, fs.pose.views);
  std::printf("model: %zu views, view 5 has %zu points\n", views.size(), views[5].size());

  // The scan (camera frame): what view 5 saw, placed at a known pose with 0.1 mm noise, on a
  // table plane 60 mm below the part's origin, sampled every 2 mm.
  const Eigen::Affine3d T_true = Eigen::Translation3d(0.02, -0.01, 0.50) *
                                 Eigen::AngleAxisd(0.7, Eigen::Vector3d(0.3, -1.0, 0.4).normalized());
  std::mt19937 rng(3);
  std::normal_distribution<double> noise(0.0, 0.0001);
  std::vector<double> scene;
  for (std::size_t i = 0; i < views[5].size(); ++i) {
    const Eigen::Vector3d p = T_true * Eigen::Vector3d(&views[5].points[3 * i]);
    scene.insert(scene.end(), {p.x() + noise(rng), p.y() + noise(rng), p.z() + noise(rng)});
  }
  for (double x = -0.2; x <= 0.2; x += 0.002)
    for (double y = -0.2; y <= 0.2; y += 0.002) scene.insert(scene.end(), {x, y, 0.62 + noise(rng)});

  fs.table.plane.threshold = 0.005;     // m
  fs.table.cluster_tolerance = 0.01;    // m
  fs.table.min_cluster_size = 200;
  const scanalign::FindObjectsResult found = scanalign::findObjects(
      views, scanalign::CloudView<double>(scene.data(), scene.size() / 3), fs);
  std::printf("table: %s, %zu object(s), %.2f s\n", found.table.success() ? "found" : "missing",
              found.table.objects.size(), found.seconds);
  if (found.poses.empty() || !found.poses[0].found) return 1;
  const scanalign::PoseResult& r = found.poses[0];
  const Eigen::Matrix4d& T = r.T_scene_model;
  const double angle = Eigen::AngleAxisd(Eigen::Matrix3d(T.topLeftCorner<3, 3>().transpose() * T_true.linear())).angle();
  const double dist = (T.topRightCorner<3, 1>() - T_true.translation()).norm();
  std::printf("object 0: view %d, fitness %.3f, coverage %.3f, inlier RMSE %.3f mm; pose error %.3f deg, %.3f mm\n",
              r.view, r.fitness, r.coverage, 1000 * r.inlier_rmse, angle * 180 / M_PI, 1000 * dist);
  return angle < 1.0 * M_PI / 180 && dist < 0.002 ? 0 : 1;
}
