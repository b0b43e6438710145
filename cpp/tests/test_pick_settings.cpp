// The pick job's settings (scanalign/grasp/pick_settings.hpp): the pick pipeline's defaults,
// which validate, and validate() naming a bad nested field with its path.
#include <gtest/gtest.h>

#include <stdexcept>
#include <string>

#include "scanalign/grasp/assembly_settings.hpp"
#include "scanalign/grasp/pick_settings.hpp"

namespace {

using namespace scanalign;

/// The message validate() throws for `s` ("" when it passes).
template <typename Settings>
std::string problem(const Settings& s) {
  try {
    s.validate();
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "";
}

TEST(PickSettings, DefaultsAreThePickPipelinesAndValidate) {
  const PickSettings s;
  EXPECT_EQ(problem(s), "");
  // python/scanalign/pick.py's PickSettings and the pipeline's calls.
  EXPECT_EQ(s.reconstruction.pixel_stride, 2);
  EXPECT_EQ(s.reconstruction.min_depth, 0.1);
  EXPECT_EQ(s.reconstruction.max_depth, 1.0);
  EXPECT_EQ(s.reconstruction.model_frame, ModelFrame::Base);
  EXPECT_EQ(s.reconstruction.registration, RegistrationMethod::Scanalign);
  EXPECT_FALSE(s.reconstruction.filter_depth);
  EXPECT_EQ(s.reconstruction.frame_to_model.icp.max_correspondence_distance, 0.003);
  EXPECT_EQ(s.reconstruction.frame_to_model.model_voxel_size, 0.001);
  EXPECT_EQ(s.reconstruction.frame_to_model.motion_model, MotionModel::Reference);
  EXPECT_EQ(s.find_parts.table.plane.threshold, 0.004);
  EXPECT_EQ(s.find_parts.table.up, Eigen::Vector3d(0, 0, 1));
  EXPECT_FALSE(s.find_parts.table.viewpoint.has_value());
  EXPECT_EQ(s.find_parts.table.cluster_tolerance, 0.01);
  EXPECT_EQ(s.find_parts.table.min_cluster_size, 300u);
  EXPECT_EQ(s.find_parts.max_objects, 10u);
  EXPECT_EQ(s.find_parts.voxel_size, 0.001);
  EXPECT_EQ(s.find_parts.cbd_radius_fraction, 0.15);
  EXPECT_EQ(s.find_parts.pose.views.resolution, 100);  // find_parts' own default
  EXPECT_EQ(s.find_parts.pose.cbd.hypotheses, 1);
  EXPECT_EQ(s.find_parts.pose.method, CoarseMethod::Cbd);
  EXPECT_EQ(s.views, PickViews::Upper);
  EXPECT_STREQ(toString(PickViews::Upper), "upper");
  EXPECT_STREQ(toString(PickViews::All), "all");
  const GraspPlannerSettings planner;
  EXPECT_EQ(s.planner.table_clearance, planner.table_clearance);
  EXPECT_EQ(s.planner.min_wrist_angle, planner.min_wrist_angle);
}

TEST(PickSettings, ValidateNamesTheBadNestedField) {
  PickSettings s;
  s.reconstruction.pixel_stride = 0;
  std::string m = problem(s);
  EXPECT_NE(m.find("reconstruction"), std::string::npos) << m;
  EXPECT_NE(m.find("pixel_stride"), std::string::npos) << m;

  s = PickSettings();
  s.reconstruction.frame_to_model.icp.max_correspondence_distance = -1;
  m = problem(s);
  EXPECT_NE(m.find("frame_to_model"), std::string::npos) << m;

  s = PickSettings();
  s.find_parts.max_objects = 0;
  m = problem(s);
  EXPECT_NE(m.find("find_parts: max_objects"), std::string::npos) << m;

  s = PickSettings();
  s.find_parts.table.cluster_tolerance = 0;
  m = problem(s);
  EXPECT_NE(m.find("find_parts: table"), std::string::npos) << m;
  EXPECT_NE(m.find("cluster_tolerance"), std::string::npos) << m;

  s = PickSettings();
  s.find_parts.pose.inlier_threshold = -0.005;
  m = problem(s);
  EXPECT_NE(m.find("find_parts: inlier_threshold"), std::string::npos) << m;

  s = PickSettings();
  s.planner.approach_step = 0;
  m = problem(s);
  EXPECT_NE(m.find("planner"), std::string::npos) << m;
  EXPECT_NE(m.find("approach_step"), std::string::npos) << m;

  s = PickSettings();
  s.views = static_cast<PickViews>(7);
  EXPECT_NE(problem(s).find("views"), std::string::npos);
}

// The assembly job's settings: the time-of-flight detection defaults differ from the pick job's
// merged-scan ones where the single view needs it, and validate() names the nested field.
TEST(AssemblySettings, DefaultsAreTheSingleViewOnesAndValidate) {
  const AssemblySettings s;
  const PickSettings pick;
  EXPECT_EQ(problem(s), "");
  EXPECT_LT(s.find_parts.table.plane.threshold, pick.find_parts.table.plane.threshold);
  EXPECT_GT(s.find_parts.table.cluster_tolerance, pick.find_parts.table.cluster_tolerance);
  EXPECT_LT(s.find_parts.table.min_cluster_size, pick.find_parts.table.min_cluster_size);
  EXPECT_LT(s.view.height, ViewPlannerSettings().height);
  EXPECT_EQ(s.views, PickViews::Upper);
}

TEST(AssemblySettings, ValidateNamesTheBadNestedField) {
  AssemblySettings s;
  s.refine_2d.max_steps = 0;
  std::string m = problem(s);
  EXPECT_NE(m.find("assembly settings: refine_2d"), std::string::npos) << m;
  s = AssemblySettings();
  s.view.height = -0.1;
  m = problem(s);
  EXPECT_NE(m.find("assembly settings: view"), std::string::npos) << m;
  s = AssemblySettings();
  s.find_parts.table.cluster_tolerance = 0;
  m = problem(s);
  EXPECT_NE(m.find("find_parts: table"), std::string::npos) << m;
  s = AssemblySettings();
  s.planner.approach_step = 0;
  m = problem(s);
  EXPECT_NE(m.find("assembly settings: planner"), std::string::npos) << m;
}

}  // namespace
