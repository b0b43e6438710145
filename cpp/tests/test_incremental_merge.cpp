// FrameToModel::merge folds frames into the model through a voxel hash; its definition is
// the re-grid of the whole model: voxelGrid(model points + frame points), each model point
// counting as one point, normals averaged and re-normalised, colours averaged. These tests
// keep that oracle beside the pipeline over several merges and compare.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <array>
#include <numeric>
#include <random>
#include <set>
#include <string>
#include <vector>

#include "scanalign/reconstruction/frame_to_model.hpp"
#include "scanalign/reconstruction/voxel_grid.hpp"
#include "test_support.hpp"

using scanalign::CloudView;
using scanalign::FrameToModel;
using scanalign::Model;
using scanalign::PreparedFrame;

namespace {

/// A frame: noisy samples of the test surface (camera coordinates), unit normals, colours
/// that vary along x; some points sit exactly on 1 mm voxel boundaries.
PreparedFrame makeFrame(std::uint32_t seed, bool with_colors, bool flip_normals = false) {
  const auto s = scanalign::test::wavySurfaceWithSphere(90, 0.12, seed);
  std::mt19937 rng(seed);
  std::normal_distribution<double> noise(0.0, 0.0002);
  std::uniform_int_distribution<int> keep(0, 3);
  PreparedFrame f;
  for (std::size_t i = 0; i < s.size(); ++i) {
    if (keep(rng) == 0) continue;
    float p[3];
    for (int k = 0; k < 3; ++k) p[k] = static_cast<float>(s.points[3 * i + k] + noise(rng));
    if (i % 50 == 0) p[0] = static_cast<float>(std::round(p[0] * 1000.0) / 1000.0);  // on a voxel face
    f.points.insert(f.points.end(), p, p + 3);
    for (int k = 0; k < 3; ++k) f.normals.push_back(flip_normals ? -s.normals[3 * i + k] : s.normals[3 * i + k]);
    if (with_colors)
      f.colors.insert(f.colors.end(), {static_cast<std::uint8_t>(128 + 1000 * p[0]), static_cast<std::uint8_t>(i % 256),
                                       static_cast<std::uint8_t>(40 + seed)});
  }
  return f;
}

/// The oracle: re-grid of the model with the frame (in the model frame) appended.
Model regrid(const Model& model, const PreparedFrame& frame, const Eigen::Matrix4d& T, double leaf) {
  const std::size_t m = model.size(), n = frame.size();
  const bool colored = !model.colors.empty() || !frame.colors.empty();
  const std::size_t dim = colored ? 6 : 3;
  std::vector<float> pts(model.points);
  std::vector<double> attrs;
  for (std::size_t i = 0; i < m; ++i) {
    for (int c = 0; c < 3; ++c) attrs.push_back(model.normals[3 * i + c]);
    if (colored)
      for (int c = 0; c < 3; ++c) attrs.push_back(model.colors.empty() ? 128.0 : model.colors[3 * i + c]);
  }
  const Eigen::Matrix3d R = T.topLeftCorner<3, 3>();
  const Eigen::Vector3d t = T.topRightCorner<3, 1>();
  for (std::size_t i = 0; i < n; ++i) {
    const Eigen::Vector3d p =
        R * Eigen::Vector3d(frame.points[3 * i], frame.points[3 * i + 1], frame.points[3 * i + 2]) + t;
    const Eigen::Vector3d q =
        R * Eigen::Vector3d(frame.normals[3 * i], frame.normals[3 * i + 1], frame.normals[3 * i + 2]);
    for (int c = 0; c < 3; ++c) pts.push_back(static_cast<float>(p[c]));
    for (int c = 0; c < 3; ++c) attrs.push_back(q[c]);
    if (colored)
      for (int c = 0; c < 3; ++c) attrs.push_back(frame.colors.empty() ? 128.0 : frame.colors[3 * i + c]);
  }
  const auto g = scanalign::voxelGrid(CloudView<float>(pts.data(), m + n), leaf, attrs.data(), dim);
  Model out;
  for (std::size_t i = 0; i < g.size(); ++i) {
    const double* a = &g.attributes[dim * i];
    const double len = std::sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]);
    for (int c = 0; c < 3; ++c) {
      out.points.push_back(static_cast<float>(g.points[3 * i + c]));
      out.normals.push_back(static_cast<float>(a[c] * (len > 1e-6 ? 1.0 / len : std::nan(""))));
      if (colored) out.colors.push_back(static_cast<std::uint8_t>(std::clamp(std::lround(a[3 + c]), 0L, 255L)));
    }
  }
  return out;
}

/// Indices of a model's points sorted by their coordinates (one point per voxel: unique).
std::vector<std::size_t> byPosition(const Model& m) {
  std::vector<std::size_t> order(m.size());
  std::iota(order.begin(), order.end(), 0);
  std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
    return std::lexicographical_compare(&m.points[3 * a], &m.points[3 * a + 3], &m.points[3 * b], &m.points[3 * b + 3]);
  });
  return order;
}

using VoxelKey = std::array<std::int64_t, 3>;

VoxelKey voxelOf(const float* p, double leaf) {
  const float inv = 1.0f / static_cast<float>(leaf);
  return {scanalign::voxelCoordinate(p[0], inv), scanalign::voxelCoordinate(p[1], inv),
          scanalign::voxelCoordinate(p[2], inv)};
}

/// The voxels a frame's points fall into at pose T.
std::set<VoxelKey> touchedVoxels(const PreparedFrame& frame, const Eigen::Matrix4d& T, double leaf) {
  std::set<VoxelKey> out;
  for (std::size_t i = 0; i < frame.size(); ++i) {
    const Eigen::Vector3d p = T.topLeftCorner<3, 3>() * Eigen::Vector3d(frame.points[3 * i], frame.points[3 * i + 1],
                                                                        frame.points[3 * i + 2]) +
                              T.topRightCorner<3, 1>();
    const float pf[3] = {static_cast<float>(p[0]), static_cast<float>(p[1]), static_cast<float>(p[2])};
    if (std::isfinite(pf[0]) && std::isfinite(pf[1]) && std::isfinite(pf[2])) out.insert(voxelOf(pf, leaf));
  }
  return out;
}

/// Same points and colours bit for bit; normals bit for bit in the voxels the last frame
/// touched, elsewhere up to the rounding of re-normalising a unit vector (the re-grid
/// re-normalises every normal, the incremental merge only those it changes).
void expectSameModel(const Model& got, const Model& want, const std::set<VoxelKey>& touched, double leaf,
                     float normal_tolerance, const std::string& what) {
  ASSERT_EQ(got.size(), want.size()) << what;
  ASSERT_EQ(got.colors.size(), want.colors.size()) << what;
  const auto a = byPosition(got), b = byPosition(want);
  std::size_t exact_normals = 0;
  for (std::size_t k = 0; k < a.size(); ++k) {
    const std::size_t i = a[k], j = b[k];
    for (int c = 0; c < 3; ++c) {
      ASSERT_EQ(got.points[3 * i + c], want.points[3 * j + c]) << what << " voxel " << k;
      if (!got.colors.empty()) ASSERT_EQ(got.colors[3 * i + c], want.colors[3 * j + c]) << what << " voxel " << k;
    }
    const bool exact = touched.count(voxelOf(&want.points[3 * j], leaf)) > 0;
    exact_normals += exact;
    for (int c = 0; c < 3; ++c) {
      const float gn = got.normals[3 * i + c], wn = want.normals[3 * j + c];
      ASSERT_EQ(std::isnan(gn), std::isnan(wn)) << what << " voxel " << k;
      if (std::isnan(wn)) continue;
      if (exact)
        ASSERT_EQ(gn, wn) << what << " touched voxel " << k;
      else
        ASSERT_NEAR(gn, wn, normal_tolerance) << what << " voxel " << k;
    }
  }
  if (!touched.empty()) EXPECT_GT(exact_normals, 0u) << what;
}

}  // namespace

TEST(IncrementalMerge, EqualsRegriddingTheModelOverManyMerges) {
  scanalign::FrameToModelSettings s;
  FrameToModel f2m(s);
  const Eigen::Matrix4d T0 = scanalign::test::rigid(0.1, -0.05, 0.2, 0.3, -0.2, 0.1);
  f2m.reset(T0);
  Model chained;  // the re-grid applied merge after merge, from the start
  std::size_t nan_voxels = 0;
  for (int k = 0; k < 8; ++k) {
    // Frames 0-2 without colour (the model is colourless, then turns grey where a coloured
    // frame arrives); small motions so most points land in voxels the model already has;
    // frame 5 is frame 4 again at the same pose seen from behind: the normals of voxels
    // holding one point cancel to NaN.
    const PreparedFrame frame = makeFrame(k == 5 ? 15 : 11 + k, k >= 3, k == 5);
    const int pose = k == 5 ? 4 : k;
    const Eigen::Matrix4d T = T0 * scanalign::test::rigid(0.01 * pose, -0.007 * pose, 0.02 * pose, 0.002 * pose,
                                                          0.001 * pose, -0.0015 * pose);
    const std::set<VoxelKey> touched = touchedVoxels(frame, T, s.model_voxel_size);
    // One merge against the re-grid of the same model: bit-identical where the frame went.
    const Model one = regrid(f2m.model(), frame, T, s.model_voxel_size);
    chained = regrid(chained, frame, T, s.model_voxel_size);
    const std::size_t size = f2m.merge(frame, T);
    ASSERT_EQ(size, one.size());
    expectSameModel(f2m.model(), one, touched, s.model_voxel_size, 3e-7f, "merge " + std::to_string(k));
    // Against the re-grid from the start: the untouched voxels' re-normalisations the
    // incremental merge skips stay at the level of float rounding.
    expectSameModel(f2m.model(), chained, {}, s.model_voxel_size, 1e-6f, "chained, merge " + std::to_string(k));
    EXPECT_EQ(f2m.lastPose(), T);
    if (k == 5)
      for (std::size_t i = 0; i < one.size(); ++i) nan_voxels += std::isnan(one.normals[3 * i]);
  }
  EXPECT_GT(nan_voxels, 0u) << "the opposite-normal frame should cancel some voxels";
  EXPECT_EQ(f2m.framesMerged(), 8);
}

TEST(IncrementalMerge, FallsBackToTheRegridFarAwayAndWhenTheLeafChanges) {
  scanalign::FrameToModelSettings s;
  FrameToModel f2m(s);
  // 2 km from the model origin: beyond the index's +-2^20 voxels of 1 mm, so every merge
  // re-grids, in the re-grid's own order.
  const Eigen::Matrix4d far = scanalign::test::rigid(0.0, 0.0, 0.3, 2000.0, -5.0, 1.0);
  for (int k = 0; k < 3; ++k) {
    const PreparedFrame frame = makeFrame(30 + k, true);
    const Eigen::Matrix4d T = far * scanalign::test::rigid(0.0, 0.0, 0.02 * k, 0.001 * k, 0.0, 0.0);
    const Model oracle = regrid(f2m.model(), frame, T, s.model_voxel_size);
    f2m.merge(frame, T);
    EXPECT_EQ(f2m.model().points, oracle.points);
    EXPECT_EQ(f2m.model().colors, oracle.colors);
    expectSameModel(f2m.model(), oracle, touchedVoxels(frame, T, s.model_voxel_size), s.model_voxel_size, 0.0f,
                    "far merge " + std::to_string(k));
  }
  // Back near the origin; from the third merge on a coarser grid: the whole model is
  // re-gridded at 2 mm once, then merged incrementally at 2 mm.
  f2m.reset();
  for (int k = 0; k < 5; ++k) {
    if (k == 2) f2m.settings().model_voxel_size = 0.002;
    const double leaf = f2m.settings().model_voxel_size;
    const PreparedFrame frame = makeFrame(40 + k, true);
    const Eigen::Matrix4d T = scanalign::test::rigid(0.0, 0.01 * k, 0.0, 0.0, 0.001 * k, 0.0);
    const Model oracle = regrid(f2m.model(), frame, T, leaf);
    f2m.merge(frame, T);
    // At the leaf change every voxel is re-gridded (all normals re-normalised).
    expectSameModel(f2m.model(), oracle, touchedVoxels(frame, T, leaf), leaf, k == 2 ? 0.0f : 3e-7f,
                    "leaf change, merge " + std::to_string(k));
  }
}

TEST(IncrementalMerge, SkipsNonFinitePointsAndRejectsBadFrames) {
  FrameToModel f2m;
  PreparedFrame frame = makeFrame(50, true);
  const Model none;
  frame.points[0] = std::nanf("");
  const Eigen::Matrix4d T = Eigen::Matrix4d::Identity();
  const Model oracle = regrid(none, frame, T, 0.001);
  f2m.merge(frame, T);
  expectSameModel(f2m.model(), oracle, touchedVoxels(frame, T, 0.001), 0.001, 0.0f, "NaN point");
  PreparedFrame bad = frame;
  bad.normals.pop_back();
  const Model before = f2m.model();
  EXPECT_THROW(f2m.merge(bad, T), std::invalid_argument);
  EXPECT_EQ(f2m.model().points, before.points);
}
