// The build reports what it holds, and a build without PCL refuses the PCL baselines by name.
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "scanalign/common/build_info.hpp"
#include "scanalign/pose/pcl/feature_alignment.hpp"
#include "scanalign/registration/pcl/baselines.hpp"

namespace {

TEST(BuildInfo, VersionAndPclMatchTheConfiguration) {
  EXPECT_EQ(std::string(scanalign::version()), EXPECTED_VERSION);
  EXPECT_EQ(scanalign::builtWithPcl(), static_cast<bool>(EXPECTED_PCL));
}

TEST(BuildInfo, PclBaselinesRunOrNameTheMissingOption) {
  // Three points of a plane and their exact copy: the stock PCL ICP converges at identity.
  const std::vector<float> pts{0, 0, 0.5f, 0.1f, 0, 0.5f, 0, 0.1f, 0.5f, 0.1f, 0.1f, 0.52f};
  const std::vector<float> nrm{0, 0, 1, 0, 0, 1, 0, 0, 1, 0, 0, 1};
  const scanalign::CloudView<float> cloud(pts.data(), 4), normals(nrm.data(), 4);
  if (scanalign::builtWithPcl()) {
    const auto r = scanalign::pclIcp(cloud, cloud, normals, Eigen::Matrix4d::Identity(), scanalign::IcpSettings{},
                                     scanalign::PclIcpVariant::Svd);
    EXPECT_LT((r.T_target_source - Eigen::Matrix4d::Identity()).cwiseAbs().maxCoeff(), 1e-6);
    return;
  }
  try {
    scanalign::pclIcp(cloud, cloud, normals, Eigen::Matrix4d::Identity(), scanalign::IcpSettings{},
                      scanalign::PclIcpVariant::Svd);
    FAIL() << "pclIcp ran in a build without PCL";
  } catch (const scanalign::NotBuiltError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("'svd'"), std::string::npos) << what;
    EXPECT_NE(what.find("SCANALIGN_WITH_PCL=ON"), std::string::npos) << what;
  }
  EXPECT_THROW(scanalign::pclFeatureAlignment(cloud, cloud), scanalign::NotBuiltError);
  EXPECT_THROW(scanalign::boxRejectorKeep(cloud, {0, 1}, scanalign::Box{}), scanalign::NotBuiltError);
  EXPECT_STREQ(scanalign::toString(scanalign::PclDescriptor::SHOT), "shot");  // names exist in every build
}

}  // namespace
