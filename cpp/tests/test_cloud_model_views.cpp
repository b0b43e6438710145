// Views of a model cloud (cloudModelViews): on a convex body a surface point is visible from a
// camera exactly when its outward normal faces the camera, which gives an analytic oracle.
#include <gtest/gtest.h>

#include <random>
#include <set>
#include <stdexcept>
#include <vector>

#include "scanalign/pose/model_views.hpp"

namespace scanalign {
namespace {

/// Points uniform on the surface of a cube of edge `a` centred at the origin, with outward normals.
void cubeSurface(double a, int n, std::vector<double>& points, std::vector<double>& normals) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(-0.5 * a, 0.5 * a);
  for (int i = 0; i < n; ++i) {
    const int face = i % 6, axis = face / 2;
    const double sign = face % 2 ? 1.0 : -1.0;
    Eigen::Vector3d p(u(rng), u(rng), u(rng)), nrm = Eigen::Vector3d::Zero();
    p[axis] = 0.5 * a * sign;
    nrm[axis] = sign;
    points.insert(points.end(), {p.x(), p.y(), p.z()});
    normals.insert(normals.end(), {nrm.x(), nrm.y(), nrm.z()});
  }
}

TEST(CloudModelViews, AConvexBodyShowsExactlyItsFacesTowardsTheCamera) {
  std::vector<double> P, N;
  cubeSurface(0.05, 60000, P, N);
  ModelViewSettings s;
  s.resolution = 100;
  for (const bool given : {true, false}) {
    const auto views = cloudModelViews(CloudView<double>(P.data(), P.size() / 3),
                                       given ? CloudView<double>(N.data(), N.size() / 3) : CloudView<double>(), s);
    ASSERT_EQ(views.size(), 42u);
    EXPECT_TRUE(isCloudModel(views));
    for (const ModelView& v : views) {
      const Eigen::Vector3d eye = v.T_model_camera.topRightCorner<3, 1>();
      std::set<std::pair<int, int>> pixels;
      for (std::size_t i = 0; i < v.size(); ++i) {
        const Eigen::Vector3d p = v.cloud()[i];
        // The outward normal of the face p lies on (the largest coordinate's axis).
        Eigen::Index axis;
        p.cwiseAbs().maxCoeff(&axis);
        const Eigen::Vector3d outward = Eigen::Vector3d::Unit(axis) * (p[axis] > 0 ? 1.0 : -1.0);
        // A back face shows only where it meets a front face, within the depth tolerance (two
        // discs of 0.75 pixel, 2 mm here) of the edge.
        const double to_edge = 0.025 - (p.cwiseAbs().array() < 0.025 - 1e-12).select(p.cwiseAbs().array(), 0).maxCoeff();
        if (outward.dot(eye - p) < 0) EXPECT_LT(to_edge, 2.5e-3) << "a back face point in view, " << to_edge << " m from an edge";
        EXPECT_GE(v.normalCloud()[i].dot(eye - p), 0.0);  // turned towards the camera
        EXPECT_TRUE(pixels.insert({v.pixels[2 * i], v.pixels[2 * i + 1]}).second);  // one point per pixel
      }
      EXPECT_GT(v.size(), 500u);  // the cube fills a good part of the image
    }
  }
}

TEST(CloudModelViews, BadCloudsAndSettingsAreRefusedNamingTheCause) {
  std::vector<double> P, N;
  cubeSurface(0.05, 600, P, N);
  const CloudView<double> cloud(P.data(), P.size() / 3);
  ModelViewSettings s;
  EXPECT_THROW(cloudModelViews(CloudView<double>(P.data(), 2), {}, s), std::invalid_argument);
  EXPECT_THROW(cloudModelViews(cloud, CloudView<double>(N.data(), 10), s), std::invalid_argument);
  std::vector<double> bad = P;
  bad[4] = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(cloudModelViews(CloudView<double>(bad.data(), bad.size() / 3), {}, s), std::invalid_argument);
  s.cloud.normal_radius = 1e-6;  // no neighbours: no normals
  try {
    cloudModelViews(cloud, {}, s);
    FAIL() << "expected invalid_argument";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("normal_radius"), std::string::npos) << e.what();
  }
  s = ModelViewSettings();
  s.cloud.splat_radius = -1;
  EXPECT_THROW(cloudModelViews(cloud, {}, s), std::invalid_argument);
  s = ModelViewSettings();
  s.level = 9;
  EXPECT_THROW(cloudModelViews(cloud, {}, s), std::invalid_argument);
}

}  // namespace
}  // namespace scanalign
