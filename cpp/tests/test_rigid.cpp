// Rigid-transform checks and the one Kabsch/Umeyama implementation (common/rigid.hpp),
// against Eigen's own umeyama and known motions.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>
#include <vector>

#include <Eigen/Geometry>

#include "scanalign/common/rigid.hpp"
#include "test_support.hpp"

using namespace scanalign;
using scanalign::test::rigid;

namespace {
std::vector<double> randomPoints(std::size_t n, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> g(0.0, 1.0);
  std::vector<double> v(3 * n);
  for (double& x : v) x = g(rng);
  return v;
}
std::vector<double> applySimilarity(const std::vector<double>& x, const Eigen::Matrix3d& R, const Eigen::Vector3d& t,
                                    double s) {
  std::vector<double> y(x.size());
  for (std::size_t i = 0; i < x.size() / 3; ++i) {
    const Eigen::Vector3d p = s * R * Eigen::Vector3d(x[3 * i], x[3 * i + 1], x[3 * i + 2]) + t;
    for (int k = 0; k < 3; ++k) y[3 * i + k] = p[k];
  }
  return y;
}
CloudView<double> view(const std::vector<double>& v) { return CloudView<double>(v.data(), v.size() / 3); }
}  // namespace

TEST(Rigid, AcceptsRotationsThroughFloatAndRejectsEverythingElse) {
  const Eigen::Matrix4d T = rigid(0.3, -0.2, 0.5, 0.7, -1.1, 0.4);
  EXPECT_TRUE(isRigid(T));
  EXPECT_TRUE(isRigid(T.cast<float>().cast<double>()));  // float rounding: ~1e-7
  Eigen::Matrix4d bad = T;
  bad.topLeftCorner<3, 3>() *= 1.001;
  EXPECT_STREQ(rigidProblem(bad), "its rotation block is not orthonormal (to 1e-5)");
  bad = T;
  bad.col(0).head<3>() *= -1.0;
  EXPECT_STREQ(rigidProblem(bad), "its rotation block is a reflection (determinant -1)");
  bad = T;
  bad(3, 0) = 0.5;
  EXPECT_STREQ(rigidProblem(bad), "its last row (the bottom row) is not 0 0 0 1");
  bad = T;
  bad(1, 3) = std::numeric_limits<double>::quiet_NaN();
  EXPECT_STREQ(rigidProblem(bad), "it has non-finite entries");
  try {
    requireRigid(bad, "T_base_camera");
    FAIL() << "no throw";
  } catch (const std::invalid_argument& e) {
    EXPECT_STREQ(e.what(), "T_base_camera is not a rigid transform: it has non-finite entries");
  }
  EXPECT_NO_THROW(requireRigid(T, "T"));
}

TEST(Rigid, FitSimilarityRecoversKnownMotionsAndMatchesEigen) {
  const auto x = randomPoints(200, 1);
  const Eigen::Matrix4d G = rigid(0.5, 1.0, -2.0, 2.5, -0.4, 1.3);
  const Eigen::Matrix3d R = G.topLeftCorner<3, 3>();
  const Eigen::Vector3d t = G.topRightCorner<3, 1>();
  const Similarity rigid_fit = fitSimilarity(view(x), view(applySimilarity(x, R, t, 1.0)));
  EXPECT_LT((rigid_fit.R - R).cwiseAbs().maxCoeff(), 1e-12);
  EXPECT_LT((rigid_fit.t - t).cwiseAbs().maxCoeff(), 1e-12);
  EXPECT_EQ(rigid_fit.scale, 1.0);
  const Similarity scaled = fitSimilarity(view(x), view(applySimilarity(x, R, t, 2.5)), true);
  EXPECT_NEAR(scaled.scale, 2.5, 1e-12);
  EXPECT_LT((scaled.R - R).cwiseAbs().maxCoeff(), 1e-12);
  // Noisy correspondences: the same answer as Eigen::umeyama (an independent implementation).
  auto y = applySimilarity(x, R, t, 0.8);
  std::mt19937 rng(2);
  std::normal_distribution<double> noise(0.0, 0.05);
  for (double& v : y) v += noise(rng);
  const Eigen::Matrix<double, 3, Eigen::Dynamic> X = Eigen::Map<const Eigen::Matrix<double, 3, Eigen::Dynamic>>(x.data(), 3, 200);
  const Eigen::Matrix<double, 3, Eigen::Dynamic> Y = Eigen::Map<const Eigen::Matrix<double, 3, Eigen::Dynamic>>(y.data(), 3, 200);
  for (bool with_scale : {false, true}) {
    const Eigen::Matrix4d oracle = Eigen::umeyama(X, Y, with_scale);
    const Eigen::Matrix4d ours = fitSimilarity(view(x), view(y), with_scale).matrix();
    EXPECT_LT((ours - oracle).cwiseAbs().maxCoeff(), 1e-10) << with_scale;
  }
}

TEST(Rigid, RotationFromCrossCovarianceNeverReflects) {
  // A mirror image: the best proper rotation, not the reflection that fits exactly.
  const auto x = randomPoints(50, 3);
  std::vector<double> y = x;
  for (std::size_t i = 0; i < y.size(); i += 3) y[i + 2] = -y[i + 2];
  const Similarity s = fitSimilarity(view(x), view(y));
  EXPECT_NEAR(s.R.determinant(), 1.0, 1e-12);
  EXPECT_TRUE(isRigid(s.matrix()));
  const CrossCovarianceRotation rot = rotationFromCrossCovariance(Eigen::Matrix3d::Identity() * -1.0);
  EXPECT_EQ(rot.d, -1.0);
  EXPECT_NEAR(rot.R.determinant(), 1.0, 1e-12);
  EXPECT_EQ(rot.rank(1e-10), 3);
}

TEST(Rigid, FitSimilarityRejectsBadInput) {
  const auto x = randomPoints(10, 4);
  EXPECT_THROW(fitSimilarity(CloudView<double>(x.data(), 2), CloudView<double>(x.data(), 2)), std::invalid_argument);
  EXPECT_THROW(fitSimilarity(CloudView<double>(x.data(), 10), CloudView<double>(x.data(), 9)), std::invalid_argument);
  std::vector<double> line;
  for (int i = 0; i < 10; ++i) line.insert(line.end(), {0.1 * i, 0.2 * i, 0.3 * i});
  EXPECT_THROW(fitSimilarity(view(line), view(line)), std::invalid_argument);
  std::vector<double> nan = x;
  nan[4] = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(fitSimilarity(view(nan), view(x)), std::invalid_argument);
}

TEST(TransformPoints, AnalyticMotionsExactly) {
  // A quarter turn about z and a translation by powers of two: every product and sum is exact.
  Eigen::Matrix4d T = Eigen::Matrix4d::Identity();
  T.topLeftCorner<3, 3>() << 0, -1, 0, 1, 0, 0, 0, 0, 1;
  T.topRightCorner<3, 1>() << 0.5, -0.25, 2.0;
  const std::vector<double> p{1, 2, 3, -0.5, 0.125, 7};
  const std::vector<double> q = transformPoints(T, view(p));
  EXPECT_EQ(q, (std::vector<double>{-2 + 0.5, 1 - 0.25, 3 + 2.0, -0.125 + 0.5, -0.5 - 0.25, 7 + 2.0}));
  // A scale is applied as given (not required to be rigid).
  const Eigen::Matrix4d S = Eigen::Vector4d(2, 3, 4, 1).asDiagonal();
  EXPECT_EQ(transformPoints(S, view(p)), (std::vector<double>{2, 6, 12, -1, 0.375, 28}));
}

TEST(TransformPoints, AgreesWithEigenAffineProductsInBothPrecisions) {
  const Eigen::Matrix4d T = rigid(0.3, -0.2, 0.5, 0.7, -1.1, 0.4);
  const auto x = randomPoints(500, 5);
  const std::vector<double> y = transformPoints(T, view(x));
  std::vector<float> xf(x.begin(), x.end());
  const std::vector<float> yf = transformPoints(T, CloudView<float>(xf.data(), 500));
  const std::vector<double> xfd(xf.begin(), xf.end());
  const std::vector<double> yfd = transformPoints(T, view(xfd));  // the float points in double
  const Eigen::Affine3d A(T);
  for (std::size_t i = 0; i < 500; ++i) {
    const Eigen::Vector3d want = A * Eigen::Vector3d(x[3 * i], x[3 * i + 1], x[3 * i + 2]);
    const Eigen::Vector3d wantf = A * Eigen::Vector3d(xf[3 * i], xf[3 * i + 1], xf[3 * i + 2]);
    for (int k = 0; k < 3; ++k) {
      EXPECT_NEAR(y[3 * i + k], want[k], 1e-14);
      EXPECT_EQ(yf[3 * i + k], static_cast<float>(yfd[3 * i + k]));  // computed in double, rounded once
      EXPECT_NEAR(yf[3 * i + k], wantf[k], 1e-6);
    }
  }
}

TEST(TransformPoints, StridedInputInPlaceAndBadTransforms) {
  const Eigen::Matrix4d T = rigid(0.1, 0.2, 0.3, 1, 2, 3);
  // Rows of 4 floats (a PCL PointXYZ layout) read through the stride.
  std::vector<float> xyzw{1, 2, 3, 99, 4, 5, 6, 99};
  const std::vector<float> strided = transformPoints(T, CloudView<float>(xyzw.data(), 2, 4));
  std::vector<float> packed{1, 2, 3, 4, 5, 6};
  EXPECT_EQ(strided, transformPoints(T, CloudView<float>(packed.data(), 2)));
  transformPoints(T, CloudView<float>(packed.data(), 2), packed.data());  // in place
  EXPECT_EQ(packed, strided);
  // Non-finite points stay non-finite rows; nothing else is touched.
  std::vector<double> nan{std::nan(""), 0, 0, 1, 1, 1};
  const std::vector<double> out = transformPoints(T, view(nan));
  EXPECT_TRUE(std::isnan(out[0]) && std::isfinite(out[3]));
  Eigen::Matrix4d projective = T;
  projective(3, 0) = 0.1;
  EXPECT_THROW(transformPoints(projective, view(nan)), std::invalid_argument);
  Eigen::Matrix4d infinite = T;
  infinite(0, 3) = std::numeric_limits<double>::infinity();
  EXPECT_THROW(transformPoints(infinite, view(nan)), std::invalid_argument);
  EXPECT_TRUE(transformPoints(T, CloudView<double>()).empty());
}
