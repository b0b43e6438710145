// Which of several known parts lies in each object cluster of a table scene, and its pose
// (Kleppe, PhD thesis, NTNU 2018, ch. 7: the CAD pose of pose_estimation.hpp per part and
// cluster). The table is segmented once (as findObjects, find_objects.hpp), every part's views
// are aligned to each cluster, the best part is named, and the detection is "ambiguous" when
// another part or a pose of the same part that its symmetry does not make equivalent scores
// alike.
//
// Frames and units: metres and radians. T_scene_model maps model (CAD) coordinates into the
// scene frame.
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "scanalign/common/cloud_view.hpp"
#include "scanalign/pose/model_views.hpp"
#include "scanalign/pose/part_symmetry.hpp"
#include "scanalign/pose/pose_estimation.hpp"
#include "scanalign/segmentation/table_segmentation.hpp"

namespace scanalign {

/// How findParts judged one object cluster.
enum class DetectionStatus {
  Found,      ///< the best part's best pose passes min_fitness / min_coverage and nothing else scores alike
  NotFound,   ///< no part's pose passes min_fitness / min_coverage (or every part was skipped by size)
  Ambiguous,  ///< found, but a runner-up (another part, or a pose of the same part that its symmetry does
              ///< not make equivalent) scores within ambiguity_margin of the best
};
const char* toString(DetectionStatus status);

struct FindPartsSettings {
  TableSegmentationSettings table = objectTableSettings();  ///< table plane and object clusters (m)
  std::size_t max_objects = 5;      ///< clusters tried, largest first
  /// Per cluster and part, as estimatePose, but one RANSAC hypothesis per view
  /// (cbd.hypotheses = 1): every view of every part already brings its own hypothesis, and
  /// the candidate selection below was measured worse with three per view (on the KR6 cell with
  /// Zivid-like noise, seed 4, a standoff 14.6 degrees off about its axis won the score).
  /// Views rendered at 100 pixels (pose.views.resolution), not 150: as accurate on the
  /// built-in parts and 2 to 3 times faster.
  PoseSettings pose = [] {
    PoseSettings p;
    p.cbd.hypotheses = 1;
    p.views.resolution = 100;
    return p;
  }();
  /// A runner-up whose score reaches (1 - ambiguity_margin) x the best score makes the
  /// detection ambiguous (score = harmonic mean of fitness and coverage, in [0, 1]). 0.02,
  /// not more: at inlier_threshold 5 mm the score saturates, and a bracket slid 8 mm along
  /// its plates (a distinct, wrong ICP minimum) still scored 0.977 against 0.999.
  double ambiguity_margin = 0.02;
  /// A runner-up fits alike only if its inlier RMSE is at most this times the best's (0: no
  /// RMSE test). The score saturates at inlier_threshold, the RMSE does not: the bracket slid
  /// 8 mm along its plates scored 0.987 against 0.999 (inside the margin) at 3 times the
  /// best's RMSE. Two copies of one model, or a symmetric part given without its symmetry, fit
  /// equally tightly and stay ambiguous.
  double ambiguity_rmse_ratio = 1.5;
  /// Candidates of the best part scoring within score_tie of its best score are ties: the one
  /// with the smallest inlier RMSE is reported (with sensor noise far below
  /// inlier_threshold, fitness and coverage saturate at 1 for poses a degree apart).
  double score_tie = 0.01;
  /// m; the reported candidate is refined once more by point-to-plane ICP with
  /// correspondences within this distance and a tight stop (1e-14), and appended to the
  /// part's candidates; it replaces the pick unless its score drops by more than score_tie.
  /// 0 = no polish.
  double polish_distance = 0.003;
  /// Two poses of the same part are the same pose when symmetricPoseError (over the part's
  /// symmetry) is at most same_pose_angle (rad) and same_pose_distance (m): the views that
  /// converge to one pose, or to one of a symmetric part's equivalent poses, never compete.
  double same_pose_angle = 5 * M_PI / 180;
  double same_pose_distance = 0.005;
  /// Cheap size gate before any alignment, on the rotation-invariant size of a cloud (its
  /// largest extent along its principal axes, m). A part is skipped for a cluster larger than
  /// max_size_ratio x the part's size (its views together: about its largest dimension; no
  /// view of the part can be larger), or smaller than min_size_ratio x its smallest view
  /// (the part seen from its narrowest side). 0 disables a bound.
  double max_size_ratio = 1.5;
  double min_size_ratio = 0.5;
  /// m; each cluster is reduced to one point per voxel (the centroid) before its pose: a
  /// merged scan holds several times the points the pose needs, and the cost grows with them.
  /// 0 (default) keeps every point: a single depth image of the table is about as dense as
  /// the model views. For a merged multi-view scan, about the views' point spacing (1 to
  /// 1.5 mm at resolution 100 for a 10 cm part).
  double voxel_size = 0.0;
  /// m; a part rests on the table, so a pose that puts any point of the part's surface (its
  /// views merged) more than this below the table plane is physically impossible and is
  /// dropped before the best pose and the runner-up are chosen. With sensor noise of a few
  /// millimetres an upside-down block or standoff still fits its top surface to the scan
  /// (score 0.74 against 0.83 for the true pose) while its boss goes 30 mm into the table.
  /// Infinity disables the check; so does a failed table plane.
  double max_table_penetration = 0.005;
  /// Refine the reported pose once more against the part's whole surface (every view merged,
  /// with its outward normals): point-to-plane ICP of the cluster's points onto the model,
  /// correspondences within polish_distance. A single view explains about half of a cluster
  /// scanned from all round; every cluster point has its surface in the merged model, so the
  /// pose is no longer pulled by the half that view does not see (SR300-like noise: the
  /// standoff's tilt from 2.2 to 0.1 degrees). Kept while it stays the same pose
  /// (same_pose_angle, same_pose_distance). A same-part rival is polished the same way before
  /// it may make the detection ambiguous.
  bool surface_polish = true;
  /// CBD neighbourhood radius per part as a fraction of the part's size (its views together,
  /// PartSize::whole): radius = max(pose.cbd.cbd.radius, cbd_radius_fraction x size). 0
  /// (default) keeps the fixed radius. The hypothesis "this cluster is part p" fixes the scale
  /// the descriptor should have; tied to the part, the model's descriptors depend on the part
  /// alone and are computed once (partPoseSettings, describeModelViews: a part library),
  /// while the cluster is described once per distinct radius.
  /// On merged scans with millimetre noise the descriptor needs a neighbourhood well above
  /// the noise on large parts (12.5 mm on the 85 mm block: the thesis's 6.3 mm lost it in one
  /// SR300-like scan in eight) but a small part needs a small one (6.3 mm on the 37 mm
  /// standoff: 12.5 mm lost it in two Zivid-like scans in four); 0.15 gives both.
  double cbd_radius_fraction = 0.0;
  /// A detection needs at least this fraction of its cluster's points within polish_distance
  /// of the part's whole surface at the reported pose (PartDetection::surface_coverage);
  /// below it the status is not_found. Every point of a cluster that is this part lies on
  /// its surface (0.999 at 3 mm on the built-in parts with SR300-like noise); a part of
  /// another size, or another part, leaves points unexplained (a block 1.6 times too large
  /// 0.94 at best, the block on the bracket's cluster 0.49), while fitness and coverage,
  /// measured on one view with inlier_threshold, still pass. 0 disables the check.
  double min_surface_coverage = 0.97;
  /// Instances per object cluster: touching parts, a part leaning on another, a heap of
  /// copies give one Euclidean cluster. When the cluster is not one part (or the part found
  /// leaves at least table.min_cluster_size points unexplained), rounds of hypotheses (every
  /// view of every part, without the upper size gate) run on the points no instance explains
  /// yet; each is verified against the cluster and the best are accepted, each point explained
  /// by at most one instance (part_instances.cpp). 1 (default): one part per cluster; a heap
  /// or touching parts need more (10 in the tests and bench_heap). Not the default: in the
  /// Kinect-like Paper 3 scenes a wrong instance 7 cm off was taken where no part was found.
  std::size_t max_instances = 1;
  /// One of several instances in a cluster needs pose.min_fitness, table.min_cluster_size
  /// points explained, and this score: the harmonic mean of its fitness (its view's points
  /// within pose.inlier_threshold of the cluster) and its agreement, the share of explained
  /// points among the free points near it that bear on it: explained (within inlier_threshold
  /// of its surface, normals within 45 degrees), inside the placed part, or continuing the
  /// surface of an explained point past the part's border (within inlier_threshold of its
  /// tangent plane, up to 3 inlier thresholds away, normals within 25 degrees). On heaps of
  /// the built-in parts with Zivid-like noise the true poses of copies seen to 80 % or more
  /// scored 0.92 to 1.00, poses 14 to 33 mm off 0.73 to 0.86.
  double min_instance_score = 0.9;
};
void validate(const FindPartsSettings& settings);

/// The pose settings findParts matches part `views` with: settings.pose with the CBD radius of
/// this part (cbd_radius_fraction). Describe a part's views with them (describeModelViews) and
/// findParts reuses the descriptors.
PoseSettings partPoseSettings(const std::vector<ModelView>& views, const FindPartsSettings& settings);

/// One object cluster and the part found in it.
struct PartDetection {
  DetectionStatus status = DetectionStatus::NotFound;
  int part = -1;                 ///< index of the best-scoring part (-1: every part was skipped)
  PoseResult pose;               ///< that part's pose (found false unless status is Found or Ambiguous)
  double score = 0;              ///< the reported candidate's score
  int runner_up_part = -1;       ///< part of the best competing pose (-1: none)
  double runner_up_score = 0;    ///< its score
  /// symmetricPoseError(best pose, runner-up pose) over the best part's symmetry: rad, m.
  double runner_up_angle = 0, runner_up_distance = 0;
  /// Fraction of the cluster's points within polish_distance of the part's whole surface at
  /// the reported pose (FindPartsSettings::min_surface_coverage); 0 when nothing was found.
  double surface_coverage = 0;
  /// The points of this detection (indices into the scene, before the voxel grid): its whole
  /// cluster, or, for one of several instances in a cluster, the points it explains.
  std::vector<std::uint32_t> indices;
  int cluster = -1;                    ///< its cluster in FindPartsResult::table.objects
  std::vector<PoseResult> parts;       ///< per part; a part skipped by the size gate says so in its message
  double size = 0;                     ///< the cluster's size (largest principal extent), m
  std::string message;                 ///< why not found, or what made it ambiguous
  double seconds = 0;                  ///< wall time of this cluster, all parts
};

struct FindPartsResult {
  /// Per object cluster (largest first), its part or its instances (max_instances): a cluster
  /// with none gives one not_found detection.
  std::vector<PartDetection> detections;
  TableSegmentationResult table;          ///< plane, clusters and counts
  double seconds = 0;                     ///< wall time
};

/// Which of several known parts lies in each object cluster of a table scene, and its pose.
/// `models[p]`: part p's views (renderModelViews); `symmetries`: one per part, or empty
/// (none symmetric). The table is segmented once (as findObjects); each cluster's normals
/// and descriptors are computed once and every part's views aligned to it (estimatePose),
/// parts outside the size gate skipped. `view_ids` (empty: all) applies to every part.
/// @throws std::invalid_argument for no models, a part without views, a symmetry count
///         other than models.size(), a bad symmetry or settings, a view index out of range.
FindPartsResult findParts(const std::vector<std::vector<ModelView>>& models, const std::vector<PartSymmetry>& symmetries,
                          const CloudView<double>& scene, const FindPartsSettings& settings = {},
                          const std::vector<int>& view_ids = {}, const CoarseAligner& aligner = {},
                          const PoseProgress& progress = {});

}  // namespace scanalign
