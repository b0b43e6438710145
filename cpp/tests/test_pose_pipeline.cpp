// The C++ CAD-pose pipeline: tessellated-sphere viewpoints, rendered model views against the
// analytic surface, estimatePose against a known pose, and its refusals.
#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <random>
#include <utility>

#include <Eigen/Geometry>

#include "scanalign/common/build_info.hpp"
#include "scanalign/pose/find_objects.hpp"
#include "scanalign/pose/pcl/coarse_aligner.hpp"
#include "scanalign/pose/pose_estimation.hpp"

namespace {

using scanalign::CloudView;

// A 60 x 40 x 20 mm block (corners at 0 and `size`): 8 vertices, 12 outward triangles.
struct Block {
  Eigen::Vector3d size{0.06, 0.04, 0.02};
  std::vector<double> V;
  std::vector<std::int32_t> F;
  Block() {
    for (int k = 0; k < 8; ++k) V.insert(V.end(), {k & 1 ? size.x() : 0.0, k & 2 ? size.y() : 0.0, k & 4 ? size.z() : 0.0});
    F = {0, 2, 3, 0, 3, 1, 4, 5, 7, 4, 7, 6, 0, 1, 5, 0, 5, 4, 2, 6, 7, 2, 7, 3, 0, 4, 6, 0, 6, 2, 1, 3, 7, 1, 7, 5};
  }
  CloudView<double> vertices() const { return {V.data(), V.size() / 3}; }
};

TEST(ModelViews, TessellatedSphereIsClosedUnitAndWoundOutwards) {
  for (int level = 0; level <= 2; ++level) {
    const auto s = scanalign::tessellatedSphere(level);
    const std::size_t nv = 10 * (std::size_t{1} << (2 * level)) + 2, nf = 20 * (std::size_t{1} << (2 * level));
    ASSERT_EQ(s.vertices.size(), nv);
    ASSERT_EQ(s.faces.size(), nf);
    std::map<std::pair<int, int>, int> edges;
    for (const auto& f : s.faces) {
      for (int k = 0; k < 3; ++k) ++edges[{std::min(f[k], f[(k + 1) % 3]), std::max(f[k], f[(k + 1) % 3])}];
      const Eigen::Vector3d a = s.vertices[f[0]], b = s.vertices[f[1]], c = s.vertices[f[2]];
      EXPECT_GT((b - a).cross(c - a).dot(a + b + c), 0.0);  // outward
    }
    for (const auto& e : edges) EXPECT_EQ(e.second, 2);    // closed
    EXPECT_EQ(static_cast<long>(nv) - static_cast<long>(edges.size()) + static_cast<long>(nf), 2);  // Euler
    for (const auto& v : s.vertices) EXPECT_NEAR(v.norm(), 1.0, 1e-15);
  }
  EXPECT_THROW(scanalign::tessellatedSphere(-1), std::invalid_argument);
}

TEST(ModelViews, PointsLieOnTheBlockFaceTheirCameraAndReproject) {
  const Block b;
  scanalign::ModelViewSettings s;
  s.resolution = 80;
  const auto views = scanalign::renderModelViews(b.vertices(), b.F.data(), b.F.size() / 3, s);
  ASSERT_EQ(views.size(), 42u);
  for (const auto& v : views) {
    ASSERT_GT(v.size(), 100u);
    const Eigen::Vector3d eye = v.T_model_camera.topRightCorner<3, 1>();
    for (std::size_t i = 0; i < v.size(); ++i) {
      const Eigen::Vector3d p(&v.points[3 * i]), n(&v.normals[3 * i]);
      // On the block's surface: inside the box and on one of its faces (exact z-buffer, up to
      // the float32 depth buffer: 6e-8 relative at ~0.1 m).
      const Eigen::Vector3d lo = p, hi = b.size - p;
      EXPECT_GT(std::min(lo.minCoeff(), hi.minCoeff()), -1e-7);
      EXPECT_LT(std::min(lo.cwiseAbs().minCoeff(), hi.cwiseAbs().minCoeff()), 1e-7);
      EXPECT_NEAR(n.norm(), 1.0, 1e-12);
      EXPECT_GT(n.dot(eye - p), 0.0);  // towards the camera
      const Eigen::Vector3d pc = v.T_model_camera.topLeftCorner<3, 3>().transpose() * (p - eye);
      EXPECT_NEAR(v.intrinsics.fx * pc.x() / pc.z() + v.intrinsics.cx, v.pixels[2 * i], 1e-6);
      EXPECT_NEAR(v.intrinsics.fy * pc.y() / pc.z() + v.intrinsics.cy, v.pixels[2 * i + 1], 1e-6);
    }
  }
  std::vector<std::int32_t> bad = b.F;
  bad[4] = 99;
  EXPECT_THROW(scanalign::renderModelViews(b.vertices(), bad.data(), bad.size() / 3, s), std::invalid_argument);
  s.resolution = 1;
  EXPECT_THROW(scanalign::renderModelViews(b.vertices(), b.F.data(), b.F.size() / 3, s), std::invalid_argument);
}

// Two blocks (an L-shaped part: no rotation maps it onto itself), its views at 120 pixels,
// and what view 9 saw placed at a known pose with 0.05 mm noise.
struct LPartScene {
  std::vector<scanalign::ModelView> views;
  Eigen::Affine3d T_true = Eigen::Translation3d(-0.05, 0.03, 0.4) * Eigen::AngleAxisd(2.1, Eigen::Vector3d(1, 1, -0.5).normalized());
  std::vector<double> scene;
  LPartScene() {
    Block a;
    std::vector<double> V = a.V;
    std::vector<std::int32_t> F = a.F;
    for (int k = 0; k < 8; ++k) V.insert(V.end(), {k & 1 ? 0.02 : 0.0, k & 2 ? 0.04 : 0.0, k & 4 ? 0.05 : 0.02});
    for (std::size_t i = 0; i < a.F.size(); ++i) F.push_back(a.F[i] + 8);
    scanalign::ModelViewSettings vs;
    vs.resolution = 120;
    views = scanalign::renderModelViews(CloudView<double>(V.data(), V.size() / 3), F.data(), F.size() / 3, vs);
    std::mt19937 rng(7);
    std::normal_distribution<double> noise(0.0, 5e-5);
    for (std::size_t i = 0; i < views[9].size(); ++i) {
      const Eigen::Vector3d p = T_true * Eigen::Vector3d(&views[9].points[3 * i]);
      scene.insert(scene.end(), {p.x() + noise(rng), p.y() + noise(rng), p.z() + noise(rng)});
    }
  }
  CloudView<double> cloud() const { return {scene.data(), scene.size() / 3}; }
};

TEST(PoseEstimation, RecoversAKnownPoseOfAViewAndRefusesBadInput) {
  const LPartScene l;
  const auto& views = l.views;
  const Eigen::Affine3d& T_true = l.T_true;
  const std::vector<double>& scene = l.scene;
  const CloudView<double> sv = l.cloud();
  const scanalign::PoseResult r = scanalign::estimatePose(views, sv, {}, {9, 20, 33});
  ASSERT_TRUE(r.found) << r.message;
  EXPECT_EQ(r.view, 9);
  ASSERT_EQ(r.candidates.size(), 3u);
  const Eigen::Matrix3d dR = r.T_scene_model.topLeftCorner<3, 3>().transpose() * T_true.linear();
  EXPECT_LT(Eigen::AngleAxisd(dR).angle(), 0.5 * M_PI / 180);
  EXPECT_LT((r.T_scene_model.topRightCorner<3, 1>() - T_true.translation()).norm(), 0.001);
  EXPECT_GT(r.fitness, 0.95);
  EXPECT_GT(r.coverage, 0.95);

  // Refusals: a tiny scene is a status, bad settings and indices are exceptions.
  const scanalign::PoseResult tiny = scanalign::estimatePose(views, CloudView<double>(scene.data(), 5), {}, {9});
  EXPECT_FALSE(tiny.found);
  EXPECT_NE(tiny.message.find("need at least 10"), std::string::npos);
  EXPECT_THROW(scanalign::estimatePose(views, sv, {}, {42}), std::invalid_argument);
  scanalign::PoseSettings bad;
  bad.inlier_threshold = -1;
  EXPECT_THROW(scanalign::estimatePose(views, sv, bad, {9}), std::invalid_argument);
  scanalign::PoseSettings external;
  external.method = scanalign::CoarseMethod::External;
  EXPECT_THROW(scanalign::estimatePose(views, sv, external, {9}), std::invalid_argument);  // no aligner
}

TEST(FindObjects, SegmentsTheTableAndEstimatesThePoseOfEachCluster) {
  // The L part's scene in front of a table 0.5 m from the camera (2 mm grid), which the part
  // does not touch: one cluster, whose pose is estimatePose's on the cluster's points.
  const LPartScene l;
  std::vector<double> scene = l.scene;
  for (double x = -0.2; x <= 0.2; x += 0.002)
    for (double y = -0.2; y <= 0.2; y += 0.002) scene.insert(scene.end(), {x, y, 0.5});
  scanalign::FindObjectsSettings s;
  s.table.cluster_tolerance = 0.01;
  s.table.min_cluster_size = 200;
  const CloudView<double> cloud(scene.data(), scene.size() / 3);
  const scanalign::FindObjectsResult out = scanalign::findObjects(l.views, cloud, s, {9, 20, 33});
  ASSERT_TRUE(out.table.success());
  ASSERT_EQ(out.poses.size(), 1u);
  ASSERT_EQ(out.table.objects[0].size(), l.scene.size() / 3);  // every point of the part, none of the table
  const scanalign::PoseResult& r = out.poses[0];
  ASSERT_TRUE(r.found) << r.message;
  const Eigen::Matrix3d dR = r.T_scene_model.topLeftCorner<3, 3>().transpose() * l.T_true.linear();
  EXPECT_LT(Eigen::AngleAxisd(dR).angle(), 0.5 * M_PI / 180);
  EXPECT_LT((r.T_scene_model.topRightCorner<3, 1>() - l.T_true.translation()).norm(), 0.001);
  std::vector<double> object;
  for (std::uint32_t i : out.table.objects[0]) object.insert(object.end(), cloud.ptr(i), cloud.ptr(i) + 3);
  const scanalign::PoseResult alone =
      scanalign::estimatePose(l.views, CloudView<double>(object.data(), object.size() / 3), s.pose, {9, 20, 33});
  EXPECT_LT((alone.T_scene_model - r.T_scene_model).cwiseAbs().maxCoeff(), 1e-9);
  EXPECT_EQ(alone.view, r.view);
  // An external method without its aligner is refused before the table is segmented.
  s.pose.method = scanalign::CoarseMethod::External;
  EXPECT_THROW(scanalign::findObjects(l.views, cloud, s), std::invalid_argument);
}

// The visible cap of a 100 x 60 x 40 mm ellipsoid with two bumps of different sizes (model
// frame, m; examples/cpp/04_cad_pose.cpp) as one model view, and the same surface at a known
// pose with 0.02 mm noise. PCL orients both clouds' normals towards the origin, so the pose
// keeps the origin under the cap (a turn and a displacement of a few centimetres).
struct BumpyCapScene {
  std::vector<scanalign::ModelView> views{1};
  Eigen::Affine3d T_true = Eigen::Translation3d(0.01, -0.02, 0.015) * Eigen::AngleAxisd(2.0, Eigen::Vector3d(1, -2, 0.5).normalized());
  std::vector<double> scene;
  BumpyCapScene() {
    scanalign::ModelView& v = views[0];
    for (int i = 0; i < 100; ++i)
      for (int j = 0; j < 200; ++j) {
        const double th = M_PI * (i + 0.5) / 100, ph = 2 * M_PI * j / 200;
        const double r = 1.0 + 0.3 * std::exp(-8 * ((th - 1.0) * (th - 1.0) + (ph - 1.0) * (ph - 1.0))) +
                         0.15 * std::exp(-30 * ((th - 1.2) * (th - 1.2) + (ph - 3.0) * (ph - 3.0)));
        const double z = 0.02 * r * std::cos(th);
        if (z < -0.004) continue;  // the underside is not seen
        v.points.insert(v.points.end(), {0.05 * r * std::sin(th) * std::cos(ph), 0.03 * r * std::sin(th) * std::sin(ph), z});
      }
    v.normals.assign(v.points.size(), 0.0);  // not used by the PCL baselines, nor by ICP (scene normals)
    std::mt19937 rng(1);
    std::normal_distribution<double> noise(0.0, 2e-5);
    for (std::size_t i = 0; i < v.size(); ++i) {
      const Eigen::Vector3d p = T_true * Eigen::Vector3d(&v.points[3 * i]);
      scene.insert(scene.end(), {p.x() + noise(rng), p.y() + noise(rng), p.z() + noise(rng)});
    }
  }
  CloudView<double> cloud() const { return {scene.data(), scene.size() / 3}; }
};

TEST(PoseEstimation, PclMethodWithTheFpfhPresetRecoversAKnownPoseOrIsNotBuilt) {
  // The stock PCL baseline chosen by the settings alone (no aligner passed): the thesis's FPFH
  // preset (prerejective RANSAC), then scanalign's ICP; the truth is the pose the scene was
  // made with.
  const BumpyCapScene l;
  scanalign::PoseSettings s;
  s.method = scanalign::CoarseMethod::Pcl;
  EXPECT_EQ(s.pcl.descriptor, scanalign::PclDescriptor::FPFH);  // the default baseline
  s.pcl = scanalign::thesisPclPreset(scanalign::PclDescriptor::FPFH);
  s.pcl.voxel_size = 0.003;  // 3 mm instead of 1 mm, to keep the test short (as tests/test_pose.py)
  s.pcl.num_threads = 2;
  if (!scanalign::builtWithPcl()) {
    EXPECT_THROW(scanalign::estimatePose(l.views, l.cloud(), s), scanalign::NotBuiltError);
    return;
  }
  const scanalign::PoseResult r = scanalign::estimatePose(l.views, l.cloud(), s);
  ASSERT_TRUE(r.found) << r.message;
  EXPECT_EQ(r.method, "fpfh");
  EXPECT_EQ(r.view, 0);
  const Eigen::Matrix3d dR = r.T_scene_model.topLeftCorner<3, 3>().transpose() * l.T_true.linear();
  EXPECT_LT(Eigen::AngleAxisd(dR).angle(), 0.5 * M_PI / 180);
  EXPECT_LT((r.T_scene_model.topRightCorner<3, 1>() - l.T_true.translation()).norm(), 0.001);
  EXPECT_GT(r.fitness, 0.95);
  EXPECT_GT(r.coverage, 0.95);
}

TEST(PoseEstimation, PclMethodWithPfhRsdGasdVfhRecoversAKnownPose) {
  // The four baselines added beside FPFH (thesis ch. 3, Paper 5 Table I, Paper 3), each chosen by
  // the settings alone, then scanalign's ICP; the truth is the pose the scene was made with.
  if (!scanalign::builtWithPcl()) GTEST_SKIP() << "built without PCL (the FPFH test checks NotBuiltError)";
  const BumpyCapScene l;
  using scanalign::PclDescriptor;
  for (const PclDescriptor d : {PclDescriptor::PFH, PclDescriptor::RSD, PclDescriptor::GASD, PclDescriptor::VFH}) {
    SCOPED_TRACE(scanalign::toString(d));
    scanalign::PoseSettings s;
    s.method = scanalign::CoarseMethod::Pcl;
    s.pcl = scanalign::thesisPclPreset(d);
    s.pcl.voxel_size = 0.003;  // as the FPFH test
    s.pcl.num_threads = 2;
    if (d == PclDescriptor::PFH) s.pcl.feature_radius = 0.015;   // k^2 pairs per point (tests/test_pose.py)
    if (d == PclDescriptor::RSD) s.pcl.max_iterations = 20000;   // two numbers per point: ambiguous matches
    const scanalign::PoseResult r = scanalign::estimatePose(l.views, l.cloud(), s);
    ASSERT_TRUE(r.found) << r.message;
    EXPECT_EQ(r.method, scanalign::toString(d));
    const Eigen::Matrix3d dR = r.T_scene_model.topLeftCorner<3, 3>().transpose() * l.T_true.linear();
    EXPECT_LT(Eigen::AngleAxisd(dR).angle(), 0.5 * M_PI / 180);
    EXPECT_LT((r.T_scene_model.topRightCorner<3, 1>() - l.T_true.translation()).norm(), 0.001);
    EXPECT_GT(r.fitness, 0.95);
  }
}

TEST(PoseEstimation, SettingsHoldTheViewsAndNameThePclBaseline) {
  const scanalign::PoseSettings s;
  EXPECT_EQ(s.views.resolution, 150);  // as Python's estimate_pose renders a mesh
  EXPECT_EQ(s.views.level, 1);         // the thesis's 42 views
  EXPECT_STREQ(scanalign::toString(scanalign::CoarseMethod::Pcl), "pcl");
  using scanalign::PclDescriptor;
  using scanalign::PclMatcher;
  using scanalign::thesisPclPreset;
  EXPECT_EQ(scanalign::pclBaselineName(thesisPclPreset(PclDescriptor::FPFH)), "fpfh");
  EXPECT_EQ(scanalign::pclBaselineName(thesisPclPreset(PclDescriptor::FPFH, PclMatcher::SacIA)), "fpfh_sac_ia");
  EXPECT_EQ(scanalign::pclBaselineName(thesisPclPreset(PclDescriptor::SHOT)), "shot");
  EXPECT_EQ(scanalign::pclBaselineName(thesisPclPreset(PclDescriptor::ShapeContext3D)), "3dsc");
  EXPECT_EQ(scanalign::pclBaselineName(thesisPclPreset(PclDescriptor::PPF, PclMatcher::SacIA)), "ppf");
  EXPECT_EQ(scanalign::pclBaselineName(thesisPclPreset(PclDescriptor::PFH)), "pfh");
  EXPECT_EQ(scanalign::pclBaselineName(thesisPclPreset(PclDescriptor::RSD)), "rsd");
  // GASD and VFH (OUR-CVFH) take the pose from reference frames: no matcher, so no suffix.
  EXPECT_EQ(scanalign::pclBaselineName(thesisPclPreset(PclDescriptor::GASD, PclMatcher::SacIA)), "gasd");
  EXPECT_EQ(scanalign::pclBaselineName(thesisPclPreset(PclDescriptor::VFH, PclMatcher::SacIA)), "vfh");
}

}  // namespace
