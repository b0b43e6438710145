// Pose of a known part in one object cloud from its CAD model: the pose step of the pipeline
// of Kleppe, PhD thesis, NTNU 2018, ch. 6-7 (papers 4 and 5). Every model view
// (model_views.hpp) is coarsely aligned to the object (CBD + RANSAC with a motor refit, paper
// 4's flags, a stock PCL baseline, or a caller's aligner), refined with scanalign's
// point-to-plane ICP, and scored by the harmonic mean of fitness (model points near the
// object) and coverage (object points near the placed model). find_objects.hpp runs it on
// every object cluster of a table scene; part_identification.hpp names the part in each
// cluster among several known parts.
//
// Frames and units: metres. T_scene_model maps model (CAD) coordinates into the scene frame.
#pragma once

#include <cstddef>
#include <functional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "scanalign/common/cloud_view.hpp"
#include "scanalign/pose/cbd.hpp"
#include "scanalign/pose/cbd_alignment.hpp"
#include "scanalign/pose/flag_alignment.hpp"
#include "scanalign/pose/model_views.hpp"
#include "scanalign/pose/pcl/feature_alignment.hpp"

namespace scanalign {

/// How each model view is brought near the object before ICP.
enum class CoarseMethod {
  Cbd,       ///< curvature-based descriptor matches + RANSAC + motor refit (paper 5)
  Flags,     ///< centroid + average normal line, motor by Levenberg-Marquardt (paper 4)
  Pcl,       ///< the stock PCL baseline of PoseSettings::pcl (thesis §7.6); NotBuiltError without PCL
  External,  ///< a caller-supplied CoarseAligner
};
const char* toString(CoarseMethod method);

struct PoseSettings {
  CoarseMethod method = CoarseMethod::Cbd;
  double inlier_threshold = 0.005;  ///< m; fitness/coverage distance and the CBD RANSAC inlier threshold (thesis: 5 mm); at a quarter of the model size or more the result is not found (fitness would not discriminate)
  double icp_distance = 0.01;       ///< m; ICP maximum correspondence distance
  double normal_radius = 0.005;     ///< m; scene normals for point-to-plane ICP and flags
  /// A pose counts as found only when the best view's points lie on the object (fitness) and
  /// cover it (coverage) at least this much: a scene without the part still has a "best"
  /// view, typically with high fitness on clutter but low coverage.
  double min_fitness = 0.5;
  double min_coverage = 0.5;
  /// CBD settings. min_neighbors defaults to 0 (automatic) here, since scan density varies;
  /// ransac.inlier_threshold is replaced by inlier_threshold.
  CbdAlignmentSettings cbd = [] {
    CbdAlignmentSettings s;
    s.cbd.min_neighbors = 0;
    return s;
  }();
  FlagAlignmentSettings flags;      ///< paper 4 settings
  /// The stock PCL baseline of method Pcl: descriptor, matcher, radii (default the thesis's
  /// FPFH preset, thesisPclPreset(PclDescriptor::FPFH)).
  PclFeatureAlignmentSettings pcl;
  /// How the part's mesh is rendered into the model views (renderModelViews). The functions
  /// here take views already rendered (once per part, reused for every scene): this is what
  /// the caller renders them with, so that one struct holds everything a pose from a CAD model
  /// needs. 150 pixels by default (the thesis uses 90 to 400).
  ModelViewSettings views;
  int num_threads = 0;              ///< OpenMP threads for every step; 0 = all cores
};
void validate(const PoseSettings& settings);

/// A scene cloud prepared once for every model view: its finite points, normals and (for
/// CBD) descriptors.
struct PreparedScene {
  std::vector<double> points;   ///< finite scene points, N x 3, m
  std::vector<double> normals;  ///< N x 3 unit normals (PCA, radius normal_radius)
  std::vector<double> oriented_points, oriented_normals;  ///< the points whose normal is finite, with it
  CbdFeatures cbd;              ///< CBD keypoints/descriptors (method Cbd only)
  CloudView<double> cloud() const { return {points.data(), points.size() / 3}; }
};
PreparedScene prepareScene(const CloudView<double>& scene, const PoseSettings& settings);

/// The CBD settings estimatePose describes model views with (settings.cbd with its thread
/// counts resolved and the RANSAC inlier threshold set to settings.inlier_threshold).
CbdAlignmentSettings cbdSettings(const PoseSettings& settings);

/// Computes and stores each view's CBD features (ModelView::cbd) with the settings
/// estimatePose would use for `settings`, so later poses skip that work. Views whose cached
/// features already match are left alone. @throws std::invalid_argument for bad settings.
void describeModelViews(std::vector<ModelView>& views, const PoseSettings& settings);

/// Outcome of a coarse aligner for one view.
struct CoarseResult {
  Eigen::Matrix4d T_scene_model = Eigen::Matrix4d::Identity();
  bool found = false;
  std::string message;
};
/// An external coarse aligner: view (model frame) -> scene.
using CoarseAligner = std::function<CoarseResult(const ModelView& view, const PreparedScene& scene)>;
/// Called after each view with (views done, views in all).
using PoseProgress = std::function<void(std::size_t, std::size_t)>;

/// Per-view summary.
struct PoseCandidate {
  int view = -1;               ///< index into the model views
  bool found = false;          ///< the coarse alignment produced a pose
  double coarse_fitness = 0;   ///< fitness after the coarse alignment alone
  double fitness = 0, coverage = 0, inlier_rmse = 0, score = 0;  ///< after ICP (when found)
  /// The view's pose after ICP (model -> scene, m); identity when the coarse alignment found
  /// nothing. Kept so that a caller can compare candidates (findParts' ambiguity test).
  Eigen::Matrix4d T_scene_model = Eigen::Matrix4d::Identity();
};

struct PoseResult {
  Eigen::Matrix4d T_scene_model = Eigen::Matrix4d::Identity();  ///< model -> scene
  bool found = false;          ///< some view aligned and ICP refined it
  double fitness = 0;          ///< fraction of the view's points within inlier_threshold of the object
  double coverage = 0;         ///< fraction of the object's points within inlier_threshold of the placed view
  double inlier_rmse = 0;      ///< m, over the fitness inliers
  /// Coarse method used: "cbd", "flags", "external", or for CoarseMethod::Pcl the baseline's
  /// name (pclBaselineName: "fpfh", "fpfh_sac_ia", "shot", "3dsc", "ppf", "pfh", "rsd", "gasd", "vfh").
  std::string method;
  int view = -1;               ///< index of the best view (-1 when nothing was found)
  double seconds = 0;          ///< wall time, all views
  double coarse_seconds = 0;   ///< the part spent in coarse alignment
  std::vector<PoseCandidate> candidates;  ///< one per view tried
  std::string message;         ///< why nothing was found (a best view below the thresholds keeps its figures)
};

/// Pose of the model in one object cloud (scene frame, m; non-finite rows ignored).
/// `views`: the model's views (renderModelViews with settings.views, or one view built from a
/// model cloud); `view_ids`: which to try (empty: all). `aligner` is required for
/// CoarseMethod::External; CoarseMethod::Pcl builds pclCoarseAligner(settings.pcl) itself.
/// @throws std::invalid_argument for bad settings, an index out of range or a missing aligner;
///         NotBuiltError for CoarseMethod::Pcl in a build without PCL.
PoseResult estimatePose(const std::vector<ModelView>& views, const CloudView<double>& scene,
                        const PoseSettings& settings = {}, const std::vector<int>& view_ids = {},
                        const CoarseAligner& aligner = {}, const PoseProgress& progress = {});

}  // namespace scanalign
