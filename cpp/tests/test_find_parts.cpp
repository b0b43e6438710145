// findParts: which built-in part lies in each cluster of a table scene, at which pose (against
// the poses the scene was built with), a cluster of no part, an ambiguous model list, the
// standoff's symmetric poses, and bad input.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include <Eigen/Geometry>

#include "scanalign/common/build_info.hpp"
#include "scanalign/pose/find_objects.hpp"
#include "scanalign/pose/part_identification.hpp"
#include "scanalign/synthetic/builtin_part.hpp"

namespace {

using namespace scanalign;

std::vector<ModelView> views(const std::string& name, int resolution = 100) {
  const BuiltinPartMesh m = builtinPartMesh(name, 48);
  std::vector<double> V;
  std::vector<std::int32_t> F;
  for (const auto& v : m.vertices) V.insert(V.end(), {v.x(), v.y(), v.z()});
  for (const auto& f : m.faces) F.insert(F.end(), {f.x(), f.y(), f.z()});
  ModelViewSettings s;
  s.resolution = resolution;
  return renderModelViews(CloudView<double>(V.data(), V.size() / 3), F.data(), F.size() / 3, s);
}

/// The view seen most nearly from `direction` (model frame): the scene's object cloud.
int viewFrom(const std::vector<ModelView>& v, const Eigen::Vector3d& direction) {
  int best = 0;
  for (std::size_t i = 0; i < v.size(); ++i)
    if (v[i].T_model_camera.col(3).head<3>().normalized().dot(direction.normalized()) >
        v[best].T_model_camera.col(3).head<3>().normalized().dot(direction.normalized()))
      best = static_cast<int>(i);
  return best;
}

struct TableScene {
  std::vector<double> points;
  std::mt19937 rng{3};
  std::normal_distribution<double> noise{0.0, 1e-4};  // Zivid-like, 0.1 mm
  TableScene() {  // a 0.5 x 0.5 m table top at z = 0, 3 mm grid
    for (double x = -0.25; x <= 0.25; x += 0.003)
      for (double y = -0.25; y <= 0.25; y += 0.003) add(Eigen::Vector3d(x, y, 0));
  }
  void add(const Eigen::Vector3d& p) { points.insert(points.end(), {p.x() + noise(rng), p.y() + noise(rng), p.z() + noise(rng)}); }
  void place(const ModelView& v, const Eigen::Isometry3d& T_scene_model) {
    for (std::size_t i = 0; i < v.size(); ++i) add(T_scene_model * Eigen::Vector3d(&v.points[3 * i]));
  }
  CloudView<double> cloud() const { return {points.data(), points.size() / 3}; }
};

Eigen::Isometry3d onTable(double x, double y, double yaw, double z) {
  return Eigen::Isometry3d(Eigen::Translation3d(x, y, z) * Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()));
}

/// The upper-hemisphere views: parts standing on a table in their CAD orientation.
std::vector<int> upperViews(const std::vector<ModelView>& v) {
  std::vector<int> ids;
  for (std::size_t i = 0; i < v.size(); ++i)
    if (v[i].T_model_camera(2, 3) > 0.2 * v[i].T_model_camera.col(3).head<3>().norm()) ids.push_back(static_cast<int>(i));
  return ids;
}

FindPartsSettings tableSettings() {
  FindPartsSettings s;
  s.table.up = Eigen::Vector3d::UnitZ();
  s.table.cluster_tolerance = 0.01;
  return s;
}

TEST(FindParts, NamesEachPartAndItsPoseAndRefusesAClusterOfNoPart) {
  // The bracket is left to tests/test_find_parts.py (a rendered camera image): from one
  // model view with its lowest 5 mm cut away by the table removal, it is found turned over.
  const std::vector<std::string> names = {"block", "standoff"};
  std::vector<std::vector<ModelView>> models;
  std::vector<PartSymmetry> sym;
  for (const auto& n : names) models.push_back(views(n)), sym.push_back(builtinPartSymmetry(n));
  const Eigen::Vector3d camera(0.3, -0.2, 1.0);  // the direction the scene is seen from
  const std::vector<Eigen::Isometry3d> truth = {onTable(-0.12, -0.10, 0.4, 0.015), onTable(-0.10, 0.12, 0.9, 0.0)};
  TableScene scene;
  for (std::size_t p = 0; p < names.size(); ++p) {  // the camera's image is denser than the model views
    const auto dense = views(names[p], 150);
    scene.place(dense[viewFrom(dense, truth[p].linear().transpose() * camera)], truth[p]);
  }
  // A sphere of radius 20 mm on the table (its upper half): no part looks like it.
  for (int i = 0; i < 4000; ++i) {
    const double u = std::uniform_real_distribution<double>(0, 1)(scene.rng), phi = 2 * M_PI * (i * 0.618034 - std::floor(i * 0.618034));
    const double z = u, r = std::sqrt(1 - z * z);
    scene.add(Eigen::Vector3d(0.12, -0.12, 0.02) + 0.02 * Eigen::Vector3d(r * std::cos(phi), r * std::sin(phi), z));
  }
  FindPartsSettings s = tableSettings();
  const FindPartsResult out = findParts(models, sym, scene.cloud(), s, upperViews(models[0]));
  ASSERT_EQ(out.detections.size(), 3u);
  std::vector<bool> seen(names.size(), false);
  for (const PartDetection& d : out.detections) {
    const Eigen::Vector3d c = Eigen::Vector3d(scene.cloud().ptr(d.indices[0]));
    if ((c.head<2>() - Eigen::Vector2d(0.12, -0.12)).norm() < 0.03) {
      EXPECT_EQ(d.status, DetectionStatus::NotFound) << d.message;
      EXPECT_FALSE(d.pose.found);
      continue;
    }
    ASSERT_EQ(d.status, DetectionStatus::Found) << d.message;
    const int p = d.part;
    ASSERT_GE(p, 0);
    EXPECT_LT((c.head<2>() - truth[p].translation().head<2>()).norm(), 0.05) << names[p] << " found elsewhere";
    seen[p] = true;
    const auto [angle, distance] = symmetricPoseError(Eigen::Isometry3d(d.pose.T_scene_model), truth[p], sym[p]);
    EXPECT_LT(angle, 0.5 * M_PI / 180) << names[p];
    EXPECT_LT(distance, 0.001) << names[p];
    EXPECT_TRUE(d.pose.found);
    EXPECT_EQ(d.parts.size(), names.size());
  }
  EXPECT_EQ(seen, std::vector<bool>(names.size(), true));
}

TEST(FindParts, TwoCopiesOfThePartAreAmbiguousButTheStandoffsSymmetricPosesAreNot) {
  const auto block = views("block"), standoff = views("standoff");
  const Eigen::Isometry3d T_block = onTable(0.0, 0.0, 0.7, 0.015), T_standoff = onTable(0.0, 0.0, 0.3, 0.0);
  const Eigen::Vector3d camera(0.2, 0.3, 1.0);
  FindPartsSettings s = tableSettings();
  {
    TableScene scene;
    const auto dense = views("block", 150);
    scene.place(dense[viewFrom(dense, T_block.linear().transpose() * camera)], T_block);
    const FindPartsResult out = findParts({block, block}, {}, scene.cloud(), s, upperViews(block));
    ASSERT_EQ(out.detections.size(), 1u);
    const PartDetection& d = out.detections[0];
    EXPECT_EQ(d.status, DetectionStatus::Ambiguous) << d.message;
    EXPECT_EQ(d.runner_up_part, 1 - d.part);
    EXPECT_GE(d.runner_up_score, (1 - s.ambiguity_margin) * d.score);
  }
  TableScene scene;
  const auto dense = views("standoff", 150);
  scene.place(dense[viewFrom(dense, T_standoff.linear().transpose() * camera)], T_standoff);
  PartSymmetry six;
  six.order = 6;
  const FindPartsResult out = findParts({standoff}, {six}, scene.cloud(), s, upperViews(standoff));
  ASSERT_EQ(out.detections.size(), 1u);
  const PartDetection& d = out.detections[0];
  EXPECT_EQ(d.status, DetectionStatus::Found) << d.message;
  const auto [angle, distance] = symmetricPoseError(Eigen::Isometry3d(d.pose.T_scene_model), T_standoff, six);
  EXPECT_LT(angle, 0.5 * M_PI / 180);
  EXPECT_LT(distance, 0.001);
  // Candidates of the standoff did land on other symmetric poses: the symmetry is what keeps
  // them from competing (without it, a 60-degree twist is a different pose).
  int twisted = 0;
  for (const PoseCandidate& c : d.pose.candidates) {
    if (!c.found || c.score < 0.9 * d.score) continue;
    const Eigen::Matrix3d R = d.pose.T_scene_model.topLeftCorner<3, 3>().transpose() * c.T_scene_model.topLeftCorner<3, 3>();
    if (Eigen::AngleAxisd(R).angle() > 0.5) ++twisted;
  }
  EXPECT_GT(twisted, 0);
}

TEST(FindParts, RefusesBadInput) {
  const auto standoff = views("standoff");
  TableScene scene;
  FindPartsSettings s = tableSettings();
  EXPECT_THROW(findParts({}, {}, scene.cloud(), s), std::invalid_argument);
  EXPECT_THROW(findParts({standoff}, {PartSymmetry{}, PartSymmetry{}}, scene.cloud(), s), std::invalid_argument);
  EXPECT_THROW(findParts({standoff, {}}, {}, scene.cloud(), s), std::invalid_argument);
  EXPECT_THROW(findParts({standoff}, {}, scene.cloud(), s, {99}), std::invalid_argument);
  PartSymmetry bad;
  bad.order = -1;
  EXPECT_THROW(findParts({standoff}, {bad}, scene.cloud(), s), std::invalid_argument);
  for (auto field : {&FindPartsSettings::ambiguity_margin, &FindPartsSettings::voxel_size, &FindPartsSettings::polish_distance,
                     &FindPartsSettings::same_pose_distance}) {
    FindPartsSettings b = s;
    b.*field = -1;
    EXPECT_THROW(findParts({standoff}, {}, scene.cloud(), b), std::invalid_argument);
  }
  // A table without objects: no detection, no error.
  EXPECT_TRUE(findParts({standoff}, {}, scene.cloud(), s).detections.empty());
  // A coarse method that cannot run is refused before any work, objects or not.
  FindPartsSettings external = s;
  external.pose.method = CoarseMethod::External;
  EXPECT_THROW(findParts({standoff}, {}, scene.cloud(), external), std::invalid_argument);  // no aligner
  if (!builtWithPcl()) {
    FindPartsSettings pcl = s;
    pcl.pose.method = CoarseMethod::Pcl;
    EXPECT_THROW(findParts({standoff}, {}, scene.cloud(), pcl), NotBuiltError);
  }
}

TEST(FindParts, DefaultSettingsRenderViewsAt100PixelsWithOneHypothesisPerView) {
  const FindPartsSettings s;
  const PoseSettings pose;
  EXPECT_EQ(s.pose.views.resolution, 100);  // as accurate as 150 on the built-in parts, 2-3x faster
  EXPECT_EQ(pose.views.resolution, 150);    // estimatePose's own default is left alone
  EXPECT_EQ(s.pose.cbd.hypotheses, 1);
  EXPECT_EQ(pose.cbd.hypotheses, 3);
  EXPECT_EQ(s.pose.method, CoarseMethod::Cbd);
  // The table of a pose search: the values the Python API used to restate, now the struct's.
  const FindObjectsSettings objects;
  for (const TableSegmentationSettings& t : {s.table, objects.table}) {
    EXPECT_EQ(t.plane.threshold, 0.005);
    EXPECT_EQ(t.cluster_tolerance, 0.01);
    EXPECT_EQ(t.min_cluster_size, 200u);
  }
  EXPECT_EQ(TableSegmentationSettings().cluster_tolerance, 0.02);  // segmentTable's own default is left alone
  EXPECT_EQ(s.pose.cbd.cbd.min_neighbors, 0);  // the rest is estimatePose's default
}

}  // namespace
